"""`RejectionFree`: the paper's chain without its rejected picks (the n-fold way).

Bortz, Kalos and Lebowitz, J. Comput. Phys. 17 (1975). With ``L`` live contacts
of ``M``, the paper's scheduler picks ``G`` contacts up to and including the next
live one, ``G`` geometric with ``p = L / M``, and that live one is uniform among
the ``L`` and independent of ``G``. So the loop draws ``G``, adds it to the steps
and collides a uniformly chosen live contact: ``steps``, ``collisions`` and the
velocities have the joint law of `UniformRandomPair`'s (not its bits).

**The draw.** ``G = 1 + floor(ln U / ln(1 - p))`` with ``U = 1 - u`` in ``(0, 1]``
and ``u`` the stream's 53-bit uniform (`engine.random.random_float`): then
``P(G > g) = P(U <= (1 - p)^g) = (1 - p)^g`` exactly up to the 2^-53 grid of
``U``. ``ln(1 - p)`` is ``log1p(-p)``, accurate for tiny ``p``. ``p = 1`` gives
``G = 1`` without a draw; ``L = 0`` never collides (the paper's chain would pick
forever). ``G`` is at most ``1 + 37 / p`` (about ``37 M``); it becomes an integer
capped at 2^62, far beyond any ``M`` numba can index, so it never overflows.

**A run ends at exactly ``max_steps``.** A ``G`` beyond the steps left ends the
run there without that collision and keeps the rest, ``G - left``, as the picks
still to come before the next live one. Given ``G > left`` that rest is again
geometric with the same ``p`` (the law is memoryless) and the live set has not
changed, so keeping it gives the same law as drawing afresh, and it makes a run
split into calls (chunks, checkpoints, resume) bit-identical to one call.

**The live set** is an array ``live[:L]`` plus a position map ``pos (M,) int32``
(``-1``: not live). After a collision only the contacts of its two balls are
re-tested: O(degree), a swap with the last entry to remove.

**The checkpoint** is the live array in its current order and the picks still to
come, ``state = [L, rest, live[0], ..., live[L-1], -1, ...]`` (``(M + 2,) int64``;
``rest = 0``: draw afresh). The set follows from
the velocities, but its order follows from the history of swaps, and the pick
``live[r]`` depends on that order: a set rebuilt in contact order would continue
the same law but not the same bits. ``state[0] = -1`` (a fresh run) means
"build from the velocities, in contact order" (and then ``rest = 0``). The position map is rebuilt from
the array at each call (O(M), like the live flags).
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np
from numba import njit

from ..engine.chain import COLLISIONS, LIVE, STEPS, Chain, LiveSet
from ..engine.errors import FieldError
from ..engine.jitcache import jit_cached_if_possible
from ..engine.loops import contact_kernels, fixed_rows
from ..engine.random import bounded, load, random_float, store
from .base import Scheduler

__all__ = ["RejectionFree", "rejection_free_kernel", "picks_until_live"]

_CAP = float(2**62)  #: picks beyond this are as good as never


@njit(cache=True, inline="always")
def picks_until_live(rng, n_live, n_contacts):
    """``(G, rng)``: the paper's picks up to and including the next live one, as a float64
    (an integer >= 1); geometric with ``p = n_live / n_contacts``, ``1 <= n_live <= n_contacts``."""
    if n_live == n_contacts:
        return 1.0, rng
    return _picks(rng, np.log1p(-(n_live / n_contacts)))


@njit(cache=True, inline="always")
def _picks(rng, log_q):
    """``(G, rng)``: ``1 + floor(ln(1 - u) / log_q)``, with ``log_q = ln(1 - p) < 0``."""
    u, rng = random_float(rng)
    return 1.0 + np.floor(np.log(1.0 - u) / log_q), rng


@functools.cache
def rejection_free_kernel(collide: Callable, dim: int, flat: bool) -> Callable:
    """The compiled loop for one rule's ``collide``, ``dim`` and ``flat``:

    run(v, pairs, ends, units, masses, params, state, rng_words, counters,
        max_steps, max_collisions, track, ptr, inc, flags) -> steps taken

    ``state (M + 2,) int64`` as in the module docstring; ``flags (M,) uint8`` the live
    flags of ``v`` and ``counters[LIVE]`` their count (from the `Simulation`): the array is
    built from them when ``state`` does not hold exactly that set (a fresh run, or
    velocities replaced), and the loop keeps them up to date.
    """
    attempt, _ = contact_kernels(collide, dim, flat)
    shaped = fixed_rows(dim)

    @njit(inline="always")
    def update(v, pairs, ends, units, masses, params, ptr, inc, flags, live, pos, n_live, ball, skip):
        """Re-test the contacts of ``ball`` but ``skip``; add or remove them from ``live[:n_live]``
        (``flags``, small enough to stay in cache, says which are in; ``pos`` is read only on a
        change); the new count."""
        for m in range(ptr[ball], ptr[ball + 1]):
            c = inc[m]
            if c == skip:
                continue
            now = 1 if attempt(v, pairs, ends, units, masses, params, c, False) else 0
            if now == flags[c]:  # no change: the common case
                continue
            flags[c] = now
            if now:
                live[n_live] = c
                pos[c] = n_live
                n_live += 1
            else:
                at = pos[c]
                n_live -= 1
                last = live[n_live]
                live[at] = last
                pos[last] = at
                live[n_live] = -1
                pos[c] = -1
        return n_live

    @njit(inline="always")
    def positions(state, counters, flags, pos):
        """Fill ``pos`` from ``state``'s live array, or rebuild both from ``flags``; the live count."""
        live, n_live = state[2:], state[0]
        ok = n_live == counters[LIVE]
        if ok:
            for m in range(n_live):
                c = live[m]
                if flags[c] == 0 or pos[c] >= 0:
                    ok = False
                    break
                pos[c] = m
        if not ok:
            pos[:] = -1
            live[:] = -1
            n_live = 0
            state[1] = 0  # picks drawn for another live set
            for k in range(flags.shape[0]):
                if flags[k] != 0:
                    live[n_live] = k
                    pos[k] = n_live
                    n_live += 1
        return n_live

    @jit_cached_if_possible
    def run(v, pairs, ends, units, masses, params, state, rng_words, counters,
            max_steps, max_collisions, track, ptr, inc, flags):
        v, pairs, ends, units = shaped(v, pairs, ends, units)
        n = pairs.shape[0]
        pos = np.full(n, -1, dtype=np.int32)
        live = state[2:]
        n_live = positions(state, counters, flags, pos)
        rest = state[1]
        log_q = np.zeros(n + 1)  # log1p(-L / n), computed once per L seen (0.0: not yet)
        steps, collisions, rng = 0, counters[COLLISIONS], load(rng_words)
        while steps < max_steps and collisions < max_collisions and not (track and n_live == 0):
            left = max_steps - steps
            if n_live == 0:  # frozen: the paper's chain picks on without ever colliding
                steps = max_steps
                break
            if rest > 0:  # picks left over from the last call
                g, rest = rest, 0
            else:
                if n_live == n:
                    x = 1.0
                else:
                    if log_q[n_live] == 0.0:
                        log_q[n_live] = np.log1p(-(n_live / n))
                    x, rng = _picks(rng, log_q[n_live])  # as picks_until_live, bit for bit
                g = np.int64(min(x, _CAP))
            if g > left:  # the next live pick lies beyond the run
                rest = g - left
                steps = max_steps
                break
            steps += g
            r, rng = bounded(rng, n_live)
            k = live[np.int64(r)]
            if attempt(v, pairs, ends, units, masses, params, k, True):  # live: always true
                collisions += 1
            # contact k is re-tested once, with ball i's: ball j's pass would find the same
            n_live = update(v, pairs, ends, units, masses, params, ptr, inc, flags, live, pos, n_live, pairs[k, 0], -1)
            n_live = update(v, pairs, ends, units, masses, params, ptr, inc, flags, live, pos, n_live, pairs[k, 1], k)
        store(rng_words, rng)
        state[0], state[1] = n_live, rest
        counters[STEPS] += steps
        counters[COLLISIONS], counters[LIVE] = collisions, n_live
        return steps

    return run


class RejectionFree(Scheduler):
    """The paper's chain without its rejected picks: each step of the loop jumps over the
    picks of non-live contacts (a geometric number, counted in ``steps``) and collides a live
    contact chosen uniformly. Same joint law of steps, collisions and velocities as
    `UniformRandomPair`; far faster when few contacts are live (a half-plane near its freeze)."""

    def loops(self, collide: Callable, geometry) -> Callable:
        return rejection_free_kernel(collide, geometry.dim, geometry.contacts.flat)

    def needs_live(self, track: bool) -> bool:
        return True

    def advance(self, loops, chain: Chain, live: LiveSet | None, state, rng, counters,
                max_steps: int, max_collisions: int, track: bool) -> int:
        return loops(*chain, state, rng, counters, max_steps, max_collisions, track, *live)

    def to_spec(self) -> dict:
        return {"kind": "rejection_free"}

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """``[-1, 0, -1, -1, ...]`` ``(n_contacts + 2,)``: build the live array from the velocities."""
        state = np.full(n_contacts + 2, -1, dtype=np.int64)
        state[1] = 0
        return state

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        super().check_state(state, n_contacts)
        n_live = state[0]
        if not -1 <= n_live <= n_contacts:
            raise FieldError("scheduler_state", f"the number of live contacts must be in [-1, {n_contacts}], "
                             f"got {n_live}")
        if not 0 <= state[1] <= 2**62 or (n_live <= 0 and state[1] != 0):
            raise FieldError("scheduler_state", f"the picks still to come must be in [0, 2**62] (0 unless a "
                             f"contact is live), got {state[1]}")
        live, rest = state[2:2 + max(n_live, 0)], state[2 + max(n_live, 0):]
        if len(live) and (live.min() < 0 or live.max() >= n_contacts or len(np.unique(live)) != len(live)):
            raise FieldError("scheduler_state", f"the live contacts must be distinct indices in [0, {n_contacts})")
        if (rest != -1).any():
            raise FieldError("scheduler_state", "entries after the live contacts must be -1")

    def check_resume(self, state: np.ndarray, loops, flags: np.ndarray | None) -> None:
        n_live = state[0]
        if n_live >= 0 and not np.array_equal(np.sort(state[2:2 + n_live]), np.flatnonzero(flags)):
            raise FieldError("scheduler_state", f"its {n_live} live contacts are not those of the velocities "
                             f"({np.count_nonzero(flags)} live)")
