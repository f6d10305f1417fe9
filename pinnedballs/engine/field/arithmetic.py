"""Which chain runs a simulation's arithmetic beyond floats.

``"exact"``: the fixed-point chain (`fixed.FixedChain`, exact policy) where it applies (equal masses,
elastic collisions, flat contacts whose normals have dyadic components in Q or one Q(sqrt d):
the triangular lattices, FCC, square and cubic packings, chains), else the rational chain
(`rational.RationalChain`: unequal masses, restitution, HCP's Q(sqrt 2, sqrt 3), other graphs).
``"certified"``: the fixed-point chain's certified policy, which only it has. A spec's ``"precision":
"auto"`` (`AUTO`) lets a certified run find its bits: it starts at `AUTO_START` and, when a
decision cannot be proved, starts again from its first step with `AUTO_GROWTH` times the bits
(`next_precisions`; `pinnedballs.run.execute` and `pinnedballs.run.ensemble` do the starting again).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import numpy as np
from gmpy2 import mpq

from ...util import checks
from ...util.errors import FieldError
from .chain import FieldChain
from .fixed import PRECISION, FixedChain, NotFixed, UncertifiedDecision, lines_of
from .numbers import NotExact
from .rational import RationalChain

__all__ = ["field_chain", "built_field_chain", "check_precisions", "MAX_PRECISION", "AUTO",
           "AUTO_GROWTH", "AUTO_START", "auto_precisions", "next_precisions", "auto_failure", "until_proved"]

#: the largest certified precision, in bits (64 limbs a coefficient). The error bounds are kept in units
#: of the state's last place (`fixed_kernels`), so no precision makes them underflow
MAX_PRECISION = 4096
#: a spec's ``precision`` that a certified run finds for itself (`auto_precisions`, `next_precisions`)
AUTO = "auto"
#: the bits an ``"auto"`` run starts at
AUTO_START = PRECISION
#: the factor by which an ``"auto"`` run's bits grow each time it starts again
AUTO_GROWTH = 1.5

T = TypeVar("T")


def auto_precisions(late_precision: int | None) -> tuple[int, int | None]:
    """``(precision, late_precision)`` of an ``"auto"`` run's first attempt: `AUTO_START` bits (the default,
    `fixed.PRECISION`), narrowing to ``late_precision`` behind the first wave where that is fewer."""
    return AUTO_START, late_precision if late_precision is not None and late_precision < AUTO_START else None


def next_precisions(failure: UncertifiedDecision, late_precision: int | None = None) -> tuple[int, int | None] | None:
    """``(precision, late_precision)`` to start an ``"auto"`` run again at after ``failure`` (the bits it
    ran at: `UncertifiedDecision.precision`, ``.late_precision``), or None where no more bits can help;
    ``late_precision``: the spec's (None: none).

    A decision that failed through the first wave (not ``narrowed``) needs more bits there: ``precision``
    grows by `AUTO_GROWTH` (whole limbs, at most `MAX_PRECISION`), the late bits stay (the spec's, where
    the attempt had none because they were not fewer). One that failed behind it needs more bits there:
    ``late_precision`` grows, and where it reaches ``precision``, the run keeps ``precision`` throughout
    (None)."""
    top, late = int(failure.precision), int(failure.late_precision)
    if top <= 0:
        return None  # not a certified chain's failure
    if failure.narrowed and late:
        late = _grown(late)
        return top, late if late < top else None
    if top >= MAX_PRECISION:
        return None
    top, late = _grown(top), late or late_precision
    return top, late if late and late < top else None


def auto_failure(failure: UncertifiedDecision, attempt: tuple[int, int | None]) -> str:
    """One line: where ``failure`` happened, at which bits, and the ``attempt`` an ``"auto"`` run makes next."""
    ran = f"{failure.late_precision} bits behind the first wave" if failure.narrowed else f"{failure.precision} bits"
    late = f" ({attempt[1]} behind the first wave)" if attempt[1] else ""
    return f"at {ran}, {failure.decision}; starting again at {attempt[0]} bits{late}"


def until_proved(attempt: Callable[[tuple[int, int | None] | None], T], late_precision: int | None,
                 told: Callable[[UncertifiedDecision, tuple[int, int | None]], None] | None = None) -> T:
    """``attempt(None)`` (an ``"auto"`` run's first attempt), then, after each `UncertifiedDecision`,
    ``attempt((precision, late_precision))`` at `next_precisions` (``late_precision``: the spec's), telling
    ``told`` first; the decision is raised where no more bits can help."""
    bits = None
    while True:
        try:
            return attempt(bits)
        except UncertifiedDecision as failure:
            bits = next_precisions(failure, late_precision)
            if bits is None:
                raise
            if told is not None:
                told(failure, bits)


def _grown(bits: int) -> int:
    """``AUTO_GROWTH`` times ``bits``, rounded up to whole 64-bit limbs, at most `MAX_PRECISION`."""
    return min(MAX_PRECISION, 64 * -(-int(bits * AUTO_GROWTH) // 64))


def check_precisions(arithmetic: str, precision, late_precision) -> tuple[int | None, int | None]:
    """``(precision, late_precision)`` checked for a run in ``arithmetic``, or a `FieldError` naming the
    one that is wrong: certified arithmetic's only, whole bits in [64, `MAX_PRECISION`], the late one at
    most the other (None: `fixed.PRECISION`)."""
    if precision == AUTO:
        raise FieldError("precision", "\"auto\" is a spec's (pinnedballs run, run_spec, run_ensemble: a run that "
                                      "starts again with more bits when a decision cannot be proved); a Simulation "
                                      "takes whole bits")
    for field, bits, what in (("precision", precision, "the precision of certified arithmetic"),
                              ("late_precision", late_precision,
                               "certified arithmetic's precision behind the first wave")):
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


def field_chain(geometry, velocities: np.ndarray, masses: np.ndarray, kick, arithmetic: str,
                precision: int | None = None, late_precision: int | None = None, picks=None) -> FieldChain:
    """The chain of ``arithmetic`` (``"exact"`` or ``"certified"``; ``kick``: the rule's exact linear form,
    `pinnedballs.rules.CollisionRule.exact_kick`; ``precision``, ``late_precision`` and ``picks``, where its picks
    are tried: `FixedChain`'s); `NotFixed` saying why the certified one cannot run these, `fields.NotExact` why no
    exact one can. The fixed-point chain runs the paper's exchange alone (equal masses, ``a_i = a_j = 1``)."""
    one = mpq(1)
    a, _ = kick(one, one)
    if not np.all(masses == masses[0]):
        reason = "the masses are not all equal"
    elif a != 1:
        reason = f"collisions are not elastic (restitution {float(2 * a - 1)})"
    else:
        try:
            return FixedChain(geometry, velocities, lines_of(geometry), arithmetic, precision, late_precision, picks)
        except NotFixed as exc:
            reason = str(exc)
    if arithmetic == "certified":
        raise NotFixed(reason)
    return RationalChain(geometry, velocities, masses, kick)


def built_field_chain(model, velocities: np.ndarray, arithmetic: str, precision: int | None = None,
                      late_precision: int | None = None, picks=None) -> FieldChain:
    """`field_chain` for a chain's `engine.chain.Model` (its geometry, masses and the rule's exact linear form), or
    a `FieldError` on ``arithmetic`` saying why none can run it."""
    try:
        return field_chain(model.geometry, velocities, model.masses, model.rule.exact_kick, arithmetic, precision,
                           late_precision, picks)
    except NotFixed as exc:
        raise FieldError("arithmetic", f"certified arithmetic needs equal masses, elastic collisions and flat contacts "
                                       f"whose normals have dyadic components in Q or one Q(sqrt d) (triangular "
                                       f"lattices, FCC, square and cubic packings, chains), and {exc}; "
                                       f"arithmetic=\"exact\" runs it") from None
    except NotExact as exc:
        raise FieldError("arithmetic", f"{arithmetic} arithmetic needs every contact normal in a known number field "
                                       f"(q*sqrt(d) components), and {type(model.geometry).__name__}'s are not: "
                                       f"{exc}; if they are within rounding of one, snap them there "
                                       f"(GraphGeometry(graph, snap=True), GraphGeometry.from_positions(positions, "
                                       f"snap=True))") from None
