"""The chain in rational arithmetic: the same picks as the compiled loop, every closing speed's sign exact.

`RationalChain` holds the velocities as elements of the number field of the geometry's contact
normals (`numbers.recognise`; coefficients rationals), beside their float64 roundings (its ``shadow``, the
simulation's ``velocities``). A contact is live when its exact closing speed ``w`` is positive; a pick of a
live contact collides it with the paper's rule in exact arithmetic (equal masses:
``v_i -= (1 + r)/2 w t_i``, ``v_j -= (1 + r)/2 w t_j``; any masses: ``v_i -= (1 + r) m_j/(m_i + m_j) w t_i``,
``v_j -= (1 + r) m_i/(m_i + m_j) w t_j``), and every velocity it changes is rounded again. The float filter
(`chain.filtered_sign`) decides most signs. The live contacts are kept after every collision (the contacts of
its two balls re-tested), so the freeze is found on the collision that causes it. Exact arithmetic runs it
where the fixed-point chain (`fixed`) cannot: unequal masses, restitution (any rule's exact linear form), HCP's
Q(sqrt 2, sqrt 3), other graphs.
"""

from __future__ import annotations

import numpy as np

from ..chain import incidence
from .chain import BLOCK, FILTER, FieldChain, filtered_sign
from .numbers import recognise

__all__ = ["RationalChain", "FieldChain", "filtered_sign", "FILTER", "BLOCK"]


class RationalChain(FieldChain):
    """The velocities of ``geometry``'s balls in exact arithmetic, and their collisions.

    velocities: ``(n_balls, dim)`` floats, taken exactly (a float is a rational); masses:
    ``(n_balls,)`` floats; kick: the rule's exact linear form (`pinnedballs.rules.CollisionRule.exact_kick`).
    Raises `fields.NotExact` when the contact normals lie in no known number field.
    """

    def __init__(self, geometry, velocities: np.ndarray, masses: np.ndarray, kick):
        field, units = recognise(geometry.contacts.units)
        super().__init__(geometry, field, units, masses, kick)
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
