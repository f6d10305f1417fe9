"""Device functions of the GPU engine: the CPU loop's arithmetic, operation by operation.

A GPU run gives the bits of the CPU loop on the counter stream, so everything here is a transcription
of the CPU's functions: the counter stream (`engine.philox`), a contact from its index
(`engine.rows.decode` or the tables), the closing speed (`engine.closing.closing_speed`), the three
built-in collision forms (`pinnedballs.rules`: ``elastic_at``, ``equal_at``, ``masses_at``) and the
closing margin (`engine.margin.track`).

**No fused multiply-add.** libNVVM contracts ``a * b + c`` into ``fma.rn.f64``, which rounds once
where the CPU rounds twice. Every floating-point operation here therefore goes through libdevice's
round-to-nearest functions (``dmul_rn``, ``dadd_rn``, ``ddiv_rn``; ``a - b`` as ``a + (-b)``, the
negation exact: ``mul.rn.f64``, ``add.rn.f64``, ... in the PTX, which the tests check holds no ``fma`` on doubles). Under numba-cuda's
simulator (``NUMBA_ENABLE_CUDASIM=1``, the tests' CPU stand-in for a GPU) libdevice is not
implemented; there the same names are plain Python operations, which round alike on a CPU.
64-bit products: ``mul.hi.u64`` (libdevice's ``umul64hi``) on a GPU, Python's integers in the simulator.

Rules are numbered as `engine.gpu.rule_code` numbers them; ``params = [factor, threshold]`` as on the CPU.
"""

from __future__ import annotations

import contextlib
import functools
import math
import sys

import numpy as np
from numba import cuda

try:  # numba-cuda >= 0.2x keeps its own configuration
    from numba.cuda.core import config as _cuda_config
except ImportError:  # pragma: no cover - older numba-cuda reads numba's
    from numba.core import config as _cuda_config

from ..margin import NEAR
from ..closing import ELASTIC, EQUAL
from ..philox import M0, M1, W0, W1, ROUNDS

__all__ = ["SIMULATED", "launching", "counter_pick", "philox_block", "lemire",
           "contact_reader", "collider", "track"]

#: True under numba-cuda's simulator: kernels run as Python threads on the CPU
SIMULATED = bool(getattr(_cuda_config, "ENABLE_CUDASIM", 0))

_MASK = (1 << 64) - 1
_U0, _U1, _U2, _U3 = np.uint64(0), np.uint64(1), np.uint64(2), np.uint64(3)
_M0, _M1, _W0, _W1 = np.uint64(M0), np.uint64(M1), np.uint64(W0), np.uint64(W1)
_FIELD, _SHIFT = (1 << 24) - 1, 1 << 23

device = functools.partial(cuda.jit, device=True, inline="always")

if SIMULATED:  # the simulator has no libdevice: the same operations in Python, which round alike
    def dmul(a, b):
        return np.float64(a) * np.float64(b)

    def dadd(a, b):
        return np.float64(a) + np.float64(b)

    def dsub(a, b):
        return np.float64(a) - np.float64(b)

    def ddiv(a, b):
        return np.float64(a) / np.float64(b)

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
    def dmul(a, b):
        return libdevice.dmul_rn(a, b)

    @device
    def dadd(a, b):
        return libdevice.dadd_rn(a, b)

    @device
    def dsub(a, b):  # libdevice has no dsub_rn: a - b is a + (-b), the negation exact
        return libdevice.dadd_rn(a, -b)

    @device
    def ddiv(a, b):
        return libdevice.ddiv_rn(a, b)

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
    """Around a kernel launch: under the simulator, a short thread switch interval (its block manager
    polls its threads, and at Python's default 5 ms a launch of a few hundred steps takes seconds)."""
    if not SIMULATED:
        yield
        return
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)
    try:
        yield
    finally:
        sys.setswitchinterval(interval)


# ---------------------------------------------------------------- the counter stream (engine.philox)


@device
def philox_block(c0, c1, c2, c3, k0, k1):
    """Philox4x64-10 at counter ``(c0, c1, c2, c3)``, key ``(k0, k1)``: `engine.philox.block`."""
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
    """``(k, accepted)``: `engine.philox.lemire`."""
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
    """Step ``s``'s contact among ``n``: `engine.philox.counter_pick` (all uint64)."""
    r = _U0
    while True:
        w0, w1, w2, w3 = philox_block(s >> _U2, r, _U0, _U0, k0, k1)
        k, accepted = lemire(_word(w0, w1, w2, w3, s & _U3), n)
        if accepted:
            return k
        r += _U1


# ---------------------------------------------------------------- contacts, collisions, margin


@functools.cache
def contact_reader(rows: bool):
    """``contact(pairs, ends, table, meta, k) -> (i, j, a, b)`` (int64): from the row pattern
    (`engine.rows.decode`; ``table`` its packed rows, ``meta = [per_row, rows, cols]`` int64 and
    ``meta_f = [inverse]``) when ``rows``, else from the tables ``pairs, ends (E, 2)``."""
    if rows:
        @device
        def contact(pairs, ends, table, meta, inverse, k):
            per_row, n_rows, cols = meta[0], meta[1], meta[2]
            r = np.int64(dmul(np.float64(k), inverse))
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


@functools.cache
def collider(rule: int, dim: int, flat: bool):
    """``collide(v, units, masses, params, i, j, a, b, write) -> (hit, w)``: the closing speed ``w`` of
    contact ``(i, j, a, b)`` and, if it collides under ``rule``, the collision (written when ``write``);
    ``hit`` when a velocity component changed (would change). The CPU's ``closing_speed`` then the
    rule's closing form, operation by operation."""
    D, FLAT, RULE = dim, flat, rule

    @device
    def t_j(units, a, b, k):
        return -units[a, k] if FLAT else units[b, k]

    @device
    def collide(v, units, masses, params, i, j, a, b, write):
        w = dadd(dmul(v[i, 0], units[a, 0]), dmul(v[j, 0], t_j(units, a, b, 0)))
        for k in range(1, D):
            w = dadd(w, dadd(dmul(v[i, k], units[a, k]), dmul(v[j, k], t_j(units, a, b, k))))
        factor, tau = params[0], params[1]
        if w <= tau:
            return False, w
        if RULE == ELASTIC:
            ci, cj = w, w
        elif RULE == EQUAL:
            ci = dmul(w, factor)
            cj = ci
        else:
            s = ddiv(dmul(factor, w), dadd(masses[i], masses[j]))
            ci, cj = dmul(s, masses[j]), dmul(s, masses[i])
        changed = False
        for k in range(D):
            new_i = dsub(v[i, k], dmul(ci, units[a, k]))
            new_j = dsub(v[j, k], dmul(cj, t_j(units, a, b, k)))
            changed |= (new_i != v[i, k]) | (new_j != v[j, k])
            if write:
                v[i, k] = new_i
                v[j, k] = new_j
        return changed, w

    return collide


@device
def track(hit, w, tau, smallest, largest, near_hits, near_rest):
    """`engine.margin.track`: one pick's closing speed folded into the running margin."""
    if hit:
        smallest = min(smallest, w)
        if w <= dmul(NEAR, tau):
            near_hits += 1.0
    elif w > 0.0:
        largest = max(largest, w)
        if dmul(w, NEAR) > tau:
            near_rest += 1.0
    return smallest, largest, near_hits, near_rest


INF = math.inf
