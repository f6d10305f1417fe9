"""Close packings of equal balls in 3-D: face-centred cubic (FCC) and hexagonal (HCP).

Both are a box of ``nx x ny x nz`` cells of 4 balls, each ball touching 12 others in
the bulk. Contacts are built with array operations from the cell's neighbour stencil:
4 million balls take seconds. Each axis is periodic or open; an open z makes a 3-D
half-space whose boundary is the bottom layer.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..util import checks
from ..util.errors import FieldError, FieldTypeError
from ..util.limits import check_memory, format_count, run_bytes
from .base import _INT32_MAX, Boundary, Contacts, Geometry, checked_radius

__all__ = ["FCC", "HCP"]

AXES = ("nx", "ny", "nz")


class _Packing(Geometry):
    """Cells of ``CELL (3,)`` radii holding balls at ``BASIS (B, 3)`` radii; ball
    ``((ix * ny + iy) * nz + iz) * B + b`` at ``radius * ((ix, iy, iz) * CELL + BASIS[b])``."""

    CELL: np.ndarray
    BASIS: np.ndarray
    kind: str  #: the spec's kind

    def __init__(self, nx: int, ny: int, nz: int, periodic=True, radius: float = 1.0):
        self.shape = tuple(checks.integer(name, n, 1) for name, n in zip(AXES, (nx, ny, nz)))
        self.periodic = _check_periodic(periodic)
        checks.number("radius", radius, 0.0, above=True)
        n = int(np.prod(self.shape)) * len(self.BASIS)
        check_memory(run_bytes(n, 6 * n, dim=3), "nx*ny*nz",
                     f"a {' x '.join(format_count(s) for s in self.shape)} {type(self).__name__} packing")
        if n > _INT32_MAX // 6:
            cells = n // len(self.BASIS)
            raise FieldError("nx*ny*nz", f"at most {_INT32_MAX // 6 // len(self.BASIS)} cells, got {cells}")
        self._stencil = _stencil(self.CELL, self.BASIS)
        _check_wrap(self._stencil, self.shape, self.periodic)
        cells = np.indices(self.shape).reshape(3, -1).T
        p = (cells[:, None, :] * self.CELL + self.BASIS[None, :, :]).reshape(-1, 3)
        self.radius = checked_radius(radius, float(np.sqrt(np.einsum("ij,ij->i", p, p).max())))
        p *= self.radius
        self.positions = p

    def to_spec(self) -> dict:
        """The packing as a run spec's ``"geometry"`` (`Geometry.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "fcc" or "hcp", "nx": ..., "ny": ..., "nz": ..., "periodic": [...], "radius": ...}``.
        """
        nx, ny, nz = self.shape
        return {"kind": self.kind, "nx": nx, "ny": ny, "nz": nz, "periodic": list(self.periodic),
                "radius": self.radius}

    @property
    def period(self) -> np.ndarray:
        """``(3,)`` side lengths of the box."""
        return self.radius * np.asarray(self.shape) * self.CELL

    @property
    def box(self) -> np.ndarray:
        """`period` along the periodic axes, ``inf`` along the open ones."""
        return np.where(self.periodic, self.period, np.inf)

    @property
    def boundary(self) -> Boundary | None:
        """With an open z: the bottom layer ``z = 0``, distance = height above it, outward ``(0, 0, -1)``."""
        if self.periodic[2]:
            return None
        outward = np.zeros((self.n_balls, 3))
        outward[:, 2] = -1.0
        return Boundary(self.positions[:, 2].copy(), outward)

    def _build_contacts(self) -> Contacts:
        shape, b = np.asarray(self.shape), len(self.BASIS)
        cells = np.indices(self.shape).reshape(3, -1).T
        units = np.array([u for _, _, _, u in self._stencil])
        parts = []
        for a, shift, c, _ in self._stencil:
            target = cells + shift
            valid = np.ones(len(cells), dtype=bool)
            for axis in range(3):
                if self.periodic[axis]:
                    target[:, axis] %= shape[axis]
                else:
                    valid &= (target[:, axis] >= 0) & (target[:, axis] < shape[axis])
            parts.append((_cell_index(cells[valid], shape) * b + a, _cell_index(target[valid], shape) * b + c))
        e = sum(len(i) for i, _ in parts)
        pairs = np.empty((e, 2), dtype=np.uint32)
        ends = np.empty((e, 2), dtype=np.uint8)
        start = 0
        for k, (i, j) in enumerate(parts):
            stop = start + len(i)
            pairs[start:stop, 0], pairs[start:stop, 1] = i, j
            ends[start:stop] = (k, k + len(units))
            start = stop
        return Contacts(pairs=pairs, ends=ends, units=np.concatenate([units, -units]))


class FCC(_Packing):
    """Face-centred cubic packing: ``4 nx ny nz`` balls, cubic cells of side ``2 sqrt(2)`` radii,
    12 contacts per ball when periodic.

    Parameters
    ----------
    nx, ny, nz : int
        Cells along each axis, at least 1 (at least 2 along a periodic axis, so that no ball touches
        itself or another twice).
    periodic : bool or tuple of bool
        One for every axis, or a triple for (x, y, z). An open z makes a 3-D half-space whose
        boundary is the bottom layer ``z = 0``.
    radius : float
        The balls' radius.

    Attributes
    ----------
    shape : tuple of int
        ``(nx, ny, nz)``.
    periodic : tuple of bool
        For (x, y, z).

    Raises
    ------
    FieldError
        On an axis too short to be periodic, ``nx*ny*nz`` (too many cells for 32-bit tables or this
        machine's memory) or ``radius``.
    FieldTypeError
        If ``periodic`` is neither a bool nor a triple of bools.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.FCC(2, 2, 2)
    >>> g.n_balls, g.n_contacts, set(g.degrees().tolist())
    (32, 192, {12})
    >>> half = pb.FCC(2, 2, 2, periodic=(True, True, False))
    >>> half.boundary.distance[:3].round(3).tolist(), half.box.round(3).tolist()
    ([0.0, 0.0, 1.414], [5.657, 5.657, inf])
    """

    kind = "fcc"
    rigid = True  # periodic on every axis, only a common velocity has every closing speed 0 (tested)
    CELL = np.full(3, 2.0 * np.sqrt(2.0))
    BASIS = np.sqrt(2.0) * np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])


class HCP(_Packing):
    """Hexagonal close packing (layers A B A B ... along z, ``sqrt(8/3)`` radii apart):
    ``4 nx ny nz`` balls in cells of ``2 x 2 sqrt(3) x 2 sqrt(8/3)`` radii, 12 contacts per ball
    when periodic.

    Parameters
    ----------
    nx, ny, nz : int
        Cells along each axis, at least 1 (a periodic x needs at least 3, y and z at least 2, so that
        no ball touches itself or another twice).
    periodic : bool or tuple of bool
        One for every axis, or a triple for (x, y, z); an open z makes a half-space, as for `FCC`.
    radius : float
        The balls' radius.

    Attributes
    ----------
    shape : tuple of int
        ``(nx, ny, nz)``.
    periodic : tuple of bool
        For (x, y, z).

    Raises
    ------
    FieldError
        On an axis too short to be periodic, ``nx*ny*nz`` or ``radius``, as for `FCC`.
    FieldTypeError
        If ``periodic`` is neither a bool nor a triple of bools.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.HCP(3, 2, 2)
    >>> g.n_balls, set(g.degrees().tolist()), g.to_spec()["kind"]
    (48, {12}, 'hcp')
    """

    kind = "hcp"
    _H = np.sqrt(8.0 / 3.0)
    CELL = np.array([2.0, 2.0 * np.sqrt(3.0), 2.0 * _H])
    BASIS = np.array([[0.0, 0.0, 0.0], [1.0, np.sqrt(3.0), 0.0],
                      [1.0, np.sqrt(3.0) / 3.0, _H], [0.0, 4.0 * np.sqrt(3.0) / 3.0, _H]])


def _cell_index(cells: np.ndarray, shape: np.ndarray) -> np.ndarray:
    return (cells[:, 0] * shape[1] + cells[:, 1]) * shape[2] + cells[:, 2]


def _check_periodic(periodic) -> tuple[bool, bool, bool]:
    if isinstance(periodic, (tuple, list)) and len(periodic) == 3:
        return tuple(checks.flag("periodic", p) for p in periodic)
    if isinstance(periodic, (bool, np.bool_)):
        return (bool(periodic),) * 3
    raise FieldTypeError("periodic", f"must be a bool or a triple of bools, got {periodic!r}")


def _stencil(cell: np.ndarray, basis: np.ndarray) -> list[tuple[int, np.ndarray, int, np.ndarray]]:
    """Each contact once: ``(a, shift (3,), b, unit (3,))`` for ball ``a`` of a cell touching ball ``b``
    of the cell ``shift`` away, with ``(shift, b)`` after ``(0, a)`` in lexicographic order."""
    out = []
    for a, shift, b in itertools.product(range(len(basis)), itertools.product((-1, 0, 1), repeat=3),
                                         range(len(basis))):
        delta = np.asarray(shift) * cell + basis[b] - basis[a]
        if abs(np.linalg.norm(delta) - 2.0) < 1e-9 and (shift, b) > ((0, 0, 0), a):
            out.append((a, np.asarray(shift), b, delta / np.linalg.norm(delta)))
    return out


def _check_wrap(stencil, shape: tuple, periodic: tuple) -> None:
    """A ``ValueError`` naming the axis if wrapping it would make a ball touch itself or one ball twice."""
    for axis, name in enumerate(AXES):
        if periodic[axis] and not _wraps_cleanly(stencil, axis, shape[axis]):
            least = next(n for n in range(2, 8) if _wraps_cleanly(stencil, axis, n))
            raise FieldError(name, f"must be >= {least} when periodic (or a ball would touch itself or "
                             f"another ball twice), got {shape[axis]}")


def _wraps_cleanly(stencil, axis: int, n: int) -> bool:
    """True if every ball's neighbours stay distinct, and not itself, with ``n`` cells along a periodic ``axis``."""
    keys = []
    for a, shift, b, _ in stencil:
        for src, s, dst in ((a, shift, b), (b, -shift, a)):
            s = s.copy()
            s[axis] %= n
            keys.append((src, tuple(s.tolist()), dst))
    return len(set(keys)) == len(keys) and not any(src == dst and not any(s) for src, s, dst in keys)
