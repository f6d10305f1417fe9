"""Geometries: where the balls sit and which of them touch.

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

from .errors import FieldTypeError, FieldValueError

__all__ = ["Contacts", "Geometry", "FlatTorus", "HalfPlane", "GraphGeometry"]

SQRT3 = float(np.sqrt(3.0))
_INT32_MAX = np.iinfo(np.int32).max


def _index_dtype(n: int) -> np.dtype:
    """The smallest unsigned integer type that indexes ``n`` rows."""
    for dtype in (np.uint8, np.uint16, np.uint32):
        if n <= np.iinfo(dtype).max + 1:
            return np.dtype(dtype)
    raise FieldValueError("contacts", f"{n} rows is too many for 32-bit tables")


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


class Geometry(ABC):
    """Balls at fixed centres and the contacts between them.

    Subclasses set ``positions`` and implement `_build_contacts`. Ball radius is
    ``radius`` (contact distance ``2 * radius``).
    """

    positions: np.ndarray  #: ``(n_balls, k) float64`` ball centres
    radius: float = 1.0

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
        orientation ``"pair" = (i, j)``, so that ``GraphGeometry(geom.contact_graph())``
        rebuilds exactly these contacts in the same order (the same seed then gives the same
        run), periodic or curved ones included.
        """
        g = nx.Graph(dim=self.dim)
        for n, p in enumerate(self.positions):
            g.add_node(n, pos=tuple(float(x) for x in p))
        c = self.contacts
        t_i, t_j = c.t_i, c.t_j
        for e, (i, j) in enumerate(c.pairs.tolist()):
            g.add_edge(i, j, contact=e, pair=(i, j), units={i: tuple(t_i[e].tolist()), j: tuple(t_j[e].tolist())})
        return g

    def __repr__(self) -> str:
        return f"{type(self).__name__}(n_balls={self.n_balls}, n_contacts={self.n_contacts}, dim={self.dim})"


# ---------------------------------------------------------------- triangular lattices

#: unit vectors of the triangular lattice: row d + 3 is exactly minus row d (signed zeros too)
_LATTICE_UNITS = np.array([[1.0, 0.0], [0.5, SQRT3 / 2], [-0.5, SQRT3 / 2]])
_LATTICE_UNITS = np.concatenate([_LATTICE_UNITS, -_LATTICE_UNITS])


def _check_int(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise FieldTypeError(name, f"must be an integer, got {value!r}")
    if value < minimum:
        raise FieldValueError(name, f"must be >= {minimum}, got {value}")
    return int(value)


def _check_radius(radius) -> float:
    if isinstance(radius, bool) or not isinstance(radius, (int, float, np.number)):
        raise FieldTypeError("radius", f"must be a number, got {radius!r}")
    if not np.isfinite(radius) or radius <= 0:
        raise FieldValueError("radius", f"must be finite and > 0, got {radius}")
    return float(radius)


def _lattice_positions(rows: int, cols: int, radius: float) -> np.ndarray:
    """``(rows*cols, 2)`` centres: ball ``r*cols + c`` at ``(2c + r%2, r*sqrt(3))`` radii."""
    r, c = np.divmod(np.arange(rows * cols), cols)
    return radius * np.column_stack([2.0 * c + (r % 2), SQRT3 * r])


def _lattice_contacts(rows: int, cols: int, periodic: bool) -> Contacts:
    """Contacts of the triangular lattice, ball by ball: right, then the two above.

    Odd rows are shifted right by one radius. Built with array operations only.
    """
    n = rows * cols
    r, c = np.divmod(np.arange(n, dtype=np.int64), cols)
    odd = r % 2
    up = r + 1
    # candidate neighbours (n, 3): right, upper-left-ish, upper-right-ish
    nr = np.stack([r, up, up], axis=1)
    nc = np.stack([c + 1, c - 1 + odd, c + odd], axis=1)
    direction = np.broadcast_to(np.array([0, 2, 1], dtype=np.int32), (n, 3))
    if periodic:
        valid = np.ones((n, 3), dtype=bool)
        nr %= rows
        nc %= cols
    else:
        valid = (nr < rows) & (nc >= 0) & (nc < cols)
    e = int(valid.sum())
    pairs = np.empty((e, 2), dtype=np.uint32)
    pairs[:, 0] = np.broadcast_to(np.arange(n, dtype=np.uint32)[:, None], (n, 3))[valid]
    pairs[:, 1] = (nr * cols + nc)[valid]
    ends = np.empty((e, 2), dtype=np.uint8)
    ends[:, 0] = direction[valid]
    ends[:, 1] = ends[:, 0] + 3
    return Contacts(pairs=pairs, ends=ends, units=_LATTICE_UNITS.copy())


class FlatTorus(Geometry):
    """Triangular lattice with periodic boundaries: ``rows * cols`` balls, each touching 6.

    Ball ``r * cols + c`` sits at ``(2c + r % 2, r * sqrt(3))`` radii; the box is
    ``2 * cols`` by ``rows * sqrt(3)`` radii. ``rows`` must be even (so the
    shifted rows close up) and at least 4, ``cols`` at least 3 (so that no two
    balls touch twice).
    """

    def __init__(self, rows: int, cols: int, radius: float = 1.0):
        rows = _check_int("rows", rows, 4)
        cols = _check_int("cols", cols, 3)
        if rows % 2:
            raise FieldValueError("rows", f"must be even for a flat torus, got {rows}")
        if rows * cols > _INT32_MAX // 3:
            raise FieldValueError("rows*cols", f"at most {_INT32_MAX // 3} balls, got {rows * cols}")
        self.rows, self.cols, self.radius = rows, cols, _check_radius(radius)
        self.positions = _lattice_positions(rows, cols, self.radius)

    @property
    def period(self) -> np.ndarray:
        """``(2,)`` side lengths of the periodic box."""
        return self.radius * np.array([2.0 * self.cols, SQRT3 * self.rows])

    def _build_contacts(self) -> Contacts:
        return _lattice_contacts(self.rows, self.cols, periodic=True)


class HalfPlane(Geometry):
    """Triangular lattice in a rectangle; row 0 is the boundary of the half-plane.

    ``rows`` rows of ``cols`` balls; odd rows are shifted right by one radius.
    The boundary line passes through the centres of row 0, so row ``r`` is at
    distance ``r * sqrt(3)`` radii from it. Interior balls touch 6 others.
    """

    def __init__(self, rows: int, cols: int, radius: float = 1.0):
        self.rows = _check_int("rows", rows, 1)
        self.cols = _check_int("cols", cols, 1)
        if self.rows * self.cols > _INT32_MAX // 3:
            raise FieldValueError("rows*cols", f"at most {_INT32_MAX // 3} balls, got {self.rows * self.cols}")
        self.radius = _check_radius(radius)
        self.positions = _lattice_positions(self.rows, self.cols, self.radius)

    @classmethod
    def from_size(cls, length: float, depth: float, radius: float = 1.0) -> "HalfPlane":
        """The paper's ``length x depth`` rectangle (in radii), long side on the boundary.

        ``cols = floor(length / 2)`` balls side by side; ``rows = floor((depth - 1) / sqrt(3)) + 1``
        rows, the last one's balls still inside the depth. ``from_size(100, 50)`` gives
        29 rows of 50 balls.
        """
        for name, value in (("length", length), ("depth", depth)):
            if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not np.isfinite(value):
                raise FieldTypeError(name, f"must be a finite number, got {value!r}")
            if value < 2:
                raise FieldValueError(name, f"must be >= 2 (one ball is 2 radii wide), got {value}")
        cols = int(np.floor(length / 2 + 1e-9))
        rows = int(np.floor((depth - 1) / SQRT3 + 1e-9)) + 1
        return cls(rows=rows, cols=cols, radius=radius)

    def boundary_distance(self) -> np.ndarray:
        """``(n_balls,)`` distance of each centre from the boundary line."""
        return self.positions[:, 1].copy()

    def boundary_center(self) -> int:
        """Index of the boundary ball nearest the middle of row 0."""
        return (self.cols - 1) // 2

    def _build_contacts(self) -> Contacts:
        return _lattice_contacts(self.rows, self.cols, periodic=False)


# ---------------------------------------------------------------- arbitrary graphs


def _as_positions(positions) -> np.ndarray:
    try:
        p = np.asarray(positions, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("positions", f"must be an array of numbers ({exc})") from None
    if p.ndim == 1:
        p = p[:, None]
    if p.ndim != 2 or p.shape[1] < 1:
        raise FieldValueError("positions", f"must have shape (n_balls, d), got {p.shape}")
    if not np.isfinite(p).all():
        raise FieldValueError("positions", "contain NaN or inf")
    return p


def _flat_units(positions: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``(n_contacts, d)`` unit vectors from ``i`` to ``j`` in flat space."""
    delta = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    norm = np.linalg.norm(delta, axis=1)
    bad = np.flatnonzero(norm == 0)
    if len(bad):
        i, j = pairs[bad[0]]
        raise FieldValueError("contacts", f"balls {i} and {j} have the same centre, so no line of centres")
    return delta / norm[:, None]


class GraphGeometry(Geometry):
    """Any contact graph: balls anywhere in ``R^d`` (``d >= 1``), edges are contacts.

    ``graph`` is a networkx graph whose nodes carry ``"pos"`` (a length-``d``
    sequence). Ball ``n`` is the ``n``-th node of ``graph.nodes``. An edge may
    carry ``"units" = {u: t_u, v: t_v}`` (needed for periodic or curved spaces);
    otherwise ``t_u`` points from ``u`` to ``v`` in a straight line and ``t_v = -t_u``.
    """

    def __init__(self, graph: nx.Graph, radius: float = 1.0):
        if not isinstance(graph, nx.Graph) or graph.is_directed() or graph.is_multigraph():
            raise FieldTypeError("graph", f"must be an undirected networkx.Graph, got {type(graph).__name__}")
        if graph.number_of_nodes() == 0:
            raise FieldValueError("graph", "has no nodes")
        nodes = list(graph.nodes)
        index = {node: n for n, node in enumerate(nodes)}
        missing = [node for node in nodes if "pos" not in graph.nodes[node]]
        if missing:
            raise FieldValueError("graph", f"node {missing[0]!r} has no 'pos' attribute")
        try:
            positions = _as_positions([graph.nodes[node]["pos"] for node in nodes])
        except (TypeError, ValueError) as exc:
            raise FieldValueError("graph", f"node 'pos' attributes must be equal-length finite sequences ({exc})") from None
        loops = list(nx.selfloop_edges(graph))
        if loops:
            raise FieldValueError("graph", f"self-loop at node {loops[0][0]!r}; a ball cannot touch itself")
        edges = self._ordered_edges(graph)
        pairs = np.array([(index[u], index[v]) for u, v, _ in edges], dtype=np.int64).reshape(-1, 2)
        t_i = _flat_units(positions, pairs) if len(pairs) else np.zeros((0, positions.shape[1]))
        t_j = -t_i
        for e, (u, v, data) in enumerate(edges):
            if data.get("units") is not None:
                t_i[e], t_j[e] = self._given_units(u, v, data["units"], positions.shape[1])
        self._init(positions, pairs, t_i, t_j, radius)
        self.nodes = nodes

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
            raise FieldValueError("graph", "edge 'contact' attributes must number the edges 0, 1, ..., n_contacts - 1")
        out = []
        for u, v, d in ordered:
            if {*d["pair"]} != {u, v} or len(d["pair"]) != 2:
                raise FieldValueError("graph", f"edge ({u!r}, {v!r}) has 'pair' {d['pair']!r}, not its two ends")
            out.append((*d["pair"], d))
        return out

    @staticmethod
    def _given_units(u, v, units, dim: int) -> tuple[np.ndarray, np.ndarray]:
        try:
            tu, tv = np.asarray(units[u], dtype=float), np.asarray(units[v], dtype=float)
        except (KeyError, TypeError, ValueError):
            raise FieldValueError("graph", f"edge ({u!r}, {v!r}) 'units' must map both ends to a vector") from None
        for t in (tu, tv):
            if t.shape != (dim,) or not np.isfinite(t).all() or abs(np.linalg.norm(t) - 1) > 1e-9:
                raise FieldValueError("graph", f"edge ({u!r}, {v!r}) 'units' must be unit vectors of length {dim}")
        return tu, tv

    def _init(self, positions, pairs, t_i, t_j, radius) -> None:
        n = len(positions)
        if n > _INT32_MAX or 2 * len(pairs) > _INT32_MAX:
            raise FieldValueError("graph", "too large for 32-bit contact tables")
        self.positions = positions
        self.radius = _check_radius(radius)
        e = len(pairs)
        units = np.empty((2 * e, positions.shape[1]))
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
            raise FieldValueError("rtol", f"must be in [0, 0.5), got {rtol}")
        contact = 2.0 * radius
        pairs = cKDTree(p).query_pairs(contact * (1 + rtol), output_type="ndarray").astype(np.int64)
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))] if len(pairs) else pairs.reshape(0, 2)
        dist = np.linalg.norm(p[pairs[:, 1]] - p[pairs[:, 0]], axis=1)
        overlap = np.flatnonzero(dist < contact * (1 - rtol))
        if len(overlap):
            i, j = pairs[overlap[0]]
            raise FieldValueError(
                "positions", f"balls {i} and {j} overlap (centres {dist[overlap[0]]:.6g} apart, "
                f"contact distance {contact:.6g}); {len(overlap)} overlapping pair(s) in all"
            )
        self = cls.__new__(cls)
        t_i = _flat_units(p, pairs) if len(pairs) else np.zeros((0, p.shape[1]))
        self._init(p, pairs, t_i, -t_i, radius)
        self.nodes = list(range(len(p)))
        return self
