"""The base of every geometry: `Contacts`, `Geometry`, the `Boundary` capability, `GraphGeometry`.

A geometry produces plain data that the compiled loop consumes (`Contacts`):
for each contact the two balls ``i, j`` and the unit vector at each end pointing
to the other ball (``t_i`` at ``i``, ``t_j`` at ``j``). In flat space
``t_j = -t_i``; on a curved surface they live in different tangent planes, and
the loop does not care. People get the same contacts as a networkx graph.
"""

from __future__ import annotations

import functools
from abc import ABC, abstractmethod
from dataclasses import dataclass

import networkx as nx
import numpy as np

from ..errors import FieldError, FieldTypeError

__all__ = ["Contacts", "Geometry", "Boundary", "GraphGeometry", "tangent_contacts"]

SQRT3 = float(np.sqrt(3.0))
_INT32_MAX = np.iinfo(np.int32).max


def _index_dtype(n: int) -> np.dtype:
    """The smallest unsigned integer type that indexes ``n`` rows."""
    for dtype in (np.uint8, np.uint16, np.uint32):
        if n <= np.iinfo(dtype).max + 1:
            return np.dtype(dtype)
    raise FieldError("contacts", f"{n} rows is too many for 32-bit tables")


@dataclass(frozen=True, eq=False)
class Contacts:
    """Contacts in the compact form the compiled loop reads.

    pairs: ``(n_contacts, 2) uint32`` the balls ``i, j`` of each contact.
    ends: ``(n_contacts, 2)`` unsigned rows of ``units`` holding ``t_i`` and ``t_j``
        (uint8 for lattices, which need only six unit vectors).
    units: ``(n_units, dim) float64`` unit vectors.

    Unsigned, narrow indices keep the tables small (a 1000x1000 torus needs 30 MB)
    and spare the loop the negative-index checks.
    """

    pairs: np.ndarray
    ends: np.ndarray
    units: np.ndarray

    @classmethod
    def build(cls, pairs, ends, units) -> "Contacts":
        """Contacts from integer arrays ``pairs (E, 2)``, ``ends (E, 2)`` and ``units (K, dim)``."""
        units = np.ascontiguousarray(units, dtype=np.float64)
        return cls(
            pairs=np.ascontiguousarray(pairs, dtype=np.uint32).reshape(-1, 2),
            ends=np.ascontiguousarray(ends, dtype=_index_dtype(len(units))).reshape(-1, 2),
            units=units,
        )

    @property
    def t_i(self) -> np.ndarray:
        """``(n_contacts, dim)`` unit vector at ``i`` pointing to ``j``."""
        return self.units[self.ends[:, 0]]

    @property
    def t_j(self) -> np.ndarray:
        """``(n_contacts, dim)`` unit vector at ``j`` pointing to ``i``."""
        return self.units[self.ends[:, 1]]

    @functools.cached_property
    def flat(self) -> bool:
        """True when every ``t_j`` is exactly ``-t_i`` (flat space): the loop then reads only ``t_i``."""
        return bool(np.array_equal(np.signbit(self.t_j), ~np.signbit(self.t_i)) and np.array_equal(self.t_j, -self.t_i))

    def __len__(self) -> int:
        return len(self.pairs)


@dataclass(frozen=True, eq=False)
class Boundary:
    """A geometry's boundary as each ball sees it.

    distance: ``(n_balls,) float64`` distance of each centre from the boundary (0 on it).
    outward: ``(n_balls, dim) float64`` unit vectors in each ball's frame, pointing out of the system.
    """

    distance: np.ndarray
    outward: np.ndarray


class Geometry(ABC):
    """Balls at fixed centres and the contacts between them.

    Subclasses set ``positions`` and implement `_build_contacts`. Ball radius is
    ``radius`` (contact distance ``2 * radius``). Capabilities that code above the
    engine asks for instead of a type: `boundary` (None, or a `Boundary`) and
    `frames` (each ball's tangent basis; identity in flat space).
    """

    positions: np.ndarray  #: ``(n_balls, k) float64`` ball centres
    radius: float = 1.0
    #: True when velocities live in tangent planes of a curved surface (`frames` is not the identity)
    curved: bool = False

    @property
    def boundary(self) -> "Boundary | None":
        """The boundary seen from each ball, or None when the geometry has none (torus, sphere)."""
        return None

    def frames(self) -> np.ndarray:
        """``(n_balls, dim, k)`` orthonormal tangent basis of each ball in embedding coordinates.

        A velocity ``v (n_balls, dim)`` in embedding coordinates is
        ``einsum("nd,ndk->nk", v, frames)``. Flat space: the identity (read-only view).
        """
        k = self.positions.shape[1]
        if self.dim != k:
            raise FieldError("frames", f"{type(self).__name__} has dim {self.dim} but {k}-D positions and no frames")
        return np.broadcast_to(np.eye(k), (self.n_balls, k, k))

    def boundary_center(self) -> int:
        """Index of the boundary ball (least ``boundary.distance``) nearest the middle of the boundary balls."""
        b = self.boundary
        if b is None:
            raise FieldError("boundary_center", f"{type(self).__name__} has no boundary")
        d = b.distance
        on = np.flatnonzero(d <= d.min() + 1e-9 * max(1.0, float(np.abs(d).max())))
        p = self.positions[on]
        return int(on[np.argmin(np.linalg.norm(p - p.mean(axis=0), axis=1))])

    @abstractmethod
    def _build_contacts(self) -> Contacts:
        """The contacts, built once on first use."""

    @functools.cached_property
    def contacts(self) -> Contacts:
        """The contacts as compact arrays (built on first use, then kept)."""
        return self._build_contacts()

    @property
    def n_balls(self) -> int:
        return len(self.positions)

    @property
    def dim(self) -> int:
        """Components of a velocity."""
        return self.contacts.units.shape[1]

    @property
    def n_contacts(self) -> int:
        return len(self.contacts)

    def degrees(self) -> np.ndarray:
        """``(n_balls,)`` number of contacts of each ball."""
        return np.bincount(self.contacts.pairs.ravel().astype(np.intp), minlength=self.n_balls)

    def contact_graph(self) -> nx.Graph:
        """A networkx graph: nodes ``0..n_balls-1`` with ``"pos"``, one edge per contact.

        Each edge carries ``"units" = {i: t_i, j: t_j}``, its index ``"contact"`` and its
        orientation ``"pair" = (i, j)``; on a curved surface each node also carries its
        ``"frame"`` (``dim x k``). So ``GraphGeometry(geom.contact_graph())`` rebuilds exactly
        these contacts in the same order (the same seed then gives the same run), periodic or
        curved ones included.
        """
        g = nx.Graph(dim=self.dim)
        frames = self.frames() if self.curved else None
        for n, p in enumerate(self.positions):
            g.add_node(n, pos=tuple(float(x) for x in p))
            if frames is not None:
                g.nodes[n]["frame"] = frames[n].tolist()
        c = self.contacts
        t_i, t_j = c.t_i, c.t_j
        for e, (i, j) in enumerate(c.pairs.tolist()):
            g.add_edge(i, j, contact=e, pair=(i, j), units={i: tuple(t_i[e].tolist()), j: tuple(t_j[e].tolist())})
        return g

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n_balls={self.n_balls}, n_contacts={self.n_contacts}, dim={self.dim})"


# ---------------------------------------------------------------- curved surfaces


def tangent_contacts(pairs: np.ndarray, T_i: np.ndarray, T_j: np.ndarray, frames: np.ndarray,
                     metric: np.ndarray) -> Contacts:
    """Contacts from embedding tangents ``T_i, T_j (E, k)`` at each end, in the balls' ``frames (n, dim, k)``.

    ``metric (k,)`` is the diagonal of the embedding's inner product (all 1, or ``(-1, 1, 1)`` on the
    hyperboloid); components are ``<e_a, T>`` for the frame vectors ``e_a``, then normalised.
    """
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    t_i = np.einsum("edk,ek->ed", frames[pairs[:, 0]], T_i * metric)
    t_j = np.einsum("edk,ek->ed", frames[pairs[:, 1]], T_j * metric)
    e = len(pairs)
    units = np.empty((2 * e, frames.shape[1]))
    units[0::2] = t_i / np.linalg.norm(t_i, axis=1, keepdims=True)
    units[1::2] = t_j / np.linalg.norm(t_j, axis=1, keepdims=True)
    return Contacts.build(pairs, np.arange(2 * e).reshape(e, 2), units)


# ---------------------------------------------------------------- argument checks

def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise FieldTypeError(name, f"must be an integer, got {value!r}")
    if value < minimum:
        raise FieldError(name, f"must be >= {minimum}, got {value}")
    return int(value)


def _check_radius(radius) -> float:
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.number)):
        raise FieldTypeError("radius", f"must be a number, got {radius!r}")
    if not np.isfinite(radius) or radius <= 0:
        raise FieldError("radius", f"must be finite and > 0, got {radius}")
    return float(radius)


# ---------------------------------------------------------------- arbitrary graphs


def _as_positions(positions) -> np.ndarray:
    try:
        p = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("positions", f"must be an array of numbers ({exc})") from None
    if p.ndim == 1:
        p = p[:, None]
    if p.ndim != 2 or p.shape[1] < 1:
        raise FieldError("positions", f"must have shape (n_balls, d), got {p.shape}")
    if not np.isfinite(p).all():
        raise FieldError("positions", "contain NaN or inf")
    return p


def _flat_units(positions: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``(n_contacts, d)`` unit vectors from ``i`` to ``j`` in flat space."""
    delta = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    norm = np.linalg.norm(delta, axis=1)
    bad = np.flatnonzero(norm == 0)
    if len(bad):
        i, j = pairs[bad[0]]
        raise FieldError("contacts", f"balls {i} and {j} have the same centre, so no line of centres")
    return delta / norm[:, None]


class GraphGeometry(Geometry):
    """Any contact graph: balls anywhere in ``R^d`` (``d >= 1``), edges are contacts.

    ``graph`` is a networkx graph whose nodes carry ``"pos"`` (a length-``d``
    sequence). Ball ``n`` is the ``n``-th node of ``graph.nodes``. An edge may
    carry ``"units" = {u: t_u, v: t_v}`` (needed for periodic or curved spaces);
    otherwise ``t_u`` points from ``u`` to ``v`` in a straight line and ``t_v = -t_u``.
    Nodes may carry ``"frame"`` ``(dim, d)``, their tangent basis on a curved surface
    (as `Geometry.contact_graph` writes it); then every edge needs ``"units"`` of length ``dim``.
    """

    def __init__(self, graph: nx.Graph, radius: float = 1.0):
        if not isinstance(graph, nx.Graph) or graph.is_directed() or graph.is_multigraph():
            raise FieldTypeError("graph", f"must be an undirected networkx.Graph, got {type(graph).__name__}")
        if graph.number_of_nodes() == 0:
            raise FieldError("graph", "has no nodes")
        nodes = list(graph.nodes)
        index = {node: n for n, node in enumerate(nodes)}
        missing = [node for node in nodes if "pos" not in graph.nodes[node]]
        if missing:
            raise FieldError("graph", f"node {missing[0]!r} has no 'pos' attribute")
        try:
            positions = _as_positions([graph.nodes[node]["pos"] for node in nodes])
        except (TypeError, ValueError) as exc:
            raise FieldError("graph", f"node 'pos' attributes must be equal-length finite sequences ({exc})") from None
        loops = list(nx.selfloop_edges(graph))
        if loops:
            raise FieldError("graph", f"self-loop at node {loops[0][0]!r}; a ball cannot touch itself")
        edges = self._ordered_edges(graph)
        pairs = np.array([(index[u], index[v]) for u, v, _ in edges], dtype=np.int64).reshape(-1, 2)
        self._frames = self._node_frames(graph, nodes, positions.shape[1])
        self.curved = self._frames is not None
        dim = positions.shape[1] if self._frames is None else self._frames.shape[1]
        if self.curved:
            t_i = np.zeros((len(pairs), dim))
        else:
            t_i = _flat_units(positions, pairs) if len(pairs) else np.zeros((0, dim))
        t_j = -t_i
        for e, (u, v, data) in enumerate(edges):
            if data.get("units") is not None:
                t_i[e], t_j[e] = self._given_units(u, v, data["units"], dim)
            elif self.curved:
                raise FieldError("graph", f"edge ({u!r}, {v!r}) needs 'units' on a curved surface (nodes carry 'frame')")
        self._init(positions, pairs, t_i, t_j, radius)
        self.nodes = nodes

    @staticmethod
    def _node_frames(graph: nx.Graph, nodes: list, k: int) -> np.ndarray | None:
        """``(n_balls, dim, k)`` from the nodes' ``"frame"`` attributes, or None if no node has one."""
        has = ["frame" in graph.nodes[node] for node in nodes]
        if not any(has):
            return None
        if not all(has):
            raise FieldError("graph", f"node {nodes[has.index(False)]!r} has no 'frame' (other nodes have one)")
        try:
            frames = np.array([graph.nodes[node]["frame"] for node in nodes], dtype=np.float64)
        except (TypeError, ValueError):
            raise FieldError("graph", "node 'frame' attributes must be equal-shape (dim, k) arrays of numbers") from None
        if frames.ndim != 3 or frames.shape[2] != k or not np.isfinite(frames).all():
            raise FieldError("graph", f"node 'frame' attributes must be finite (dim, {k}) arrays, got {frames.shape[1:]}")
        return frames

    def frames(self) -> np.ndarray:
        """``(n_balls, dim, k)``: the nodes' ``"frame"`` attributes if given, else the identity."""
        return super().frames() if self._frames is None else self._frames

    @staticmethod
    def _ordered_edges(graph: nx.Graph) -> list[tuple]:
        """``(u, v, data)`` per edge: in contact order, ``u`` first, when every edge carries
        ``"contact"`` (its index) and ``"pair"`` (``(u, v)``), as `Geometry.contact_graph`
        writes them; otherwise in networkx's order."""
        edges = list(graph.edges(data=True))
        if not edges or not all("contact" in d and "pair" in d for _, _, d in edges):
            return edges
        ordered = sorted(edges, key=lambda edge: edge[2]["contact"])
        if [d["contact"] for _, _, d in ordered] != list(range(len(edges))):
            raise FieldError("graph", "edge 'contact' attributes must number the edges 0, 1, ..., n_contacts - 1")
        out = []
        for u, v, d in ordered:
            if {*d["pair"]} != {u, v} or len(d["pair"]) != 2:
                raise FieldError("graph", f"edge ({u!r}, {v!r}) has 'pair' {d['pair']!r}, not its two ends")
            out.append((*d["pair"], d))
        return out

    @staticmethod
    def _given_units(u, v, units, dim: int) -> tuple[np.ndarray, np.ndarray]:
        try:
            tu, tv = np.asarray(units[u], dtype=float), np.asarray(units[v], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise FieldError("graph", f"edge ({u!r}, {v!r}) 'units' must map both ends to a vector") from None
        for t in (tu, tv):
            if t.shape != (dim,) or not np.isfinite(t).all() or abs(np.linalg.norm(t) - 1) > 1e-9:
                raise FieldError("graph", f"edge ({u!r}, {v!r}) 'units' must be unit vectors of length {dim}")
        return tu, tv

    def _init(self, positions, pairs, t_i, t_j, radius) -> None:
        n = len(positions)
        if n > _INT32_MAX or 2 * len(pairs) > _INT32_MAX:
            raise FieldError("graph", "too large for 32-bit contact tables")
        self.positions = positions
        self.radius = _check_radius(radius)
        e = len(pairs)
        units = np.empty((2 * e, t_i.shape[1]))
        units[0::2], units[1::2] = t_i, t_j
        ends = np.arange(2 * e).reshape(e, 2)
        self._contacts = Contacts.build(pairs, ends, units)

    def _build_contacts(self) -> Contacts:
        return self._contacts

    @classmethod
    def from_positions(cls, positions, radius: float = 1.0, rtol: float = 1e-6) -> "GraphGeometry":
        """Balls of ``radius`` at ``positions`` ``(n_balls, d)``; contacts are pairs at distance ``2*radius``.

        Distances within ``rtol * 2 * radius`` of contact count as touching (centres
        computed by repeated addition still touch); closer pairs are overlapping
        balls and an error. Uses a scipy KD-tree: ``O(n log n)``.
        """
        from scipy.spatial import cKDTree

        p = _as_positions(positions)
        radius = _check_radius(radius)
        if not (0 <= rtol < 0.5):
            raise FieldError("rtol", f"must be in [0, 0.5), got {rtol}")
        contact = 2.0 * radius
        pairs = cKDTree(p).query_pairs(contact * (1 + rtol), output_type="ndarray").astype(np.int64)
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if len(pairs) else pairs.reshape(0, 2)
        dist = np.linalg.norm(p[pairs[:, 1]] - p[pairs[:, 0]], axis=1)
        overlap = np.flatnonzero(dist < contact * (1 - rtol))
        if len(overlap):
            i, j = pairs[overlap[0]]
            raise FieldError(
                "positions", f"balls {i} and {j} overlap (centres {dist[overlap[0]]:.6g} apart, "
                f"contact distance {contact:.6g}); {len(overlap)} overlapping pair(s) in all"
            )
        self = cls.__new__(cls)
        self._frames = None
        t_i = _flat_units(p, pairs) if len(pairs) else np.zeros((0, p.shape[1]))
        self._init(p, pairs, t_i, -t_i, radius)
        self.nodes = list(range(len(p)))
        return self
