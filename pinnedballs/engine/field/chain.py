"""What every chain in the number field of the contact normals shares (`FieldChain`): the field and the exact
unit vectors, the rule in exact form, the arithmetic of one contact on any velocities, the velocities as numbers
and text; and the float filter that decides most signs without exact arithmetic (`filtered_sign`).

Most signs need no exact arithmetic: ``w`` computed in floats from the rounded velocities and rounded normals
is within ``FILTER * 2^-53 * sum |v t|`` of the exact one, so a float ``w`` outside that band has the exact
sign; inside it (rest, rounding remnants, genuine slow approaches) the exact ``w`` decides.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from gmpy2 import mpq

from .numbers import FieldNumber

__all__ = ["exchange", "FieldChain", "filtered_sign", "FILTER", "BLOCK"]

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

def exchange(m_i, m_j) -> tuple:
    """The paper's elastic exchange of equal masses as an exact linear form: ``a_i = a_j = 1`` (what the
    fixed-point chain runs; `pinnedballs.rules.CollisionRule.exact_kick`)."""
    return type(m_i)(1), type(m_j)(1)


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

    def __init__(self, geometry, field, units: list, masses: np.ndarray, kick: Callable):
        c = geometry.contacts
        self.field, self.units = field, units
        self.pairs = c.pairs.astype(np.int64).tolist()
        self.ends = c.ends.astype(np.int64).tolist()
        self.units_f = c.units.tolist()
        self.dim = geometry.dim
        m = np.asarray(masses, dtype=np.float64)
        self.equal = bool(np.all(m == m[0]))
        self.masses = [mpq(x) for x in m.tolist()]
        #: the rule's exact linear form (`pinnedballs.rules.CollisionRule.exact_kick`): its kick by masses
        self.kick = kick
        self.factor = kick(self.masses[0], self.masses[0])[0] if self.equal else None  # all alike: computed once

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
        ai, aj = self.kick(self.masses[i], self.masses[j])
        return F.scale(w, ai), F.scale(w, aj)

    def kicked(self, row, c: tuple, t: tuple) -> list:
        """``row - c t``: a velocity after a kick ``c`` along unit vector ``t``."""
        F = self.field
        return [F.sub(x, F.mul(c, td)) for x, td in zip(row, t)]

    # ------------------------------------------------------------ the velocities as numbers and text
    def numbers(self) -> np.ndarray:
        """``(n_balls, dim)`` object array of `numbers.FieldNumber` numbers: the velocities."""
        rows = self.v
        out = np.empty((len(rows), self.dim), dtype=object)
        for i, row in enumerate(rows):
            for d, x in enumerate(row):
                out[i, d] = FieldNumber(self.field, x)
        return out

    def coefficients(self) -> np.ndarray:
        """``(n_balls, dim, m)`` strings: each velocity component's coefficients on the field's basis."""
        return np.array([[[str(c) for c in x] for x in row] for row in self.v], dtype=object)

    def parse(self, coefficients: np.ndarray) -> list[list[tuple]]:
        """Exact velocities from `coefficients`' strings (a ValueError if they do not parse)."""
        return [[self.field.parse(list(x)) for x in row] for row in np.asarray(coefficients).tolist()]
