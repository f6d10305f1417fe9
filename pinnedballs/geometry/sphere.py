"""Balls on the unit sphere: the icosahedral geodesic grid, or any points and their Delaunay edges.

Equal balls cannot all touch on a sphere beyond small cases, so contacts come from a
graph; at each end of a contact ``t_i`` is the unit tangent at ``x_i`` of the great
circle to ``x_j``: ``(x_j - cos(th) x_i) / sin(th)`` with ``cos(th) = x_i . x_j``.
Velocities have 2 components, in each ball's tangent frame (`Sphere.frames`).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..util import checks
from ..util.errors import FieldError, FieldTypeError
from ..util.limits import check_memory, format_count, run_bytes
from .base import Contacts, Geometry, checked_radius, tangent_contacts

__all__ = ["Sphere"]

_PHI = (1.0 + np.sqrt(5.0)) / 2.0
#: the icosahedron's 12 vertices (before normalising) and 20 faces, counter-clockwise seen from outside
_ICO_VERTICES = np.array([[-1, _PHI, 0], [1, _PHI, 0], [-1, -_PHI, 0], [1, -_PHI, 0],
                          [0, -1, _PHI], [0, 1, _PHI], [0, -1, -_PHI], [0, 1, -_PHI],
                          [_PHI, 0, -1], [_PHI, 0, 1], [-_PHI, 0, -1], [-_PHI, 0, 1]])
#: at most this many balls in a geodesic grid (frequency 1,414)
MAX_BALLS = 20_000_000
#: peak bytes per ball while the geodesic grid is built (its points, their keys and index, the edge set),
#: besides the run's own arrays (`run_bytes`): measured 0.98 to 1.03 kB
BUILD_BYTES = 1_100
_ICO_FACES = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
              (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
              (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]


class Sphere(Geometry):
    """Balls on the unit sphere; contacts are the edges of a graph.

    Build with `geodesic` or `from_points`. ``dim`` is 2: a velocity is a tangent vector
    in the ball's frame (`frames`). No boundary.

    Parameters
    ----------
    positions : numpy.ndarray
        ``(n, 3)`` centres on the unit sphere.
    pairs : numpy.ndarray
        ``(E, 2)`` the balls of each contact.
    radius : float
        The balls' size: the centres lie on the unit surface.

    Attributes
    ----------
    frequency : int or None
        Of the geodesic grid; None for a sphere from points.

    Raises
    ------
    FieldError
        On ``radius``.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.Sphere.geodesic(2)
    >>> g.n_balls, g.n_contacts, g.dim, g.boundary
    (42, 120, 2, None)
    >>> sorted(set(g.degrees().tolist()))
    [5, 6]
    """

    curved = True
    view = "sphere"
    metric = np.ones(3)  #: Euclidean: the contact checks measure directions in the frames with it
    frequency: int | None = None  #: of the geodesic grid; None for a sphere from points

    def __init__(self, positions: np.ndarray, pairs: np.ndarray, radius: float = 1.0):
        self.positions = np.ascontiguousarray(positions, dtype=np.float64)
        self.pairs = np.ascontiguousarray(pairs, dtype=np.int64).reshape(-1, 2)
        self.radius = checked_radius(radius)  # the balls' size: the centres lie on the unit surface

    @classmethod
    def geodesic(cls, frequency: int, radius: float = 1.0) -> Sphere:
        """The icosahedral geodesic grid: each face cut into ``frequency^2`` triangles, projected.

        ``10 f^2 + 2`` balls (12 of degree 5, the rest 6) and ``30 f^2`` contacts. Points
        shared by faces are merged by exact integer barycentric keys, never by rounding.

        Parameters
        ----------
        frequency : int
            ``f``, at least 1 (at most 1,414: 20,000,000 balls).
        radius : float
            The balls' size.

        Returns
        -------
        Sphere

        Raises
        ------
        FieldError
            On ``frequency`` (below 1, or a grid beyond 20,000,000 balls or this machine's memory).

        Examples
        --------
        >>> import pinnedballs as pb
        >>> g = pb.Sphere.geodesic(3)
        >>> g.n_balls, g.n_contacts, g.to_spec()
        (92, 270, {'kind': 'sphere', 'frequency': 3, 'radius': 1.0})
        """
        f = checks.integer("frequency", frequency, 1)
        _check_size(f)
        keys, points, index = [], [], {}
        edges = set()
        for face in _ICO_FACES:
            local = {}
            for a, b in itertools.product(range(f + 1), repeat=2):
                if a + b > f:
                    continue
                weights = ((face[0], f - a - b), (face[1], a), (face[2], b))
                key = tuple(sorted((v, w) for v, w in weights if w))
                if key not in index:
                    index[key] = len(keys)
                    keys.append(key)
                    points.append(sum(w * _ICO_VERTICES[v] for v, w in key))
                local[a, b] = index[key]
            for (a, b), n in local.items():
                for da, db in ((1, 0), (0, 1), (-1, 1)):
                    m = local.get((a + da, b + db))
                    if m is not None:
                        edges.add((min(n, m), max(n, m)))
        p = np.array(points, dtype=np.float64)
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        sphere = cls(p, np.array(sorted(edges), dtype=np.int64), radius)
        sphere.frequency = f
        return sphere

    @classmethod
    def from_points(cls, points, radius: float = 1.0) -> Sphere:
        """Balls at given points; contacts are the edges of their spherical Delaunay triangulation.

        The Delaunay edges are those of the faces of the points' convex hull that face away from the
        origin. Positions are scaled onto the unit sphere.

        Parameters
        ----------
        points : array_like
            ``(n, 3)``, all at the same distance from the origin (n >= 4, not all on one plane, no two
            at the same place).
        radius : float
            The balls' size.

        Returns
        -------
        Sphere

        Raises
        ------
        FieldError
            On ``points`` (a bad shape, NaN, a ball off the sphere or at the origin, two balls at the same
            place, all on one plane).
        FieldTypeError
            If ``points`` are not numbers.

        Examples
        --------
        >>> import pinnedballs as pb
        >>> octahedron = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
        >>> g = pb.Sphere.from_points(octahedron)
        >>> g.n_contacts, set(g.degrees().tolist()), g.to_spec()
        (12, {4}, None)
        """
        from scipy.spatial import ConvexHull, QhullError

        p = _points_on_a_sphere(points)
        try:
            hull = ConvexHull(p)
        except QhullError as exc:
            raise FieldError("points", f"no convex hull (all on one plane?): {str(exc).splitlines()[0]}") from None
        # a face is Delaunay when the origin is inside its plane; points within one hemisphere also
        # have hull faces on the far side of the origin, which are not
        s = hull.simplices[hull.equations[:, -1] < -1e-12]
        edges = np.sort(np.concatenate([s[:, [0, 1]], s[:, [1, 2]], s[:, [0, 2]]]), axis=1)
        return cls(p, np.unique(edges, axis=0), radius)

    def to_spec(self) -> dict | None:
        """The geodesic grid as a run spec's ``"geometry"`` (`Geometry.to_spec`).

        Returns
        -------
        dict or None
            ``{"kind": "sphere", "frequency": ..., "radius": ...}``; None for a sphere from points (rebuilt
            from its stored positions).
        """
        if self.frequency is None:
            return None
        return {"kind": "sphere", "frequency": self.frequency, "radius": self.radius}

    def frames(self) -> np.ndarray:
        """Each ball's orthonormal tangent basis (`Geometry.frames`).

        Returns
        -------
        numpy.ndarray
            ``(n_balls, 2, 3)``: ``e1`` towards the z-axis (the x-axis within 0.9 of a pole), ``e2 = x x e1``.
        """
        x = self.positions
        axis = np.zeros_like(x)
        near_pole = np.abs(x[:, 2]) > 0.9
        axis[~near_pole, 2] = 1.0
        axis[near_pole, 0] = 1.0
        e1 = axis - np.einsum("nk,nk->n", axis, x)[:, None] * x
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        return np.stack([e1, np.cross(x, e1)], axis=1)

    def great_circle_tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """The unit tangents of each contact's great circle at its ends, each towards the other ball.

        Returns
        -------
        T_i, T_j : numpy.ndarray
            ``(n_contacts, 3)`` each, in embedding coordinates.
        """
        xi, xj = self.positions[self.pairs[:, 0]], self.positions[self.pairs[:, 1]]
        return _unit(xj - np.einsum("ek,ek->e", xi, xj)[:, None] * xi), \
            _unit(xi - np.einsum("ek,ek->e", xi, xj)[:, None] * xj)

    def _build_contacts(self) -> Contacts:
        T_i, T_j = self.great_circle_tangents()
        return tangent_contacts(self.pairs, T_i, T_j, self.frames(), np.ones(3))


def _check_size(f: int) -> None:
    """Refuse at once a geodesic grid of frequency ``f`` above `MAX_BALLS` balls or the memory there is."""
    n, what = 10 * f * f + 2, f"a geodesic sphere of frequency {f:,}"
    check_memory(n * BUILD_BYTES + run_bytes(n, 30 * f * f, dim=2, embed=3), "frequency",
                 f"{what} ({format_count(n) if n >= 10**15 else f'{n:,}'} balls)")
    if n > MAX_BALLS:
        raise FieldError("frequency", f"{what} has {n:,} balls, more than the {MAX_BALLS:,} a grid is built with "
                                      f"(frequency at most 1,414)")


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.linalg.norm(a, axis=1, keepdims=True)


def _points_on_a_sphere(points) -> np.ndarray:
    """``points (n, 3)`` scaled to the unit sphere; errors name balls off the sphere or repeated."""
    try:
        p = np.array(points, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("points", f"must be an array of numbers ({exc})") from None
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 4:
        raise FieldError("points", f"must have shape (n, 3) with n >= 4, got {p.shape}")
    if not np.isfinite(p).all():
        raise FieldError("points", "contain NaN or inf")
    norm = np.linalg.norm(p, axis=1)
    if not norm[0] > 0:
        raise FieldError("points", "ball 0 is at the origin, not on a sphere around it")
    off = np.flatnonzero(np.abs(norm / norm[0] - 1) > 1e-9)
    if len(off):
        raise FieldError("points", f"ball {off[0]} is off the sphere (|x| = {norm[off[0]]:.12g}, ball 0 has "
                         f"{norm[0]:.12g}); {len(off)} ball(s) off in all")
    p /= norm[:, None]
    from scipy.spatial import cKDTree

    close = cKDTree(p).query_pairs(1e-9, output_type="ndarray")
    if len(close):
        i, j = sorted(close[0].tolist())
        raise FieldError("points", f"balls {i} and {j} are at the same place")
    return p
