"""The compiled loop of the fixed-point chain (`pinnedballs.engine.field.fixed`): picks tried in turn,
every decision exact (policy "exact") or proved equal to exact arithmetic's (policy "certified").

Plain data (shapes; ``L`` lines, ``m`` coefficients per component, ``P`` limbs): `Tables` (the
geometry's contact lines), `State` (the velocities, their shadows and bounds) and `Scratch`.
``info (4,)``: ``(x, E, bound, contact)`` of an uncertified decision, its closing speed ``w~ = x 2^E``
and the bound in units of ``2^-S``; ``prog (7,) int64``:
``(collisions, index of the last, collided since the last scan, live contacts or -1, picks to the
next scan, a step at which not to stop for a due check, picks decided in fixed point)``, kept
across calls.

The float filter: a shadow is within ``9 * 2^-53`` of its size of the number it stands for (two
limbs read, rounded, and one product by ``sqrt d``), so the float closing speed computed from the
shadows is within ``FILTER * 2^-53 * usum (ms_i + ms_j) + TINY`` (``TINY`` covers underflow) of the
exact one, with room to spare; only picks inside that band (widened by the bounds ``bmax`` in the
certified policy) look further.

The certified policy keeps its bounds in units of ``2^-S`` (the state's last place), so they neither
underflow nor lose digits at any precision; a decision compares ``W``, read with its own exponent
(`_normal`), with the bound scaled to it (`_beyond`). Only the band of the float filter (``bmax``, in
the rows) is absolute, where an underflow is covered by ``TINY``.

Every kernel is compiled without reference counting (see `limbs`), so the loop's many small
inlined functions cost no atomic operations; the loop fetches the tables of picks a few steps
ahead (`prefetch`), which hides the memory latency of systems larger than the cache.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..jit.cache import njit_cached
from ..jit.intrinsics import prefetch
from .limbs import diff_combination, exchange, field_sign, low_bits, scaled_float, shift_round, sign

__all__ = ["Tables", "State", "Scratch", "run_picks", "cap", "fold", "unfolded", "count_live", "refresh_shadows",
           "FILTER", "TINY", "UP", "SQRT2_UP", "DONE", "FROZEN", "WIDEN", "UNCERTIFIED", "UNCOUNTED", "DUE"]

#: the float filter's band, in units of 2^-53 times the sizes (its error bound is about 20)
FILTER = 64.0
#: an absolute floor under the band: far above what underflow can lose (2^-1074 per operation)
TINY = 2.0 ** -1000
#: a float upper bound times UP stays one after up to three more rounded operations (2^-50 > 4 * 2^-53)
UP = 1.0 + 2.0 ** -50
#: sqrt(2) rounded up: G = sqrt(2) sum |rho| is computed as ``sum * SQRT2_UP * UP``
SQRT2_UP = math.sqrt(2.0) * UP
_U = 2.0 ** -53
_SMALLEST = 5e-324
#: 2^e for every e whose power is a normal float, at ``e + 1022``: `_ldexp`'s one product
_POW2 = np.ldexp(1.0, np.arange(-1022, 1024))

#: how `run_picks` ends: the picks ran out (or ``collisions_left`` was reached); the run froze;
#: a collision needs a wider state (exact policy); a pick, or a count of the live contacts, could
#: not be certified; a check is due (the certified policy's narrowing, `fixed.FixedChain.narrow`)
DONE, FROZEN, WIDEN, UNCERTIFIED, UNCOUNTED, DUE = 0, 1, 2, 3, 4, 5

#: how many picks ahead `run_picks` fetches a pick's contact, its balls' shadows, and (when the
#: float filter does not rule it out) their coefficients and bounds (measured: bench_exact.py)
AHEAD_CONTACT, AHEAD_ROWS, AHEAD_BALLS = 24, 12, 6
#: the rows of `run_picks`' ring of the float filter's decisions made ahead (more than ``AHEAD_BALLS``)
RING = 8

kernel = njit_cached(_nrt=False)
inlined = njit_cached(_nrt=False, inline="always")


class Tables(NamedTuple):
    """A geometry's contacts by line. Contact ``k`` lies on line ``l = ls[k] >> 1``, with ``t_i = u_l``
    or, when ``ls[k] & 1``, ``-u_l``. ``2^e[l] u_l`` has integer coefficients: ``(V_i - V_j) . u_l``
    (at scale ``S + e``) has coefficient ``c`` equal to ``sum f (X_i[d, s] - X_j[d, s])`` over the
    ``wcount[l, c]`` terms ``wterms[l, c] = (d, s, f)``; ``omega u_l``'s coefficient ``c`` of component
    ``d`` (at scale ``S``) is ``sum f Omega[s]`` over ``kterms[l, d, c] = (s, f)``."""

    pairs: np.ndarray  #: (E, 2) uint32
    ls: np.ndarray  #: (E,) uint8
    uf: np.ndarray  #: (L, dim) the lines' unit vectors as floats
    usum: np.ndarray  #: (L,) the sums of their components' magnitudes, rounded up
    e: np.ndarray  #: (L,) int64
    wterms: np.ndarray  #: (L, m, T, 3) int64
    wcount: np.ndarray  #: (L, m) int64
    kterms: np.ndarray  #: (L, dim, m, T, 2) int64
    kcount: np.ndarray  #: (L, dim, m) int64
    coef: np.ndarray  #: (4, L, L): |u_l.u_m|, |P_perp(l) u_m|, ||P_perp(m) P_perp(l)||, |P_perp(m) u_l|, rounded up
    root: np.ndarray  #: (3,): d, sqrt d, sqrt d rounded up
    emax: int  #: the largest ``e``
    rmax: float  #: the largest ``|rho|`` a collision can round off, in units of ``2^-S``, rounded up
    #: (dim,) int64: the one coefficient of each component that is not 0 throughout, -1 where both may not be
    #: (`grading`: the terms reading the other are dropped from the terms above)
    parity: np.ndarray


class State(NamedTuple):
    """The velocities, ``X / 2^S``, and what the loop keeps beside them."""

    X: np.ndarray  #: (n, dim, m, P) uint64: each component's coefficients (`limbs`)
    rows: np.ndarray  #: (n, dim + 2): shadows, size ms (0 exactly at rest), bmax (largest B, absolute)
    dirty: np.ndarray  #: (n,) uint8: changed since the last `sync`
    B: np.ndarray  #: (n, L): certified bounds along each line, in units of 2^-S
    Pp: np.ndarray  #: (n, L): certified bounds across each line, in units of 2^-S
    acc: np.ndarray  #: (2,): sum |rho| and G, rounded up, in units of 2^-S (batched: the sum folded so far)
    T: np.ndarray  #: (P,): T[h] = 2^(64 (h + 1) - S), the scale of a float read from limb h down
    #: (2,) uint64: the batched rule's sums of |rho_0|, |rho_1| not yet folded, in units of 2^-(S + emax)
    rho: np.ndarray
    bound: np.ndarray  #: (2,) int64: the batched rule's steps a batch ``K`` (> 0), the batch of G


class Scratch(NamedTuple):
    W: np.ndarray  #: (m, P): a closing speed, then omega
    tmp: np.ndarray  #: (2, P)
    big: np.ndarray  #: (3, 4P + 2): full squares for the rare exact signs


@inlined
def _ldexp(x, e):
    """``math.ldexp(x, e)``, bit for bit, without its call into the C library where ``2^e`` is a normal float: then
    one product by it, rounded once as ldexp rounds (to nearest, into the subnormals too)."""
    if -1022 <= e <= 1023:
        return x * _POW2[e + 1022]
    return math.ldexp(x, e)


@inlined
def _closing(tables, X, i, j, line, W):
    """``W = (V_i - V_j) . u_l`` exactly, at scale ``S + e[l]``."""
    for c in range(W.shape[0]):
        diff_combination(W[c], X[i], X[j], tables.wterms[line, c], tables.wcount[line, c])


@inlined
def _normal(W, root):
    """``(x, err, E)``: the element ``W`` is within ``err 2^E`` of ``x 2^E`` (``|x| <= 1 + sqrt d``: no
    overflow at any width; ``E`` the larger of its coefficients' exponents)."""
    f0, e0 = scaled_float(W[0])
    if W.shape[0] == 1:
        return f0, 4.0 * _U * abs(f0) + TINY, e0
    f1, e1 = scaled_float(W[1])
    E = max(e0, e1)
    a, b = _ldexp(f0, int(e0 - E)), _ldexp(f1, int(e1 - E))
    return a + b * root[1], 9.0 * _U * (abs(a) + abs(b) * root[1]) + TINY, E


@inlined
def _absolute(x, E):
    """``x 2^E`` as a float, 0 only when ``x`` is (an underflow keeps the sign and the smallest size)."""
    y = _ldexp(x, int(E))
    return y if y != 0.0 or x == 0.0 else math.copysign(_SMALLEST, x)


@inlined
def _beyond(x, err, E, e, beta):
    """1 when ``x 2^E`` (within ``err 2^E``) certainly exceeds ``beta 2^e``, 0 when it certainly lies
    below ``-beta 2^e``, -1 when neither: the bound is scaled to ``2^E`` (rounded up, at least ``TINY``)."""
    bound = max(_ldexp(beta, int(e - E)), TINY)
    if x - err > bound:
        return 1
    if x + err < -bound:
        return 0
    return -1


@inlined
def _exact_sign(W, root, scratch):
    """The exact sign of the element ``W``."""
    if W.shape[0] == 1:
        return sign(W[0])
    return field_sign(W[0], W[1], root[1], np.int64(root[0]), scratch.tmp[0], scratch.tmp[1], scratch.big)


@inlined
def _filter(tables, rows, k):
    """The float filter on contact ``k``: ``(decision, line, s, x)``, decision 1 (live) or 0 (not) when
    certain whatever the error bounds ``bmax`` allow, 2 when not; ``s`` the sign of ``t_i`` on ``u_l``;
    ``x`` the closing speed in floats (NaN when both balls are at rest)."""
    i, j = tables.pairs[k, 0], tables.pairs[k, 1]
    code = tables.ls[k]
    line, s = np.int64(code >> 1), 1.0 - 2.0 * (code & 1)
    D = rows.shape[1] - 2
    if rows[i, D] == 0.0 and rows[j, D] == 0.0:  # both at rest
        return 0, line, s, np.nan
    w = 0.0
    for d in range(D):
        w += (rows[i, d] - rows[j, d]) * tables.uf[line, d]
    band = FILTER * _U * tables.usum[line] * (rows[i, D] + rows[j, D]) + TINY + (rows[i, D + 1] + rows[j, D + 1]) * UP
    x = s * w
    return (0 if x < -band else 1 if x > band else 2), line, s, x


@inlined
def _decide(k, tables, state, scale, certify, scratch, info):
    """``(decision, computed, x)``: decision 1 when contact ``k`` is live (its closing speed exactly
    positive), 0 when not, -1 when certified arithmetic cannot tell (``info``: ``w~`` and the bound);
    ``computed``: ``scratch.W`` holds ``(V_i - V_j) . u_l`` in fixed point; ``x``: the closing speed
    in floats (0 exactly when it is 0, NaN when both balls are at rest)."""
    decision, line, s, x = _filter(tables, state.rows, k)
    return _settle(k, decision, line, s, x, tables, state, scale, certify, scratch, info)


@inlined
def _settle(k, decision, line, s, x, tables, state, scale, certify, scratch, info):
    """`_decide` after the float filter's ``(decision, line, s, x)`` on contact ``k``."""
    if decision < 2:
        return decision, False, x
    i, j = tables.pairs[k, 0], tables.pairs[k, 1]
    beta = (state.B[i, line] + state.B[j, line]) * UP if certify else 0.0  # units of 2^-S
    W = scratch.W
    _closing(tables, state.X, i, j, line, W)
    f, err, E = _normal(W, tables.root)
    x = s * _absolute(f, E - scale - tables.e[line])
    if beta == 0.0:  # w~ is w: its exact sign
        return (1 if s * _exact_sign(W, tables.root, scratch) > 0 else 0), True, x
    decision = _beyond(s * f, err, E, tables.e[line], beta)
    if decision < 0:
        info[0], info[1], info[2], info[3] = s * f, E - scale - tables.e[line], beta, k
    return decision, True, x


@inlined
def _coefficient(X, b, d, c, T):
    """Coefficient ``c`` of ball ``b``'s component ``d`` as a float, scaled by ``T``, and whether it is not 0."""
    f, e = scaled_float(X[b, d, c])
    return (f * T[(e >> 6) - 1] if f != 0.0 else 0.0), f != 0.0


@inlined
def _shadow(X, b, T, root, rows, parity):
    """Ball ``b``'s shadows and size from its coefficients (only the one ``parity[d]`` of a component where it is
    not -1: the other is 0, `grading`; the same floats as from both, ``a + 0 sqrt d`` being ``a``)."""
    D, m = X.shape[1], X.shape[2]
    size, moving = 0.0, False
    for d in range(D):
        if m == 1 or parity[d] == 0:
            a, live = _coefficient(X, b, d, 0, T)
            rows[b, d] = a
            size, moving = max(size, abs(a)), moving or live
        elif parity[d] == 1:
            c, live = _coefficient(X, b, d, 1, T)
            rows[b, d] = c * root[1]
            size, moving = max(size, abs(c) * root[1]), moving or live
        else:
            a, live0 = _coefficient(X, b, d, 0, T)
            c, live1 = _coefficient(X, b, d, 1, T)
            rows[b, d] = a + c * root[1]
            size, moving = max(size, abs(a) + abs(c) * root[1]), moving or live0 or live1
    rows[b, D] = max(size, _SMALLEST) if moving else 0.0


@inlined
def _band(bmax, scale):
    """A largest bound in units of ``2^-scale`` as the float filter reads it: absolute, rounded up
    (an underflow loses less than the filter's ``TINY``)."""
    return _ldexp(bmax, -int(scale)) * UP


@kernel
def refresh_shadows(X, T, root, rows, B, scale, parity):
    """Every ball's row (shadows, size, largest bound) from ``X`` and ``B`` (units of ``2^-scale``); ``parity``:
    `Tables.parity`."""
    D = X.shape[1]
    for b in range(X.shape[0]):
        _shadow(X, b, T, root, rows, parity)
        bmax = 0.0
        for m in range(B.shape[1]):
            bmax = max(bmax, B[b, m])
        rows[b, D + 1] = _band(bmax, scale)


@inlined
def _carry_bounds(state, coef, i, j, line, r, scale):
    """The error bounds of balls ``i, j`` after their collision along ``line`` with rounding ``|rho| <= r``
    (units of ``2^-scale``): the parallel components are exchanged, the perpendicular ones kept; each
    capped by ``G``."""
    B, Pp, rows, G = state.B, state.Pp, state.rows, state.acc[1]
    uu, nu, nn, un = coef[0], coef[1], coef[2], coef[3]
    pi, pj = Pp[i, line], Pp[j, line]
    ai, aj = (B[j, line] + r) * UP, (B[i, line] + r) * UP
    D = rows.shape[1] - 2
    bi, bj = 0.0, 0.0
    for m in range(B.shape[1]):  # x y + z w: three roundings, less than UP's 2^-50 with room
        B[i, m] = min(G, (pi * nu[line, m] + ai * uu[line, m]) * UP)
        Pp[i, m] = min(G, (pi * nn[line, m] + ai * un[line, m]) * UP)
        B[j, m] = min(G, (pj * nu[line, m] + aj * uu[line, m]) * UP)
        Pp[j, m] = min(G, (pj * nn[line, m] + aj * un[line, m]) * UP)
        bi, bj = max(bi, B[i, m]), max(bj, B[j, m])
    rows[i, D + 1], rows[j, D + 1] = _band(bi, scale), _band(bj, scale)


@inlined
def cap(base, rmaxK):
    """The batched rule's ``G`` through a batch whose earlier batches rounded off ``base`` in all (units of
    ``2^-S``): ``sqrt(2) (base + K rmax)``, rounded up (the batch's own collisions add at most ``K rmax``)."""
    return (base + rmaxK) * SQRT2_UP * UP


@inlined
def unfolded(rho, emax, root_up):
    """The batched rule's exact sums ``rho`` as a float in units of ``2^-S``, rounded up."""
    part = float(rho[0]) * UP + float(rho[1]) * UP * root_up * UP  # float(x) * UP >= x
    return math.ldexp(part * UP, -int(emax))


@inlined
def fold(acc, rho, bound, batch, emax, rmax, root_up):
    """The batched rule's fold: the exact sums ``rho`` added to ``acc[0]`` (rounded up) and cleared, ``G =
    acc[1]`` the cap of a batch after them (`cap`), ``bound[1] = batch``."""
    if rho[0] != 0 or rho[1] != 0:
        acc[0] = (acc[0] + unfolded(rho, emax, root_up)) * UP
        rho[0], rho[1] = 0, 0
    acc[1] = cap(acc[0], rmax * bound[0])
    bound[1] = batch


@inlined
def _round_off(state, tables, step, line, rho0, rho1):
    """What a collision at ``step`` along ``line`` rounded off (``rho0 + rho1 sqrt d`` in units of
    ``2^-(S + e)``) added to the sum behind ``G``, batched: the first collision of a batch of ``K`` steps folds
    the sums of the batches before (`fold`); ``G`` is then fixed for the batch, and the collision's ``|rho|``
    is added to exact integer sums, so that neither depends on the order the batch's collisions are made in
    (a GPU's, by reservations). ``K`` > 0 always (the chain refuses a state without a batch: `fixed.FixedChain`);
    the guard first, as the loop had it before (it drops the division's check for zero and its raise; the forms
    without it ran slower: `benchmarks/results/measurements.md`)."""
    K = state.bound[0]
    if K <= 0:
        return
    batch = step // K
    if batch != state.bound[1]:
        fold(state.acc, state.rho, state.bound, batch, tables.emax, tables.rmax, tables.root[2])
    shift = np.uint64(tables.emax - tables.e[line])
    state.rho[0] += np.uint64(abs(rho0)) << shift
    state.rho[1] += np.uint64(abs(rho1)) << shift


@inlined
def _collide(k, tables, state, scale, certify, scratch, step):
    """Collide contact ``k`` at ``step``, whose ``W`` is computed and closing speed positive. False (nothing
    changed) when the exact policy needs a wider state first."""
    X, W, root = state.X, scratch.W, tables.root
    i, j, line = tables.pairs[k, 0], tables.pairs[k, 1], np.int64(tables.ls[k] >> 1)
    m, bits = W.shape[0], 2 * tables.e[line]
    r, rho0, rho1 = 0.0, np.int64(0), np.int64(0)
    if bits > 0:  # omega: W with its lowest 2 e bits cleared, so that omega u_l is exact at scale S
        if not certify:
            for c in range(m):
                if low_bits(W[c], bits) != 0:
                    return False
        rho0 = shift_round(W[0], W[0], bits)
        rho1 = shift_round(W[1], W[1], bits) if m == 2 else np.int64(0)
        if rho0 != 0 or rho1 != 0:
            r = _ldexp((abs(rho0) + abs(rho1) * root[2] * UP) * UP, int(-tables.e[line]))  # units of 2^-S
    for d in range(X.shape[1]):  # V_i -= omega u_l, V_j += omega u_l
        for c in range(m):
            exchange(X[i, d, c], X[j, d, c], W, tables.kterms[line, d, c], tables.kcount[line, d, c])
    _shadow(X, i, state.T, root, state.rows, tables.parity)
    _shadow(X, j, state.T, root, state.rows, tables.parity)
    state.dirty[i], state.dirty[j] = 1, 1
    if certify:
        _round_off(state, tables, step, line, rho0, rho1)
        _carry_bounds(state, tables.coef, i, j, line, r, scale)
    return True


@kernel
def count_live(tables, state, scale, certify, scratch, info):
    """The number of live contacts, or -1 when a decision cannot be certified (``info`` says which)."""
    live = 0
    for k in range(tables.pairs.shape[0]):
        decision, _, _ = _decide(k, tables, state, scale, certify, scratch, info)
        if decision < 0:
            return -1
        live += decision
    return live


@inlined
def _ahead(tables, state, certify, picks, t, flat, ring):
    """Cache hints for the picks after ``t``: their contacts, their balls' shadows, and the coefficients and
    bounds of balls the float filter does not rule out (``flat``: the coefficients ``state.X`` as one axis,
    reshaped once a call of `run_picks`, not once a pick). The filter's ``(decision, line, s, x)`` on pick
    ``t + AHEAD_BALLS`` is kept in ``ring``'s row ``(t + AHEAD_BALLS) % RING``, for the pick itself to use when
    no collision changes a shadow in between (`_filtered`)."""
    n, pairs, rows = picks.shape[0], tables.pairs, state.rows
    if t + AHEAD_CONTACT < n:
        prefetch(pairs, picks[t + AHEAD_CONTACT])
        prefetch(tables.ls, picks[t + AHEAD_CONTACT])
    if t + AHEAD_ROWS < n:
        k = picks[t + AHEAD_ROWS]
        prefetch(rows, pairs[k, 0])
        prefetch(rows, pairs[k, 1])
    if t + AHEAD_BALLS < n:
        k = picks[t + AHEAD_BALLS]
        decision, line, s, x = _filter(tables, rows, k)
        slot = ring[(t + AHEAD_BALLS) % RING]
        slot[0], slot[1], slot[2], slot[3] = decision, line, s, x
        if decision > 0:  # live or undecided
            for b in (pairs[k, 0], pairs[k, 1]):
                _fetch_ball(state.X, flat, b, tables.parity)
                if certify:
                    prefetch(state.B, b)
                    prefetch(state.Pp, b)


@inlined
def _fetch_ball(X, flat, b, parity):
    """Cache hints for ball ``b``'s coefficients (``flat``: ``X`` as one axis), a cache line of limbs at a time and
    the last of each component: only the one coefficient ``parity[d]`` of a component where it is not -1 (the other
    is 0 throughout and never read, `grading`)."""
    D, m, P = X.shape[1], X.shape[2], X.shape[3]
    for d in range(D):
        p = parity[d]
        start = (b * D + d) * m * P + (p * P if p >= 0 else 0)
        length = P if p >= 0 else m * P
        for q in range(0, length, 8):
            prefetch(flat, start + q)
        prefetch(flat, start + length - 1)


@inlined
def _filtered(tables, rows, picks, t, ring, since):
    """The float filter on pick ``t``: as `_ahead` kept it when it was made at pick ``t - AHEAD_BALLS >= since``
    (``since``: the pick after the last collision, or this call's first pick), otherwise anew; the same
    ``(decision, line, s, x)`` either way (the filter reads the shadows, which only a collision changes)."""
    if t - AHEAD_BALLS >= since:
        slot = ring[t % RING]
        return np.int64(slot[0]), np.int64(slot[1]), slot[2], slot[3]
    return _filter(tables, rows, picks[t])


@inlined
def _due(first, t, every, checked):
    """The pick from ``t`` on whose step (``first`` + its index) is the first multiple of ``every`` other
    than ``checked``: a check is due before it; -1 when ``every`` is 0 (none is ever due)."""
    if every <= 0:
        return -1
    due = (first + t + every - 1) // every * every
    return (due + every if due == checked else due) - first


def run_picks(tables, state, scale, certify, picks, t, collisions_left, until_frozen, chunk, at, prog, scratch, info,
              margin, at_last, first, every):
    """Try ``picks[t:]`` in turn: ``(how it ended, picks used)``; ``margin`` gathers the smallest
    closing speed of a collision, the largest (nonzero) of a pick set aside, and the number of picks
    set aside whose closing speed is exactly 0 between balls not both at rest. ``at_last`` ``(2,)``:
    ``margin[1:]`` as it was at the last collision (kept across the calls of one run, as ``prog``), to
    which a freeze rewinds it with the picks (those tried after the last collision are not the run's).

    DONE: all used, or stopped right after the ``collisions_left``-th collision of this run (``prog[0]``
    counts them, ``at`` holds their indices); FROZEN: with ``until_frozen``, a scan (every ``chunk``
    picks and at the end, when a collision happened since the last) found no live contact, so the
    run ends right after its last collision; WIDEN: pick ``t`` needs a wider state (call again from
    it); UNCERTIFIED: pick ``t`` cannot be certified (``info`` says why); UNCOUNTED: the scan after
    ``t`` picks cannot be; DUE: with ``every > 0``, the step ``first + t`` of pick ``t`` is a multiple
    of ``every`` other than ``prog[5]``: a check is due before it (call again from it).
    """
    return _run_picks(tables, state, scale, certify, picks, t, collisions_left, until_frozen, chunk, at, prog,
                      scratch, info, margin, at_last, first, every, np.empty((RING, 4)))


@kernel
def _run_picks(tables, state, scale, certify, picks, t, collisions_left, until_frozen, chunk, at, prog, scratch, info,
               margin, at_last, first, every, ring):
    """`run_picks`' loop; ``ring (RING, 4)``: scratch for the float filter's decisions made ahead (`_ahead`)."""
    made, last, fresh, countdown = prog[0], prog[1], prog[2], prog[4]
    n = picks.shape[0]
    status = DONE
    due = _due(first, t, every, prog[5])  # one division a call, not one a pick
    inside = 0
    flat = state.X.reshape(-1)
    since = t  # the filter's decisions made ahead from here on still hold (no collision since)
    while t < n:
        if t == due:
            status = DUE
            break
        _ahead(tables, state, certify, picks, t, flat, ring)
        k = picks[t]
        decision, line, s, x = _filtered(tables, state.rows, picks, t, ring, since)
        decision, computed, x = _settle(k, decision, line, s, x, tables, state, scale, certify, scratch, info)
        if decision < 0:
            status = UNCERTIFIED
            break
        if computed:  # the float filter could not decide it
            inside += 1
        if decision > 0:
            margin[0] = min(margin[0], x)
        elif x == 0.0:
            margin[2] += 1.0
        elif x > margin[1]:  # (False for NaN: both at rest)
            margin[1] = x
        if decision > 0:
            if not computed:
                _closing(tables, state.X, tables.pairs[k, 0], tables.pairs[k, 1], np.int64(tables.ls[k] >> 1),
                         scratch.W)
            if not _collide(k, tables, state, scale, certify, scratch, first + t):
                status = WIDEN
                break
            at[made] = t
            made, last, fresh, since = made + 1, t, 1, t + 1
            at_last[0], at_last[1] = margin[1], margin[2]
            prog[3] = -1
        t += 1
        countdown -= 1
        if made == collisions_left:
            break
        if until_frozen and fresh and (countdown <= 0 or t == n):
            live = count_live(tables, state, scale, certify, scratch, info)
            if live < 0:
                status = UNCOUNTED
                break
            prog[3], fresh = live, 0
            if live == 0:
                status, t = FROZEN, last + 1
                margin[1], margin[2] = at_last[0], at_last[1]
                break
        if countdown <= 0:
            countdown = chunk
    prog[0], prog[1], prog[2], prog[4] = made, last, fresh, countdown
    prog[6] += inside
    return status, t
