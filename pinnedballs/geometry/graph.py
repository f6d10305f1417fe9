"""Geometries given as data: any contact graph (`GraphGeometry`), balls touching at given
positions (`GraphGeometry.from_positions`), and a geometry read back from a results file
(`StoredGeometry`)."""

from __future__ import annotations

import networkx as nx
import numpy as np

from ..util import checks
from ..util.errors import FieldError, FieldTypeError
from .base import _INT32_MAX, LENGTHS, VIEWS, Boundary, Contacts, Geometry, checked_radius
from .checks import LENGTH_RTOL, UNIT_TOLERANCE

__all__ = ["GraphGeometry", "StoredGeometry", "SNAP_ULPS"]

#: ``snap=True`` moves a unit vector's components by at most ``SNAP_ULPS * eps * (1 + far / (2 radius))``
#: (``far``: the largest coordinate of a centre): a normal computed from centres rounded to float64 is off
#: by about ``0.2 eps (1 + far / (2 radius))`` (networkx's hexagonal lattices, up to 200 x 200)
SNAP_ULPS = 64


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
    far = float(np.abs(p).max()) if p.size else 0.0
    if far > LENGTHS[1]:
        raise FieldError("positions", f"a centre has a coordinate of {far:.3g}; lengths beyond {LENGTHS[1]:g} lose "
                                      f"their digits when squared: scale them down")
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


def _snap_tolerance(snap, positions: np.ndarray, radius: float) -> float | None:
    """The absolute tolerance ``snap`` asks for on each component of a unit vector (None: no snapping)."""
    if snap is False or snap is None:
        return None
    if snap is True:
        far = float(np.abs(positions).max()) if positions.size else 0.0
        return SNAP_ULPS * float(np.finfo(np.float64).eps) * (1.0 + far / (2.0 * radius))
    if isinstance(snap, bool) or not isinstance(snap, (int, float, np.floating, np.integer)) \
            or not 0 < float(snap) < 0.5:
        raise FieldError("snap", f"must be True, False or a tolerance in (0, 0.5) on each component of a unit "
                                 f"vector, got {snap!r}")
    return float(snap)


def _snapped(units: np.ndarray, tolerance: float | None) -> np.ndarray:
    """``units (K, dim)`` moved to the floats of a number field's unit vectors within ``tolerance``
    (`engine.field.numbers.snap`), or a `FieldError` on ``snap`` naming the first that has none."""
    if tolerance is None or not len(units):
        return units
    from ..engine.field.numbers import NotExact, snap

    try:
        return snap(units, tolerance)
    except NotExact as exc:
        raise FieldError("snap", f"{exc} (within {tolerance:.3g}: give snap a larger tolerance if the centres "
                                 f"are rounded more)") from None


def _check_lengths(edges: list, positions: np.ndarray, pairs: np.ndarray, stated: np.ndarray, radius: float,
                   rtol: float) -> None:
    """A `FieldError` on ``graph`` naming the first edge without ``"units"`` whose balls are not
    ``2 * radius`` apart within ``rtol``, with the radius that fits (every such edge of one length)
    or `GraphGeometry.from_positions`, which finds the pairs that touch."""
    free = np.flatnonzero(~stated)
    if not len(free):
        return
    length = np.linalg.norm(positions[pairs[free, 1]] - positions[pairs[free, 0]], axis=1)
    contact = 2.0 * radius
    bad = np.flatnonzero(~(np.abs(length - contact) <= rtol * contact))
    if not len(bad):
        return
    u, v, _ = edges[free[bad[0]]]
    lo, hi = float(length.min()), float(length.max())
    if hi - lo <= rtol * hi:
        hint = f"every edge is {hi:.6g} long: GraphGeometry(graph, radius={hi / 2:.6g})"
    else:
        hint = (f"its edges have lengths from {lo:.6g} to {hi:.6g}: GraphGeometry.from_positions(positions, "
                f"radius=...) takes as contacts the pairs that touch")
    raise FieldError("graph", f"edge ({u!r}, {v!r}) joins balls {float(length[bad[0]]):.6g} apart, but touching "
                              f"balls of radius {radius:g} are {contact:g} apart (relative tolerance {rtol:g}); "
                              f"{hint}")


def _graph_metric(graph: nx.Graph, k: int) -> np.ndarray | None:
    metric = graph.graph.get("metric")
    if metric is None:
        return None
    try:
        m = np.asarray(metric, dtype=np.float64)
    except (TypeError, ValueError):
        m = np.empty(0)
    if m.shape != (k,) or not np.isfinite(m).all() or not np.isin(m, (-1.0, 1.0)).all():
        raise FieldError("graph", f"its 'metric' attribute must be {k} signs (1 or -1), got {metric!r}")
    return m


class GraphGeometry(Geometry):
    """Any contact graph: balls anywhere in ``R^d`` (``d >= 1``), edges are contacts.

    ``graph`` is a networkx graph whose nodes carry ``"pos"`` (a length-``d``
    sequence). Ball ``n`` is the ``n``-th node of ``graph.nodes``. An edge may
    carry ``"units" = {u: t_u, v: t_v}`` (needed for periodic or curved spaces);
    otherwise ``t_u`` points from ``u`` to ``v`` in a straight line and ``t_v = -t_u``.
    Nodes may carry ``"frame"`` ``(dim, d)``, their tangent basis on a curved surface
    (as `Geometry.contact_graph` writes it); then every edge needs ``"units"`` of length ``dim``.

    An edge without ``"units"`` must join balls ``2 * radius`` apart within ``rtol`` (relative), or
    the graph is refused here, with the radius that fits. The rest of the contacts is checked when a
    `Simulation` is built (`pinnedballs.geometry.checks`). An edge with
    ``"units"`` states its own contact: its length is not checked, and its direction only where its
    straight segment is ``2 * radius`` long (elsewhere it may run through a periodic boundary the
    graph does not know). On a curved surface directions are checked under the graph's ``"metric"``
    attribute (the diagonal of the embedding's inner product, which `contact_graph` writes), and not
    at all without one: the frames alone do not say whether the surface is a sphere or a hyperboloid.

    Parameters
    ----------
    graph : networkx.Graph
        Nodes with ``"pos"``, edges the contacts.
    radius : float
        The balls' radius: an edge without ``"units"`` is ``2 * radius`` long.
    rtol : float
        Relative tolerance on that length.
    snap : bool or float
        Move each unit vector (contact normal) to the float nearest a unit vector of a number field
        within rounding of it (True: within ``SNAP_ULPS * eps * (1 + far / (2 radius))`` on each
        component, ``far`` the largest coordinate of a centre; a float: within that tolerance), so that
        ``arithmetic="exact"`` and ``"certified"`` run centres computed in floats (networkx's
        ``hexagonal_lattice_graph(m, n, with_positions=True)``: Q(sqrt 3)). The centres and the
        contacts stay as given. False (the default): the normals as computed.

    Attributes
    ----------
    nodes : list
        The graph's nodes: ball ``n`` is ``nodes[n]``.

    Raises
    ------
    FieldError
        On ``graph`` (no nodes, a node without ``"pos"``, a self-loop, an edge of the wrong length:
        its message gives the radius that fits), or on ``snap`` (a normal with no field within the
        tolerance, or a bad tolerance).
    FieldTypeError
        If ``graph`` is not an undirected networkx graph.

    Examples
    --------
    >>> import networkx as nx
    >>> import pinnedballs as pb
    >>> g = pb.GraphGeometry(nx.hexagonal_lattice_graph(2, 2, with_positions=True), radius=0.5, snap=True)
    >>> sorted({round(abs(float(x)), 3) for x in g.contacts.units.ravel()})
    [0.0, 0.5, 0.866, 1.0]

    A chain of three balls, contacts along the line:

    >>> chain = nx.path_graph(3)
    >>> nx.set_node_attributes(chain, {n: (2.0 * n,) for n in chain}, "pos")
    >>> g = pb.GraphGeometry(chain)
    >>> g.n_balls, g.n_contacts, g.dim, g.contacts.t_i.tolist()
    (3, 2, 1, [[1.0], [1.0]])
    """

    def __init__(self, graph: nx.Graph, radius: float = 1.0, rtol: float = LENGTH_RTOL, snap: bool | float = False):
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
        self.metric = _graph_metric(graph, positions.shape[1])
        dim = positions.shape[1] if self._frames is None else self._frames.shape[1]
        if self.curved:
            t_i = np.zeros((len(pairs), dim))
        else:
            t_i = _flat_units(positions, pairs) if len(pairs) else np.zeros((0, dim))
        t_j = -t_i
        self._stated = np.array([data.get("units") is not None for _, _, data in edges], dtype=bool)
        for e, (u, v, data) in enumerate(edges):
            if data.get("units") is not None:
                t_i[e], t_j[e] = self._given_units(u, v, data["units"], dim)
            elif self.curved:
                raise FieldError("graph",
                                 f"edge ({u!r}, {v!r}) needs 'units' on a curved surface (nodes carry 'frame')")
        if not self.curved and len(pairs):
            _check_lengths(edges, positions, pairs, self._stated, checked_radius(radius),
                           checks.number("rtol", rtol, 0.0))
        self._init(positions, pairs, t_i, t_j, radius, rtol, snap)
        self.nodes = nodes
        self._view = graph.graph.get("view")
        if self._view is not None:
            checks.choice("graph (its 'view' attribute)", self._view, VIEWS)

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
            raise FieldError("graph",
                             "node 'frame' attributes must be equal-shape (dim, k) arrays of numbers") from None
        if frames.ndim != 3 or frames.shape[2] != k or not np.isfinite(frames).all():
            raise FieldError("graph",
                             f"node 'frame' attributes must be finite (dim, {k}) arrays, got {frames.shape[1:]}")
        return frames

    def frames(self) -> np.ndarray:
        """Each ball's tangent basis (`Geometry.frames`).

        Returns
        -------
        numpy.ndarray
            ``(n_balls, dim, k)``: the nodes' ``"frame"`` attributes if given, else the identity.
        """
        return super().frames() if self._frames is None else self._frames

    def stated_contacts(self) -> np.ndarray:
        """The edges that carry ``"units"`` (`Geometry.stated_contacts`).

        Returns
        -------
        numpy.ndarray
            ``(n_contacts,) bool``.
        """
        return self._stated

    @property
    def view(self) -> str:
        """The graph's ``"view"`` attribute if it has one (`Geometry.contact_graph` writes it), else
        as for any geometry (`Geometry.view`)."""
        return self._view or super().view

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
            if t.shape != (dim,) or not np.isfinite(t).all() or not abs(np.linalg.norm(t) - 1) <= UNIT_TOLERANCE:
                raise FieldError("graph", f"edge ({u!r}, {v!r}) 'units' must be unit vectors of {dim} components (norm "
                                          f"1 within {UNIT_TOLERANCE:g}), got {t.tolist()}")
        return tu, tv

    def _init(self, positions, pairs, t_i, t_j, radius, rtol, snap=False) -> None:
        n = len(positions)
        if n > _INT32_MAX or 2 * len(pairs) > _INT32_MAX:
            raise FieldError("graph", "too large for 32-bit contact tables")
        self.positions = positions
        self.radius = checked_radius(radius)
        self.rtol = checks.number("rtol", rtol, 0.0)
        e = len(pairs)
        units = np.empty((2 * e, t_i.shape[1]))
        units[0::2], units[1::2] = t_i, t_j
        units = _snapped(units, _snap_tolerance(snap, positions, self.radius))
        ends = np.arange(2 * e).reshape(e, 2)
        self._contacts = Contacts.build(pairs, ends, units)

    def _build_contacts(self) -> Contacts:
        return self._contacts

    @classmethod
    def from_positions(cls, positions, radius: float = 1.0, rtol: float = 1e-6,
                       snap: bool | float = False) -> GraphGeometry:
        """Balls of ``radius`` at ``positions`` ``(n_balls, d)``; contacts are pairs at distance ``2*radius``.

        Distances within ``rtol * 2 * radius`` of contact count as touching (centres
        computed by repeated addition still touch); closer pairs are overlapping
        balls and an error. Uses a scipy KD-tree: ``O(n log n)``.

        Parameters
        ----------
        positions : array_like
            ``(n_balls, d)`` centres (``(n_balls,)`` for a chain).
        radius : float
            The balls' radius.
        rtol : float
            Relative tolerance on the contact distance, in ``[0, 0.5)``.
        snap : bool or float
            As for `GraphGeometry`: the contact normals moved to a number field's within rounding
            (True) or within a tolerance (a float), for exact and certified arithmetic.

        Returns
        -------
        GraphGeometry
            Contacts in the order of their lower ball, then the higher.

        Raises
        ------
        FieldError
            On ``positions`` (a bad shape, NaN, overlapping balls), ``radius``, ``rtol`` or ``snap``.

        Examples
        --------
        >>> import pinnedballs as pb
        >>> g = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0], [1.0, 3 ** 0.5], [5.0, 0.0]])
        >>> g.contacts.pairs.tolist()
        [[0, 1], [0, 2], [1, 2]]
        """
        from scipy.spatial import cKDTree

        radius = checked_radius(radius)
        p = _as_positions(positions)
        if not (0 <= rtol < 0.5):
            raise FieldError("rtol", f"must be in [0, 0.5), got {rtol}")
        contact = 2.0 * radius
        far = float(np.abs(p).max()) if p.size else 0.0
        if np.spacing(far) > 1e-6 * contact:  # distances between centres would not resolve the contact distance
            raise FieldError("radius", f"{radius:g} is too small for centres up to {far:.3g} from the origin: they are "
                                       f"rounded to {np.spacing(far):.2g}, more than a millionth of the contact "
                                       f"distance {contact:g} (move the centres near the origin, or scale them)")
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
        self._frames, self._view, self.metric = None, None, None
        self._stated = np.zeros(len(pairs), dtype=bool)
        t_i = _flat_units(p, pairs) if len(pairs) else np.zeros((0, p.shape[1]))
        self._init(p, pairs, t_i, -t_i, radius, rtol, snap)
        self.nodes = list(range(len(p)))
        return self


class StoredGeometry(Geometry):
    """A geometry as a results file stores it: centres ``positions (n, k)``, contacts ``pairs (E, 2)``
    with unit vectors ``t_i, t_j (E, d)``, and what the layers above the engine ask of a geometry:
    its ``boundary`` (or None), its ``frames`` ``(n, d, k)`` on a curved surface (or None) and its
    ``view``. The same contact arrays give the same bits, so a run continues on it exactly.
    ``complete``: the view was given (results files store it with the boundary and frames since
    the results layout that added them; older files hold only the contacts).
    """

    def __init__(self, positions, pairs, t_i, t_j, radius: float = 1.0, *, boundary: Boundary | None = None,
                 frames: np.ndarray | None = None, view: str | None = None):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.radius = float(radius)
        e = len(pairs)
        units = np.empty((2 * e, np.shape(t_i)[1]))
        units[0::2], units[1::2] = t_i, t_j
        self._contacts = Contacts.build(pairs, np.arange(2 * e).reshape(e, 2), units)
        self._boundary, self._frames = boundary, frames
        self.curved = frames is not None
        self._view = None if view is None else checks.choice("view", view, VIEWS)
        self.complete = view is not None

    @property
    def boundary(self) -> Boundary | None:
        return self._boundary

    @property
    def view(self) -> str:
        return self._view or super().view

    def frames(self) -> np.ndarray:
        return super().frames() if self._frames is None else self._frames

    def stated_contacts(self) -> np.ndarray:
        """Every contact: the file does not say which run through a periodic boundary."""
        return np.ones(self.n_contacts, dtype=bool)

    def _build_contacts(self) -> Contacts:
        return self._contacts
