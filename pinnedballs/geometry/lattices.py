"""Flat triangular lattices: the torus and the half-plane (in both orientations)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..util import checks
from ..util.errors import FieldError
from ..util.limits import check_memory, format_count, run_bytes
from .base import _INT32_MAX, SQRT3, Boundary, Contacts, Geometry, checked_radius

__all__ = ["FlatTorus", "HalfPlane"]

#: how `HalfPlane` lays its lattice rows against the boundary
ORIENTATIONS = ("along", "across")

#: unit vectors of the triangular lattice: row d + 3 is exactly minus row d (signed zeros too)
_LATTICE_UNITS = np.array([[1.0, 0.0], [0.5, SQRT3 / 2], [-0.5, SQRT3 / 2]])
_LATTICE_UNITS = np.concatenate([_LATTICE_UNITS, -_LATTICE_UNITS])
#: the direction (row of the units) of a ball's contact to the right, upper left and upper right
_DIRECTIONS = np.array([0, 2, 1], dtype=np.uint8)

#: a lattice is built this many balls at a time: the temporaries of building it stay about 9 MB whatever its
#: size (whole-lattice temporaries took 155 MB to build the 30 MB of a 1000x1000 torus's tables)
_CHUNK = 1 << 16


@dataclass(frozen=True, eq=False)
class LatticeContacts(Contacts):
    """A triangular lattice's contacts (`_lattice_contacts`): `Contacts` whose `flat` and `closed_rows` are
    read off the construction instead of computed from every contact. Every contact's ``ends`` are
    ``(d, d + 3)``, and row ``d + 3`` of ``units`` is minus row ``d``; a torus closes every row. (From the
    tables, `Contacts` builds (E, 2) float64 and int64 temporaries: 100 MB for `flat` and over 400 MB for
    `closed_rows` on a 1000x1000 torus.)

    periodic: the lattice is a torus.
    """

    periodic: bool = False

    @functools.cached_property
    def flat(self) -> bool:
        """`Contacts.flat`: ``t_j = units[d + 3]`` is exactly ``-t_i = -units[d]``, signed zeros too."""
        u = self.units
        return bool(np.array_equal(np.signbit(u[3:]), ~np.signbit(u[:3])) and np.array_equal(u[3:], -u[:3]))

    @functools.cached_property
    def closed_rows(self) -> bool:
        """`Contacts.closed_rows`: a torus's lattice lines close (rows even, at least 3 columns)."""
        return self.periodic and self.flat and len(self.pairs) > 0


def _lattice_positions(rows: int, cols: int, radius) -> tuple[np.ndarray, float]:
    """``(rows*cols, 2)`` centres: ball ``r*cols + c`` at ``(2c + r%2, r*sqrt(3))`` radii; and the radius,
    checked against the farthest centre (`checked_radius`). Written in place: no temporary of the lattice's
    size."""
    p = np.empty((rows * cols, 2))
    grid = p.reshape(rows, cols, 2)
    r = np.arange(rows)
    np.add(2.0 * np.arange(cols)[None, :], (r % 2)[:, None], out=grid[:, :, 0])
    np.multiply(SQRT3, r[:, None], out=grid[:, :, 1])
    farthest = max((float(np.einsum("ij,ij->i", p[s:s + _CHUNK], p[s:s + _CHUNK]).max())
                    for s in range(0, len(p), _CHUNK)), default=0.0)
    radius = checked_radius(radius, float(np.sqrt(farthest)))
    p *= radius
    return p, radius


def _candidates(start: int, stop: int, rows: int, cols: int, periodic: bool) -> tuple:
    """Balls ``start .. stop-1``'s three candidate contacts, ``(j (m, 3) int64, valid (m, 3) bool or None)``:
    right, upper left, upper right (odd rows are shifted right by one radius); None: all valid (a torus)."""
    r, c = np.divmod(np.arange(start, stop, dtype=np.int64), cols)
    odd = r % 2
    up = r + 1
    nr = np.stack([r, up, up], axis=1)
    nc = np.stack([c + 1, c - 1 + odd, c + odd], axis=1)
    if periodic:
        nr %= rows
        nc %= cols
        valid = None
    else:
        valid = (nr < rows) & (nc >= 0) & (nc < cols)
    nr *= cols
    nr += nc
    return nr, valid


def _lattice_contacts(rows: int, cols: int, periodic: bool) -> LatticeContacts:
    """Contacts of the triangular lattice, ball by ball: right, then the two above.

    Built with array operations, `_CHUNK` balls at a time (counted first where the lattice has edges),
    straight into the uint32 and uint8 tables.
    """
    n = rows * cols
    chunks = [(s, min(s + _CHUNK, n)) for s in range(0, n, _CHUNK)]
    e = 3 * n if periodic else sum(int(_candidates(s, t, rows, cols, False)[1].sum()) for s, t in chunks)
    pairs = np.empty((e, 2), dtype=np.uint32)
    ends = np.empty((e, 2), dtype=np.uint8)
    at = 0
    for s, t in chunks:
        j, valid = _candidates(s, t, rows, cols, periodic)
        i = np.broadcast_to(np.arange(s, t, dtype=np.uint32)[:, None], j.shape)
        d = np.broadcast_to(_DIRECTIONS, j.shape)
        if valid is not None:
            i, j, d = i[valid], j[valid], d[valid]
        m = j.size
        pairs[at:at + m, 0] = i.ravel()
        pairs[at:at + m, 1] = j.ravel()
        ends[at:at + m, 0] = d.ravel()
        at += m
    ends[:, 1] = ends[:, 0] + 3
    return LatticeContacts(pairs=pairs, ends=ends, units=_LATTICE_UNITS.copy(), periodic=periodic)


class FlatTorus(Geometry):
    """Triangular lattice with periodic boundaries: ``rows * cols`` balls, each touching 6.

    Ball ``r * cols + c`` sits at ``(2c + r % 2, r * sqrt(3))`` radii; the box is
    ``2 * cols`` by ``rows * sqrt(3)`` radii (`period`).

    Parameters
    ----------
    rows : int
        Lattice rows: even (so the shifted rows close up) and at least 4.
    cols : int
        Balls to a row: at least 3 (so that no two balls touch twice).
    radius : float
        The balls' radius.

    Raises
    ------
    FieldError
        On ``rows`` (odd, or below 4), ``cols`` (below 3), ``rows*cols`` (more balls than 32-bit tables
        or this machine's memory hold) or ``radius``.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.FlatTorus(rows=4, cols=3)
    >>> g.n_balls, g.n_contacts, set(g.degrees().tolist()), g.boundary
    (12, 36, {6}, None)
    >>> g.period.round(3).tolist()
    [6.0, 6.928]
    """

    rigid = True  # only a common velocity has every closing speed 0 (tested)

    def __init__(self, rows: int, cols: int, radius: float = 1.0):
        rows = checks.integer("rows", rows, 4)
        cols = checks.integer("cols", cols, 3)
        if rows % 2:
            raise FieldError("rows", f"must be even for a flat torus, got {rows}")
        check_memory(run_bytes(rows * cols, 3 * rows * cols), "rows*cols",
                     f"a {format_count(rows)} x {format_count(cols)} flat torus")
        if rows * cols > _INT32_MAX // 3:
            raise FieldError("rows*cols", f"at most {_INT32_MAX // 3} balls, got {rows * cols}")
        self.rows, self.cols = rows, cols
        self.positions, self.radius = _lattice_positions(rows, cols, radius)

    @property
    def period(self) -> np.ndarray:
        """``(2,)`` side lengths of the periodic box."""
        return self.radius * np.array([2.0 * self.cols, SQRT3 * self.rows])

    @property
    def box(self) -> np.ndarray:
        """The periodic box: `period`."""
        return self.period

    def row_shape(self) -> tuple[int, int]:
        """The lattice's shape (`Geometry.row_shape`).

        Returns
        -------
        tuple of int
            ``(rows, cols)``.
        """
        return self.rows, self.cols

    def to_spec(self) -> dict:
        """The torus as a run spec's ``"geometry"`` (`Geometry.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "flat_torus", "rows": ..., "cols": ..., "radius": ...}``.
        """
        return {"kind": "flat_torus", "rows": self.rows, "cols": self.cols, "radius": self.radius}

    def _build_contacts(self) -> Contacts:
        return _lattice_contacts(self.rows, self.cols, periodic=True)


class HalfPlane(Geometry):
    """Triangular lattice in a rectangle whose bottom side ``y = 0`` is the boundary of the half-plane.

    Interior balls touch 6 others; ``boundary.outward`` is ``(0, -1)``. `from_size` builds the
    paper's ``length x depth`` rectangles.

    Parameters
    ----------
    rows : int
        Lattice rows (at least 1).
    cols : int
        Balls to a row (at least 1).
    radius : float
        The balls' radius.
    orientation : {"along", "across"}
        ``"along"``: ``rows`` lattice rows of ``cols`` balls parallel to the
        boundary; ball ``r * cols + c`` at ``(2c + r % 2, r * sqrt(3))`` radii, so row 0 lies on
        the boundary and row ``r`` is at distance ``r * sqrt(3)``.
        ``"across"`` (the paper's): the same lattice turned a quarter, its ``rows``
        rows perpendicular to the boundary; ball ``r * cols + c`` at ``(r * sqrt(3), 2c + r % 2)``
        radii, so the boundary is a zig-zag of balls at distances 0 and 1.

    Raises
    ------
    FieldError
        On ``rows``, ``cols``, ``rows*cols`` (more balls than 32-bit tables or this machine's memory
        hold), ``radius`` or ``orientation``.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=3, cols=4)
    >>> g.n_balls, g.n_contacts
    (12, 23)
    >>> g.boundary.distance.round(3).tolist()[::4]
    [0.0, 1.732, 3.464]
    >>> pb.HalfPlane(rows=3, cols=4, orientation="across").boundary.distance.tolist()[::4]
    [0.0, 1.0, 0.0]
    """

    def __init__(self, rows: int, cols: int, radius: float = 1.0, orientation: str = "along"):
        self.rows = checks.integer("rows", rows, 1)
        self.cols = checks.integer("cols", cols, 1)
        check_memory(run_bytes(self.rows * self.cols, 3 * self.rows * self.cols), "rows*cols",
                     f"a {format_count(self.rows)} x {format_count(self.cols)} half-plane lattice")
        if self.rows * self.cols > _INT32_MAX // 3:
            raise FieldError("rows*cols", f"at most {_INT32_MAX // 3} balls, got {self.rows * self.cols}")
        self.orientation = checks.choice("orientation", orientation, ORIENTATIONS)
        p, self.radius = _lattice_positions(self.rows, self.cols, radius)
        self.positions = p if self.orientation == "along" else np.ascontiguousarray(p[:, ::-1])

    @classmethod
    def from_size(cls, length: float, depth: float, radius: float = 1.0, orientation: str = "along") -> HalfPlane:
        """The paper's ``length x depth`` rectangle (in radii), long side on the boundary.

        ``"along"``: ``cols = floor(length / 2)`` balls side by side and ``rows =
        floor((depth - 1) / sqrt(3)) + 1`` rows, the last one's balls still inside the depth;
        ``from_size(100, 50)`` gives 29 rows of 50 balls. ``"across"``: ``rows = floor(length /
        sqrt(3))`` rows of ``cols = floor(depth / 2)`` balls; ``from_size(100, 50, orientation="across")``
        gives 57 rows of 25, the paper's 1,425 balls.

        Parameters
        ----------
        length : float
            The side on the boundary, in radii (at least 2).
        depth : float
            The side perpendicular to it, in radii (at least 2).
        radius : float
            The balls' radius.
        orientation : {"along", "across"}
            How the lattice rows lie against the boundary, as for `HalfPlane`.

        Returns
        -------
        HalfPlane

        Raises
        ------
        FieldError
            On ``length`` or ``depth`` below 2 (one ball is 2 radii wide), or on ``orientation``.

        Examples
        --------
        >>> import pinnedballs as pb
        >>> g = pb.HalfPlane.from_size(100, 50, orientation="across")
        >>> g.rows, g.cols, g.n_balls
        (57, 25, 1425)
        """
        for name, value in (("length", length), ("depth", depth)):
            if checks.number(name, value) < 2:
                raise FieldError(name, f"must be >= 2 (one ball is 2 radii wide), got {value}")
        if checks.choice("orientation", orientation, ORIENTATIONS) == "across":
            rows, cols = int(np.floor(length / SQRT3 + 1e-9)), int(np.floor(depth / 2 + 1e-9))
            return cls(rows=max(rows, 1), cols=cols, radius=radius, orientation=orientation)
        cols = int(np.floor(length / 2 + 1e-9))
        rows = int(np.floor((depth - 1) / SQRT3 + 1e-9)) + 1
        return cls(rows=rows, cols=cols, radius=radius)

    def row_shape(self) -> tuple[int, int]:
        """The lattice's shape (`Geometry.row_shape`).

        Returns
        -------
        tuple of int
            ``(rows, cols)``.
        """
        return self.rows, self.cols

    def to_spec(self) -> dict:
        """The half-plane as a run spec's ``"geometry"`` (`Geometry.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "half_plane", "rows": ..., "cols": ..., "radius": ..., "orientation": ...}``.
        """
        return {"kind": "half_plane", "rows": self.rows, "cols": self.cols, "radius": self.radius,
                "orientation": self.orientation}

    def boundary_distance(self) -> np.ndarray:
        """The distance of each centre from the boundary line ``y = 0``.

        Returns
        -------
        numpy.ndarray
            ``(n_balls,) float64`` (a copy).
        """
        return self.positions[:, 1].copy()

    @property
    def boundary(self) -> Boundary:
        """Distances from the line ``y = 0``; outward is ``(0, -1)`` for every ball."""
        outward = np.zeros((self.n_balls, 2))
        outward[:, 1] = -1.0
        return Boundary(self.boundary_distance(), outward)

    def _build_contacts(self) -> Contacts:
        c = _lattice_contacts(self.rows, self.cols, periodic=False)
        if self.orientation == "along":
            return c
        return LatticeContacts(pairs=c.pairs, ends=c.ends, units=np.ascontiguousarray(c.units[:, ::-1]))

