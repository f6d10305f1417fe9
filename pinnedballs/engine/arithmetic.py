"""Which chain runs a simulation's arithmetic beyond floats.

``"exact"``: the fixed-point chain (`fixed.FixedChain`, exact policy) where it applies (equal masses,
elastic collisions, flat contacts whose normals have dyadic components in Q or one Q(sqrt d):
the triangular lattices, FCC, square and cubic packings, chains), else the rational chain
(`exact.ExactChain`: unequal masses, restitution, HCP's Q(sqrt 2, sqrt 3), other graphs).
``"certified"``: the fixed-point chain's certified policy, which only it has.
"""

from __future__ import annotations

import numpy as np

from . import checks
from .errors import FieldError
from .exact import ExactChain, FieldChain
from .fixed import PRECISION, FixedChain, NotFixed, lines_of

__all__ = ["field_chain", "check_precisions", "ARITHMETICS", "MAX_PRECISION"]

#: the values of `Simulation`'s ``arithmetic``
ARITHMETICS = ("float", "exact", "certified")
#: the largest certified precision, in bits (64 limbs a coefficient). The error bounds are kept in units
#: of the state's last place (`fixed_kernels`), so no precision makes them underflow
MAX_PRECISION = 4096


def check_precisions(arithmetic: str, precision, late_precision) -> tuple[int | None, int | None]:
    """``(precision, late_precision)`` checked for a run in ``arithmetic``, or a `FieldError` naming the
    one that is wrong: certified arithmetic's only, whole bits in [64, `MAX_PRECISION`], the late one at
    most the other (None: `fixed.PRECISION`)."""
    for field, bits, what in (("precision", precision, "the precision of certified arithmetic"),
                              ("late_precision", late_precision, "certified arithmetic's precision behind the first wave")):
        if bits is not None and arithmetic != "certified":
            raise FieldError(field, f"is {what}; this run's is {arithmetic!r}")
    if precision is not None:
        precision = checks.integer("precision", precision, 64, MAX_PRECISION)
    if late_precision is not None:
        late_precision = checks.integer("late_precision", late_precision, 64, MAX_PRECISION)
        top = PRECISION if precision is None else precision
        if late_precision > top:
            raise FieldError("late_precision", f"must be at most precision ({top} bits), got {late_precision}")
    return precision, late_precision


def field_chain(geometry, velocities: np.ndarray, masses: np.ndarray, restitution: float, arithmetic: str,
                precision: int | None = None, late_precision: int | None = None) -> FieldChain:
    """The chain of ``arithmetic`` (``"exact"`` or ``"certified"``; ``precision`` and ``late_precision``:
    `FixedChain`'s); `NotFixed` saying why the certified one cannot run these, `fields.NotExact` why no
    exact one can."""
    if not np.all(masses == masses[0]):
        reason = "the masses are not all equal"
    elif restitution != 1.0:
        reason = f"collisions are not elastic (restitution {restitution})"
    else:
        try:
            return FixedChain(geometry, velocities, lines_of(geometry), arithmetic, precision, late_precision)
        except NotFixed as exc:
            reason = str(exc)
    if arithmetic == "certified":
        raise NotFixed(reason)
    return ExactChain(geometry, velocities, masses, restitution)
