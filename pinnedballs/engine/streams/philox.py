"""The counter stream: Philox4x64-10, so that the pick of step ``s`` is a function of ``(seed, s)`` alone.

`UniformRandomPair(stream="counter")` draws its picks here instead of from xoshiro256**
(`engine.streams.xoshiro`). Philox4x64-10 (Salmon, Moraes, Dror, Shaw, *Parallel random numbers: as easy
as 1, 2, 3*, SC'11) is a keyed bijection of a 256-bit counter: `block` maps a counter
``(c0, c1, c2, c3)`` and a key ``(k0, k1)`` to four 64-bit words, exactly as numpy's
`numpy.random.Philox` does (numpy's generator increments its counter before each block, so
``Philox(key=(k0, k1), counter=2**256 - 1).random_raw()`` yields word ``s`` of this stream as its
``s``-th word: the tests check it).

**The stream.** Word ``s`` is word ``s % 4`` of the block at counter ``(s // 4, 0, 0, 0)``; step ``s``
(0-based: the picks made before it) turns word ``s`` into a contact with Lemire's multiply-and-reject
on 64 bits (`counter_pick`, unbiased for any number of contacts). In the rare case the word is
rejected (probability below ``n / 2^64``), the step draws word ``s % 4`` of the block at counter
``(s // 4, r, 0, 0)``, ``r = 1, 2, ...``, until one is accepted: still a function of ``(key, s)``,
so any thread, core or GPU computes any step's pick, and a batch of steps can be cut anywhere.

**The state.** A simulation's stream is its ``(4,) uint64`` words ``(k0, k1, s, 0)``: the key
(the first two words xoshiro256** would have been seeded with, `random.seed_state`) and the number
of picks drawn. A checkpoint saves them as it saves xoshiro's state, and a resumed run goes on with
the same picks.

`mulhilo` is the full 64x64 -> 128-bit product (one instruction through LLVM's ``i128``); without the
JIT it is Python's integers. The GPU engine (`engine.gpu`) has its own twin of these functions.
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import config, types
from numba.extending import intrinsic

from ..jit.cache import njit_cached

__all__ = ["M0", "M1", "W0", "W1", "ROUNDS", "mulhilo", "block", "counter_word", "lemire", "counter_pick",
           "pick_counter", "select_counter", "CACHE_WORDS", "counter_stream", "stream_words", "counter_picks",
           "CounterPicks"]

#: the multipliers and the key increments (Weyl constants) of Philox4x64
M0, M1 = 0xD2E7470EE14C6C93, 0xCA5A826395121157
W0, W1 = 0x9E3779B97F4A7C15, 0xBB67AE8584CAA73B
ROUNDS = 10

_M0, _M1, _W0, _W1 = np.uint64(M0), np.uint64(M1), np.uint64(W0), np.uint64(W1)
_MASK = (1 << 64) - 1


@intrinsic
def _mulhilo_intrinsic(typingctx, a, b):
    """``(hi, lo)``: the 128-bit product of two uint64, through LLVM's ``i128`` multiply."""
    if not (isinstance(a, types.Integer) and isinstance(b, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        i64, i128 = ir.IntType(64), ir.IntType(128)
        x = builder.zext(context.cast(builder, args[0], signature.args[0], types.uint64), i128)
        y = builder.zext(context.cast(builder, args[1], signature.args[1], types.uint64), i128)
        p = builder.mul(x, y)
        hi = builder.trunc(builder.lshr(p, i128(64)), i64)
        lo = builder.trunc(p, i64)
        return context.make_tuple(builder, signature.return_type, (hi, lo))

    return types.UniTuple(types.uint64, 2)(a, b), codegen


def _mulhilo_python(a, b):
    """Without the JIT: Python's integers."""
    p = int(a) * int(b)
    return np.uint64(p >> 64), np.uint64(p & _MASK)


#: ``mulhilo(a, b) -> (hi, lo)``: the high and low 64 bits of ``a * b`` (uint64)
mulhilo = _mulhilo_python if config.DISABLE_JIT else _mulhilo_intrinsic


@njit_cached(inline="always")
def _add(a, b):
    """``a + b`` modulo 2^64."""
    return np.uint64(a) + np.uint64(b)


@njit_cached(inline="always")
def block(c0, c1, c2, c3, k0, k1):
    """The four words of Philox4x64-10 at counter ``(c0, c1, c2, c3)`` with key ``(k0, k1)`` (uint64)."""
    for r in range(ROUNDS):
        if r > 0:
            k0, k1 = _add(k0, _W0), _add(k1, _W1)
        hi0, lo0 = mulhilo(_M0, c0)
        hi1, lo1 = mulhilo(_M1, c2)
        c0, c1, c2, c3 = hi1 ^ c1 ^ k0, lo1, hi0 ^ c3 ^ k1, lo0
    return c0, c1, c2, c3


@njit_cached(inline="always")
def counter_word(k0, k1, s, r):
    """Word ``s % 4`` of the block at counter ``(s // 4, r, 0, 0)``: the ``r``-th try of step ``s``."""
    zero = np.uint64(0)
    w0, w1, w2, w3 = block(np.uint64(s) >> np.uint64(2), np.uint64(r), zero, zero, k0, k1)
    q = np.uint64(s) & np.uint64(3)
    if q == np.uint64(0):
        return w0
    if q == np.uint64(1):
        return w1
    return w2 if q == np.uint64(2) else w3


@njit_cached(inline="always")
def lemire(x, n):
    """``(k, accepted)``: the contact word ``x`` gives among ``n`` (Lemire's 64-bit multiply-and-reject);
    a rejected word (``accepted`` False) must be replaced, else the law is not uniform."""
    n = np.uint64(n)
    hi, lo = mulhilo(x, n)
    if lo < n:
        if lo < (np.uint64(0) - n) % n:  # 2^64 mod n
            return hi, False
    return hi, True


@njit_cached(inline="always")
def counter_pick(k0, k1, s, n):
    """Step ``s``'s contact among ``n`` (uint64), a function of the key and ``s`` alone (module docstring)."""
    r = np.uint64(0)
    while True:
        k, accepted = lemire(counter_word(k0, k1, s, r), n)
        if accepted:
            return k
        r += np.uint64(1)


@njit_cached(inline="always")
def pick_counter(state, rng, n_contacts):
    """`UniformRandomPair(stream="counter")`'s pick: ``rng = (k0, k1, s, 0)``, the key and the picks drawn."""
    k0, k1, s, spare = rng
    return counter_pick(k0, k1, s, n_contacts), (k0, k1, s + np.uint64(1), spare)


#: the length of a counter selector's ``aux``: the key and block it last computed, and that block's words
CACHE_WORDS = 7


@njit_cached(inline="always")
def select_counter(state, aux, rng, n_contacts, left):
    """The counter stream as an engine selector (`engine.sequential.loops.Selector`): ``pick_counter``'s pick, the
    Philox block computed once for its four steps and kept in ``aux (CACHE_WORDS,) uint64`` as
    ``[k0, k1, block + 1, w0, w1, w2, w3]`` (a pure function of the key and the block: rewinding or
    restoring a state leaves it right)."""
    k0, k1, s, spare = rng
    q = s >> np.uint64(2)
    if aux[0] != k0 or aux[1] != k1 or aux[2] != q + np.uint64(1):
        zero = np.uint64(0)
        aux[3], aux[4], aux[5], aux[6] = block(q, zero, zero, zero, k0, k1)
        aux[0], aux[1], aux[2] = k0, k1, q + np.uint64(1)
    k, accepted = lemire(aux[3 + (s & np.uint64(3))], n_contacts)
    if not accepted:
        k = counter_pick(k0, k1, s, n_contacts)
    return k, 1, (k0, k1, s + np.uint64(1), spare)


def counter_stream(words: np.ndarray) -> np.ndarray:
    """``(4,) uint64`` counter-stream words ``(k0, k1, 0, 0)`` from a seeded xoshiro state ``words``
    (`random.seed_state`): its first two words are the key, no pick drawn yet."""
    out = np.zeros(4, dtype=np.uint64)
    out[:2] = words[:2]
    if not out.any():  # a key of zeros would make the state look empty (2^-128)
        out[0] = _W0
    return out


def stream_words(key: tuple[int, int], start: int, count: int) -> np.ndarray:
    """``(count,) uint64`` words ``start .. start + count - 1`` of the stream with ``key``, from numpy's own
    `numpy.random.Philox` (what the tests hold `block` to)."""
    first = start // 4
    g = np.random.Philox(key=np.array([int(key[0]), int(key[1])], dtype=np.uint64), counter=(first - 1) % 2**256)
    words = g.random_raw(4 * ((start + count + 3) // 4 - first))
    return words[start - 4 * first:start - 4 * first + count]


@njit_cached
def counter_picks(k0, k1, s0, n_contacts, out):
    """``out[t]``: the pick of step ``s0 + t`` among ``n_contacts`` (`counter_pick`; all uint64 but ``out``, int64)."""
    n = np.uint64(n_contacts)
    for t in range(out.shape[0]):
        out[t] = counter_pick(k0, k1, s0 + np.uint64(t), n)


class CounterPicks:
    """The counter stream's picks of ``count`` steps from ``s0`` (key ``k0, k1``, among ``n_contacts``), drawn where
    they are tried: a GPU draws them itself (`pinnedballs.engine.gpu.certified`); `host` draws them here."""

    def __init__(self, k0, k1, s0: int, count: int, n_contacts: int):
        self.key, self.s0, self.count, self.n_contacts = (np.uint64(k0), np.uint64(k1)), int(s0), int(count), n_contacts

    def __len__(self) -> int:
        return self.count

    def host(self) -> np.ndarray:
        """``(count,) int64``: the picks, drawn on the CPU."""
        out = np.empty(self.count, dtype=np.int64)
        counter_picks(self.key[0], self.key[1], np.uint64(self.s0), self.n_contacts, out)
        return out
