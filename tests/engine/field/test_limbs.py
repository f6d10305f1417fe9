"""The fixed-point kernels against their plain-Python twin, Python's integers: every operation
exact modulo 2^(64 P), signs exact, floats within their stated error."""

from __future__ import annotations

import math
from fractions import Fraction

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pinnedballs.engine.field import limbs

P = 3
MOD = 1 << (64 * P)
HALF = MOD >> 1
BIG = np.empty((3, 4 * P + 2), dtype=np.uint64)  # scratch of the full squares


def wrap(x: int) -> int:
    """``x`` modulo 2^(64 P), as a signed integer (what P limbs hold)."""
    x %= MOD
    return x - MOD if x >= HALF else x


def arr(x: int) -> np.ndarray:
    return limbs.to_limbs([x], P)[0]


def val(a: np.ndarray) -> int:
    return int(limbs.from_limbs(a[None])[0])


# integers near the limb boundaries and the extremes, where carries and borrows ripple
edges = st.sampled_from([0, 1, -1, 2**64 - 1, 2**64, -(2**64), 2**128 - 1, -(2**128), HALF - 1, -HALF,
                         (1 << 63), -(1 << 63) - 1])
numbers = st.one_of(edges, st.integers(-HALF, HALF - 1), st.integers(-(2**70), 2**70))
small = st.integers(-(2**31) + 1, 2**31 - 1)
# a lattice's factors (its unit vectors' numerators, d), which the kernels take by paths of their own, and any other
factors = st.one_of(st.sampled_from([1, -1, 3, -3]), small)


@settings(max_examples=300, deadline=None)
@given(x=numbers, y=numbers)
def test_add_and_subtract_are_those_of_integers_modulo_the_width(x, y):
    a = arr(x)
    limbs.add_to(a, arr(y))
    assert val(a) == wrap(x + y)
    out = np.empty(P, dtype=np.uint64)
    limbs.sub_into(out, arr(x), arr(y))
    assert val(out) == wrap(x - y)
    limbs.negate_into(out, arr(x))
    assert val(out) == wrap(-x)


@settings(max_examples=300, deadline=None)
@given(acc=numbers, x=numbers, c=small)
def test_adding_a_small_multiple_is_that_of_integers(acc, x, c):
    a = arr(acc)
    limbs.addmul(a, arr(x), c)
    assert val(a) == wrap(acc + c * x)


@settings(max_examples=300, deadline=None)
@given(x=numbers, bits=st.integers(1, 63))
def test_a_rounded_shift_is_nearest_with_ties_up_and_returns_the_remainder(x, bits):
    out = np.empty(P, dtype=np.uint64)
    rest = limbs.shift_round(out, arr(x), bits)
    q = (x + (1 << (bits - 1))) >> bits  # floor((x + half) / 2^bits): nearest, ties up
    assert val(out) == wrap(q) and rest == x - (q << bits)
    assert -(1 << (bits - 1)) <= rest < (1 << (bits - 1))
    assert limbs.low_bits(arr(x), bits) == x % (1 << bits)


@settings(max_examples=300, deadline=None)
@given(x=numbers, scale=st.integers(-200, 1000))
def test_sign_zero_and_float_of_a_number(x, scale):
    """A float within 4 units of 2^-53 of the number, relatively (in the normal range)."""
    a = arr(x)
    assert limbs.sign(a) == (x > 0) - (x < 0) and limbs.is_zero(a) == (x == 0)
    f, e = limbs.scaled_float(a)
    assert abs(Fraction(f) * 2**e - x) <= Fraction(4, 2**53) * abs(x)
    exact = Fraction(x, 2**scale) if scale >= 0 else Fraction(x * 2**-scale)
    if x == 0 or 2**-1000 < abs(exact) < 2**1000:
        assert abs(Fraction(limbs.to_float(a, scale)) - exact) <= Fraction(4, 2**53) * abs(exact)


@settings(max_examples=300, deadline=None)
@given(a=st.integers(0, HALF - 1), b=st.integers(0, HALF // 2), c=st.sampled_from([1, 2, 3, 5, 7, 2**31 - 1]))
def test_squares_compare_as_integers(a, b, c):
    assert limbs.compare_squares(arr(a), arr(b), c, BIG) == ((a * a > c * b * b) - (a * a < c * b * b))


def exact_sign(w0: int, w1: int, d: int) -> int:
    """The sign of w0 + w1 sqrt(d), by integers only."""
    if w1 == 0 or (w0 > 0) == (w1 > 0) and w0 != 0:
        return (w0 > 0) - (w0 < 0)
    if w0 == 0:
        return (w1 > 0) - (w1 < 0)
    return (1 if w0 > 0 else -1) if w0 * w0 > d * w1 * w1 else (1 if w1 > 0 else -1)


@settings(max_examples=300, deadline=None)
@given(w0=numbers, w1=st.integers(-(2**100), 2**100), d=st.sampled_from([2, 3]))
def test_the_sign_of_an_element_of_a_quadratic_field_is_exact(w0, w1, d):
    scratch = [np.empty(P, dtype=np.uint64) for _ in range(2)]
    assert limbs.field_sign(arr(w0), arr(w1), math.sqrt(d), d, *scratch, BIG) == exact_sign(w0, w1, d)


@pytest.mark.parametrize("d", [2, 3])
def test_signs_of_near_cancellations_in_a_quadratic_field(d):
    """Convergents of sqrt(d): w0 + w1 sqrt(d) within 1e-40 of zero, of both signs, where only the
    full squares decide."""
    a = math.isqrt(d)
    h, k, h1, k1 = a, 1, 1, 0  # continued fraction convergents h/k of sqrt(d)
    m, dd, aa = 0, 1, a
    seen = set()
    scratch = [np.empty(P, dtype=np.uint64) for _ in range(2)]
    for _ in range(120):
        m = dd * aa - m
        dd = (d - m * m) // dd
        aa = (a + m) // dd
        h, h1 = aa * h + h1, h
        k, k1 = aa * k + k1, k
        if h >= HALF:
            break
        for w0, w1 in ((h, -k), (-h, k)):
            assert limbs.field_sign(arr(w0), arr(w1), math.sqrt(d), d, *scratch, BIG) == exact_sign(w0, w1, d)
            seen.add(exact_sign(w0, w1, d))
    assert seen == {1, -1} and h > 2**100


def test_integers_go_in_and_out_unchanged():
    values = [0, 1, -1, HALF - 1, -HALF, 12345678901234567890123]
    assert limbs.from_limbs(limbs.to_limbs(values, P)).tolist() == values
    with pytest.raises(OverflowError):
        limbs.to_limbs([HALF], P)


@settings(max_examples=200, deadline=None)
@given(xs=st.lists(numbers, min_size=4, max_size=4), ys=st.lists(numbers, min_size=4, max_size=4),
       fs=st.lists(factors, min_size=3, max_size=3), count=st.integers(0, 3))
def test_a_linear_combination_of_differences_is_that_of_integers(xs, ys, fs, count):
    """``sum f_t (x[d_t, s_t] - y[d_t, s_t])`` in one pass through the 128-bit accumulator."""
    x = limbs.to_limbs(np.array(xs, dtype=object).reshape(2, 2), P)  # (dim, m, P)
    y = limbs.to_limbs(np.array(ys, dtype=object).reshape(2, 2), P)
    picked = [(0, 0), (1, 1), (1, 0)][:count]
    terms = np.array([[d, s, f] for (d, s), f in zip(picked, fs)] or [[0, 0, 0]], dtype=np.int64)
    out = np.empty(P, dtype=np.uint64)
    limbs.diff_combination(out, x, y, terms, count)
    expected = sum(f * (xs[2 * d + s] - ys[2 * d + s]) for (d, s), f in zip(picked, fs))
    assert val(out) == wrap(expected)


@settings(max_examples=200, deadline=None)
@given(xi=numbers, xj=numbers, om=st.lists(numbers, min_size=2, max_size=2),
       fs=st.lists(factors, min_size=2, max_size=2), count=st.integers(0, 2))
def test_an_exchange_moves_the_same_combination_out_of_one_number_and_into_the_other(xi, xj, om, fs, count):
    a, b = arr(xi), arr(xj)
    terms = np.array([[s, f] for s, f in zip((1, 0), fs)], dtype=np.int64)
    limbs.exchange(a, b, limbs.to_limbs(om, P), terms, count)
    k = sum(f * om[s] for s, f in list(zip((1, 0), fs))[:count])
    assert (val(a), val(b)) == (wrap(xi - k), wrap(xj + k))


@numba.njit
def _mac_diff(hi, lo, x, y, c):
    return limbs.mac_diff(hi, lo, x, y, c)


@settings(max_examples=300, deadline=None)
@given(acc=st.integers(-(2**120), 2**120), x=st.integers(0, 2**64 - 1), y=st.integers(0, 2**64 - 1), c=small)
def test_a_product_of_a_difference_of_limbs_gathers_as_integers_do(acc, x, y, c):
    """``mac_diff``: the 128-bit accumulator plus ``c (x - y)`` with one product, as its plain-Python twin."""
    hi, lo = np.int64(acc >> 64), np.uint64(acc & (2**64 - 1))  # the accumulator: hi 2^64 + lo
    got = _mac_diff(hi, lo, np.uint64(x), np.uint64(y), np.int64(c))
    twin = limbs._mac_diff_python(hi, lo, np.uint64(x), np.uint64(y), np.int64(c))
    total = (int(hi) << 64) + int(lo) + c * (x - y)
    assert (int(got[0]), int(got[1])) == (int(twin[0]), int(twin[1])) == (total >> 64, total & (2**64 - 1))


def _scaled_float_by_search(x: np.ndarray) -> tuple:
    """`limbs.scaled_float` as it was first written (a search from the top limb down, branches on the sign): the
    reference its selects must equal bit for bit."""
    n, neg = len(x), bool(int(x[-1]) >> 63)
    fill = 2**64 - 1 if neg else 0
    h = n - 1
    while h >= 0 and int(x[h]) == fill:
        h -= 1
    if h < 0:
        return (-(2.0**-64) if neg else 0.0), 64 if neg else 0
    top = int(x[h]) ^ fill
    f = float(top) * 2.0**64
    if h > 0:
        f += float(int(x[h - 1]) ^ fill)
    elif neg:
        f += 2.0**64
    f *= 2.0**-128
    return (-f if neg else f), 64 * (h + 1)


@settings(max_examples=400, deadline=None)
@given(x=st.one_of(numbers, st.integers(-(2**64), 2**64), st.sampled_from([0, -1, -2, 1, 2**63, -(2**63)])))
def test_a_numbers_float_is_the_one_a_search_from_the_top_limb_finds(x):
    """The float of a number, its top limb found by one pass when it is sign fill (0, -1 and short numbers, which
    a lattice's velocities are full of), is bit for bit the one the search from the top found, and its sign."""
    f, e = limbs.scaled_float(arr(x))
    g, h = _scaled_float_by_search(arr(x))
    assert (f, int(e), math.copysign(1.0, f)) == (g, h, math.copysign(1.0, g))


def test_combinations_of_numbers_that_are_0_are_0_whatever_the_output_held():
    """The shortcuts for sources that are 0 (half the coefficients of a lattice's velocities): the output is cleared
    (not left as it was), K = 0 moves nothing, and a source that is not 0 beside one that is still counts."""
    x = limbs.to_limbs(np.array([[0, 5], [0, -7]], dtype=object), P)
    y = limbs.to_limbs(np.array([[0, 2], [0, 3]], dtype=object), P)
    out = np.full(P, 12345, dtype=np.uint64)
    limbs.diff_combination(out, x, y, np.array([[0, 0, 3]], dtype=np.int64), 1)
    assert val(out) == 0
    out[:] = 999
    limbs.diff_combination(out, x, y, np.array([[0, 0, 3], [1, 0, -2]], dtype=np.int64), 2)
    assert val(out) == 0
    limbs.diff_combination(out, x, y, np.array([[0, 0, 3], [1, 1, -2]], dtype=np.int64), 2)
    assert val(out) == -2 * (-7 - 3)
    a, b = arr(-11), arr(4)
    om = limbs.to_limbs([0, 0], P)
    for count in (1, 2):
        limbs.exchange(a, b, om, np.array([[0, 3], [1, -5]], dtype=np.int64), count)
        assert (val(a), val(b)) == (-11, 4)
    limbs.exchange(a, b, limbs.to_limbs([0, 6], P), np.array([[0, 3], [1, -5]], dtype=np.int64), 2)
    assert (val(a), val(b)) == (-11 + 30, 4 - 30)
    assert limbs.is_zero(arr(0)) and not limbs.is_zero(arr(1 << 150)) and not limbs.is_zero(arr(-1))


@pytest.mark.parametrize("fa, fc", [(1, 1), (1, -1), (-1, 1), (-1, -1), (1, 3), (-3, -1)])
def test_a_lattices_factors_combine_as_integers_do_across_carries(fa, fc):
    """Factors of 1 and -1 (differences without a product) and 3 (an exchange's constant), each sign, on numbers
    whose limbs carry and borrow throughout, for one term and two: the integers' combination, modulo 2^(64 P)."""
    values = [2**64 - 1, -(2**128), HALF - 1, -HALF, 1, -1, 2**190 + 12345, -(2**64) + 7]
    xs, ys = values[:4], values[4:]
    x = limbs.to_limbs(np.array(xs, dtype=object).reshape(2, 2), P)
    y = limbs.to_limbs(np.array(ys, dtype=object).reshape(2, 2), P)
    out = np.empty(P, dtype=np.uint64)
    terms = np.array([[0, 1, fa], [1, 0, fc]], dtype=np.int64)
    limbs.diff_combination(out, x, y, terms, 1)
    assert val(out) == wrap(fa * (xs[1] - ys[1]))
    limbs.diff_combination(out, x, y, terms, 2)
    assert val(out) == wrap(fa * (xs[1] - ys[1]) + fc * (xs[2] - ys[2]))
    for xi, xj, om in ((values[0], values[3], values[6]), (values[2], values[1], values[7])):
        a, b = arr(xi), arr(xj)
        limbs.exchange(a, b, limbs.to_limbs([values[5], om], P), np.array([[1, fa]], dtype=np.int64), 1)
        assert (val(a), val(b)) == (wrap(xi - fa * om), wrap(xj + fa * om))
