"""Device functions of the GPU engine that the CPU writes otherwise: the counter stream (`engine.streams.philox`) and
a contact read from its index (`engine.rows.decode`) or from the tables.

A GPU run gives the bits of the CPU loop on the counter stream. The arithmetic of a collision and of the
margin is not here: the kernels call the CPU's own functions (`engine.closing.trial_form`,
`engine.margin.track`), which numba-cuda compiles for the device without contraction (`compile`). What
is here is integer work the CPU does with its own intrinsics: Philox's 64-bit products (``mul.hi.u64``,
libdevice's ``umul64hi``, on a GPU; Python's integers under numba-cuda's simulator, which has no libdevice).
"""

from __future__ import annotations

import contextlib
import functools
import math
import sys

import numpy as np
from numba import cuda

from ..streams.philox import M0, M1, ROUNDS, W0, W1
from .compile import SIMULATED, contraction_off

__all__ = ["SIMULATED", "device", "launching", "counter_pick", "philox_block", "lemire", "contact_reader", "INF"]

_MASK = (1 << 64) - 1
_U0, _U1, _U2, _U3 = np.uint64(0), np.uint64(1), np.uint64(2), np.uint64(3)
_M0, _M1, _W0, _W1 = np.uint64(M0), np.uint64(M1), np.uint64(W0), np.uint64(W1)
_FIELD, _SHIFT = (1 << 24) - 1, 1 << 23

device = functools.partial(cuda.jit, device=True, inline="always")

if SIMULATED:  # the simulator has no libdevice: Python's integers
    def mulhilo(a, b):
        p = int(a) * int(b)
        return np.uint64(p >> 64), np.uint64(p & _MASK)

    def add64(a, b):
        return np.uint64((int(a) + int(b)) & _MASK)

    def wrap(n):
        return np.uint64((-int(n)) % int(n))
else:
    from numba.cuda import libdevice

    @device
    def mulhilo(a, b):
        return np.uint64(libdevice.umul64hi(a, b)), np.uint64(a) * np.uint64(b)

    @device
    def add64(a, b):
        return np.uint64(a) + np.uint64(b)

    @device
    def wrap(n):
        return (_U0 - n) % n


@contextlib.contextmanager
def launching():
    """Around a kernel's compile and launch: NVVM without contraction (`compile.contraction_off`); under the
    simulator, a short thread switch interval (its block manager polls its threads, and at Python's default
    5 ms a launch of a few hundred steps takes seconds)."""
    if not SIMULATED:
        with contraction_off():
            yield
        return
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)
    try:
        yield
    finally:
        sys.setswitchinterval(interval)


# ---------------------------------------------------------------- the counter stream (engine.streams.philox)


@device
def philox_block(c0, c1, c2, c3, k0, k1):
    """Philox4x64-10 at counter ``(c0, c1, c2, c3)``, key ``(k0, k1)``: `engine.streams.philox.block`."""
    for r in range(ROUNDS):
        if r > 0:
            k0 = add64(k0, _W0)
            k1 = add64(k1, _W1)
        hi0, lo0 = mulhilo(_M0, c0)
        hi1, lo1 = mulhilo(_M1, c2)
        c0, c1, c2, c3 = hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0
    return c0, c1, c2, c3


@device
def lemire(x, n):
    """``(k, accepted)``: `engine.streams.philox.lemire`."""
    hi, lo = mulhilo(x, n)
    if lo < n:
        if lo < wrap(n):  # 2^64 mod n
            return hi, False
    return hi, True


@device
def _word(w0, w1, w2, w3, q):
    if q == _U0:
        return w0
    if q == _U1:
        return w1
    return w2 if q == _U2 else w3


@device
def counter_pick(k0, k1, s, n):
    """Step ``s``'s contact among ``n``: `engine.streams.philox.counter_pick` (all uint64)."""
    r = _U0
    while True:
        w0, w1, w2, w3 = philox_block(s >> _U2, r, _U0, _U0, k0, k1)
        k, accepted = lemire(_word(w0, w1, w2, w3, s & _U3), n)
        if accepted:
            return k
        r += _U1


# ---------------------------------------------------------------- contacts


@functools.cache
def contact_reader(rows: bool):
    """``contact(pairs, ends, table, meta, k) -> (i, j, a, b)`` (int64): from the row pattern
    (`engine.rows.decode`; ``table`` its packed rows, ``meta = [per_row, rows, cols]`` int64 and
    ``meta_f = [inverse]``) when ``rows``, else from the tables ``pairs, ends (E, 2)``."""
    if rows:
        @device
        def contact(pairs, ends, table, meta, inverse, k):
            per_row, n_rows, cols = meta[0], meta[1], meta[2]
            r = np.int64(np.float64(k) * inverse)
            if r * per_row > k:
                r -= 1
            elif (r + 1) * per_row <= k:
                r += 1
            last = r >= n_rows - 1
            if last:
                r = n_rows - 1
            e = table[k - r * per_row + (2 * per_row if last else (r & 1) * per_row)]
            i = r * cols + (e & _FIELD)
            return i, i + ((e >> 24) & _FIELD) - _SHIFT, (e >> 48) & 0xFF, e >> 56
    else:
        @device
        def contact(pairs, ends, table, meta, inverse, k):
            return np.int64(pairs[k, 0]), np.int64(pairs[k, 1]), np.int64(ends[k, 0]), np.int64(ends[k, 1])
    return contact


#: the margin's smallest collision before any
INF = math.inf
