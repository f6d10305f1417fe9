"""Fixed-point integers as arrays of 64-bit limbs: the arithmetic of the fixed-point chain.

A number is an integer ``X`` in ``P`` uint64 limbs ``x (P,)``, little-endian (``x[0]`` least
significant), in two's complement: ``X = sum_k x[k] 2^(64 k)``, minus ``2^(64 P)`` when the top bit
of ``x[P-1]`` is set. The chain reads it as ``X / 2^S`` (`pinnedballs.engine.field.fixed`).

Every operation here is exact arithmetic modulo ``2^(64 P)``: a result is right whenever the true
value fits in ``P`` limbs, which the chain guarantees by leaving headroom above its largest values
(intermediate sums may wrap; the final value does not). Multipliers are small signed integers
(``|c| < 2^31``: the numerators of a geometry's unit vectors times its root).

Every function is compiled by numba without its reference counting (``_nrt=False``: the chain's
loop passes arrays to them on every pick, and counting references costs atomic operations each
time), so none allocates: callers hand in scratch. Each works unchanged as plain Python
(``NUMBA_DISABLE_JIT=1``); its twin, Python's own integers, checks it in ``tests/engine/field/test_limbs.py``.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import config, types
from numba.core import cgutils
from numba.extending import intrinsic

from ..jit.cache import njit_cached

__all__ = ["mac", "mac_top", "mac_diff", "next_limb", "diff_combination", "exchange", "add_to", "sub_into", "addmul",
           "negate_into", "shift_round", "low_bits", "is_zero", "sign", "scaled_float", "to_float",
           "compare_squares", "field_sign", "to_limbs", "from_limbs"]

_0, _1 = np.uint64(0), np.uint64(1)
_LOW32, _32, _63, _64 = np.uint64(0xFFFFFFFF), np.uint64(32), np.uint64(63), np.uint64(64)
_ALL = np.uint64(0xFFFFFFFFFFFFFFFF)
_TWO64 = 18446744073709551616.0

#: the small operations are inlined where they are used (numba's own inlining: a call between
#: compiled functions passes every array as a structure and is not inlined by LLVM)
inlined = njit_cached(_nrt=False, inline="always")


@inlined
def _bit(b):
    """A bool as the limb 0 or 1."""
    return _1 if b else _0


# ---------------------------------------------------------------- a signed 128-bit accumulator
# ``(hi, lo)``, int64 and uint64, is the integer ``hi 2^64 + lo``: sums of small multiples of limbs
# (a linear combination of numbers, one limb position at a time) gather in it without a carry chain.


def _mac_codegen(signed: bool):
    def codegen(context, builder, signature, args):
        i128 = ir.IntType(128)
        hi, lo, x, c = args
        acc = builder.or_(builder.shl(builder.sext(hi, i128), ir.Constant(i128, 64)), builder.zext(lo, i128))
        wide = builder.sext(x, i128) if signed else builder.zext(x, i128)
        acc = builder.add(acc, builder.mul(builder.sext(c, i128), wide))
        out_hi = builder.trunc(builder.ashr(acc, ir.Constant(i128, 64)), ir.IntType(64))
        return cgutils.make_anonymous_struct(builder, [out_hi, builder.trunc(acc, ir.IntType(64))])
    return codegen


def _mac_diff_codegen(context, builder, signature, args):
    i128 = ir.IntType(128)
    hi, lo, x, y, c = args
    acc = builder.or_(builder.shl(builder.sext(hi, i128), ir.Constant(i128, 64)), builder.zext(lo, i128))
    diff = builder.sub(builder.zext(x, i128), builder.zext(y, i128))  # within 2^64 either way: one product
    acc = builder.add(acc, builder.mul(builder.sext(c, i128), diff))
    out_hi = builder.trunc(builder.ashr(acc, ir.Constant(i128, 64)), ir.IntType(64))
    return cgutils.make_anonymous_struct(builder, [out_hi, builder.trunc(acc, ir.IntType(64))])


@intrinsic
def _mac_intrinsic(typingctx, hi, lo, x, c):
    sig = types.Tuple((types.int64, types.uint64))(types.int64, types.uint64, types.uint64, types.int64)
    return sig, _mac_codegen(False)


@intrinsic
def _mac_top_intrinsic(typingctx, hi, lo, x, c):
    sig = types.Tuple((types.int64, types.uint64))(types.int64, types.uint64, types.uint64, types.int64)
    return sig, _mac_codegen(True)


@intrinsic
def _mac_diff_intrinsic(typingctx, hi, lo, x, y, c):
    sig = types.Tuple((types.int64, types.uint64))(types.int64, types.uint64, types.uint64, types.uint64, types.int64)
    return sig, _mac_diff_codegen


def _split(acc: int) -> tuple:
    return np.int64(acc >> 64), np.uint64(acc & ((1 << 64) - 1))


def _mac_python(hi, lo, x, c):
    """Without the JIT: the same with Python's integers."""
    return _split((int(hi) << 64) + int(lo) + int(c) * int(x))


def _mac_top_python(hi, lo, x, c):
    x = int(x)
    return _split((int(hi) << 64) + int(lo) + int(c) * (x - (1 << 64) if x >> 63 else x))


def _mac_diff_python(hi, lo, x, y, c):
    return _split((int(hi) << 64) + int(lo) + int(c) * (int(x) - int(y)))


#: ``mac(hi, lo, x, c) -> (hi, lo)``: the accumulator plus ``c x``, the limb ``x`` read unsigned;
#: ``mac_top``: the same with ``x`` read signed (the top limb of a two's complement number)
mac = _mac_python if config.DISABLE_JIT else _mac_intrinsic
mac_top = _mac_top_python if config.DISABLE_JIT else _mac_top_intrinsic
#: ``mac_diff(hi, lo, x, y, c) -> (hi, lo)``: the accumulator plus ``c (x - y)``, the limbs read unsigned (one
#: product where ``mac`` twice takes two)
mac_diff = _mac_diff_python if config.DISABLE_JIT else _mac_diff_intrinsic


def _next_limb_python(hi, lo):
    return _split(int(hi))


@inlined
def _next_limb_jit(hi, lo):
    return hi >> np.int64(63), np.uint64(hi)


#: ``next_limb(hi, lo) -> (hi, lo)``: the accumulator shifted down one limb (its low limb written
#: out by the caller before)
next_limb = _next_limb_python if config.DISABLE_JIT else _next_limb_jit


@inlined
def diff_combination(out, xi, xj, terms, count):
    """``out = sum_t f_t (xi[d_t, s_t] - xj[d_t, s_t])`` over ``t < count``, ``terms[t] = (d_t, s_t, f_t)``;
    ``xi, xj``: ``(dim, m, P)`` numbers, ``out``: ``(P,)``. One pass, the terms gathered limb by limb, one product
    a term and limb (the top limb's low 64 bits are the same read signed or not); one or two terms (the usual)
    with their numbers and factors read once, not once a limb, and factors of -1 and 1 (a lattice's usual: its
    unit vectors' numerators) as the constant 1, whose product the compiler drops (`_diff_by`)."""
    if count == 1:
        a, b, fa = xi[terms[0, 0], terms[0, 1]], xj[terms[0, 0], terms[0, 1]], terms[0, 2]
        if is_zero(a) and is_zero(b):  # (half the coefficients of a lattice's velocities are 0 throughout)
            _clear(out)
            return
        if fa == -1:  # -(a - b) = b - a
            a, b, fa = b, a, np.int64(1)
        if fa == 1:
            _diff_by(out, a, b, np.int64(1), a, b, np.int64(0))
        else:
            _diff_by(out, a, b, fa, a, b, np.int64(0))
        return
    if count == 2:
        a, b, fa = xi[terms[0, 0], terms[0, 1]], xj[terms[0, 0], terms[0, 1]], terms[0, 2]
        c, d, fc = xi[terms[1, 0], terms[1, 1]], xj[terms[1, 0], terms[1, 1]], terms[1, 2]
        if is_zero(a) and is_zero(b) and is_zero(c) and is_zero(d):
            _clear(out)
            return
        if fa == -1:
            a, b, fa = b, a, np.int64(1)
        if fc == -1:
            c, d, fc = d, c, np.int64(1)
        if fa == 1 and fc == 1:
            _diff_by(out, a, b, np.int64(1), c, d, np.int64(1))
        else:
            _diff_by(out, a, b, fa, c, d, fc)
        return
    hi, lo = np.int64(0), _0
    for k in range(out.shape[0]):
        for t in range(count):
            d, s = terms[t, 0], terms[t, 1]
            hi, lo = mac_diff(hi, lo, xi[d, s, k], xj[d, s, k], terms[t, 2])
        out[k] = lo
        hi, lo = next_limb(hi, lo)


@inlined
def _diff_by(out, a, b, fa, c, d, fc):
    """``out = fa (a - b) + fc (c - d)`` limb by limb in the accumulator (``fc`` 0: one term). Called with the
    factors 1 and 0 as constants where they are (a lattice's usual), so that the compiler drops those products: by a
    factor read from the tables, `mac_diff` makes a full 128-bit product a limb."""
    hi, lo = np.int64(0), _0
    for k in range(out.shape[0]):
        hi, lo = mac_diff(hi, lo, a[k], b[k], fa)
        if fc != 0:
            hi, lo = mac_diff(hi, lo, c[k], d[k], fc)
        out[k] = lo
        hi, lo = next_limb(hi, lo)


@inlined
def exchange(xi, xj, om, terms, count):
    """``xi -= K``, ``xj += K`` for ``K = sum_t f_t om[s_t]`` over ``t < count``, ``terms[t] = (s_t, f_t)``;
    ``xi, xj``: ``(P,)``, ``om``: ``(m, P)``. One pass: ``K``'s limb gathered once, then taken from one number and
    added to the other (three accumulators; the top limb's low 64 bits are the same read signed or not); one or
    two terms (the usual) with their numbers and factors read once, not once a limb; one term's factor of 1 or 3
    (up to sign) as a constant (`_exchange_by`)."""
    if count == 0:  # K = 0 (a line across this component)
        return
    hk, lk, hi, lo, hj, lj = np.int64(0), _0, np.int64(0), _0, np.int64(0), _0
    if count == 1:
        a, fa = om[terms[0, 0]], terms[0, 1]
        if is_zero(a):  # K = 0
            return
        if fa < 0:  # xi -= K, xj += K for K = -|f| a: xj -= |f| a, xi += |f| a
            xi, xj, fa = xj, xi, -fa
        if fa == 1:
            _exchange_by(xi, xj, a, np.int64(1))
        elif fa == 3:
            _exchange_by(xi, xj, a, np.int64(3))
        else:
            _exchange_by(xi, xj, a, fa)
        return
    if count == 2:
        a, fa, b, fb = om[terms[0, 0]], terms[0, 1], om[terms[1, 0]], terms[1, 1]
        if is_zero(a) and is_zero(b):
            return
        for k in range(xi.shape[0]):
            hk, lk = mac(hk, lk, a[k], fa)
            hk, lk = mac(hk, lk, b[k], fb)
            hk, lk, hi, lo, hj, lj = _exchange_limb(xi, xj, k, hk, lk, hi, lo, hj, lj)
        return
    for k in range(xi.shape[0]):
        for t in range(count):
            hk, lk = mac(hk, lk, om[terms[t, 0], k], terms[t, 1])
        hk, lk, hi, lo, hj, lj = _exchange_limb(xi, xj, k, hk, lk, hi, lo, hj, lj)


@inlined
def _exchange_by(xi, xj, a, fa):
    """`exchange` of ``K = fa a``, ``fa > 0``; called with the factors of the usual lattices (1, 3: their unit
    vectors' numerators and ``d``) as constants, whose products the compiler makes without a multiplication by a
    factor read from the tables."""
    hk, lk, hi, lo, hj, lj = np.int64(0), _0, np.int64(0), _0, np.int64(0), _0
    for k in range(xi.shape[0]):
        hk, lk = mac(hk, lk, a[k], fa)
        hk, lk, hi, lo, hj, lj = _exchange_limb(xi, xj, k, hk, lk, hi, lo, hj, lj)


@inlined
def _exchange_limb(xi, xj, k, hk, lk, hi, lo, hj, lj):
    """Limb ``k`` of `exchange`, ``K``'s limb ``lk`` gathered: ``xi[k] -= lk``, ``xj[k] += lk``; the three
    accumulators shifted down to the next limb."""
    hi, lo = _moved(hi, lo, xi[k], lk, -1)
    hj, lj = _moved(hj, lj, xj[k], lk, 1)
    xi[k], xj[k] = lo, lj
    hk, lk = next_limb(hk, lk)
    hi, lo = next_limb(hi, lo)
    hj, lj = next_limb(hj, lj)
    return hk, lk, hi, lo, hj, lj


@inlined
def _moved(hi, lo, x, lk, sign):
    """The accumulator ``(hi, lo)`` of ``x -+ K`` after limb ``x`` of the number and ``lk`` of ``K`` (``sign`` -1
    or 1)."""
    hi, lo = mac(hi, lo, x, 1)
    return mac(hi, lo, lk, sign)


@inlined
def add_to(acc, x):
    """``acc += x``."""
    carry = _0
    for k in range(acc.shape[0]):
        a = acc[k]
        s = a + x[k]
        t = s + carry
        acc[k] = t
        carry = np.uint64(s < a) | np.uint64(t < s)


@inlined
def sub_into(out, x, y):
    """``out = x - y`` (``out`` may be ``x`` or ``y``)."""
    borrow = _0
    for k in range(out.shape[0]):
        a, b = x[k], y[k]
        d = a - b
        out[k] = d - borrow
        borrow = np.uint64(a < b) | np.uint64(d < borrow)


@inlined
def addmul(acc, x, c):
    """``acc += c x`` for a small signed integer ``c`` (``|c| < 2^31``)."""
    if c == 1:
        add_to(acc, x)
    elif c == -1:
        sub_into(acc, acc, x)
    elif c != 0:
        _addmul(acc, x, c)


@inlined
def _addmul(acc, x, c):
    """`addmul` by multiplying: each limb split in 32-bit halves."""
    neg = c < 0
    cc = np.uint64(-c if neg else c)
    pcarry, carry = _0, _0
    for k in range(acc.shape[0]):
        xk = x[k]
        lo = (xk & _LOW32) * cc
        hi = (xk >> _32) * cc
        t = lo + pcarry
        p = t + (hi << _32)  # limb k of c x
        pcarry = (hi >> _32) + np.uint64(p < t)
        a = acc[k]
        if neg:
            d = a - p
            acc[k] = d - carry
            carry = np.uint64(a < p) | np.uint64(d < carry)
        else:
            s = a + p
            u = s + carry
            acc[k] = u
            carry = np.uint64(s < a) | np.uint64(u < s)


@inlined
def negate_into(out, x):
    """``out = -x`` (``out`` may be ``x``)."""
    carry = _1
    for k in range(out.shape[0]):
        v = ~x[k] + carry
        carry = _bit(carry == _1 and v == _0)
        out[k] = v


@inlined
def low_bits(x, bits):
    """``X mod 2^bits`` (``0 <= bits < 64``), as a limb."""
    return x[0] & ((_1 << np.uint64(bits)) - _1)


@inlined
def shift_round(out, x, bits):
    """``out = X / 2^bits`` rounded to nearest (ties up), ``1 <= bits < 64``; returns the remainder
    ``X - out 2^bits``, in ``[-2^(bits-1), 2^(bits-1))``, as an int64 (``out`` may be ``x``)."""
    b = np.uint64(bits)
    r = x[0] & ((_1 << b) - _1)
    fill = _ALL << (_64 - b) if x[x.shape[0] - 1] >> _63 else _0
    n = out.shape[0]
    for k in range(n - 1):
        out[k] = (x[k] >> b) | (x[k + 1] << (_64 - b))
    out[n - 1] = (x[n - 1] >> b) | fill
    if r >= _1 << (b - _1):  # up: out + 1, remainder r - 2^bits
        for k in range(n):
            out[k] += _1
            if out[k] != _0:
                break
        return np.int64(r) - (np.int64(1) << np.int64(bits))
    return np.int64(r)


@inlined
def _clear(out):
    """``out = 0``."""
    for k in range(out.shape[0]):
        out[k] = _0


@inlined
def is_zero(x):
    """Whether ``X`` is 0: every limb read, without a branch a limb (a loop the compiler vectorises)."""
    acc = _0
    for k in range(x.shape[0]):
        acc |= x[k]
    return acc == _0


@inlined
def sign(x):
    """-1, 0 or 1."""
    if x[x.shape[0] - 1] >> _63:
        return -1
    return 0 if is_zero(x) else 1


@inlined
def scaled_float(x):
    """``(f, e)``: ``X`` within ``4 * 2^-53 |X|`` of ``f 2^e``, ``|f| <= 1`` (read from the top two limbs
    that are not sign fill, so there is neither overflow nor underflow, and ``e`` is a multiple of
    64); ``(0.0, 0)`` for zero. A negative number's magnitude ``~X + 1`` is read as ``~X`` when it
    has two limbs or more: off by at most 2^-64 of it. Selects rather than branches where the sign decides,
    and a number that is 0 or -1 (all limbs sign fill: a lattice's velocities have many) told by one pass
    over its limbs, not a search from the top."""
    n = x.shape[0]
    neg = x[n - 1] >> _63
    fill = _ALL if neg else _0
    h = n - 1
    if x[h] == fill:  # a short number: its top limb in a lower place, or none
        acc = _0
        for k in range(n):
            acc |= x[k] ^ fill
        if acc == _0:
            h = -1
        else:
            while x[h] == fill:
                h -= 1
    h = max(h, int(neg) - 1)  # -1 (all ones) is read from limb 0, as 2^-64 2^64
    f = float(x[max(h, 0)] ^ fill) * _TWO64
    f += float(x[max(h - 1, 0)] ^ fill) if h > 0 else _TWO64 * float(neg)  # one limb: ~X + 1 exactly
    f *= 2.0 ** -128
    return (-f if neg else f), 64 * (h + 1)


@njit_cached(_nrt=False)
def to_float(x, scale):
    """``X / 2^scale`` as a float: within ``4 * 2^-53`` of it, relatively, in the normal range."""
    f, e = scaled_float(x)
    return math.ldexp(f, int(e - scale))


@njit_cached(_nrt=False)
def _square_times(out, x, c, digits):
    """``out = c X^2`` as 32-bit digits in uint64s (``4P + 2`` of them) for a magnitude ``x >= 0`` and
    ``0 < c < 2^31``; ``digits``: ``(2P,)`` scratch."""
    n = 2 * x.shape[0]
    for k in range(x.shape[0]):
        digits[2 * k] = x[k] & _LOW32
        digits[2 * k + 1] = x[k] >> _32
    for k in range(out.shape[0]):
        out[k] = _0
    for i in range(n):
        carry = _0
        ai = digits[i]
        for j in range(n):
            t = out[i + j] + ai * digits[j] + carry  # < 2^64: (2^32-1)^2 + 2 (2^32-1)
            out[i + j] = t & _LOW32
            carry = t >> _32
        out[i + n] = carry
    cc, carry = np.uint64(c), _0
    for k in range(out.shape[0]):
        t = out[k] * cc + carry
        out[k] = t & _LOW32
        carry = t >> _32


@njit_cached(_nrt=False)
def compare_squares(a, b, c, big):
    """The sign of ``A^2 - c B^2`` for magnitudes ``a, b >= 0`` (limb arrays) and ``0 < c < 2^31``;
    ``big``: ``(3, 4P + 2)`` scratch."""
    n = 2 * a.shape[0]
    p, q = big[0], big[1]
    _square_times(p, a, 1, big[2, :n])
    _square_times(q, b, c, big[2, :n])
    for k in range(p.shape[0] - 1, -1, -1):
        if p[k] != q[k]:
            return 1 if p[k] > q[k] else -1
    return 0


@njit_cached(_nrt=False)
def field_sign(w0, w1, root, d, tmp0, tmp1, big):
    """The exact sign of ``w0 + w1 sqrt(d)`` (limb arrays; ``root``: the float sqrt(d)); ``tmp0, tmp1``:
    ``(P,)`` and ``big``: ``(3, 4P + 2)`` scratch. The coefficients' signs, then (only when they differ) floats, then
    (only when the floats cannot tell) ``w0^2`` against ``d w1^2`` in full."""
    s0, s1 = sign(w0), sign(w1)
    if s1 == 0 or s0 == s1:
        return s0
    if s0 == 0:
        return s1
    f0, e0 = scaled_float(w0)
    f1, e1 = scaled_float(w1)
    a, b = abs(f0), abs(f1) * root  # |w0| and sqrt(d)|w1|, each within 6 * 2^-53 relatively
    if e0 >= e1:
        a = math.ldexp(a, int(min(e0 - e1, 2000)))
    else:
        b = math.ldexp(b, int(min(e1 - e0, 2000)))
    if a > b * (1.0 + 2.0 ** -48):
        return s0
    if b > a * (1.0 + 2.0 ** -48):
        return s1
    for k in range(w0.shape[0]):  # the magnitudes
        tmp0[k], tmp1[k] = w0[k], w1[k]
    if s0 < 0:
        negate_into(tmp0, w0)
    if s1 < 0:
        negate_into(tmp1, w1)
    return s0 if compare_squares(tmp0, tmp1, d, big) > 0 else s1


# ---------------------------------------------------------------- Python integers in and out


def to_limbs(values, limbs: int) -> np.ndarray:
    """``(..., limbs) uint64``: the Python integers ``values`` (any nested shape) in two's complement;
    an OverflowError if one does not fit."""
    flat = np.asarray(values, dtype=object)
    out = np.empty(flat.shape + (limbs,), dtype=np.uint64)
    view = out.reshape(-1, limbs)
    for n, v in enumerate(flat.ravel().tolist()):
        view[n] = np.frombuffer(int(v).to_bytes(8 * limbs, "little", signed=True), dtype="<u8")
    return out


def from_limbs(x: np.ndarray) -> np.ndarray:
    """The Python integers (object array of shape ``x.shape[:-1]``) held in the limb arrays ``x``."""
    x = np.asarray(x, dtype=np.uint64)
    width = 8 * x.shape[-1]
    data = np.ascontiguousarray(x, dtype="<u8").tobytes()
    out = np.empty(len(data) // width if width else 0, dtype=object)
    out[:] = [int.from_bytes(data[o:o + width], "little", signed=True) for o in range(0, len(data), width)]
    return out.reshape(x.shape[:-1])
