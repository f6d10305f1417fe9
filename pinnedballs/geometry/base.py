"""The base of every geometry: `Contacts`, `Geometry` and the `Boundary` capability.

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
from typing import TYPE_CHECKING

import numpy as np

from ..engine.rows import row_pattern
from ..util import checks
from ..util.errors import FieldError
from .checks import LENGTH_RTOL, raw_tables
from .pictures import display

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["Contacts", "Geometry", "Boundary", "tangent_contacts", "VIEWS", "LENGTHS", "checked_radius"]

SQRT3 = float(np.sqrt(3.0))
_INT32_MAX = np.iinfo(np.int32).max

#: how a state is drawn (`Geometry.view`): arrows in the plane; both hemispheres of a sphere; the
#: Poincare disk; a 3-D packing layer by layer; a 1-D chain; each component against the ball index
VIEWS = ("plane", "sphere", "poincare", "layers", "chain", "components")


#: the lengths a geometry may hold (radius, centres' distances from the origin): distances are computed
#: as square roots of sums of squares, and these squares stay normal float64 numbers
LENGTHS = (1e-150, 1e150)


def checked_radius(radius, reach: float = 1.0) -> float:
    """``radius`` as a float if it is finite, > 0 and keeps every length of the geometry within
    `LENGTHS`: the radius itself, and centres up to ``reach`` radii from the origin. Else a
    `FieldError` on ``radius`` giving the range that does (the centres would overflow, or lengths
    lose their digits to rounding, and a results file would hold what cannot be read back)."""
    r = checks.number("radius", radius, 0.0, above=True)
    low, high = LENGTHS
    top = high / max(float(reach), 1.0)
    if not low <= r <= top:
        where = f" for centres up to {float(reach):.3g} radii from the origin" if reach > 1 else ""
        raise FieldError("radius", f"must be in [{low:g}, {top:.3g}]{where} (lengths beyond [{low:g}, {high:g}] "
                                   f"lose their digits when squared), got {radius!r}")
    return r


def _index_dtype(n: int) -> np.dtype:
    """The smallest unsigned integer type that indexes ``n`` rows."""
    for dtype in (np.uint8, np.uint16, np.uint32):
        if n <= np.iinfo(dtype).max + 1:
            return np.dtype(dtype)
    raise FieldError("contacts", f"{n} rows is too many for 32-bit tables")


@dataclass(frozen=True, eq=False)
class Contacts:
    """Contacts in the compact form the compiled loop reads.

    Unsigned, narrow indices keep the tables small (a 1000x1000 torus needs 30 MB)
    and spare the loop the negative-index checks. `build` makes them from any integer arrays.

    Parameters
    ----------
    pairs : numpy.ndarray
        ``(n_contacts, 2) uint32``: the balls ``i, j`` of each contact.
    ends : numpy.ndarray
        ``(n_contacts, 2)`` unsigned rows of ``units`` holding ``t_i`` and ``t_j``
        (uint8 for lattices, which need only six unit vectors).
    units : numpy.ndarray
        ``(n_units, dim) float64`` unit vectors.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> c = pb.Contacts.build([[0, 1]], [[0, 1]], [[1.0, 0.0], [-1.0, 0.0]])
    >>> len(c), c.t_i.tolist(), c.t_j.tolist()
    (1, [[1.0, 0.0]], [[-1.0, 0.0]])
    """

    pairs: np.ndarray
    ends: np.ndarray
    units: np.ndarray

    @classmethod
    def build(cls, pairs, ends, units) -> Contacts:
        """Contacts from integer arrays, narrowed to the compact tables.

        The arrays are checked as given (`checks.raw_tables`: whole numbers, no negative index, ends
        within units) before they are narrowed; the rest (balls in range, unit lengths, directions)
        is checked against the geometry when a `Simulation` is built (`checks.check_contacts`).

        Parameters
        ----------
        pairs : array_like
            ``(E, 2)`` integers: the balls of each contact.
        ends : array_like
            ``(E, 2)`` integers: the rows of ``units`` at each end.
        units : array_like
            ``(K, dim)`` unit vectors.

        Returns
        -------
        Contacts
            ``pairs`` as uint32, ``ends`` in the narrowest unsigned type that indexes ``units``.

        Raises
        ------
        FieldError
            On ``contacts`` for tables that are not whole numbers, hold a negative index or an end
            outside ``units``.
        """
        pairs, ends, units = raw_tables(pairs, ends, units)
        return cls(
            pairs=np.ascontiguousarray(pairs, dtype=np.uint32),
            ends=np.ascontiguousarray(ends, dtype=_index_dtype(len(units))),
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

    @functools.cached_property
    def closed_rows(self) -> bool:
        """True when space is flat and every contact lies on a closed row: balls ``x_0, ..., x_L = x_0``, each
        touching the next along one unit vector ``u`` (a torus's lattice lines). The closing speeds
        ``(v_x_m - v_x_m+1) . u`` of a row sum to zero, so a frozen state has every closing speed zero."""
        if not self.flat or len(self.pairs) == 0:
            return False
        direction = np.unique(self.units, axis=0, return_inverse=True)[1].ravel().astype(np.int64)
        n_dir = int(direction.max()) + 1
        ball = self.pairs.astype(np.int64).ravel()  # half-edges: 2k runs i -> j, 2k + 1 runs j -> i
        to = self.pairs[:, ::-1].astype(np.int64).ravel()
        way = direction[self.ends.astype(np.int64).ravel()]
        leaving = ball * n_dir + way  # each (ball, direction) must leave along one contact only
        order = np.argsort(leaving, kind="stable")
        keys = leaving[order]
        if np.any(keys[1:] == keys[:-1]):
            return False
        # a row goes on from each half-edge's far ball along the same direction: it must exist for every one
        onward = to * n_dir + way
        at = np.minimum(np.searchsorted(keys, onward), len(keys) - 1)
        return bool(np.all(keys[at] == onward))  # a successor for every half-edge: a permutation, so rows close

    def __len__(self) -> int:
        return len(self.pairs)

    def __getstate__(self) -> dict:
        """A pickle leaves out the checks' verdict (`checks.check_contacts`): a copy is checked afresh."""
        return {k: v for k, v in self.__dict__.items() if k != "_sound_for"}


@dataclass(frozen=True, eq=False)
class Boundary:
    """A geometry's boundary as each ball sees it (`Geometry.boundary`).

    Parameters
    ----------
    distance : numpy.ndarray
        ``(n_balls,) float64``: distance of each centre from the boundary (0 on it).
    outward : numpy.ndarray
        ``(n_balls, dim) float64``: unit vectors in each ball's frame, pointing out of the system.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> b = pb.HalfPlane(rows=2, cols=2).boundary
    >>> b.distance.round(3).tolist(), b.outward[0].tolist()
    ([0.0, 0.0, 1.732, 1.732], [0.0, -1.0])
    """

    distance: np.ndarray
    outward: np.ndarray


class Geometry(ABC):
    """Balls at fixed centres and the contacts between them.

    Subclasses set ``positions`` and implement `_build_contacts` (docs/extending.md). Ball radius is
    ``radius`` (contact distance ``2 * radius``). Capabilities that code above the
    engine asks for instead of a type: `boundary` (None, or a `Boundary`) and
    `frames` (each ball's tangent basis; identity in flat space).

    Attributes
    ----------
    positions : numpy.ndarray
        ``(n_balls, k) float64`` ball centres.
    radius : float
        The balls' radius (1.0 unless set).
    curved : bool
        True when velocities live in tangent planes of a curved surface (`frames` is not the identity).
    metric : numpy.ndarray or None
        On a curved surface, the embedding's inner product as the diagonal ``(k,)`` of its matrix (a
        sphere: ``(1, 1, 1)``; the hyperboloid: ``(-1, 1, 1)``): the contact checks measure the direction
        from one ball to another in its frame with it. None: not stated (directions on the surface are not
        checked).
    rtol : float
        Relative tolerance on the length ``2 * radius`` of a contact in flat space (checked with the
        contacts).
    rigid : bool
        True when only one common velocity gives every contact closing speed 0 (the closing speeds' map
        has only the translations in its kernel): with `Contacts.closed_rows`, the only frozen states.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=3, cols=4)
    >>> g.n_balls, g.n_contacts, g.dim, g.view, g.curved
    (12, 23, 2, 'plane', False)
    >>> g.degrees().tolist()
    [2, 4, 4, 3, 5, 6, 6, 3, 2, 4, 4, 3]
    """

    positions: np.ndarray  #: ``(n_balls, k) float64`` ball centres
    radius: float = 1.0
    #: True when velocities live in tangent planes of a curved surface (`frames` is not the identity)
    curved: bool = False
    #: on a curved surface, the embedding's inner product as the diagonal ``(k,)`` of its matrix (a sphere:
    #: ``(1, 1, 1)``; the hyperboloid: ``(-1, 1, 1)``): the contact checks measure the direction from one
    #: ball to another in its frame with it. None: not stated (directions on the surface are not checked)
    metric: np.ndarray | None = None
    #: relative tolerance on the length ``2 * radius`` of a contact in flat space (checked with the contacts)
    rtol: float = LENGTH_RTOL
    #: True when only one common velocity gives every contact closing speed 0 (the closing speeds' map has
    #: only the translations in its kernel): with `Contacts.closed_rows`, the only frozen states
    rigid: bool = False

    @property
    def view(self) -> str:
        """How a state is drawn, one of `VIEWS`. Flat space: ``"plane"`` in 2-D, ``"layers"`` in 3-D,
        ``"chain"`` in 1-D; anything else ``"components"``. A curved surface says its own."""
        k = self.positions.shape[1]
        if self.curved or self.dim != k:
            return "components"
        return {1: "chain", 2: "plane", 3: "layers"}.get(k, "components")

    def to_spec(self) -> dict | None:
        """The geometry as a run spec's ``"geometry"``.

        Returns
        -------
        dict or None
            A dict with its ``"kind"`` (`pinnedballs.specs.geometry`), or None if it has none (it is then
            rebuilt from the contacts a results file stores).

        Examples
        --------
        >>> import pinnedballs as pb
        >>> pb.FlatTorus(4, 3).to_spec()
        {'kind': 'flat_torus', 'rows': 4, 'cols': 3, 'radius': 1.0}
        """
        return None

    @property
    def boundary(self) -> Boundary | None:
        """The boundary seen from each ball, or None when the geometry has none (torus, sphere)."""
        return None

    def frames(self) -> np.ndarray:
        """The orthonormal tangent basis of each ball in embedding coordinates.

        A velocity ``v (n_balls, dim)`` in embedding coordinates is
        ``einsum("nd,ndk->nk", v, frames)``.

        Returns
        -------
        numpy.ndarray
            ``(n_balls, dim, k)``; flat space: the identity (a read-only view).

        Raises
        ------
        FieldError
            On ``frames`` for a geometry whose ``dim`` differs from its positions' ``k`` and that gives
            no frames of its own.
        """
        k = self.positions.shape[1]
        if self.dim != k:
            raise FieldError("frames", f"{type(self).__name__} has dim {self.dim} but {k}-D positions and no frames")
        return np.broadcast_to(np.eye(k), (self.n_balls, k, k))

    @property
    def box(self) -> np.ndarray | None:
        """``(k,)`` side lengths of the periodic box, ``inf`` along an open axis; None when nothing is
        periodic. The contact checks (`pinnedballs.geometry.checks`) measure each contact to the
        nearest periodic image of the other ball."""
        return None

    def stated_contacts(self) -> np.ndarray | None:
        """The contacts given as data, whose straight segment need not be the contact.

        Such a segment may cross a periodic boundary the geometry does not know. The contact checks
        measure their direction only where the segment is ``2 * radius`` long, their length never.

        Returns
        -------
        numpy.ndarray or None
            ``(n_contacts,) bool``, or None: no contact is stated.
        """
        return None

    def boundary_center(self) -> int:
        """The boundary ball nearest the middle of the boundary balls (those of least ``boundary.distance``).

        Returns
        -------
        int
            Its index (a spec's ``"ball": "boundary_center"`` names it).

        Raises
        ------
        FieldError
            On ``boundary_center`` for a geometry without a boundary.

        Examples
        --------
        >>> import pinnedballs as pb
        >>> pb.HalfPlane(rows=3, cols=5).boundary_center()
        2
        """
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

    def row_shape(self) -> tuple[int, int] | None:
        """The lattice's shape, where the balls are numbered row by row and the contacts ball by ball.

        Returns
        -------
        tuple of int or None
            ``(rows, cols)``, ``cols`` balls to a row (the lattices), else None.
        """
        return None

    @functools.cached_property
    def row_pattern(self) -> tuple | None:
        """The contacts' row pattern (`pinnedballs.engine.rows`), checked against every contact, or
        None: what the engine's loops read instead of the tables on a large lattice."""
        shape = self.row_shape()
        if shape is None:
            return None
        c = self.contacts
        return row_pattern(c.pairs, c.ends, *shape)

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
        """The number of contacts of each ball.

        Returns
        -------
        numpy.ndarray
            ``(n_balls,)`` integers.
        """
        return np.bincount(self.contacts.pairs.ravel().astype(np.intp), minlength=self.n_balls)

    def contact_graph(self) -> nx.Graph:
        """The contacts as a networkx graph: nodes ``0..n_balls-1`` with ``"pos"``, one edge per contact.

        Each edge carries ``"units" = {i: t_i, j: t_j}``, its index ``"contact"`` and its
        orientation ``"pair" = (i, j)``; on a curved surface each node also carries its
        ``"frame"`` (``dim x k``) and the graph its ``"metric"``; the graph carries its ``"view"``. So
        ``GraphGeometry(geom.contact_graph())`` rebuilds exactly these contacts in the same order (the same seed then
        gives the same run), periodic or curved ones included.

        Returns
        -------
        networkx.Graph

        Examples
        --------
        >>> import pinnedballs as pb
        >>> g = pb.FlatTorus(4, 3)
        >>> again = pb.GraphGeometry(g.contact_graph())
        >>> bool((again.contacts.pairs == g.contacts.pairs).all()), again.n_contacts
        (True, 36)
        """
        import networkx as nx  # here: a lattice is built, checked and run without it

        g = nx.Graph(dim=self.dim, view=self.view)
        frames = self.frames() if self.curved else None
        if self.curved and self.metric is not None:  # how the contact checks measure directions on it
            g.graph["metric"] = tuple(float(x) for x in self.metric)
        for n, p in enumerate(self.positions):
            g.add_node(n, pos=tuple(float(x) for x in p))
            if frames is not None:
                g.nodes[n]["frame"] = frames[n].tolist()
        c = self.contacts
        t_i, t_j = c.t_i, c.t_j
        for e, (i, j) in enumerate(c.pairs.tolist()):
            g.add_edge(i, j, contact=e, pair=(i, j), units={i: tuple(t_i[e].tolist()), j: tuple(t_j[e].tolist())})
        return g

    def plot(self, ax=None, title: str | None = None):
        """The balls at rest in the geometry's own view (`pinnedballs.plot.states.state_picture`).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Draw into these axes; else a new figure.
        title : str, optional
            The figure's title.

        Returns
        -------
        matplotlib.figure.Figure
        """
        return display().state_picture(self)(np.zeros((self.n_balls, self.dim)), title, ax=ax)

    def _repr_html_(self) -> str:  # notebooks: a table of the balls beside their picture
        shown = display()
        return shown.geometry_html(self, shown.geometry_png(self))

    def _repr_png_(self) -> bytes | None:
        return display().geometry_png(self)

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:  # the picture drawn once for both
        shown = display()
        return shown.mimebundle(self, shown.geometry_html, shown.geometry_png, include, exclude)

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
