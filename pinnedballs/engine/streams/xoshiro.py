"""The simulation's random stream: xoshiro256** inside the compiled loop.

A simulation owns one stream, a ``(4,) uint64`` state array seeded from
``numpy.random.SeedSequence(seed)``. The state is plain data, so a checkpoint
saves it and a resumed run continues the same stream bit for bit. Ensembles
seed replica ``k`` with ``SeedSequence(seed).spawn(N)[k]``.

Bounded integers use Lemire's unbiased multiply-and-reject method.
"""

from __future__ import annotations

import numpy as np

from ...util import checks
from ..jit.cache import njit_cached

__all__ = ["seed_state", "load", "store", "next_uint64", "bounded", "random_float"]

_U32 = np.uint64(0xFFFFFFFF)
_2_32 = 1 << 32


def seed_state(seed: int | np.random.SeedSequence | None) -> np.ndarray:
    """A fresh ``(4,) uint64`` xoshiro256** state from an int, a SeedSequence or None."""
    if seed is None:
        seq = np.random.SeedSequence()
    else:
        seed = checks.seed("seed", seed)
        seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    state = seq.generate_state(4, dtype=np.uint64)
    if not state.any():  # the one state xoshiro cannot leave
        state[0] = np.uint64(0x9E3779B97F4A7C15)
    return state


@njit_cached(inline="always")
def _rotl(x, k):
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@njit_cached(inline="always")
def load(words):
    """The ``(4,) uint64`` state array as the 4-tuple the compiled code threads through."""
    return (words[0], words[1], words[2], words[3])


@njit_cached(inline="always")
def store(words, s):
    """Write the 4-tuple ``s`` back into the ``(4,) uint64`` state array."""
    words[0], words[1], words[2], words[3] = s


@njit_cached(inline="always")
def next_uint64(s):
    """``(bits, s')``: the next 64 random bits and the advanced 4-tuple state.

    The state is a tuple rather than an array so that it stays in registers in the hot loop.
    """
    s0, s1, s2, s3 = s
    result = _rotl(s1 * np.uint64(5), 7) * np.uint64(9)
    t = s1 << np.uint64(17)
    s2 ^= s0
    s3 ^= s1
    s1 ^= s2
    s0 ^= s3
    s2 ^= t
    s3 = _rotl(s3, 45)
    return result, (s0, s1, s2, s3)


@njit_cached(inline="always")
def bounded(s, n):
    """``(k, s')``: ``k`` uniform in ``[0, n)`` as uint64, without bias (Lemire 2019); ``1 <= n``."""
    n64 = np.uint64(n)
    if n64 <= np.uint64(_2_32):
        x, s = next_uint64(s)
        m = (x >> np.uint64(32)) * n64
        low = m & _U32
        if low < n64:
            threshold = (np.uint64(_2_32) - n64) % n64
            while low < threshold:
                x, s = next_uint64(s)
                m = (x >> np.uint64(32)) * n64
                low = m & _U32
        return m >> np.uint64(32), s
    # more than 2**32 choices: mask and reject
    mask = np.uint64(1)
    while mask < n64 - np.uint64(1):
        mask = (mask << np.uint64(1)) | np.uint64(1)
    x, s = next_uint64(s)
    x &= mask
    while x >= n64:
        x, s = next_uint64(s)
        x &= mask
    return x, s


@njit_cached(inline="always")
def random_float(s):
    """``(u, s')``: ``u`` uniform in ``[0, 1)`` with 53 random bits."""
    x, s = next_uint64(s)
    return np.float64(x >> np.uint64(11)) * (1.0 / 9007199254740992.0), s
