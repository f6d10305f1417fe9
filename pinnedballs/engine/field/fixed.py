"""The chain in fixed point: exact decisions at about the cost of floats.

Where every contact normal's components are dyadic multiples of 1 or of one ``sqrt(d)`` (the
triangular lattices: Q(sqrt 3); FCC: Q(sqrt 2); square and cubic packings, chains: Q), the masses
are equal and collisions elastic, a velocity component ``a + b sqrt(d)`` has dyadic coefficients
``a, b`` through any number of collisions. `FixedChain` holds each as an integer over ``2^S`` (one
``S`` for the whole state) in ``P`` 64-bit limbs (two's complement, `limbs`), beside float shadows
that decide most picks (the float filter, `fixed_kernels`); a pick inside the filter's band
computes its closing speed in fixed point. A collision along line ``l`` (``t_i = -t_j = +-u_l``)
computes ``w~ = (V_i - V_j) . u_l`` exactly at scale ``S + e`` (``2^e u_l`` has integer
coefficients), rounds it to ``omega`` with its lowest ``2e`` bits cleared so that ``omega u_l`` is
exact at scale ``S``, and sets ``V_i -= omega u_l``, ``V_j += omega u_l``. ``rho = w~ - omega`` is the
only rounding anywhere.

Two policies:

* ``"exact"``: no rounding ever. A collision whose ``rho`` would not be 0 first widens the whole
  state (``P += 1`` limb at the bottom, ``S += 64``: exact) and is done again. Decisions are exact
  signs of exact values: the collisions, steps and velocities of `rational.RationalChain`.
* ``"certified"``: ``P`` fixed (``precision`` bits), ``rho`` rounded to nearest, and every decision
  proved equal to exact arithmetic's. Per ball and line ``l``, ``B[i, l] >= |dV_i . u_l|`` and
  ``Pp[i, l] >= |P_perp(l) dV_i|`` bound the error ``dV_i = V_i(exact) - V~_i``. A collision
  exchanges the parallel components exactly, so ``dV_i' = P_perp(dV_i) + P_par(dV_j) - rho t`` and
  the bounds follow (`fixed_kernels._carry_bounds`), computed in floats rounded upwards (every
  result of up to three rounded operations times ``UP = 1 + 2^-50``, more than their relative
  error of ``3 * 2^-53``), each capped by ``G = sqrt(2) sum |rho|``, which bounds the whole error
  vector (a collision is an isometry of it). A decision is certified when ``|w~| > B[i, l] + B[j, l]``,
  or the bounds are 0 (then ``w~`` is ``w``: its exact sign); otherwise the run stops with
  `UncertifiedDecision`. A ball that passes its momentum on along a line to a ball at rest hands
  on an ``omega`` already rounded, so ``rho = 0``: Newton's cradles stay exact (bounds 0). But an
  exact zero of ``w`` between balls whose velocities were rounded can never be certified (``|w~|``
  is then the error itself): such zeros occur early in large runs (the paper's half-plane, seed 1:
  at 500x250 with 256 bits, at 1000x500 with 512), hence the default `PRECISION`. They occur at
  the front of the first wave, between a ball exactly at rest and one moving exactly across their
  line, whose coefficients lengthen by about 2.2 bits per row the front has crossed. With a
  ``late_precision``, the certified policy narrows the state to it (`narrow`: the rounding added
  to the bounds) once the wave has passed (`settled`: no ball at rest, and at most a thousandth of
  the balls still exact, bounds 0, but too long for the narrower state), checked before each step
  that is a multiple of `LATE_EVERY_PER_CONTACT` picks per contact, so the step it narrows at
  depends on the state alone, not on how the run is split (a narrowing among the picks a freeze
  takes back, after the last collision, is taken back with them). The paper's 1000x500 half-plane needs
  768 bits through its front and 256 behind it (docs/performance.md).

Headroom: the conjugate map ``sqrt(d) -> -sqrt(d)`` sends normals to normals, so the conjugate
velocities keep the conjugate energy, which is the energy (floats are rational): every
coefficient is at most ``V = sqrt(2E/m)``, every closing speed's at most ``2V``. ``S`` leaves
`HEADROOM` bits above ``V`` and the geometry's ``e``.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import NamedTuple

import numpy as np
from gmpy2 import mpq

from ...util.errors import FieldError
from ..sequential.loops import FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT
from ..streams.philox import CounterPicks
from .chain import FieldChain, exchange
from .fixed_kernels import (
    DONE,
    DUE,
    FROZEN,
    UNCERTIFIED,
    UNCOUNTED,
    UP,
    WIDEN,
    Scratch,
    State,
    Tables,
    cap,
    count_live,
    fold,
    refresh_shadows,
    run_picks,
    unfolded,
)
from .fixed_state import STEP_ORDER_RULE, CertifiedState, error_bound, nearest_floats, power_text, scaled_up
from .grading import tables_for
from .limbs import from_limbs, to_limbs
from .numbers import Field, recognise

__all__ = ["FixedChain", "NotFixed", "UncertifiedDecision", "Lines", "lines_of", "bound_batch", "HEADROOM",
           "PRECISION"]

#: bits above the speed scale V (sign, 2V closing speeds, and slack)
HEADROOM = 6
#: the certified policy with a ``late_precision`` checks whether to narrow (`FixedChain.settled`) before
#: every step that is a multiple of this many picks per contact
LATE_EVERY_PER_CONTACT = 16
#: the certified policy's default bits per coefficient (12 limbs). The paper's half-plane (seed 1)
#: needs more than 256 at 500x250 and more than 512 at 1000x500 (768 suffice): early in a run,
#: exact zeros of the closing speed between balls whose velocities were rounded (benchmarks/bench_exact.py)
PRECISION = 768


class NotFixed(ValueError):
    """A geometry, rule or set of masses the fixed-point chain cannot run; the message says why."""


class UncertifiedDecision(FieldError):
    """A decision certified arithmetic cannot prove equal to exact arithmetic's: ``|w~|`` is within
    the error bound. The run stops consistent as of the pick before it. ``narrowed``: whether the
    state had been narrowed to its ``late_precision`` (in the process that raised it); ``precision``,
    ``late_precision``: the chain's bits through the first wave and behind it (0: none), as
    `FixedChain.bits`; ``decision``: the message without its advice."""

    decision = ""
    narrowed = False
    precision = 0
    late_precision = 0


class Lines(NamedTuple):
    """The contact lines of a geometry, in the form the kernels read (`fixed_kernels`)."""

    field: Field
    units: list  #: the exact unit vectors (`fields.recognise`)
    tables: Tables


def lines_of(geometry) -> Lines:
    """The lines of ``geometry``'s contacts, or `NotFixed` saying why it has none the chain can use
    (`NotExact` when its normals lie in no known number field: exact arithmetic cannot run it either)."""
    c = geometry.contacts
    if not c.flat:
        raise NotFixed("its contacts are not flat (t_j = -t_i)")
    field, units = recognise(c.units)
    if field.m > 2:
        raise NotFixed(f"its normals lie in {field}, not in Q or one Q(sqrt d)")
    keys, line_of_unit, sign_of_unit = {}, [], []
    for t in units:
        flat = [x for comp in t for x in comp]
        s = 1 if next(x for x in flat if x) > 0 else -1
        key = tuple(s * x for x in flat)
        line_of_unit.append(keys.setdefault(key, len(keys)))
        sign_of_unit.append(s)
    lines = [units[line_of_unit.index(n)] for n in range(len(keys))]
    lines = [tuple(tuple(sign_of_unit[line_of_unit.index(n)] * x for x in comp) for comp in u)
             for n, u in enumerate(lines)]
    d = field.basis[-1]
    L, dim, m = len(lines), geometry.dim, field.m
    mul, e = np.zeros((L, dim, m, m), dtype=np.int64), np.zeros(L, dtype=np.int64)
    for n, u in enumerate(lines):
        e[n] = max(int(x.denominator).bit_length() - 1 for comp in u for x in comp)
        for k, comp in enumerate(u):
            if any(x.denominator != 1 << (int(x.denominator).bit_length() - 1) for x in comp):
                raise NotFixed(f"a component of its unit vector {k} is not dyadic")
            c0, c1 = (int(x * (1 << int(e[n]))) for x in (comp + (0,))[:2])
            mul[n, k] = [[c0, d * c1], [c1, c0]] if m == 2 else [[c0]]
    if np.abs(mul).max() >= 1 << 31 or e.max() > 30:
        raise NotFixed("its unit vectors' coefficients are too fine for the fixed-point chain")
    if L > 127:
        raise NotFixed(f"its contacts lie on {L} lines, more than the 127 the chain's tables hold")
    code = 2 * np.array(line_of_unit, dtype=np.int64) + (np.array(sign_of_unit) < 0)
    ls = code[c.ends[:, 0].astype(np.int64)].astype(np.uint8)
    uf = np.array([[field.to_float(x) for x in u] for u in lines], dtype=np.float64)
    usum = np.abs(uf).sum(axis=1) * UP
    root = np.array([d, math.sqrt(d), np.nextafter(math.sqrt(d), np.inf)], dtype=np.float64)
    pairs = np.ascontiguousarray(c.pairs, dtype=np.uint32)
    wterms, wcount = np.zeros((L, m, dim * m, 3), dtype=np.int64), np.zeros((L, m), dtype=np.int64)
    kterms, kcount = np.zeros((L, dim, m, m, 2), dtype=np.int64), np.zeros((L, dim, m), dtype=np.int64)
    for n in range(L):  # the nonzero entries of mul, as the kernels' lists of terms
        for d, c_, s_ in zip(*np.nonzero(mul[n])):
            f = mul[n, d, c_, s_]
            wterms[n, c_, wcount[n, c_]] = d, s_, f
            wcount[n, c_] += 1
            kterms[n, d, c_, kcount[n, d, c_]] = s_, f
            kcount[n, d, c_] += 1
    tables = Tables(pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, _coefficients(field, lines, dim), root,
                    int(e.max()), _largest_rounding(e, root, m), np.full(dim, -1, dtype=np.int64))
    return Lines(field, units, tables)


def _largest_rounding(e: np.ndarray, root: np.ndarray, m: int) -> float:
    """The largest ``|rho|`` a collision rounds off, in units of ``2^-S``, rounded up: `fixed_kernels._collide`'s
    ``r`` with ``|rho_0|, |rho_1|`` at their largest, ``2^(2e - 1)`` (0 on a line with ``e = 0``: no rounding)."""
    largest = 0.0
    for el in e.tolist():
        if el > 0:
            half = math.ldexp(1.0, 2 * el - 1)
            largest = max(largest, math.ldexp((half + (half * root[2] * UP if m == 2 else 0.0)) * UP, -el) * UP)
    return largest


def bound_batch(n_contacts: int, emax: int) -> int:
    """Steps a batch of the batched bound rule (`fixed_kernels._round_off`): the power of two at or above the
    contacts, within [2^10, 2^22], and small enough that a batch's exact sums of ``|rho|`` fit 63 bits."""
    K = 1 << max(10, min(22, (max(1, n_contacts) - 1).bit_length()))
    return min(K, 1 << max(0, 62 - 2 * int(emax)))


def _coefficients(field: Field, lines: list, dim: int) -> np.ndarray:
    """``(4, L, L)``: ``|u_l.u_m|``, ``|P_perp(l) u_m|``, ``||P_perp(m) P_perp(l)||``, ``|P_perp(m) u_l|``,
    rounded up (exactly 0 and 1 where they are: on the diagonal, for orthogonal lines)."""
    L = len(lines)
    out = np.zeros((4, L, L))
    for a in range(L):
        for b in range(L):
            dot = field.zero
            for x, y in zip(lines[a], lines[b]):
                dot = field.add(dot, field.mul(x, y))
            s = field.sign(field.sub(field.mul(dot, dot), field.of(1)))
            if s == 0:  # parallel (the same line)
                out[:, a, b] = [1.0, 0.0, 1.0 if dim > 1 else 0.0, 0.0]
                continue
            c = min(1.0, abs(field.to_float(dot)) * UP) if any(dot) else 0.0  # to_float: within an ulp
            p = min(1.0, math.sqrt(field.to_float(field.sub(field.of(1), field.mul(dot, dot))) * UP) * UP * UP)
            out[:, a, b] = [c, p, c if dim == 2 else 1.0, p]
    return out


def _elements(X: np.ndarray, S: int) -> list[list[tuple]]:
    """Limb arrays ``X (rows, dim, m, P)`` over ``2^S`` as rows of field elements (tuples of `mpq`)."""
    den = 1 << S
    return [[tuple(mpq(int(c), den) for c in comp) for comp in row] for row in from_limbs(X).tolist()]


class CPUPicks:
    """Where `FixedChain` tries its picks and keeps its state: the CPU's kernels (`fixed_kernels.run_picks`,
    `count_live`) on the chain's own arrays. A GPU's (`pinnedballs.engine.gpu.certified.DevicePicks`) keeps the
    state on the GPU between calls and stands in with the same arguments; the chain reads its state through
    `to_host`, `take_dirty` and `settled`."""

    run_picks = staticmethod(run_picks)
    count_live = staticmethod(count_live)
    #: whether it draws the counter stream's picks itself (`engine.streams.philox.CounterPicks`)
    draws = False

    @staticmethod
    def to_host(state: State, writes: bool) -> None:
        """The chain's arrays made the newest state (here they always are)."""

    @staticmethod
    def take_dirty(state: State) -> tuple[np.ndarray, np.ndarray]:
        """``(balls, X[balls])``: the balls changed since the last call, their flags cleared."""
        balls = np.flatnonzero(state.dirty)
        state.dirty[balls] = 0
        return balls, state.X[balls]

    @staticmethod
    def settled(state: State, late_P: int) -> bool:
        """`FixedChain.settled` of ``state``: no ball at rest, and at most a thousandth of the balls exact (bounds 0)
        yet with a limb below the ``late_P`` top ones that is not 0."""
        D, P = state.X.shape[1], state.X.shape[3]
        if np.any(state.rows[:, D] == 0.0):
            return False
        exact = ~(np.any(state.B, axis=1) | np.any(state.Pp, axis=1))
        long = np.any(state.X[exact, ..., :P - late_P] != 0, axis=(1, 2, 3))
        return int(np.count_nonzero(long)) <= state.X.shape[0] // 1000


class FixedChain(FieldChain):
    """The velocities of ``geometry``'s balls in fixed point, and their collisions (module docstring).

    velocities: ``(n_balls, dim)`` floats, taken exactly; lines: the geometry's (`lines_of`);
    policy: ``"exact"`` or ``"certified"``; precision: bits per coefficient, rounded up to a
    multiple of 64 and raised to what the velocities given need to be held exactly: the certified
    policy's (None: `PRECISION`), or the width the exact policy starts from (None: the least);
    late_precision: the certified policy's bits once the first wave has passed (`settled`, `narrow`;
    None: ``precision`` throughout).
    """

    def __init__(self, geometry, velocities: np.ndarray, lines: Lines, policy: str, precision: int | None = None,
                 late_precision: int | None = None, picks=None):
        super().__init__(geometry, lines.field, lines.units, np.ones(geometry.n_balls), exchange)
        #: the kernels' tables: the geometry's (``lines.tables``), or those graded for the state (`grading`)
        self.policy, self.tables, self._ungraded = policy, lines.tables, lines.tables
        self.certify = policy == "certified"
        v = np.array(velocities, dtype=np.float64)
        n, dim = v.shape
        speed = math.sqrt(float(np.sum(v * v))) * UP
        self.top = max(0, math.frexp(speed)[1]) + HEADROOM + int(self.tables.e.max())  # integer bits
        fraction = max((Fraction(x).denominator.bit_length() - 1 for x in v[v != 0].tolist()), default=0)
        wanted = PRECISION if precision is None and self.certify else (precision or 0)
        self.P = max(1, -(-wanted // 64), -(-(self.top + fraction) // 64))
        self.S = 64 * self.P - self.top
        #: the limbs the certified policy narrows to once the first wave has passed (`narrow`), or None
        self.late_P = None
        if self.certify and late_precision is not None:
            self.late_P = min(self.P, max(-(-late_precision // 64), -(-(self.top + 1) // 64)))
            self.late_P = None if self.late_P == self.P else self.late_P  # nothing to narrow
        #: the bits this chain runs at through the first wave and behind it (0: no narrowing), as built
        self.bits = (64 * self.P, 64 * self.late_P if self.late_P is not None else 0)
        self.narrowed = None  #: the step before which the state was narrowed, in this object's life
        #: picks between checks for `narrow` (steps that are multiples of it), and the last step checked
        self.every = LATE_EVERY_PER_CONTACT * geometry.n_contacts if self.late_P is not None else 0
        self._checked = -1
        self.shadow = v.copy()  # written by `sync`: the simulation's velocities
        L = self.tables.uf.shape[0]
        self.rows = np.zeros((n, dim + 2))
        self.rows[:, :dim] = v
        self.rows[:, dim] = np.abs(v).max(axis=1)
        self.dirty = np.zeros(n, dtype=np.uint8)
        self.B, self.Pp, self.acc = np.zeros((n, L)), np.zeros((n, L)), np.zeros(2)
        #: the bound rule's sums not yet folded and ``[K, the batch of G]`` (`fixed_kernels._round_off`): batched
        self.rho = np.zeros(2, dtype=np.uint64)
        self.bound = np.array([bound_batch(geometry.n_contacts, self.tables.emax), -1], dtype=np.int64)
        self.acc[1] = cap(0.0, self.tables.rmax * self.bound[0])
        self.X = np.zeros((n, dim, self.field.m, self.P), dtype=np.uint64)
        rows = np.flatnonzero(self.rows[:, dim])
        if len(rows):
            self.X[rows, :, 0] = to_limbs([[int(Fraction(x) * (1 << self.S)) for x in v[b]] for b in rows], self.P)
        self.live, self.failure, self._at = -1, None, None
        self._after = None  #: the step the last `run` ended after (None: not known), for messages
        #: the smallest closing speed counted as a collision, the largest nonzero one set aside, and the
        #: number of picks set aside with closing speed exactly 0 (balls not both at rest), so far: since the
        #: run began (a certified state keeps it, `set_certified_state`), else since this chain was built
        self.margin = np.array([np.inf, -np.inf, 0.0])
        #: whether ``margin`` covers the run from its start: False once resumed from a certified state that did
        #: not keep it (a file written before), whose margin is then unknown
        self.margin_kept = True
        self.widenings = 0
        #: picks the float filter could not decide, decided in fixed point, in this object's life (a
        #: measure of the work, counting picks a frozen chunk tried after its last collision too)
        self.inside = 0
        chunk = max(FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT * geometry.n_contacts)
        self.chunk, self.block = chunk, 4 * chunk
        self.picks = CPUPicks() if picks is None else picks  #: where the picks are tried (a GPU's `DevicePicks`)
        self._scratch()
        self.tables = tables_for(self._ungraded, self.X)

    def _scratch(self) -> None:
        """Scratch and the scales of floats read from each limb, for the current ``P`` and ``S``."""
        self.T = np.array([math.ldexp(1.0, 64 * (h + 1) - self.S) for h in range(self.P)])
        m = self.field.m
        self.scratch = Scratch(np.zeros((m, self.P), dtype=np.uint64), np.zeros((2, self.P), dtype=np.uint64),
                               np.zeros((3, 4 * self.P + 2), dtype=np.uint64))
        self.info = np.zeros(4)

    def _state(self) -> tuple:
        return State(self.X, self.rows, self.dirty, self.B, self.Pp, self.acc, self.T, self.rho, self.bound)

    # ------------------------------------------------------------ exact policy: widening
    def widen(self) -> None:
        """One more limb at the bottom: ``P += 1``, ``S += 64``; every value unchanged."""
        self._host(writes=True)
        X = np.zeros(self.X.shape[:-1] + (self.P + 1,), dtype=np.uint64)
        X[..., 1:] = self.X
        self.X, self.P, self.S = X, self.P + 1, self.S + 64
        self.widenings += 1
        self._scratch()

    # ------------------------------------------------------------ certified policy: narrowing
    def settled(self) -> bool:
        """Whether the first wave has passed, as `narrow` asks: no ball is exactly at rest, and at most
        a thousandth of the balls are exact (bounds 0) yet too long for ``late_P`` limbs."""
        return self.picks.settled(self._state(), self.late_P)

    def _host(self, writes: bool = False) -> None:
        """The state in this object's arrays (where a GPU holds it, copied back); ``writes``: about to change it."""
        self.picks.to_host(self._state(), writes)

    def narrow(self, step: int | None = None) -> None:
        """Round the state to ``late_P`` limbs (``S`` down by 64 per limb dropped), to nearest, ties
        up, and widen each ball's bounds by its rounding: at most half a unit of the new last place
        per coefficient, ``(1 + sqrt d) / 2^(S + 1)`` per component, ``sqrt(dim)`` times that per
        ball (balls whose dropped limbs are 0, at rest among them, keep theirs); ``G`` grows by the
        whole vector's, ``sqrt(balls rounded)`` times a ball's. ``step``: the first pick at the new
        width, for messages."""
        self._host(writes=True)
        k = self.P - self.late_P
        X = self.X
        high = np.ascontiguousarray(X[..., k:])
        carry = X[..., k - 1] >> np.uint64(63)  # the dropped part's top bit: round half up
        for h in range(self.late_P):
            high[..., h] += carry
            carry = (carry & (high[..., h] == 0)).astype(np.uint64)
        rounded = np.any(X[..., :k] != 0, axis=(1, 2, 3))
        S = self.S - 64 * k
        dim, m = X.shape[1], X.shape[2]
        root = float(self.tables.root[2]) if m == 2 else 0.0
        per = math.sqrt(dim) * UP * (1.0 + root) * UP * 0.5 * UP  # units of 2^-S, the new S
        self.B, self.Pp = scaled_up(self.B, -64 * k), scaled_up(self.Pp, -64 * k)
        self.B[rounded] = (self.B[rounded] + per) * UP
        self.Pp[rounded] = (self.Pp[rounded] + per) * UP
        self._fold_pending()
        whole = float(scaled_up(self.acc[:1], -64 * k)[0])
        self.acc[0] = (whole + math.sqrt(int(rounded.sum())) * UP * per * UP) * UP
        self._set_cap()
        self.X, self.P, self.S = high, self.late_P, S
        self._scratch()
        self._reshadow()
        self.narrowed = step

    def _before_narrowing(self) -> tuple:
        """What `narrow` changes, copied (for `_take_back`)."""
        self._host()
        return (self.X.copy(), self.S, self.P, self.B.copy(), self.Pp.copy(), self.acc.copy(), self.rho.copy(),
                self.bound.copy(), self.narrowed)

    def _take_back(self, checked: int, saved: tuple) -> None:
        """The state as before a narrowing (`_before_narrowing`) whose step a freeze took back with its picks: a
        run split otherwise, whose freeze scans fall elsewhere, never reaches that step either."""
        self._host(writes=True)
        self.X, self.S, self.P, self.B, self.Pp, acc, rho, bound, self.narrowed = saved
        self.acc[:], self.rho[:], self.bound[:] = acc, rho, bound
        self._checked = checked
        self._scratch()
        self._reshadow()

    # ------------------------------------------------------------ the live set and a run
    def prepare(self, until_frozen: bool) -> None:
        """Make ready for `run`: the live set known when the run stops at the freeze."""
        if until_frozen and self.live < 0:
            self.count_live()

    def count_live(self) -> int:
        """Decide every contact; keep and return the number of live ones."""
        live = self.picks.count_live(self.tables, self._state(), self.S, self.certify, self.scratch, self.info)
        if live < 0:
            raise self._uncertified(None, self._after)
        self.live = live
        return live

    def run(self, picks: np.ndarray, collisions_left: int, until_frozen: bool, first_step: int = 1
            ) -> tuple[int, int, np.ndarray]:
        """Try the contacts ``picks`` in turn, stopping right after the ``collisions_left``-th collision
        or, with ``until_frozen``, right after the one that leaves no live contact: ``(picks used,
        collisions, the index in picks of each collision)``. With ``until_frozen`` the live contacts
        are counted every ``chunk`` picks; a frozen chunk ends at its last collision. A decision
        certified arithmetic cannot make leaves ``failure`` (`UncertifiedDecision`, naming the step:
        ``first_step`` is that of ``picks[0]``) set, the picks before it used."""
        if not isinstance(picks, CounterPicks):  # (those a GPU draws itself stay as they are)
            picks = np.ascontiguousarray(picks, dtype=np.int64)
        if self._at is None or len(self._at) < len(picks):
            self._at = np.empty(len(picks), dtype=np.int64)
        at = self._at
        prog = np.array([0, -1, 0, self.live, self.chunk, self._checked, 0], dtype=np.int64)
        at_last = self.margin[1:].copy()  # margin[1:] at this run's last collision (`run_picks`)
        t, left = 0, min(collisions_left, len(picks) + 1)  # int64 in the kernel
        unnarrowed = None  # (pick, the last step checked before, the state) of a narrowing in this call
        while True:
            every = self.every if self.late_P is not None and self.P > self.late_P else 0
            status, t = self.picks.run_picks(self.tables, self._state(), self.S, self.certify, picks, t, left,
                                             until_frozen, self.chunk, at, prog, self.scratch, self.info, self.margin,
                                             at_last, first_step, every)
            if status == WIDEN:
                self.widen()
            elif status == DUE:
                checked, self._checked = self._checked, first_step + t
                prog[5] = self._checked
                if self.settled():
                    unnarrowed = (t, checked, self._before_narrowing())
                    self.narrow(first_step + t)
            else:
                break
        if status == FROZEN and unnarrowed is not None and t <= unnarrowed[0]:
            self._take_back(*unnarrowed[1:])  # the freeze ends the run before the step it narrowed at
        made, self.live = int(prog[0]), int(prog[3])
        self.inside += int(prog[6])
        self._after = first_step + t - 1
        if status == DONE and until_frozen and self.live < 0:  # stopped by collisions_left: is it frozen?
            self.live = self.picks.count_live(self.tables, self._state(), self.S, self.certify, self.scratch, self.info)
            status = UNCOUNTED if self.live < 0 else status
        if status == UNCERTIFIED:
            self.failure = self._uncertified(first_step + t, None)
        elif status == UNCOUNTED:
            self.failure = self._uncertified(None, first_step + t - 1)
        return t, made, at[:made].copy()

    # ------------------------------------------------------------ one contact (as RationalChain's)
    def closing(self, k: int) -> tuple:
        """The exact closing speed of contact ``k`` (a field element; for the certified policy, ``w~``)."""
        i, j = self.pairs[k]
        rows = self._elements(np.array([i, j]))
        return self.closing_of(rows[0], rows[1], k)

    def collide(self, k: int) -> bool:
        """Collide contact ``k`` if it is live; True if it was (a failure to certify raises)."""
        _, made, _ = self.run(np.array([k]), 1, False)
        self._after = None  # one contact, at no step of a run
        failure, self.failure = self.failure, None
        if failure is not None:
            raise failure
        return made == 1

    def _uncertified(self, step: int | None, after: int | None) -> UncertifiedDecision:
        """The error for an undecided pick at ``step``, or for a count of the live contacts ``after``
        a step (None: outside a run)."""
        x, E, bound, k = self.info[:4]
        i, j = self.pairs[int(k)]
        where = f"step {step:,}" if step is not None else "a count of the live contacts" + (
            f" after step {after:,}" if after is not None else "")
        now = f"now {64 * self.P} bits"
        narrowed = self.late_P is not None and self.P == self.late_P
        if narrowed:
            now += ", the late_precision it narrowed to once the first wave had passed"
        decision = (f"certified arithmetic cannot decide contact {int(k)} (balls {i}, {j}) at {where}: its closing "
                    f"speed {power_text(x, int(E))} is within the error bound {power_text(bound, -self.S)}")
        failure = UncertifiedDecision("arithmetic",
                                      f"{decision}; use arithmetic=\"exact\" or a larger precision ({now})")
        failure.decision, failure.narrowed, (failure.precision, failure.late_precision) = decision, narrowed, self.bits
        return failure

    # ------------------------------------------------------------ values
    @property
    def v(self) -> list[list[tuple]]:
        """The velocities as rows of field elements (`fields`), exactly ``X / 2^S``."""
        self._host()
        return _elements(self.X, self.S)

    def _elements(self, rows: np.ndarray) -> list[list[tuple]]:
        self._host()
        return _elements(self.X[rows], self.S)

    def sync(self) -> np.ndarray:
        """The velocities of the balls changed since the last call rounded into ``shadow`` (which it
        returns): in the exact policy as `rational.RationalChain` rounds them (`Field.to_float`), in the
        certified policy to the nearest float (`fixed_state.nearest_floats`)."""
        rows, X = self.picks.take_dirty(self._state())
        if len(rows):
            if self.certify:
                self.shadow[rows] = nearest_floats(from_limbs(X), self.S, self.field.basis[-1])
            else:
                F = self.field
                self.shadow[rows] = [[F.to_float(x) for x in row] for row in _elements(X, self.S)]
        return self.shadow

    def set_velocities(self, exact: list[list[tuple]]) -> None:
        """Replace the velocities by exact ones ``(n_balls, dim)`` of field elements with dyadic
        coefficients (a ValueError otherwise); the state widens as they need."""
        self._host(writes=True)
        fraction = 0
        for row in exact:
            for x in row:
                for c in x:
                    den = int(c.denominator)
                    if den & (den - 1):
                        raise ValueError(f"the coefficient {c} is not a dyadic rational (its denominator is "
                                         f"not a power of 2), so no run in exact arithmetic reached it")
                    fraction = max(fraction, den.bit_length() - 1)
        while self.S < fraction:
            self.widen()
        scale = 1 << self.S
        values = [[[int(c * scale) for c in x] for x in row] for row in exact]
        try:
            X = to_limbs(values, self.P)
        except OverflowError:
            raise ValueError("a velocity is larger than the energy of the velocities given allows") from None
        self.X = X
        self._reshadow()
        self.live, self._after = -1, None

    def _reshadow(self) -> None:
        """Tables (graded for ``X`` where it is: `grading`), shadows, rest flags and ``shadow`` for every ball."""
        self.tables = tables_for(self._ungraded, self.X)
        self.dirty[:] = 1
        refresh_shadows(self.X, self.T, self.tables.root, self.rows, self.B, self.S, self.tables.parity)
        self.sync()

    # ------------------------------------------------------------ certified policy: the bound
    @property
    def error_bound(self) -> tuple[float, float]:
        """``(G, largest)``: bounds on the whole error vector and on each ball's (`fixed_state.error_bound`)."""
        self._host()
        return error_bound(np.stack([self.B, self.Pp], axis=1), float(self.acc[0]), self.S, self._unfolded())

    def certified_state(self) -> CertifiedState:
        self._host()
        return CertifiedState(self.X.copy(), self.S, np.stack([self.B, self.Pp], axis=1), float(self.acc[0]), self.S,
                              *self.bits, self.margin.copy() if self.margin_kept else None, int(self.bound[0]),
                              int(self.bound[1]), tuple(int(x) for x in self.rho), self._unfolded())

    def _set_cap(self) -> None:
        """``G`` from ``acc[0]``: its `fixed_kernels.cap` for a batch of ``K`` steps."""
        self.acc[1] = cap(float(self.acc[0]), self.tables.rmax * int(self.bound[0]))

    def _unfolded(self) -> float:
        """The batched rule's sums not yet folded, as a float in units of ``2^-S`` rounded up (0: none)."""
        return float(unfolded(self.rho, self.tables.emax, self.tables.root[2])) if self.rho.any() else 0.0

    def _fold_pending(self) -> None:
        """The batched rule's sums not yet folded, folded into ``acc[0]`` (before ``S`` changes)."""
        fold(self.acc, self.rho, self.bound, self.bound[1], self.tables.emax, self.tables.rmax, self.tables.root[2])

    def set_certified_state(self, state: CertifiedState) -> None:
        """Take a `CertifiedState` of this geometry (checked by the caller); its bounds rescaled to units
        of ``2^-S`` (rounded up), its margin as it is (one that kept none leaves the margin unknown,
        `margin_kept`). A state of the step-order bound rule (``bound_batch`` 0) is refused: the chain keeps
        the batched rule alone."""
        if state.bound_batch == 0:
            raise FieldError("certified", f"a state {STEP_ORDER_RULE} does not resume; run it again from its start")
        self._host(writes=True)  # (the new arrays go to a GPU at its next run)
        self.X, self.S, self.P = state.limbs.copy(), int(state.scale), state.limbs.shape[-1]
        self.margin_kept = state.margin is not None
        self.margin = np.array([np.inf, -np.inf, 0.0]) if state.margin is None else \
            np.array(state.margin, dtype=np.float64)
        shift = self.S - int(state.bound_scale)
        self.B, self.Pp = scaled_up(state.bounds[:, 0], shift), scaled_up(state.bounds[:, 1], shift)
        self.acc[0] = float(scaled_up(np.array([state.rounding]), shift)[0])
        self.rho[:] = np.array(state.pending, dtype=np.uint64)
        self.bound[:] = state.bound_batch, state.bound_at
        self._set_cap()
        self._scratch()
        self._reshadow()
        self.live, self._after = -1, None
