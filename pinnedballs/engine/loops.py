"""The compiled loops (numba).

`chain_kernel(collide, pick, dim, flat)` builds the hot loops for a collision
rule and a scheduler: pick a contact, try to collide it, count. The
rule's ``collide`` and the scheduler's ``pick`` are compiled into the loop
(inlined, not called through pointers); each combination is built once per
process and cached on disk (`jitcache`), so later processes load it.
"""

from __future__ import annotations

import functools
from typing import Callable, NamedTuple

import numpy as np
from numba import njit

from .chain import COLLISIONS, LIVE, STEPS
from .intrinsics import fixed_width, prefetch
from .jitcache import jit_cached_if_possible
from .random import load, store

__all__ = ["chain_kernel", "contact_kernels", "fixed_rows", "live_kernel", "Loops", "LOOKAHEAD_BYTES"]

#: picks drawn ahead, and how far ahead the velocity rows are fetched, in the lookahead loop
LOOKAHEAD, HALFWAY = 8, 4
_RING = 16  # ring buffer of drawn picks: a power of two > LOOKAHEAD

#: above this many bytes of tables and velocities the loop prefetches (they no longer fit in cache)
LOOKAHEAD_BYTES = 4 << 20

_FEW = 1 << 32  #: at most this many contacts: a bounded pick needs no wide path


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
        or, when ``track``, right after the collision that leaves no live contact;
    live_flags(v, pairs, ends, units, masses, params, flags) -> count
        sets ``flags[k] = 1`` where picking contact ``k`` would change velocities (it is
        *live*: approaching, and not by a rounding remnant) and counts them.

    Shapes: v ``(n_balls, dim)``; pairs, ends ``(E, 2)``; units ``(K, dim)``; rng_words
    ``(4,) uint64``; counters ``(3,) int64`` totals ``[steps, collisions, live contacts]``,
    the last exact only when ``track``, kept with ``flags (E,) uint8`` and the incidence
    ``ptr, inc`` (see `incidence`). The loops return the number of steps taken.
    """

    steps: Callable
    steps_prefetched: Callable
    limited: Callable
    live_flags: Callable


@functools.cache
def fixed_rows(dim: int) -> Callable:
    """``shaped(v, pairs, ends, units) -> (v, pairs, ends, units)``: the same arrays (views,
    same memory) with their row lengths ``dim`` and 2 as compile-time constants, so the loop
    finds a row with a shift or ``lea`` instead of a multiply by a shape held in memory."""
    D = dim

    @njit(inline="always")
    def shaped(v, pairs, ends, units):
        if v.shape[1] != D or units.shape[1] != D or pairs.shape[1] != 2 or ends.shape[1] != 2:
            raise ValueError("the loop's tables do not have the row lengths it was built for")
        return fixed_width(v, D), fixed_width(pairs, 2), fixed_width(ends, 2), fixed_width(units, D)

    return shaped


@functools.cache
def contact_kernels(collide: Callable, dim: int, flat: bool) -> tuple[Callable, Callable]:
    """``(attempt, refresh)``: the inlined building blocks of every loop for one rule.

    attempt(v, pairs, ends, units, masses, params, k, write) -> bool
        try contact ``k`` (`pinnedballs.rules`); writes only if ``write``;
    refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, ball) -> int
        re-test the contacts of ``ball``, update ``flags``, return the change in live ones.
    """
    D, FLAT = dim, flat  # constants of the compiled loops: component loops unroll

    @njit(inline="always")
    def attempt(v, pairs, ends, units, masses, params, k, write):
        return collide(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], masses, params, D, FLAT, write)

    @njit(inline="always")
    def refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, ball):
        """Re-test the contacts of ``ball``; return the change in the number of live ones."""
        delta = 0
        for m in range(ptr[ball], ptr[ball + 1]):
            c = inc[m]
            live = 1 if attempt(v, pairs, ends, units, masses, params, c, False) else 0
            delta += live - np.int64(flags[c])  # int64: uint8 would wrap without the JIT
            flags[c] = live
        return delta

    return attempt, refresh


@functools.cache
def live_kernel(collide: Callable, dim: int, flat: bool) -> Callable:
    """``live_flags(v, pairs, ends, units, masses, params, flags) -> count`` for one rule (see `Loops`)."""
    attempt, _ = contact_kernels(collide, dim, flat)

    @jit_cached_if_possible
    def live_flags(v, pairs, ends, units, masses, params, flags):
        count = 0
        for k in range(pairs.shape[0]):
            live = 1 if attempt(v, pairs, ends, units, masses, params, k, False) else 0
            flags[k] = live
            count += live
        return count

    return live_flags


@functools.cache
def chain_kernel(collide: Callable, pick: Callable, dim: int, flat: bool) -> Loops:
    """The compiled loops for one rule's ``collide``, one scheduler's ``pick``, ``dim`` and
    ``flat`` (every ``t_j == -t_i``, so the loops read one unit vector per contact)."""
    attempt, refresh = contact_kernels(collide, dim, flat)
    live_flags = live_kernel(collide, dim, flat)
    shaped = fixed_rows(dim)

    @njit(inline="always")
    def run_steps(v, pairs, ends, units, masses, params, sched_state, rng, n, max_steps):
        made = 0
        for _ in range(max_steps):
            k, rng = pick(sched_state, rng, n)
            if attempt(v, pairs, ends, units, masses, params, k, True):
                made += 1
        return made, rng

    @jit_cached_if_possible
    def steps(v, pairs, ends, units, masses, params, sched_state, rng_words, counters, max_steps):
        v, pairs, ends, units = shaped(v, pairs, ends, units)
        n, rng = pairs.shape[0], load(rng_words)
        if n <= _FEW:  # the same loop; knowing n's bound lets the compiler drop a test per pick
            made, rng = run_steps(v, pairs, ends, units, masses, params, sched_state, rng, n, max_steps)
        else:
            made, rng = run_steps(v, pairs, ends, units, masses, params, sched_state, rng, n, max_steps)
        store(rng_words, rng)
        counters[STEPS] += max_steps
        counters[COLLISIONS] += made
        return max_steps

    @jit_cached_if_possible
    def steps_prefetched(v, pairs, ends, units, masses, params, sched_state, rng_words, counters, max_steps):
        # Every pick drawn is used before returning, so the scheduler and random
        # state left behind are those of `steps`, bit for bit.
        v, pairs, ends, units = shaped(v, pairs, ends, units)
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
            made += attempt(v, pairs, ends, units, masses, params, ring[t % _RING], True)
        store(rng_words, rng)
        counters[STEPS] += max_steps
        counters[COLLISIONS] += made
        return max_steps

    @jit_cached_if_possible
    def limited(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
                max_steps, max_collisions, track, ptr, inc, flags):
        v, pairs, ends, units = shaped(v, pairs, ends, units)
        n, steps, rng = pairs.shape[0], 0, load(rng_words)
        collisions, live = counters[COLLISIONS], counters[LIVE]
        while steps < max_steps and collisions < max_collisions and not (track and live == 0):
            k, rng = pick(sched_state, rng, n)
            steps += 1
            if attempt(v, pairs, ends, units, masses, params, k, True):
                collisions += 1
                if track:
                    live += refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, pairs[k, 0])
                    live += refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, pairs[k, 1])
        store(rng_words, rng)
        counters[STEPS] += steps
        counters[COLLISIONS], counters[LIVE] = collisions, live
        return steps

    return Loops(steps, steps_prefetched, limited, live_flags)
