"""Jumping the random stream ahead: the state xoshiro256** reaches after ``N`` words, without drawing them.

xoshiro256**'s state moves by a linear map ``T`` over GF(2) (its output scrambler is not, but the
state is). So ``T^N s = r(T) s`` for ``r(x) = x^N mod p(x)``, ``p`` the characteristic polynomial of
``T`` (degree 256): `polynomial` finds ``p`` once (Berlekamp-Massey on one state bit's sequence),
`jump_polynomial(N)` computes ``r`` (square and multiply over GF(2)), and `jump` applies it with
256 steps of the generator (the way the generator's own ``jump()`` applies its fixed 2^128). Threads
of a parallel chain (`engine.threads.regions`) each draw their part of a block of words this way, and the
picks they make are the stream's own, word for word.
"""

from __future__ import annotations

import functools

import numpy as np

from ..jit.cache import njit_cached
from .xoshiro import next_uint64

__all__ = ["polynomial", "jump_polynomial", "jump", "DEGREE"]

DEGREE = 256  #: the degree of the characteristic polynomial: the bits of the state


def _state_bits(count: int) -> list[int]:
    """The lowest bit of the state's first word over ``count`` successive states (from any state)."""
    s = (0x9E3779B97F4A7C15, 0xBF58476D1CE4E5B9, 0x94D049BB133111EB, 0x2545F4914F6CDD1D)
    mask = (1 << 64) - 1
    bits = []
    for _ in range(count):
        bits.append(s[0] & 1)
        s0, s1, s2, s3 = s
        t = (s1 << 17) & mask
        s2 ^= s0
        s3 ^= s1
        s1 ^= s2
        s0 ^= s3
        s2 ^= t
        s3 = ((s3 << 45) | (s3 >> 19)) & mask
        s = (s0, s1, s2, s3)
    return bits


@functools.cache
def polynomial() -> int:
    """The characteristic polynomial of xoshiro256's state map as an int (bit ``i``: the coefficient
    of ``x^i``), from Berlekamp-Massey on 2 * 256 bits of one state bit's sequence."""
    bits = _state_bits(2 * DEGREE)
    c, b, length, m = 1, 1, 0, 1  # connection polynomials as ints, bit j: coefficient of x^j
    for i, bit in enumerate(bits):
        d = bit
        for j in range(1, length + 1):
            d ^= ((c >> j) & 1) & bits[i - j]
        if not d:
            m += 1
            continue
        t = c
        c ^= b << m
        if 2 * length <= i:
            length, b, m = i + 1 - length, t, 1
        else:
            m += 1
    if length != DEGREE:
        raise RuntimeError(f"xoshiro256's characteristic polynomial came out of degree {length}, not {DEGREE}")
    reversed_c = 0  # p(x) = x^L C(1/x)
    for j in range(length + 1):
        if (c >> j) & 1:
            reversed_c |= 1 << (length - j)
    return reversed_c


def _mulmod(a: int, b: int, p: int) -> int:
    """``a b mod p`` over GF(2)."""
    result = 0
    while b:
        if b & 1:
            result ^= a
        b >>= 1
        a <<= 1
        if (a >> DEGREE) & 1:
            a ^= p
    return result


@functools.cache
def jump_polynomial(words: int) -> np.ndarray:
    """``x^words mod p(x)`` as ``(4,) uint64`` words (bit ``i`` of the 256: the coefficient of ``x^i``)."""
    p, result, power, n = polynomial(), 1, 2, int(words)
    while n:
        if n & 1:
            result = _mulmod(result, power, p)
        power = _mulmod(power, power, p)
        n >>= 1
    return np.array([(result >> (64 * k)) & ((1 << 64) - 1) for k in range(4)], dtype=np.uint64)


@njit_cached(inline="always")
def jump(s, poly):
    """The 4-tuple state ``s`` advanced by the words ``poly`` (a `jump_polynomial`) stands for."""
    a0, a1, a2, a3 = np.uint64(0), np.uint64(0), np.uint64(0), np.uint64(0)
    for w in range(4):
        word = poly[w]
        for bit in range(64):
            if (word >> np.uint64(bit)) & np.uint64(1):
                a0 ^= s[0]
                a1 ^= s[1]
                a2 ^= s[2]
                a3 ^= s[3]
            _, s = next_uint64(s)
    return (a0, a1, a2, a3)
