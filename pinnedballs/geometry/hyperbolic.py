"""The hyperbolic plane (curvature -1): balls at the vertices of the {3,q} tiling, q >= 7.

Positions are in the hyperboloid model ``-x0^2 + x1^2 + x2^2 = -1`` with the Minkowski
product ``<a, b> = -a0 b0 + a1 b1 + a2 b2``. The tiling is built ring by ring from a
central ball: each ball's ``q`` neighbours lie at the contact length in the directions of
its parent turned by multiples of ``2 pi / q``; new balls are merged with known ones by position.
Every ball is kept in polar form ``(r, phi)`` (``x = (cosh r, sinh r cos phi, sinh r sin phi)``)
and each step uses the hyperbolic laws of a triangle with the centre, whose terms add up
instead of cancelling; in extended precision (``numpy.longdouble``), rounded to float64 once.
Products of boosted coordinates (``x0 ~ e^r / 2``, 877 on ring 7) cancel, so a Lorentz-matrix
construction in float64, or the Poincare disk (used here only for pictures), loses ~1e-10.
Velocities have 2 components, in each ball's Minkowski-orthonormal frame (`frames`).
"""

from __future__ import annotations

import math

import numpy as np

from ..util import checks
from ..util.errors import FieldError
from ..util.limits import check_memory, format_bytes, format_count, run_bytes
from .base import Boundary, Contacts, Geometry, checked_radius

__all__ = ["HyperbolicPlane", "contact_length", "MINKOWSKI"]

#: diagonal of the Minkowski product
MINKOWSKI = np.array([-1.0, 1.0, 1.0])
#: at most this many balls
MAX_BALLS = 20_000_000
#: peak bytes per ball while the tiling is built (its polar coordinates in longdouble, the k-d trees of
#: each ring, the candidates), besides the run's own arrays (`run_bytes`): measured 0.93 to 1.06 kB
BUILD_BYTES = 1_100


def contact_length(q: int) -> float:
    """Length of every edge of the {3,q} tiling: ``2 arccosh(cos(pi/3) / sin(pi/q))`` (1.090550 for q = 7)."""
    return float(2.0 * np.arccosh(np.cos(np.pi / 3) / np.sin(np.pi / q)))


class HyperbolicPlane(Geometry):
    """The {3,q} tiling out to graph distance ``layers`` from a central ball (ball 0).

    Ball ``n`` is in ring ``ring[n]`` (BFS order: rings of 1, 7, 21, 56, 147, 385, ... for
    q = 7). Interior balls touch ``q`` others; every contact has length `contact_length`.
    The outermost ring is the boundary: ``boundary.distance`` is ``(layers - ring) *
    contact_length`` (the path length along contacts to the outermost ring) and
    ``boundary.outward`` the radial direction away from ball 0, ``(1, 0)`` in every frame.

    Parameters
    ----------
    q : int
        Triangles at each vertex, at least 7.
    layers : int
        Rings around ball 0, at least 0.
    radius : float
        The balls' size: the centres lie on the unit surface (the hyperboloid).

    Attributes
    ----------
    ring : numpy.ndarray
        ``(n_balls,) int64``: each ball's ring.
    length : float
        `contact_length` of ``q``.

    Raises
    ------
    FieldError
        On ``q``, ``layers`` (a tiling beyond 20,000,000 balls or this machine's memory) or ``radius``.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HyperbolicPlane(q=7, layers=2)
    >>> g.n_balls, g.n_contacts, np.bincount(g.ring).tolist()
    (29, 63, [1, 7, 21])
    >>> g.boundary.distance[:2].round(6).tolist()
    [2.181099, 1.09055]
    """

    curved = True
    view = "poincare"
    metric = MINKOWSKI

    def __init__(self, q: int = 7, layers: int = 4, radius: float = 1.0):
        self.q = checks.integer("q", q, 7)
        self.layers = checks.integer("layers", layers, 0)
        self.radius = checked_radius(radius)  # the balls' size: the centres lie on the unit surface
        self.length = contact_length(self.q)
        _check_size(self.q, self.layers)
        self._r, self._phi, self.ring, self.pairs = _tiling(self.q, self.layers)
        self.positions = _hyperboloid(self._r, self._phi).astype(np.float64)

    def to_spec(self) -> dict:
        """The tiling as a run spec's ``"geometry"`` (`Geometry.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "hyperbolic_plane", "q": ..., "layers": ..., "radius": ...}``.
        """
        return {"kind": "hyperbolic_plane", "q": self.q, "layers": self.layers, "radius": self.radius}

    @property
    def boundary(self) -> Boundary:
        """The outermost ring: distances ``(layers - ring) * length``, outward ``(1, 0)`` in every frame."""
        outward = np.zeros((self.n_balls, 2))
        outward[:, 0] = 1.0
        return Boundary((self.layers - self.ring) * self.length, outward)

    def polar(self) -> tuple[np.ndarray, np.ndarray]:
        """Each ball in polar form: ``x = (cosh r, sinh r cos phi, sinh r sin phi)``.

        Returns
        -------
        r, phi : numpy.ndarray
            ``(n_balls,) float64`` each: the distance from ball 0 and the angle.
        """
        return self._r.astype(np.float64), self._phi.astype(np.float64)

    def frames(self) -> np.ndarray:
        """Each ball's Minkowski-orthonormal tangent basis (`Geometry.frames`).

        Returns
        -------
        numpy.ndarray
            ``(n_balls, 2, 3)``: the radial unit tangent (away from ball 0) and the angular one.
        """
        r, phi = self._r, self._phi
        c, s = np.cos(phi), np.sin(phi)
        radial = np.stack([np.sinh(r), np.cosh(r) * c, np.cosh(r) * s], axis=1)
        angular = np.stack([np.zeros_like(r), -s, c], axis=1)
        return np.stack([radial, angular], axis=1).astype(np.float64)

    def poincare(self) -> np.ndarray:
        """The positions in the Poincare disk, for pictures only.

        Returns
        -------
        numpy.ndarray
            ``(n_balls, 2)``: ``tanh(r / 2) (cos phi, sin phi)``.
        """
        rho = np.tanh(self._r / 2)
        return np.column_stack([rho * np.cos(self._phi), rho * np.sin(self._phi)]).astype(np.float64)

    def _build_contacts(self) -> Contacts:
        i, j = self.pairs[:, 0], self.pairs[:, 1]
        ch = np.cosh(_ld_length(self.q))
        psi_i = _direction(self._r[i], self._phi[i], self._r[j], self._phi[j], ch)
        psi_j = _direction(self._r[j], self._phi[j], self._r[i], self._phi[i], ch)
        e = len(self.pairs)
        units = np.empty((2 * e, 2))
        units[0::2] = np.column_stack([np.cos(psi_i), np.sin(psi_i)]).astype(np.float64)
        units[1::2] = np.column_stack([np.cos(psi_j), np.sin(psi_j)]).astype(np.float64)
        return Contacts.build(self.pairs, np.arange(2 * e).reshape(e, 2), units)


def ring_sizes(q: int, layers: int, most: int = MAX_BALLS) -> list[int]:
    """The balls of rings 0, 1, ..., ``layers`` of the {3,q} tiling (1, q, q(q - 4), then each ring
    ``(q - 4)`` times the one before less the one before that), stopping once they hold more than ``most``."""
    sizes = [1, q, q * (q - 4)][:layers + 1]
    while len(sizes) <= layers and sum(sizes) <= most:
        sizes.append((q - 4) * sizes[-1] - sizes[-2])
    return sizes


def _check_size(q: int, layers: int) -> None:
    """Refuse at once, from `ring_sizes`, a tiling of more than `MAX_BALLS` balls or more memory than there is."""
    sizes = ring_sizes(q, layers, most=10**15)
    n, what = sum(sizes), f"{layers:,} rings of the {{3,{q}}} tiling"
    if n <= MAX_BALLS:
        check_memory(n * BUILD_BYTES + run_bytes(n, q * n // 2, dim=2, embed=3), "layers", f"{what} ({n:,} balls)")
        return
    if len(sizes) == layers + 1:
        count, memory = f"{n:,}" if n < 10**15 else format_count(n), format_bytes(n * BUILD_BYTES)
    else:  # each ring (q - 4 + sqrt((q - 4)^2 - 4)) / 2 times the one before, nearly: a geometric sum
        growth = ((q - 4) + math.sqrt((q - 4) ** 2 - 4)) / 2
        log_n = math.log10(sizes[-1]) + (layers + 1 - len(sizes)) * math.log10(growth) - math.log10(1 - 1 / growth)
        count, memory = f"~10^{math.floor(log_n):,}", f"10^{math.floor(log_n + math.log10(BUILD_BYTES)):,} bytes"
    raise FieldError("layers", f"{what} hold {count} balls, more than the {MAX_BALLS:,} a tiling is built with "
                               f"(they would need about {memory} of memory)")


def _ld_length(q: int) -> np.longdouble:
    ld = np.longdouble
    return 2 * np.arccosh(np.cos(ld(np.pi) / 3) / np.sin(ld(np.pi) / q))


def _hyperboloid(r: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """``(n, 3)`` hyperboloid coordinates of polar ``r, phi (n,)``."""
    return np.column_stack([np.cosh(r), np.sinh(r) * np.cos(phi), np.sinh(r) * np.sin(phi)])


def _direction(ri, fi, rj, fj, cosh_d):
    """Angle at ``i`` of the geodesic to ``j`` (length ``d``), from the radial direction towards the angular one.

    With ``D = phi_j - phi_i``: ``sin(psi) sinh d cosh r_i = sinh r_j sin D cosh r_i`` and
    ``cos(psi) sinh d cosh r_i = sinh r_j cos D - cosh d sinh r_i`` (``j`` in ``i``'s frame).
    """
    delta = fj - fi
    return np.arctan2(np.sinh(rj) * np.sin(delta) * np.cosh(ri), np.sinh(rj) * np.cos(delta) - cosh_d * np.sinh(ri))


def _step(r, phi, psi, d):
    """Polar ``(r', phi')`` of the points at distance ``d`` from ``(r, phi)`` in direction ``psi`` (radians
    from the radial direction towards the angular one); all ``(n,)``."""
    a = np.cosh(d) * np.sinh(r) + np.sinh(d) * np.cos(psi) * np.cosh(r)
    b = np.sinh(d) * np.sin(psi)
    return np.arcsinh(np.hypot(a, b)), phi + np.arctan2(b, a)


def _tiling(q: int, layers: int):
    """Polar ``r, phi (n,)`` longdouble, ``ring (n,)`` and contacts ``pairs (E, 2)`` (``i < j``, sorted)."""
    from scipy.spatial import cKDTree

    ld = np.longdouble
    d = _ld_length(q)
    turns = 2 * ld(np.pi) * np.arange(q, dtype=ld) / q
    r, phi, psi = np.zeros(1, dtype=ld), np.zeros(1, dtype=ld), np.zeros(1, dtype=ld)
    ring, edges, start = [np.zeros(1, dtype=np.int64)], [], 0
    for k in range(layers + 1):
        owner = np.repeat(np.arange(start, len(r)), q)
        cr, cphi = _step(r[owner], phi[owner], (psi[start:, None] + turns).ravel(), d)
        x = _hyperboloid(r, phi).astype(np.float64)
        known = cKDTree(x).query(_hyperboloid(cr, cphi).astype(np.float64), distance_upper_bound=0.5)[1]
        new = np.flatnonzero(known == len(r))
        ok = known < len(r)
        edges.append(np.column_stack([owner[ok], known[ok]]))
        if k == layers:
            break
        if len(r) + len(new) > MAX_BALLS:
            raise FieldError("layers", f"{layers} rings of the {{3,{q}}} tiling exceed {MAX_BALLS:,} balls")
        # merge the new candidates among themselves, first appearance first
        # (a ball of the next ring touches at most two of this ring, so one level of merging suffices)
        first = np.arange(len(new))
        same = np.sort(cKDTree(_hyperboloid(cr[new], cphi[new]).astype(np.float64)).query_pairs(
            0.5, output_type="ndarray"), axis=1)
        np.minimum.at(first, same[:, 1], same[:, 0])
        first = first[first]
        keep = np.unique(first)
        renumber = np.full(len(new), -1, dtype=np.int64)
        renumber[keep] = len(r) + np.arange(len(keep))
        edges.append(np.column_stack([owner[new], renumber[first]]))
        nr, nphi = cr[new[keep]], cphi[new[keep]]
        parent = owner[new[keep]]
        npsi = _direction(nr, nphi, r[parent], phi[parent], np.cosh(d))
        start = len(r)
        r, phi, psi = np.concatenate([r, nr]), np.concatenate([phi, nphi]), np.concatenate([psi, npsi])
        ring.append(np.full(len(keep), k + 1, dtype=np.int64))
    pairs = np.unique(np.sort(np.concatenate(edges), axis=1), axis=0)
    return r, phi, np.concatenate(ring), pairs
