"""The compiled loop (numba) and its helpers for tracking frozen states.

`chain_kernel(collide, pick, dim, flat)` builds the hot loops for a collision
rule and a scheduler: pick a contact, try to collide it, count. The
rule's ``collide`` and the scheduler's ``pick`` are compiled into the loop
(inlined, not called through pointers); each combination is built once per
process and cached on disk (`pinnedballs.jitcache`), so later processes load it.
"""

from __future__ import annotations

import functools
from typing import Callable, NamedTuple

import numpy as np
from numba import njit

from .jitcache import jit_cached_if_possible
from .prefetch import prefetch
from .random import load, store
from .rules import closing_speed

__all__ = ["chain_kernel", "Loops", "approaching_flags", "incidence", "STEPS", "COLLISIONS", "APPROACHING",
           "NO_LIMIT"]

#: indices into the ``counters`` array shared by Python and the loop
STEPS, COLLISIONS, APPROACHING = 0, 1, 2

NO_LIMIT = np.iinfo(np.int64).max  #: "no limit" for max_steps or max_collisions

#: picks drawn ahead, and how far ahead the velocity rows are fetched, in the lookahead loop
LOOKAHEAD, HALFWAY = 8, 4
_RING = 16  # ring buffer of drawn picks: a power of two > LOOKAHEAD

#: above this many bytes of tables and velocities the loop prefetches (they no longer fit in cache)
LOOKAHEAD_BYTES = 4 << 20


@njit(cache=True)
def approaching_flags(v, pairs, ends, units, flags):
    """Set ``flags[k] = 1`` where contact ``k`` approaches; return how many do."""
    count = 0
    for k in range(pairs.shape[0]):
        w = closing_speed(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], v.shape[1], False)
        flags[k] = 1 if w > 0.0 else 0
        count += flags[k]
    return count


def incidence(pairs: np.ndarray, n_balls: int) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of each ball in CSR form: ``(ptr (n_balls+1,) int64, contacts (2E,) uint32)``."""
    balls = pairs.ravel()
    contacts = (np.argsort(balls, kind="stable") // 2).astype(np.uint32)
    ptr = np.zeros(n_balls + 1, dtype=np.int64)
    np.cumsum(np.bincount(balls.astype(np.intp), minlength=n_balls), out=ptr[1:])
    return ptr, contacts


@njit(cache=True, inline="always")
def _refresh(v, pairs, ends, units, ptr, inc, flags, ball, dim, flat):
    """Re-test the contacts of ``ball``; return the change in the number approaching."""
    delta = 0
    for m in range(ptr[ball], ptr[ball + 1]):
        c = inc[m]
        w = closing_speed(v, units, pairs[c, 0], pairs[c, 1], ends[c, 0], ends[c, 1], dim, flat)
        new = 1 if w > 0.0 else 0
        delta += new - flags[c]
        flags[c] = new
    return delta


class Loops(NamedTuple):
    """The compiled loops of one (rule, scheduler, dim, flat), each compiled on first use.

    steps(v, pairs, ends, units, masses, params, sched_state, rng_words, counters, max_steps)
        picks ``max_steps`` contacts;
    steps_prefetched(... same ...)
        the same, bit for bit, prefetching rows of picks drawn a few steps early (faster
        when the tables do not fit in cache);
    limited(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
            max_steps, max_collisions, track, ptr, inc, flags)
        stops after ``max_steps`` picks, at ``max_collisions`` in total (`NO_LIMIT`: none)
        or, when ``track``, right after the collision that leaves no contact approaching.

    Shapes: v ``(n_balls, dim)``; pairs, ends ``(E, 2)``; units ``(K, dim)``; rng_words
    ``(4,) uint64``; counters ``(3,) int64`` totals ``[steps, collisions, approaching]``,
    approaching exact only when ``track``, kept with ``flags (E,) uint8`` and the
    incidence ``ptr, inc`` (see `incidence`). Each returns the number of steps taken.
    """

    steps: Callable
    steps_prefetched: Callable
    limited: Callable


@functools.cache
def chain_kernel(collide: Callable, pick: Callable, dim: int, flat: bool) -> Loops:
    """The compiled loops for one rule's ``collide``, one scheduler's ``pick``, ``dim`` and
    ``flat`` (every ``t_j == -t_i``, so the loops read one unit vector per contact)."""
    D, FLAT = dim, flat  # constants of the compiled loops: component loops unroll

    @njit(inline="always")
    def attempt(v, pairs, ends, units, masses, params, k):
        return collide(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], masses, params, D, FLAT)

    @jit_cached_if_possible
    def steps(v, pairs, ends, units, masses, params, sched_state, rng_words, counters, max_steps):
        n, made, rng = pairs.shape[0], 0, load(rng_words)
        for _ in range(max_steps):
            k, rng = pick(sched_state, rng, n)
            made += attempt(v, pairs, ends, units, masses, params, k)
        store(rng_words, rng)
        counters[STEPS] += max_steps
        counters[COLLISIONS] += made
        return max_steps

    @jit_cached_if_possible
    def steps_prefetched(v, pairs, ends, units, masses, params, sched_state, rng_words, counters, max_steps):
        # Every pick drawn is used before returning, so the scheduler and random
        # state left behind are those of `steps`, bit for bit.
        n, made, rng = pairs.shape[0], 0, load(rng_words)
        ring = np.empty(_RING, dtype=np.uint64)
        for t in range(min(LOOKAHEAD, max_steps)):
            ring[t], rng = pick(sched_state, rng, n)
            prefetch(pairs, ring[t])
            prefetch(ends, ring[t])
        for t in range(max_steps):
            if t + LOOKAHEAD < max_steps:
                k, rng = pick(sched_state, rng, n)
                ring[(t + LOOKAHEAD) % _RING] = k
                prefetch(pairs, k)
                prefetch(ends, k)
            if t + HALFWAY < max_steps:
                k = ring[(t + HALFWAY) % _RING]
                prefetch(v, pairs[k, 0])
                prefetch(v, pairs[k, 1])
            made += attempt(v, pairs, ends, units, masses, params, ring[t % _RING])
        store(rng_words, rng)
        counters[STEPS] += max_steps
        counters[COLLISIONS] += made
        return max_steps

    @jit_cached_if_possible
    def limited(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
                max_steps, max_collisions, track, ptr, inc, flags):
        n, steps, rng = pairs.shape[0], 0, load(rng_words)
        collisions, approaching = counters[COLLISIONS], counters[APPROACHING]
        while steps < max_steps and collisions < max_collisions and not (track and approaching == 0):
            k, rng = pick(sched_state, rng, n)
            steps += 1
            if attempt(v, pairs, ends, units, masses, params, k):
                collisions += 1
                if track:
                    approaching += _refresh(v, pairs, ends, units, ptr, inc, flags, pairs[k, 0], D, FLAT)
                    approaching += _refresh(v, pairs, ends, units, ptr, inc, flags, pairs[k, 1], D, FLAT)
        store(rng_words, rng)
        counters[STEPS] += steps
        counters[COLLISIONS], counters[APPROACHING] = collisions, approaching
        return steps

    return Loops(steps, steps_prefetched, limited)
