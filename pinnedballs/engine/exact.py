"""The chain in exact arithmetic: the same picks as the compiled loop, every closing speed's sign exact.

`ExactChain` holds the velocities as elements of the number field of the geometry's contact
normals (`fields.recognise`), beside their float64 roundings (its ``shadow``, the simulation's
``velocities``). A contact is live when its exact closing speed ``w`` is positive; a pick of a
live contact collides it with the paper's rule in exact arithmetic (equal masses:
``v_i -= (1 + r)/2 w t_i``, ``v_j -= (1 + r)/2 w t_j``; any masses: ``v_i -= (1 + r) m_j/(m_i + m_j) w t_i``,
``v_j -= (1 + r) m_i/(m_i + m_j) w t_j``), and every velocity it changes is rounded again.

Most signs need no exact arithmetic: ``w`` computed in floats from the rounded velocities and
rounded normals is within ``FILTER * 2^-53 * sum |v t|`` of the exact one, so a float ``w``
outside that band has the exact sign; inside it (rest, rounding remnants, genuine slow
approaches) the exact ``w`` decides. The live contacts are kept after every collision (the
contacts of its two balls re-tested), so the freeze is found on the collision that causes it.
"""

from __future__ import annotations

import numpy as np
from gmpy2 import mpq

from .chain import incidence
from .fields import Exact, recognise

__all__ = ["FieldChain", "ExactChain", "FILTER", "BLOCK"]

#: picks drawn at a time from the compiled selector
BLOCK = 1 << 14

#: the float filter's band, in units of 2^-53 times ``sum |v t|`` (first-order error bound: about 12 in 2-D)
FILTER = 64.0
_U = 2.0 ** -53



def filtered_sign(ti, tj, vi, vj, dim: int) -> tuple[int, float]:
    """The float filter on a closing speed ``vi.ti + vj.tj`` from the rounded velocities: ``(+1 or -1,
    size)`` when its sign is certain (outside ``FILTER`` ulp of ``size = sum |v t|``), ``(0, size)``
    when the exact value must decide."""
    w = size = 0.0
    for d in range(dim):
        x, y = vi[d] * ti[d], vj[d] * tj[d]
        w += x + y
        size += abs(x) + abs(y)
    band = FILTER * _U * size
    return (1 if w > band else -1 if w < -band else 0), size

class FieldChain:
    """What every chain in the number field of ``geometry``'s contact normals shares: the field and
    the exact unit vectors (`fields.recognise`), the rule in exact form, and the arithmetic of one
    contact on any velocities. A subclass holds the velocities ``v`` (rows of field elements) and
    runs picks in blocks of ``block`` (`run`); a run it cannot finish leaves ``failure``, the error
    to raise once the picks it used are counted."""

    block = BLOCK
    failure: Exception | None = None
    _picks: np.ndarray | None = None

    def picks_buffer(self, size: int) -> np.ndarray:
        """``(size,) int64``: room for a block of picks, the same memory every time (a fresh array
        would cost the operating system's page faults on every block)."""
        if self._picks is None or len(self._picks) < size:
            self._picks = np.empty(max(size, self.block), dtype=np.int64)
        return self._picks[:size]

    def __init__(self, geometry, field, units: list, masses: np.ndarray, restitution: float):
        c = geometry.contacts
        self.field, self.units = field, units
        self.pairs = c.pairs.astype(np.int64).tolist()
        self.ends = c.ends.astype(np.int64).tolist()
        self.units_f = c.units.tolist()
        self.dim = geometry.dim
        m = np.asarray(masses, dtype=np.float64)
        self.equal = bool(np.all(m == m[0]))
        self.masses = [mpq(x) for x in m.tolist()]
        self.factor = (1 + mpq(restitution)) / (2 if self.equal else 1)

    # ------------------------------------------------------------ one contact, in any state
    def closing_of(self, vi, vj, k: int) -> tuple:
        """The exact closing speed ``w = v_i . t_i + v_j . t_j`` of contact ``k`` for the rows ``vi, vj``."""
        F, (a, b) = self.field, self.ends[k]
        ti, tj = self.units[a], self.units[b]
        w = F.zero
        for d in range(self.dim):
            w = F.add(w, F.add(F.mul(vi[d], ti[d]), F.mul(vj[d], tj[d])))
        return w

    def kicks(self, w: tuple, k: int) -> tuple[tuple, tuple]:
        """The rows ``(v_i, v_j)`` are replaced by ``v_i - c_i t_i`` and ``v_j - c_j t_j``: ``(c_i, c_j)``
        for closing speed ``w`` on contact ``k``."""
        F, (i, j) = self.field, self.pairs[k]
        if self.equal:
            c = F.scale(w, self.factor)
            return c, c
        s = F.scale(w, self.factor / (self.masses[i] + self.masses[j]))
        return F.scale(s, self.masses[j]), F.scale(s, self.masses[i])

    def kicked(self, row, c: tuple, t: tuple) -> list:
        """``row - c t``: a velocity after a kick ``c`` along unit vector ``t``."""
        F = self.field
        return [F.sub(x, F.mul(c, td)) for x, td in zip(row, t)]

    # ------------------------------------------------------------ the velocities as numbers and text
    def numbers(self) -> np.ndarray:
        """``(n_balls, dim)`` object array of `Exact` numbers: the velocities."""
        rows = self.v
        out = np.empty((len(rows), self.dim), dtype=object)
        for i, row in enumerate(rows):
            for d, x in enumerate(row):
                out[i, d] = Exact(self.field, x)
        return out

    def coefficients(self) -> np.ndarray:
        """``(n_balls, dim, m)`` strings: each velocity component's coefficients on the field's basis."""
        return np.array([[[str(c) for c in x] for x in row] for row in self.v], dtype=object)

    def parse(self, coefficients: np.ndarray) -> list[list[tuple]]:
        """Exact velocities from `coefficients`' strings (a ValueError if they do not parse)."""
        return [[self.field.parse(list(x)) for x in row] for row in np.asarray(coefficients).tolist()]


class ExactChain(FieldChain):
    """The velocities of ``geometry``'s balls in exact arithmetic, and their collisions.

    velocities: ``(n_balls, dim)`` floats, taken exactly (a float is a rational); masses:
    ``(n_balls,)`` floats; restitution: the rule's ``r`` (1: elastic). Raises `fields.NotExact`
    when the contact normals lie in no known number field.
    """

    def __init__(self, geometry, velocities: np.ndarray, masses: np.ndarray, restitution: float):
        field, units = recognise(geometry.contacts.units)
        super().__init__(geometry, field, units, masses, restitution)
        F = self.field
        self.shadow = np.array(velocities, dtype=np.float64)  # written by `sync`
        self.floats = self.shadow.tolist()  # the roundings the filter reads, as Python floats
        self.v = [[F.of(x) for x in row] for row in self.floats]
        self.rest = [not any(row) for row in self.floats]
        ptr, inc = incidence(geometry.contacts.pairs, geometry.n_balls)
        self.around = [inc[ptr[b]:ptr[b + 1]].astype(np.int64).tolist() for b in range(geometry.n_balls)]
        self.flags: list[bool] | None = None
        self.live = -1

    def prepare(self, until_frozen: bool) -> None:
        """Make ready for `run`: the live set known."""
        if self.flags is None:
            self.count_live()

    # ------------------------------------------------------------ one contact, in the chain's state
    def closing(self, k: int) -> tuple:
        """The exact closing speed of contact ``k`` (an element)."""
        i, j = self.pairs[k]
        return self.closing_of(self.v[i], self.v[j], k)

    def approaching(self, k: int) -> bool:
        """True when contact ``k``'s exact closing speed is positive (the float filter first)."""
        i, j = self.pairs[k]
        if self.rest[i] and self.rest[j]:
            return False
        a, b = self.ends[k]
        sign, _ = filtered_sign(self.units_f[a], self.units_f[b], self.floats[i], self.floats[j], self.dim)
        return sign > 0 if sign else self.field.sign(self.closing(k)) > 0

    def collide(self, k: int) -> bool:
        """Collide contact ``k`` if it is live (exactly); True if it was."""
        if not self.approaching(k):
            return False
        F, (i, j), (a, b) = self.field, self.pairs[k], self.ends[k]
        ci, cj = self.kicks(self.closing(k), k)
        for ball, c, t in ((i, ci, self.units[a]), (j, cj, self.units[b])):
            row = self.v[ball] = self.kicked(self.v[ball], c, t)
            self.floats[ball] = [F.to_float(x) for x in row]
            self.rest[ball] = not any(any(x) for x in row)
        return True

    # ------------------------------------------------------------ the live set
    def count_live(self) -> int:
        """Test every contact; keep and return the number of live ones."""
        self.flags = [self.approaching(k) for k in range(len(self.pairs))]
        self.live = sum(self.flags)
        return self.live

    def _retest(self, ball: int, skip: int) -> None:
        flags = self.flags
        for c in self.around[ball]:
            if c != skip:
                now = self.approaching(c)
                self.live += now - flags[c]
                flags[c] = now

    # ------------------------------------------------------------ a run
    def run(self, picks, collisions_left: int, until_frozen: bool, first_step: int = 1) -> tuple[int, int, list[int]]:
        """Try the contacts ``picks`` in turn, stopping right after the ``collisions_left``-th
        collision or, with ``until_frozen``, right after the one that leaves no live contact:
        ``(picks used, collisions, the index in picks of each collision)``. The live set must be
        known (`count_live`). (``first_step``, the step of ``picks[0]``, names the step of a failure
        in chains that can fail.)"""
        at = []
        for t, k in enumerate(np.asarray(picks).tolist()):
            if self.collide(k):
                at.append(t)
                i, j = self.pairs[k]
                self._retest(i, -1)
                self._retest(j, k)
                if len(at) == collisions_left or (until_frozen and self.live == 0):
                    return t + 1, len(at), at
        return len(picks), len(at), at

    # ------------------------------------------------------------ state
    def set_velocities(self, exact: list[list[tuple]]) -> None:
        """Replace the velocities by exact ones ``(n_balls, dim)`` of elements; the live set is then unknown."""
        self.v = [list(row) for row in exact]
        self.floats = [[self.field.to_float(x) for x in row] for row in self.v]
        self.sync()
        self.rest = [not any(any(x) for x in row) for row in self.v]
        self.flags, self.live = None, -1

    def sync(self) -> np.ndarray:
        """The float roundings written into ``shadow`` (the simulation's velocities), which it returns."""
        self.shadow[:] = self.floats
        return self.shadow
