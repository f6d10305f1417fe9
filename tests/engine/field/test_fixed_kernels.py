"""The fixed-point chain's kernels: the bound rule behind ``G``. Batched (`fixed_kernels._round_off`), the state
after a batch does not depend on the order its collisions are made in, so long as each ball sees its own in
step order (what a GPU's deterministic reservations keep)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs.engine.field.fixed import FixedChain, bound_batch, lines_of
from pinnedballs.engine.field.fixed_kernels import (
    RING,
    SQRT2_UP,
    UP,
    _ahead,
    _filter,
    _filtered,
    _ldexp,
    cap,
    fold,
    unfolded,
)


def rounds(picks: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """``picks`` reordered as deterministic reservations make them: round by round, each round the picks that
    are the earliest left on both their balls (so every ball sees its picks in step order)."""
    left, order = list(range(len(picks))), []
    while left:
        taken, held = [], set()
        for t in left:  # in step order: a ball once passed over stays held for the round
            i, j = pairs[picks[t]]
            if i not in held and j not in held:
                taken.append(t)
            held.update((int(i), int(j)))
        order += taken
        left = [t for t in left if t not in set(taken)]
    assert sorted(order) == list(range(len(picks)))
    return picks[np.array(order)]


def chain(g, v) -> FixedChain:
    return FixedChain(g, v, lines_of(g), "certified", precision=64)


def test_the_batched_rule_does_not_depend_on_the_order_of_a_batchs_collisions():
    """The same picks of one batch, in step order and in the order of reservation rounds: the batched rule ends
    on the same bits (velocities, bounds, sums)."""
    g = pb.HalfPlane(8, 8)
    rng = np.random.default_rng(3)
    v = np.round(rng.normal(size=(g.n_balls, 2)) * 2**45) / 2**45  # 64 bits hold them, and soon round
    picks = rng.integers(0, g.n_contacts, size=bound_batch(g.n_contacts, 1) - 1)
    one, other = chain(g, v), chain(g, v)
    _, made, _ = one.run(picks, len(picks) + 1, False, 1)
    _, made_too, _ = other.run(rounds(picks, g.contacts.pairs), len(picks) + 1, False, 1)
    assert made == made_too > 200 and np.array_equal(one.X, other.X)
    assert (one.rho.any() or one.acc[0] > 0) and one.B.any()  # it rounded
    same = [np.array_equal(a, b) for a, b in ((one.B, other.B), (one.Pp, other.Pp), (one.acc, other.acc),
                                               (one.rho, other.rho))]
    assert all(same)


def test_the_largest_rounding_bounds_every_collisions():
    """``rmax`` is at least what `_collide` adds for any ``rho_0, rho_1`` in ``[-2^(2e-1), 2^(2e-1))``."""
    for g in (pb.HalfPlane(4, 4), pb.FCC(2, 2, 2)):
        t = lines_of(g).tables
        for e in set(t.e.tolist()):
            half = 1 << (2 * e - 1) if e else 0
            for rho0 in (-half, half - 1, 0):
                for rho1 in (-half, half - 1, 0):
                    r = math.ldexp((abs(rho0) + abs(rho1) * t.root[2] * UP) * UP, -e) if e else 0.0
                    assert r <= t.rmax


@settings(max_examples=50, deadline=None, derandomize=True)
@given(st.integers(0, 2**62), st.integers(0, 2**62), st.floats(0, 2.0**40), st.integers(0, 30),
       st.sampled_from([2, 3]))
def test_a_fold_bounds_the_exact_sums_from_above(r0, r1, base, emax, d):
    """``acc[0]`` after a fold is at least ``base + (r0 + r1 sqrt d) 2^-emax``; ``G`` at least ``sqrt 2`` times
    that plus ``K rmax``; the sums cleared and the batch kept."""
    root_up = np.nextafter(math.sqrt(d), np.inf)
    acc, rho, bound = np.array([base, 0.0]), np.array([r0, r1], dtype=np.uint64), np.array([1024, 3], dtype=np.int64)
    assert unfolded(rho, emax, root_up) >= (r0 + r1 * math.sqrt(d)) / 2**emax
    fold(acc, rho, bound, 7, emax, 0.5, root_up)
    low = Fraction(base) + (Fraction(r0) + Fraction(r1) * Fraction(math.sqrt(d) * (1 - 2.0**-52))) / 2**emax
    assert Fraction(acc[0]) >= low and not rho.any() and bound[1] == 7
    assert acc[1] == cap(acc[0], 512.0) and Fraction(acc[1]) >= Fraction(math.sqrt(2) * (1 - 2.0**-52)) * (
        Fraction(acc[0]) + 512) and SQRT2_UP > math.sqrt(2)


@settings(max_examples=500, deadline=None)
@given(x=st.one_of(st.floats(allow_nan=False, allow_infinity=False), st.sampled_from([5e-324, -2.2250738585072014e-308,
                                                                                      1.0, 1.5, 2.0**-60])),
       e=st.integers(-1200, 1200))
def test_the_loops_ldexp_is_the_c_librarys_bit_for_bit(x, e):
    """One product by a power of two where that power is a normal float, the library's call elsewhere: the same
    float in every range, the subnormal results (rounded once, to nearest) and the overflows included."""
    with np.errstate(over="ignore"):
        library = np.ldexp(np.float64(x), e)  # the C library's, overflowing to infinity as the loop's does
    assert np.float64(_ldexp(x, e)).tobytes() == library.tobytes()


def test_the_filters_decision_made_ahead_is_the_one_the_pick_would_make():
    """`_ahead` keeps the float filter's ``(decision, line, s, x)`` on the pick ``AHEAD_BALLS`` on, and
    `_filtered` hands it back to that pick when no collision came between (otherwise it filters anew): on a
    moving half-plane, every pick's kept decision is the filter's own, the both-at-rest NaN included."""
    g = pb.HalfPlane(10, 10)
    rng = np.random.default_rng(5)
    v = np.zeros((g.n_balls, 2))
    v[: g.n_balls // 2] = rng.normal(size=(g.n_balls // 2, 2))  # half at rest: NaN closing speeds too
    c = FixedChain(g, v, lines_of(g), "certified")
    state, tables = c._state(), c.tables
    picks = rng.integers(0, g.n_contacts, size=400)
    ring, flat = np.full((RING, 4), -7.0), state.X.reshape(-1)
    kinds = set()
    for t in range(len(picks)):
        _ahead(tables, state, c.certify, picks, t, flat, ring)
        kept = _filtered(tables, state.rows, picks, t, ring, 0)
        fresh = _filter(tables, state.rows, picks[t])
        assert kept[:3] == fresh[:3] and np.float64(kept[3]).tobytes() == np.float64(fresh[3]).tobytes(), t
        kinds.add(int(fresh[0]) if fresh[3] == fresh[3] else "rest")
    assert {0, 1, "rest"} <= kinds
    assert _filtered(tables, state.rows, picks, 10, np.full((RING, 4), -7.0), 5)[:3] == _filter(
        tables, state.rows, picks[10])[:3]  # made before the last collision (since 5 > 10 - 6): filtered anew
