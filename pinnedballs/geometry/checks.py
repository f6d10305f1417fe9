"""Sound contact tables: what every geometry's contacts must satisfy before a compiled loop reads them.

The loops index the velocities with ``pairs`` and the unit vectors with ``ends`` without bounds
checks, and trust ``units`` to be unit vectors: a bad index corrupts memory or kills the interpreter,
a vector of length 2 creates energy. So `Simulation` calls `check_contacts` on every geometry (the
verdict is kept on its `Contacts`, so a second simulation on the same geometry pays nothing), and
`Contacts.build` calls `raw_tables` on what it is given before converting it (a negative index would
otherwise wrap to a huge unsigned one).

A failure is one `FieldError` naming the table (``pairs``, ``ends``, ``units``) and the first
offending contact (the lowest index; for a pair listed twice, its second listing) with its values.
Each contact, in this order:

* ``pairs``: ball indices in ``[0, n_balls)``; ``ends``: rows of ``units`` in ``[0, len(units))``;
* ``pairs``: not a ball touching itself, not a pair (unordered) listed before;
* ``units``: ``t_i`` and ``t_j`` finite and of length 1 within `UNIT_TOLERANCE`;
* ``pairs``, flat space: the balls ``2 * radius`` apart within ``geometry.rtol`` (relative), measured
  to the nearest periodic image (`Geometry.box`);
* ``units``: ``t_i`` points from ball ``i`` towards ``j`` and ``t_j`` back. Flat space:
  ``t_i . (x_j - x_i) > 0``, to the nearest periodic image. On a curved surface: the chord
  ``x_j - x_i``'s component in ball ``i``'s tangent frame, under the embedding's inner product
  (`Geometry.metric`), is the geodesic's direction, and ``t_i`` must have a positive component along
  it; a surface that states no metric is not checked (its frames alone do not say whether it is a
  sphere or a hyperboloid).

A geometry given as data may state contacts whose straight segment is not the contact (a torus's
contact graph: the segment of a contact across the boundary runs through the box;
`Geometry.stated_contacts`): their length is not checked, and their direction only where the
segment is ``2 * radius`` long.

One compiled pass over the contacts (`_first_fault`) and one over a table of each ball's contacts
(`_first_repeat`, O(contacts + balls)) do it, for less than building a lattice's contacts costs
(CPU seconds, measured on this project's 2-core machine: HalfPlane(1155, 2000), 6.9 million
contacts, 0.10 against 0.8-1.0 to build them; FCC(100, 100, 100), 24 million, 0.9-1.0 against
2.5-2.6). A plain-Python twin in the tests checks them.
"""

from __future__ import annotations

import weakref

import numpy as np

from ..engine.jit.cache import njit_cached
from ..util.errors import FieldError, FieldTypeError

__all__ = ["UNIT_TOLERANCE", "LENGTH_RTOL", "raw_tables", "check_contacts"]

#: a unit vector's length may differ from 1 by this much (one normalised in float64 is within ~4e-16)
UNIT_TOLERANCE = 1e-12
#: default relative tolerance on a flat contact's length ``2 radius`` (`Geometry.rtol`)
LENGTH_RTOL = 1e-6
_UINT32_LIMIT = 1 << 32

#: what `_first_fault` finds wrong with a contact
OK, PAIRS_RANGE, ENDS_RANGE, SELF, UNIT, LENGTH, DIRECTION = range(7)
#: how `_first_fault` measures directions: not at all, in flat space, on a curved surface
NO_DIRECTIONS, FLAT, CURVED = range(3)


# ---------------------------------------------------------------- what Contacts.build is given


def _whole(name: str, a, what: str) -> np.ndarray:
    """``a`` as an ``(E, 2)`` array of whole numbers (an integer dtype kept), else a `FieldError`."""
    try:
        arr = np.asarray(a)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError(name, f"must be an (n_contacts, 2) array of {what} ({exc})") from None
    if arr.size == 0:
        return arr.reshape(0, 2).astype(np.int64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise FieldError(name, f"must have shape (n_contacts, 2), got {arr.shape}")
    if arr.dtype.kind in "iu":
        return arr
    if arr.dtype.kind != "f":
        raise FieldTypeError(name, f"must be {what} (integers), got dtype {arr.dtype}")
    bad = ~np.isfinite(arr) | (arr != np.round(arr))
    if bad.any():
        k = int(np.flatnonzero(bad.any(axis=1))[0])
        raise FieldError(name, f"contact {k} has {tuple(arr[k].tolist())}: {what} must be whole numbers")
    return arr.astype(np.int64)


def _first_outside(arr: np.ndarray, limit: int) -> int | None:
    """The first row of ``arr (E, 2)`` with an entry below 0 or at least ``limit``, or None."""
    bad = (arr >= limit).any(axis=1)
    if arr.dtype.kind == "i":
        bad |= (arr < 0).any(axis=1)
    hits = np.flatnonzero(bad)
    return int(hits[0]) if len(hits) else None


def raw_tables(pairs, ends, units) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``pairs (E, 2)``, ``ends (E, 2)`` and ``units (K, dim) float64`` as given to `Contacts.build`,
    checked before any conversion: whole numbers, no negative index, ``ends`` within ``units``, indices
    that fit 32 bits. A `FieldError` naming the table and the first bad contact."""
    try:
        u = np.ascontiguousarray(units, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("units", f"must be an (n_units, dim) array of numbers ({exc})") from None
    if u.ndim != 2 or u.shape[1] < 1:
        raise FieldError("units", f"must have shape (n_units, dim), got {u.shape}")
    p, e = _whole("pairs", pairs, "ball indices"), _whole("ends", ends, "rows of units")
    if len(e) != len(p):
        raise FieldError("ends", f"must have one row per contact: {len(p)} pairs but {len(e)} ends")
    k = _first_outside(p, _UINT32_LIMIT)
    if k is not None:
        raise FieldError("pairs", f"contact {k} has balls {tuple(p[k].tolist())}: ball indices are whole "
                                  f"numbers from 0 (below 2**32)")
    k = _first_outside(e, len(u))
    if k is not None:
        raise FieldError("ends", f"contact {k} has ends {tuple(e[k].tolist())}, but units has {len(u)} rows "
                                 f"(0 to {len(u) - 1})")
    return p, e, u


# ---------------------------------------------------------------- a geometry's contacts


def check_contacts(geometry) -> None:
    """A `FieldError` naming the table and the first offending contact if ``geometry``'s contacts are
    not sound (see the module's docstring); nothing otherwise. The verdict is kept on the contacts."""
    c = geometry.contacts
    seen = c.__dict__.get("_sound_for")
    try:
        if seen is not None and geometry in seen:
            return
    except TypeError:  # a geometry that cannot be weakly referenced is checked every time
        pass
    pairs, ends = _table("pairs", c.pairs), _table("ends", c.ends)
    units = c.units
    if not isinstance(units, np.ndarray) or units.dtype != np.float64 or units.ndim != 2 or units.shape[1] < 1:
        raise FieldError("units", f"must be an (n_units, dim) float64 array, got "
                                  f"{getattr(units, 'dtype', type(units).__name__)} {np.shape(units)}")
    if len(ends) != len(pairs):
        raise FieldError("ends", f"must have one row per contact: {len(pairs)} pairs but {len(ends)} ends")
    args = _direction_args(geometry, units.shape[1], len(pairs))
    fault, k, side = _first_fault(pairs, ends, np.ascontiguousarray(units), geometry.n_balls, *args)
    # a pair listed before is a fault of the pairs, named before the units of that contact and after the rest
    stop = len(pairs) if fault == OK else k + 1 if fault in (UNIT, LENGTH, DIRECTION) else k
    later, first = _first_repeat(pairs, geometry.n_balls, stop)
    if later >= 0:
        raise FieldError("pairs", f"contact {later} repeats contact {first}: balls {tuple(pairs[later].tolist())}")
    if fault != OK:
        raise _error(geometry, c, fault, k, side, args)
    try:
        c.__dict__.setdefault("_sound_for", weakref.WeakSet()).add(geometry)
    except TypeError:
        pass


def _table(name: str, arr) -> np.ndarray:
    """``arr`` as the kernel reads it: an ``(E, 2)`` integer array (uint8/16/32 as they are, else int64)."""
    if not isinstance(arr, np.ndarray) or arr.dtype.kind not in "iu" or arr.ndim != 2 or arr.shape[1] != 2:
        raise FieldError(name, f"must be an (n_contacts, 2) integer array, got "
                               f"{getattr(arr, 'dtype', type(arr).__name__)} {np.shape(arr)}")
    if arr.dtype in (np.uint8, np.uint16, np.uint32):
        return arr
    if arr.dtype == np.uint64 and len(arr) and int(arr.max()) >= 1 << 63:
        return np.minimum(arr, np.uint64(1 << 62)).astype(np.int64)  # still out of range, without wrapping
    return arr.astype(np.int64)


def _direction_args(geometry, dim: int, n_contacts: int) -> tuple:
    """``(mode, positions, box, stated, frames, metric, contact length, rtol)`` for `_first_fault`."""
    p = np.ascontiguousarray(geometry.positions, dtype=np.float64)
    box, stated, metric = geometry.box, geometry.stated_contacts(), geometry.metric
    k = p.shape[1] if p.ndim == 2 else 0
    box = np.full(k, np.inf) if box is None else np.asarray(box, dtype=np.float64)
    stated = np.zeros(0, dtype=np.bool_) if stated is None else np.asarray(stated, dtype=np.bool_)
    metric = np.ones(k) if metric is None else np.asarray(metric, dtype=np.float64)
    frames, mode = np.zeros((0, 0, 0)), NO_DIRECTIONS
    if p.ndim != 2 or len(p) != geometry.n_balls or box.shape != (k,) or metric.shape != (k,) \
            or stated.shape not in ((0,), (n_contacts,)):
        p, box, metric, stated = np.zeros((0, 0)), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.bool_)
    elif not geometry.curved:
        mode = FLAT if k == dim else NO_DIRECTIONS
    elif geometry.metric is not None:
        frames = np.ascontiguousarray(geometry.frames(), dtype=np.float64)
        mode = CURVED if frames.shape == (len(p), dim, k) else NO_DIRECTIONS
    return (mode, p, box, stated, frames, metric, 2.0 * float(geometry.radius), float(geometry.rtol))


def _vec(x) -> str:
    return "(" + ", ".join(f"{float(c):.6g}" for c in np.atleast_1d(x)) + ")"


def _error(geometry, c, fault: int, k: int, side: int, args) -> FieldError:
    """The one-line error for `_first_fault`'s verdict on contact ``k``."""
    n = geometry.n_balls
    balls = tuple(int(x) for x in c.pairs[k])
    if fault == PAIRS_RANGE:
        return FieldError("pairs", f"contact {k} has balls {balls}, but there are {n} balls (0 to {n - 1})")
    if fault == ENDS_RANGE:
        return FieldError("ends", f"contact {k} has ends {tuple(int(x) for x in c.ends[k])}, but units has "
                                  f"{len(c.units)} rows (0 to {len(c.units) - 1})")
    if fault == SELF:
        return FieldError("pairs", f"contact {k} joins ball {balls[0]} to itself")
    name = f"t_{'ij'[side]}"
    t = c.units[int(c.ends[k, side])]
    if fault == UNIT:
        what = "is not finite" if not np.isfinite(t).all() else \
            f"has length {float(np.linalg.norm(t)):.17g}, not 1 (tolerance {UNIT_TOLERANCE:g})"
        return FieldError("units", f"contact {k} (balls {balls}): {name} = {_vec(t)} {what}")
    mode, p, box, _, _, _, contact, rtol = args
    d = p[balls[1]] - p[balls[0]]
    finite = np.isfinite(box)
    d[finite] -= box[finite] * np.round(d[finite] / box[finite])
    if fault == LENGTH:
        return FieldError("pairs", f"contact {k} joins balls {balls} {float(np.linalg.norm(d)):.6g} apart, but "
                                   f"touching balls of radius {contact / 2:g} are {contact:g} apart (relative "
                                   f"tolerance {rtol:g})")
    where = "" if mode == FLAT else " (in its tangent frame)"
    return FieldError("units", f"contact {k} (balls {balls}): {name} = {_vec(t)} points away from ball "
                               f"{balls[1 - side]}{where}: {name} . (x_{'ji'[side]} - x_{'ij'[side]}) <= 0")


# ---------------------------------------------------------------- compiled passes


@njit_cached
def _first_fault(pairs, ends, units, n_balls, mode, positions, box, stated, frames, metric, contact, rtol):
    """``(fault, contact, side)`` of the first contact with a fault (``OK, -1, 0`` when none): see the
    module's docstring for the order in which a contact is checked."""
    n_units, dim = units.shape
    k = positions.shape[1]
    d = np.empty(k)
    for e in range(len(pairs)):
        i, j, a, b = pairs[e, 0], pairs[e, 1], ends[e, 0], ends[e, 1]
        if i < 0 or j < 0 or i >= n_balls or j >= n_balls:
            return PAIRS_RANGE, e, 0
        if a < 0 or b < 0 or a >= n_units or b >= n_units:
            return ENDS_RANGE, e, 0
        if i == j:
            return SELF, e, 0
        for side in range(2):
            row = a if side == 0 else b
            norm2 = 0.0
            for c in range(dim):
                norm2 += units[row, c] * units[row, c]
            if not abs(np.sqrt(norm2) - 1.0) <= UNIT_TOLERANCE:
                return UNIT, e, side
        if mode == NO_DIRECTIONS:
            continue
        length2 = 0.0
        for c in range(k):
            x = positions[j, c] - positions[i, c]
            if np.isfinite(box[c]):
                x -= box[c] * np.rint(x / box[c])  # np.round's halves to even: its first compile costs 0.5 s more
            d[c] = x
            length2 += x * x
        if mode == FLAT and not abs(np.sqrt(length2) - contact) <= rtol * contact:
            if len(stated) and stated[e]:
                continue  # a stated contact whose straight segment is not the contact: nothing to measure
            return LENGTH, e, 0
        for side in range(2):
            row, ball, sign = (a, i, 1.0) if side == 0 else (b, j, -1.0)
            dot = 0.0
            if mode == FLAT:
                for c in range(dim):
                    dot += units[row, c] * sign * d[c]
            else:
                for s in range(dim):
                    along = 0.0
                    for c in range(k):
                        along += frames[ball, s, c] * metric[c] * sign * d[c]
                    dot += units[row, s] * along
            if not dot > 0.0:
                return DIRECTION, e, side
    return OK, -1, 0


@njit_cached
def _first_repeat(pairs, n_balls, stop):
    """``(later, first)``: the earliest second listing, among contacts ``0 .. stop-1`` (whose balls are in
    range), of an unordered pair listed before, and that first listing; ``(-1, -1)`` when none. Each
    ball's contacts, in contact order, from a counting sort on the lower ball: O(contacts + balls).

    Its scratch is uint32, as the tables are (contact and ball indices below 2**32; `raw_tables`): 4 bytes a
    ball three times and 4 a contact (int64 took 24 a ball: 36 MB beside a 1000x1000 torus's 30 MB tables)."""
    start = np.empty(n_balls + 1, dtype=np.uint32)
    for b in range(n_balls + 1):  # zeros, without compiling np.zeros
        start[b] = 0
    for e in range(stop):
        start[min(pairs[e, 0], pairs[e, 1]) + 1] += 1
    for b in range(n_balls):
        start[b + 1] += start[b]
    order = np.empty(stop, dtype=np.uint32)
    fill = start[:-1].copy()
    for e in range(stop):
        lo = min(pairs[e, 0], pairs[e, 1])
        order[fill[lo]] = e
        fill[lo] += 1
    mark = fill  # reused: 1 + the last lower ball seen with each upper ball (0: none)
    mark[:] = 0
    first = np.empty(n_balls, dtype=np.uint32)
    later, earlier = np.int64(stop), np.int64(-1)
    for b in range(n_balls):
        seen = np.uint32(b + 1)
        for q in range(np.int64(start[b]), np.int64(start[b + 1])):
            e = np.int64(order[q])
            hi = max(pairs[e, 0], pairs[e, 1])
            if mark[hi] == seen:
                if e < later:
                    later, earlier = e, np.int64(first[hi])
            else:
                mark[hi] = seen
                first[hi] = e
    return (later, earlier) if earlier >= 0 else (np.int64(-1), np.int64(-1))
