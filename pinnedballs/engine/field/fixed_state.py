"""What a run in certified arithmetic resumes from (`CertifiedState`), and its velocities rounded
to the nearest floats (`nearest_floats`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...util.errors import FieldError

__all__ = ["CertifiedState", "nearest_floats", "error_bound", "scaled_up", "power_text", "precisions_problem",
           "bound_rule_problem", "margin_problem", "SMALLEST", "LARGEST", "ZEROS", "STEP_ORDER_RULE"]

#: why a certified state with ``bound_batch`` 0 does not resume: its bounds grew under the rule in step order,
#: which the chain no longer keeps (its kernel sums the batched rule's alone); it still loads
STEP_ORDER_RULE = "written under the step-order bound rule of pinnedballs < 1.0"

#: the entries of a certified state's ``margin`` (`CertifiedState`): the smallest closing speed counted as a
#: collision, the largest nonzero one set aside, the picks set aside whose closing speed is exactly 0
SMALLEST, LARGEST, ZEROS = 0, 1, 2

#: (as `fixed_kernels.UP` and `SQRT2_UP`: this module stays free of numba)
_UP = 1.0 + 2.0 ** -50
_SQRT2_UP = math.sqrt(2.0) * _UP


def scaled_up(x: np.ndarray, shift: int) -> np.ndarray:
    """``x 2^shift`` for floats ``x >= 0``, rounded up: exact unless it leaves the normal range; a
    result that underflows is raised to the next float (so a bound stays a bound, never 0), one that
    overflows is inf."""
    x = np.asarray(x, dtype=np.float64)
    with np.errstate(over="ignore"):  # inf: said by the caller's check
        y = np.ldexp(x, int(shift))
    tiny = (x > 0) & (y < 2.0 ** -1021)
    y[tiny] = np.nextafter(y[tiny], np.inf)
    return y


def power_text(x: float, exponent: int) -> str:
    """``x 2^exponent`` in words: a float where one holds it, else ``m * 2^e`` (for messages)."""
    if x == 0.0:
        return "0"
    y = math.ldexp(x, exponent)
    if 2.0 ** -1000 < abs(y) < 2.0 ** 1000:
        return f"{y:.6g}"
    m, e = math.frexp(x)  # |m| in [0.5, 1)
    return f"{2 * m:.6g} * 2^{e - 1 + exponent}"


def error_bound(bounds: np.ndarray, rounding: float, bound_scale: int = 0,
                unfolded: float = 0.0) -> tuple[float, float]:
    """``(G, largest)`` from a certified state's ``bounds (n_balls, 2, L)`` and ``rounding`` (the sum
    of every ``|rho|``), both in units of ``2^-bound_scale``: ``G = sqrt(2) * rounding`` bounds the
    whole error vector (rounded up as the chain computes it; ``unfolded``: the batched rule's sums
    not yet in ``rounding``, added), ``largest`` every ball's error ``|V_i(exact) - V~_i|`` (the least over lines of
    ``hypot(B, Pp)``, rounded up, and at most ``G``). Absolute floats, rounded up: a bound below the
    smallest float is 5e-324, not 0."""
    G = (rounding + unfolded) * _UP * _SQRT2_UP * _UP
    largest = 0.0
    if bounds.size:
        largest = float(min(G, (np.min(np.hypot(bounds[:, 0], bounds[:, 1]), axis=1) * _UP).max()))
    G, largest = scaled_up(np.array([G, largest]), -int(bound_scale)).tolist()
    return G, largest


@dataclass(frozen=True, eq=False)
class CertifiedState:
    """The state of a run in certified arithmetic (`pinnedballs.engine.field.fixed`), bit for bit.

    limbs: ``(n_balls, dim, m, P) uint64``, each velocity component's ``m`` coefficients on the
    field's basis as integers over ``2^scale`` in ``P`` little-endian 64-bit limbs, two's complement;
    scale: ``S``; bounds: ``(n_balls, 2, L) float64``, each ball's error bounds along (``[:, 0]``,
    ``B``) and across (``[:, 1]``, ``Pp``) each of the geometry's ``L`` contact lines; rounding: the
    sum of every ``|rho|`` so far, rounded up (``G = sqrt(2)`` times it); bound_scale: bounds and
    rounding are in units of ``2^-bound_scale`` (the chain writes ``S``: no underflow at any
    precision; 0, absolute, in files written before it was kept); precision, late_precision: the
    bits the chain ran at through the first wave and behind it (``64 P`` limbs, as built; 0: not
    kept, in files written before; ``late_precision`` 0 also: none), which a spec's ``"precision":
    "auto"`` resumes at (`pinnedballs.results.load.Results.simulation`); margin: the closing margin of
    the chain's decisions since the run began (`FixedChain.margin`), ``(3,) float64``: the smallest
    closing speed counted as a collision (inf: none yet), the largest nonzero one set aside (-inf: none),
    the picks set aside whose closing speed is exactly 0 (`SMALLEST`, `LARGEST`, `ZEROS`); None: not kept
    (a file written before it was, or a run resumed from one: unknown).

    The bound rule (`pinnedballs.engine.field.fixed_kernels._round_off`): bound_batch ``K``, the steps a batch
    of the batched rule, whose ``G`` does not depend on the order of a batch's collisions (a GPU's), or 0:
    the rule in step order of files written by pinnedballs before 1.0 (such a state loads, but does not
    resume: `STEP_ORDER_RULE`);
    bound_at: the batch of the last collision (-1: none yet); pending: the exact sums of ``|rho_0|`` and
    ``|rho_1|`` of that batch, not yet in ``rounding`` (units of ``2^-(bound_scale + e_max)``); unfolded:
    those sums as a float in units of ``2^-bound_scale``, rounded up (for `error_bound`).
    """

    limbs: np.ndarray
    scale: int
    bounds: np.ndarray
    rounding: float
    bound_scale: int = 0
    precision: int = 0
    late_precision: int = 0
    margin: np.ndarray | None = None
    bound_batch: int = 0
    bound_at: int = -1
    pending: tuple = (0, 0)
    unfolded: float = 0.0

    def copy(self) -> CertifiedState:
        return CertifiedState(self.limbs.copy(), self.scale, self.bounds.copy(), self.rounding, self.bound_scale,
                              self.precision, self.late_precision, None if self.margin is None else self.margin.copy(),
                              self.bound_batch, self.bound_at, tuple(self.pending), self.unfolded)

    def scalars(self) -> tuple:
        return (self.scale, self.rounding, self.bound_scale, self.precision, self.late_precision, self.bound_batch,
                self.bound_at, tuple(int(x) for x in self.pending), self.unfolded)

    def identical(self, other: CertifiedState) -> bool:
        """True when ``other`` is this state bit for bit: limbs, bounds, scalars, and the margins where both
        keep one (a state that kept none, None, says nothing of it)."""
        return self.scalars() == other.scalars() and all(
            a.dtype == b.dtype and np.array_equal(a, b) for a, b in ((self.limbs, other.limbs),
                                                                      (self.bounds, other.bounds))) \
            and (self.margin is None or other.margin is None or np.array_equal(self.margin, other.margin))

    def error_bound(self) -> tuple[float, float]:
        """``(G, largest)``: see `error_bound`."""
        return error_bound(self.bounds, self.rounding, self.bound_scale, self.unfolded)

    def check(self, shape: tuple[int, int, int], lines: int) -> None:
        """A `FieldError` on ``certified`` unless this state fits ``shape = (n_balls, dim, m)`` and
        ``lines``: limbs of that shape and ``scale < 64 P``, bounds finite and >= 0, rounding too."""
        limbs, bounds = np.asarray(self.limbs), np.asarray(self.bounds)
        if limbs.dtype != np.uint64 or limbs.ndim != 4 or limbs.shape[:3] != shape or limbs.shape[3] < 1:
            raise FieldError("certified", f"limbs must be uint64 of shape (n_balls, dim, m, P) = {shape + ('P',)}, "
                                          f"got {limbs.dtype} {limbs.shape}")
        if not (isinstance(self.scale, (int, np.integer)) and 0 <= self.scale < 64 * limbs.shape[3]):
            raise FieldError("certified", f"scale must be an integer in [0, {64 * limbs.shape[3]}), got {self.scale!r}")
        if bounds.dtype != np.float64 or bounds.shape != (shape[0], 2, lines):
            raise FieldError("certified", f"bounds must be float64 of shape ({shape[0]}, 2, {lines}), "
                                          f"got {bounds.dtype} {bounds.shape}")
        if not (np.isfinite(bounds).all() and (bounds >= 0).all()):
            raise FieldError("certified", "bounds must be finite and >= 0")
        if not (isinstance(self.rounding, float) and math.isfinite(self.rounding) and self.rounding >= 0):
            raise FieldError("certified", f"rounding must be a finite float >= 0, got {self.rounding!r}")
        if not (isinstance(self.bound_scale, (int, np.integer)) and 0 <= self.bound_scale < 64 * limbs.shape[3]):
            raise FieldError("certified", f"bound_scale must be an integer in [0, {64 * limbs.shape[3]}), "
                                          f"got {self.bound_scale!r}")
        if not np.isfinite(scaled_up(bounds, int(self.scale) - int(self.bound_scale))).all():
            raise FieldError("certified", "bounds must be finite in units of 2^-scale")
        problem = precisions_problem(self.precision, self.late_precision, limbs.shape[3]) or \
            bound_rule_problem(self.bound_batch, self.bound_at, self.pending, self.unfolded)
        if problem:
            raise FieldError("certified", problem)
        problem = "" if self.margin is None else margin_problem(self.margin)
        if problem:
            raise FieldError("certified", problem)


def margin_problem(margin) -> str:
    """What is wrong with ``margin`` as a `CertifiedState`'s ('' if nothing): ``(3,) float64``, the smallest
    collision's closing speed >= 0 (inf: none yet; 0 only where a float could not hold it), the largest set
    aside's below inf (-inf: none), the exact zeros set aside a whole number >= 0."""
    m = np.asarray(margin)
    if m.shape != (3,) or m.dtype != np.float64:
        return f"margin must be 3 float64 numbers, got {m.dtype} {m.shape}"
    smallest, largest, zeros = m.tolist()
    if not smallest >= 0:
        return f"margin: the smallest collision's closing speed must be >= 0 (inf: none yet), got {smallest}"
    if not largest < math.inf:
        return f"margin: the largest closing speed set aside must be a number below inf (-inf: none), got {largest}"
    if not (math.isfinite(zeros) and zeros >= 0 and zeros == math.floor(zeros)):
        return f"margin: the picks set aside at closing speed 0 must be a whole number >= 0, got {zeros}"
    return ""


def bound_rule_problem(bound_batch, bound_at, pending, unfolded) -> str:
    """What is wrong with a `CertifiedState`'s bound rule ('' if nothing): ``bound_batch`` 0 or a power of two,
    ``bound_at`` a whole number >= -1, ``pending`` two whole numbers in [0, 2^63), ``unfolded`` a finite float >= 0
    (0 only when nothing is pending); under the rule in step order (``bound_batch`` 0) nothing pending."""
    def whole(x):
        return isinstance(x, (int, np.integer)) and not isinstance(x, bool)

    if not (whole(bound_batch) and bound_batch >= 0 and bound_batch & (bound_batch - 1) == 0):
        return f"bound_batch must be 0 or a power of two, got {bound_batch!r}"
    if not (whole(bound_at) and bound_at >= -1):
        return f"bound_at must be a whole number >= -1, got {bound_at!r}"
    if not (len(pending) == 2 and all(whole(x) and 0 <= x < 1 << 63 for x in pending)):
        return f"pending must be two whole numbers in [0, 2^63), got {pending!r}"
    if not (isinstance(unfolded, float) and math.isfinite(unfolded) and unfolded >= 0
            and (unfolded > 0) == any(pending)):
        return f"unfolded must be a finite float >= 0, above 0 exactly when a sum is pending, got {unfolded!r}"
    if bound_batch == 0 and (any(pending) or bound_at != -1):
        return "a state under the bound rule in step order (bound_batch 0) has no pending sums or bound_at"
    return ""


def precisions_problem(precision, late_precision, limbs: int) -> str:
    """What is wrong with a `CertifiedState`'s ``precision`` and ``late_precision`` for a state of
    ``limbs`` limbs ('' if nothing): 0 (not kept), or whole multiples of 64 bits with the state's ``64
    limbs`` bits being one of them, the late one below the other (0: none)."""
    whole = all(isinstance(b, (int, np.integer)) and not isinstance(b, bool) and b >= 0 and b % 64 == 0
                for b in (precision, late_precision))
    if not whole:
        return f"precision and late_precision must be whole multiples of 64 bits, got {precision!r}, {late_precision!r}"
    if precision == 0:
        return "" if late_precision == 0 else \
            f"late_precision must be 0 where precision is (not kept), got {late_precision}"
    if late_precision >= precision or 64 * limbs not in (precision, late_precision):
        return (f"a state of {64 * limbs} bits cannot be of a chain at precision {precision} and late_precision "
                f"{late_precision} (0: none)")
    return ""


def nearest_floats(ints: np.ndarray, scale: int, d: int) -> np.ndarray:
    """``(rows, dim)`` floats: each ``(a + b sqrt(d)) / 2^scale`` rounded to the nearest float, for the
    integer coefficients ``ints (rows, dim, m)`` (``m`` 1 or 2). A rational is Python's correctly
    rounded division of integers; an irrational lies between two integers over ``2^(scale + k)``
    (``math.isqrt``), and ``k`` doubles until both round to the same float (the number is never
    halfway between floats, so this ends)."""
    out = np.empty(ints.shape[:2])
    for n, row in enumerate(ints.tolist()):
        for c, coefficients in enumerate(row):
            a, b = (coefficients + [0])[:2]
            out[n, c] = a / (1 << scale) if b == 0 else _nearest(a, b, scale, d)
    return out


def _nearest(a: int, b: int, scale: int, d: int) -> float:
    k = 128
    while True:
        root = math.isqrt(d * b * b << (2 * k))  # root <= |b| sqrt(d) 2^k < root + 1
        low = (a << k) + (root if b > 0 else -root - 1)
        one = 1 << (scale + k)
        if low / one == (low + 1) / one:
            return low / one
        k *= 2
