"""The one loop template: the engine owns the loop, its stop conditions, its counters and freeze
detection; a scheduler supplies only its `Selector` ("which contact next"), a rule its ``collide``.

`loops(collide, selector, dim, flat)` builds, for one rule and one scheduler, the compiled loops
(`Loops`), each compiled on first use and cached on disk (`engine.jit.cache`): the rule's ``collide`` and
the selector's functions are inlined, and ``dim`` and ``flat`` are compile-time constants.

**The loops.** Every loop picks a contact (``select``), tries to collide it (``collide``) and counts:
a *step* is a pick, a *collision* a pick that changed velocities.

* ``limited`` takes at most ``max_steps`` steps, stops at a total of ``max_collisions`` and, with
  ``until_frozen``, right after the collision that leaves no live contact (plain steps are the same
  loop without the last two limits, so a rule's first ``run(steps=...)`` and first
  ``run_until_frozen`` share one compiled loop). ``limited_prefetched`` gives the same bits, drawing
  picks a few steps early and fetching their rows into cache (tables larger than the cache);
  ``limited_rows`` also reads each contact from the lattice's row pattern (`engine.rows`) instead of
  the ``(E, 2)`` tables, so a step touches only the two velocity rows. It tracks nothing per
  collision: it runs *chunks* of steps untracked, then asks `any_live` (a scan of the contacts that
  stops at the first live one), within the limits of `engine.harness`, compiled in: a chunk whose scan
  finds the system frozen ends at its last collision, the random stream and the scheduler's state
  restored to the start of the chunk and its picks replayed up to that collision.
  Where ``limited`` reads the tables (they fit in cache), for a rule written by its impulse and a selector
  of one step a pick, it runs its chunks in blocks of `BLOCK` steps, each one with a branch on every pick's
  collision or without one (`free_trial_kernel`), whichever its blocks have measured the cheaper on this CPU
  at the share of collisions of the block before (`engine.sequential.choice`: on a lattice in equilibrium
  about half the picks collide and a branch on them is mispredicted nearly as often, yet on some CPUs the
  branch still wins; where few picks collide, a half-plane near its freeze, it is right nearly always).
  ``tune`` keeps what it measured between calls. The same bits either way
  (`tests/engine/sequential/test_branch_free.py`).
* ``tracked`` keeps the live set up to date after every collision (``flags``, their count, and the
  selector told of every change): for a selector that picks among live contacts (`RejectionFree`).

**A selector** (`Selector`) is a few jitted functions and the arrays they use:
``select(state, aux, rng, n_contacts, left) -> (k, taken, rng)`` picks the next contact ``k`` and
says how many steps the pick takes (1 for the paper's picks; a selector that jumps over picks says
how many, at most ``left``, and returns ``k < 0`` when none falls within them); ``begin(state, aux,
flags)`` prepares ``aux`` from ``state`` at the start of each call (and after a rewind);
``changed(state, aux, c, live)`` hears that contact ``c`` became live or not (tracked loops only).
``state`` is the scheduler's ``int64`` array (checkpointed), ``aux`` anything else it needs (tables,
scratch), rebuilt from the geometry and ``state``. A scheduler that only picks gives
``pick(state, rng, n_contacts) -> (k, rng)`` and `pick_selector` wraps it.

Every loop also keeps the run's closing margin (`engine.margin`): ``margin (4,) float64`` is updated
with the closing speed of every pick it tries (a colliding loop computes it anyway: the same bits).

Shapes: v ``(n_balls, dim)``; pairs, ends ``(E, 2)``; units ``(K, dim)``; rng_words ``(4,) uint64``;
counters ``(4,) int64``, totals ``[steps, collisions, live, last]`` (live: the number of live contacts
after a tracked loop, 0 after a loop that found the system frozen, -1 when not known; last: the
steps counted right after the call's last collision, unchanged by a call that made none); flags
``(E,) uint8`` and the incidence ``ptr, inc`` (`chain.incidence`). Every loop returns the steps taken.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from ..chain import COLLISIONS, LAST, LIVE, STEPS
from ..closing import WRITE, branch_free_form, choose, closing_speed, compiled_form
from ..harness import limits_loop
from ..jit.cache import jit_cached_if_possible, njit_cached
from ..jit.intrinsics import prefetch, ticks
from ..margin import LARGEST, NEAR, NEAR_COLLISIONS, NEAR_REMNANTS, SMALLEST, track
from ..rows import decode
from ..selector import NO_AUX, Selector, no_begin, no_change, pick_selector  # the selector protocol, re-exported
from ..streams.xoshiro import load, store
from .choice import BLOCK, BRANCH_FREE_PERCENT, PREVIOUS, next_free  # the first two re-exported
from .start import fixed_rows, limited_prepare  # re-exported

__all__ = ["Selector", "Loops", "loops", "pick_selector", "selector_picks", "contact_kernels", "live_kernel",
           "free_trial_kernel", "fixed_rows", "limited_prepare", "LOOKAHEAD_BYTES", "FREEZE_CHUNK_MIN",
           "FREEZE_CHUNK_PER_CONTACT", "UNKNOWN", "NO_PATTERN", "BLOCK", "BRANCH_FREE_PERCENT", "NO_AUX", "no_begin",
           "no_change"]

#: picks drawn ahead, and how far ahead the velocity rows are fetched, in the prefetching loops
LOOKAHEAD, HALFWAY = 8, 4
#: picks drawn (and decoded, their velocity rows fetched) ahead in the row-pattern loop
ROWS_AHEAD = 16
_RING = 32  # ring buffer of drawn picks: a power of two > LOOKAHEAD, ROWS_AHEAD

#: the row pattern a loop that reads the tables is handed (`engine.rows`; never decoded)
NO_PATTERN = (np.zeros(1, dtype=np.int64), np.int64(1), np.int64(1), np.int64(1), 1.0)

#: above this many bytes of tables and velocities the loops prefetch (they no longer fit in cache), where the
#: CPU's L2 cache cannot be read, and where a run has not yet timed its loops (`engine.sequential.sizes`)
LOOKAHEAD_BYTES = 4 << 20

#: an untracked chunk is at least this many steps ...
FREEZE_CHUNK_MIN = 1 << 12
#: ... and this many per contact (chosen by measurement: benchmarks/bench_freeze.py)
FREEZE_CHUNK_PER_CONTACT = 4

#: ``counters[LIVE]`` when no loop counted the live contacts
UNKNOWN = -1


class Loops(NamedTuple):
    """The compiled loops of one (rule, selector, dim, flat); see the module docstring.

    limited, limited_prefetched, limited_rows(v, pairs, ends, units, masses, params, pattern, state, aux,
                                              rng_words, counters, margin, max_steps, max_collisions,
                                              until_frozen, chunk, saved, log, tune)
        ``pattern``: the row pattern (`engine.rows`; `NO_PATTERN` for the first two); ``chunk``: steps
        between scans for the freeze; ``saved``: scratch as long as ``state``; ``tune``: how the table
        loop chooses its blocks, and what it measured (`engine.sequential.choice.new_tune`; the others
        ignore it); plain steps are ``max_collisions = NO_LIMIT``, ``until_frozen = False``,
        ``chunk = max_steps``;
    tracked(v, pairs, ends, units, masses, params, state, aux, rng_words, counters, margin,
            max_steps, max_collisions, until_frozen, ptr, inc, flags, log)
        ``counters[LIVE]`` and ``flags`` must hold the live contacts of ``v`` on entry;
    limited_logged, limited_prefetched_logged, limited_rows_logged, tracked_logged(... the same ...)
        the same loops writing each collision to ``log (capacity, 2) int64`` as ``(step, contact)``
        (the step counted as ``counters[STEPS]`` counts it) and stopping when it is full; the others
        take an empty ``log``;
    picks(state, aux, rng_words, n_contacts, out) -> None
        the next ``len(out)`` picks into ``out`` (int64), advancing the stream and the state as a
        loop would: what a run in exact arithmetic follows.
    Each is compiled on first use.
    """

    limited: Callable
    limited_prefetched: Callable
    limited_rows: Callable
    tracked: Callable
    picks: Callable
    limited_logged: Callable
    limited_prefetched_logged: Callable
    limited_rows_logged: Callable
    tracked_logged: Callable


@njit_cached(inline="always")
def copy_into(dst, src):
    """``dst[:] = src`` for two arrays of one length, element by element: numba compiles a slice assignment
    with its shape-mismatch error, whose message formatting takes seconds to compile on a first run."""
    for q in range(src.shape[0]):
        dst[q] = src[q]


@functools.cache
def contact_kernels(collide: Callable, dim: int, flat: bool) -> tuple[Callable, Callable]:
    """``(attempt, refresh)``: the inlined building blocks of every loop for one rule.

    attempt(v, pairs, ends, units, masses, params, k, write) -> bool
        try contact ``k`` (`pinnedballs.rules`); writes only if ``write``;
    refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, ball, skip, changed, state, aux) -> int
        re-test the contacts of ``ball`` but ``skip``, update ``flags``, tell ``changed`` of each
        change; returns the change in the number of live contacts.

    Both call the rule's `compiled_form` (``collide`` is ``collide_at`` given its closing speed).
    """
    collide_at = compiled_form(collide, dim, flat)
    D, FLAT = dim, flat  # constants of the compiled loops: component loops unroll

    @njit(inline="always")
    def attempt(v, pairs, ends, units, masses, params, k, write):
        i, j, a, b = pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1]
        return collide_at(v, units, i, j, a, b, masses, params, np.bool_(write),
                          closing_speed(v, units, i, j, a, b, D, FLAT))

    @njit(inline="always")
    def refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, ball, skip, changed, state, aux):
        delta = 0
        for m in range(ptr[ball], ptr[ball + 1]):
            c = inc[m]
            if c == skip:
                continue
            live = 1 if attempt(v, pairs, ends, units, masses, params, c, False) else 0
            if live != flags[c]:  # int64 arithmetic: uint8 would wrap without the JIT
                flags[c] = live
                delta += 2 * live - 1
                changed(state, aux, c, live)
        return delta

    return attempt, refresh


@functools.cache
def trial_kernel(collide: Callable, dim: int, flat: bool) -> Callable:
    """``tried(v, units, masses, params, i, j, a, b, tau, m) -> (hit, m)``, inlined into the loops:
    collide the contact ``(i, j, a, b)`` if it approaches; ``m``, the running margin ``(smallest,
    largest, near_hits, near_rest)``, is returned updated beside it (`engine.margin`)."""
    collide_at = compiled_form(collide, dim, flat)
    D, FLAT = dim, flat

    @njit(inline="always")
    def tried(v, units, masses, params, i, j, a, b, tau, m):
        w = closing_speed(v, units, i, j, a, b, D, FLAT)
        hit = collide_at(v, units, i, j, a, b, masses, params, WRITE, w)
        return hit, track(hit, w, tau, m[0], m[1], m[2], m[3])

    return tried


@functools.cache
def free_trial_kernel(collide: Callable, dim: int, flat: bool) -> Callable | None:
    """``tried_free(v, units, masses, params, tau, i, j, a, b) -> (hit, w)``, inlined into the table loop:
    what `trial_kernel`'s ``tried`` does to ``v`` (``tau = params[-1]``), without a branch on the collision
    (`closing.branch_free_form`), and the closing speed ``w`` for the margin; None for a rule written whole
    (not by its impulse)."""
    collide_free = branch_free_form(collide, dim, flat)
    if collide_free is None:
        return None
    D, FLAT = dim, flat

    @njit(inline="always")
    def tried_free(v, units, masses, params, tau, i, j, a, b):
        w = closing_speed(v, units, i, j, a, b, D, FLAT)
        return collide_free(v, units, i, j, a, b, masses, params, tau, w), w

    return tried_free


@functools.cache
def live_kernel(collide: Callable, dim: int, flat: bool) -> tuple[Callable, Callable]:
    """``(live_flags, any_live)`` for one rule, compiled once and shared by every scheduler:

    live_flags(v, pairs, ends, units, masses, params, flags) -> count
        sets ``flags[k] = 1`` where picking contact ``k`` would collide (it is *live*) and counts them;
    any_live(v, pairs, ends, units, masses, params) -> bool
        whether any contact is live: a scan in contact order that stops at the first.
    """
    attempt, _ = contact_kernels(collide, dim, flat)
    shaped = fixed_rows(dim)

    @jit_cached_if_possible
    def live_flags(v, pairs, ends, units, masses, params, flags):
        count = 0
        for k in range(pairs.shape[0]):
            live = 1 if attempt(v, pairs, ends, units, masses, params, k, False) else 0
            flags[k] = live
            count += live
        return count

    @jit_cached_if_possible
    def any_live(v, pairs, ends, units, masses, params):
        v, pairs, ends, units = shaped(v, pairs, ends, units)
        for k in range(pairs.shape[0]):
            if attempt(v, pairs, ends, units, masses, params, k, False):
                return True
        return False

    return live_flags, any_live


@functools.cache
def selector_picks(select: Callable, begin: Callable) -> Callable:
    """``picks(state, aux, rng_words, n_contacts, out)``: the next ``len(out)`` picks of one selector
    into ``out`` (int64), the stream and the state advanced as a loop would advance them. Compiled
    once per selector, whatever the rule: a run in exact arithmetic draws its picks and rewinds
    its blocks with it (the compiled loops rewind with `selector_replay`, inlined)."""

    @jit_cached_if_possible
    def picks(state, aux, rng_words, n, out):
        rng = load(rng_words)
        begin(state, aux, np.empty(0, dtype=np.uint8))
        taken = 0
        while taken < out.shape[0]:
            k, g, rng = select(state, aux, rng, n, out.shape[0] - taken)
            out[taken] = k
            taken += g
        store(rng_words, rng)

    return picks


def selector_replay(select: Callable) -> Callable:
    """``replay(state, aux, rng, n_contacts, count) -> rng``: the next ``count`` picks of one selector
    drawn and dropped, inlined into a loop (a limited loop rewinding a chunk to its last collision),
    so that loop needs no separately compiled `selector_picks`."""

    @njit(inline="always")
    def replay(state, aux, rng, n, count):
        taken = 0
        while taken < count:
            _, g, rng = select(state, aux, rng, n, count - taken)
            taken += g
        return rng

    return replay


@functools.cache
def loops(collide: Callable, select: Callable, begin: Callable, changed: Callable, skips: bool, dim: int,
          flat: bool) -> Loops:
    """The compiled `Loops` for one rule's ``collide``, one selector's functions (see `Selector`),
    ``dim`` and ``flat`` (every ``t_j == -t_i``, so the loops read one unit vector per contact). How the
    table loop runs its blocks is chosen at run time, by its ``tune`` (`engine.sequential.choice`)."""
    attempt, refresh = contact_kernels(collide, dim, flat)
    _, any_live = live_kernel(collide, dim, flat)
    tried = trial_kernel(collide, dim, flat)
    tried_free = free_trial_kernel(collide, dim, flat)
    picks = selector_picks(select, begin)
    replay = selector_replay(select)
    shaped = fixed_rows(dim)
    SKIPS = skips
    #: the table loop may run blocks without a branch: a rule given by its impulse, one step a pick
    FREE = tried_free is not None and not skips

    # The chunks: each is the harness's ``advance(data, carry, count, left, taken, collisions)`` of one loop
    # (`make_limited` says ``data`` and ``carry``), written for it, so numba inlines one level less.

    def table_chunk(LOG):
        """Up to ``count`` steps, stopping right after the ``collisions_left``-th collision: ``(steps taken,
        collisions, step index of the last collision or -1, carry)``. With ``LOG``, collision ``c`` is written
        to ``log[c] = (step, contact)``, its step counted as ``counters[STEPS]`` counts it."""

        @njit(inline="always")
        def chunk(data, carry, count, collisions_left, before, collisions):
            v, pairs, ends, units, masses, params, pattern, state, aux, n, saved, log, base, first, tau, _ = data[:16]
            rng, m, at_last, free = carry
            log, base = log[collisions - first:], base + before
            taken, made, last = 0, 0, -1
            at_last = (m[1], m[3])  # the margin's remnant side as of the last collision (see `make_limited`)
            while taken < count:
                k, g, rng = select(state, aux, rng, n, count - taken)
                taken += g
                if SKIPS and k < 0:
                    break
                hit, m = tried(v, units, masses, params, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], tau, m)
                if hit:
                    if LOG:
                        log[made, 0], log[made, 1] = base + taken, k
                    made += 1
                    last = taken - 1
                    at_last = (m[1], m[3])
                    if made == collisions_left:
                        break
            return taken, made, last, (rng, m, at_last, free)

        return chunk

    @njit(inline="always")
    def chunk_blocks(data, carry, count, collisions_left, before, collisions):
        """`chunk` without a log for a selector of one step a pick, in blocks of `BLOCK` steps: a block tries
        its picks with ``tried`` (a branch on each collision) or with ``tried_free`` (no branch), as
        `choice.next_free` chose after the block before, from their costs timed on this CPU (``tune``). The same
        bits, counts and margin either way. ``free`` (in ``carry``): how the first block runs; the choice for
        the next comes back in it."""
        v, pairs, ends, units, masses, params, pattern, state, aux, n, saved, log, base, first, tau, _ = data[:16]
        tune = data[19]
        rng, m, at_last, free = carry
        taken, made, last = 0, 0, -1
        smallest, largest, near_hits, near_rest = m
        at_last = (largest, near_rest)  # the margin's remnant side as of the last collision ...
        settled = -1  # ... while last <= settled; after, the side is unchanged since the last collision
        near_up = np.nextafter(NEAR * tau, np.inf)  # w <= NEAR * tau exactly when w < near_up
        rule_tau = params[params.shape[0] - 1]  # read once: after each pick's writes to `v` it would be read again
        done = False
        tune[PREVIOUS] = 0.0  # no block before this chunk's first to compare it with (a scan ran between)
        clock = ticks()
        while taken < count and not done:
            size = min(BLOCK, count - taken)
            start = made
            if free:
                left = collisions_left - made  # one count where two would take two registers
                for t in range(taken, taken + size):
                    k, _, rng = select(state, aux, rng, n, count - t)
                    hit, w = tried_free(v, units, masses, params, rule_tau, pairs[k, 0], pairs[k, 1], ends[k, 0],
                                        ends[k, 1])
                    left -= np.int64(hit)
                    last = choose(hit, t, last)
                    smallest = choose(hit & (w < smallest), w, smallest)  # min(smallest, w) where hit
                    # the rest of `track`, rare: a collision with w <= NEAR * tau (w < near_up), or w > 0 set
                    # aside; one comparison (two are two branches, one of them on w > 0: mispredicted)
                    if choose(hit, near_up - w, w) > 0.0:
                        if hit:
                            near_hits += 1.0
                        else:
                            if last > settled:
                                at_last = (largest, near_rest)
                            settled = t
                            largest = max(largest, w)
                            if w * NEAR > tau:
                                near_rest += 1.0
                    if left == 0:
                        size, done = t + 1 - taken, True
                        break
                made = collisions_left - left
                if last > settled:
                    at_last = (largest, near_rest)
            else:
                for t in range(taken, taken + size):
                    k, _, rng = select(state, aux, rng, n, count - t)
                    hit, mt = tried(v, units, masses, params, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], tau,
                                    (smallest, largest, near_hits, near_rest))
                    smallest, largest, near_hits, near_rest = mt
                    if hit:
                        made += 1
                        last = t
                        at_last = (largest, near_rest)
                        if made == collisions_left:
                            size, done = t + 1 - taken, True
                            break
            settled = last
            taken += size
            now = ticks()
            free = next_free(tune, free, made - start, size, now - clock)
            clock = now
        return taken, made, last, (rng, (smallest, largest, near_hits, near_rest), at_last, free)

    def prefetched_chunk(LOG):
        """`table_chunk`'s, fetching ahead the rows of picks drawn `LOOKAHEAD` steps early (one step per pick).
        A chunk that stops early leaves the stream past picks it drew: the harness rewinds (``settle``)."""

        @njit(inline="always")
        def chunk(data, carry, count, collisions_left, before, collisions):
            v, pairs, ends, units, masses, params, pattern, state, aux, n, saved, log, base, first, tau, _ = data[:16]
            rng, m, at_last, free = carry
            log, base = log[collisions - first:], base + before
            made, last, taken = 0, -1, count
            at_last = (m[1], m[3])
            ring = np.empty(_RING, dtype=np.int64)
            for t in range(min(LOOKAHEAD, count)):
                k, _, rng = select(state, aux, rng, n, np.int64(1))
                ring[t] = k
                prefetch(pairs, k)
                prefetch(ends, k)
            for t in range(count):
                if t + LOOKAHEAD < count:
                    k, _, rng = select(state, aux, rng, n, np.int64(1))
                    ring[(t + LOOKAHEAD) % _RING] = k
                    prefetch(pairs, k)
                    prefetch(ends, k)
                if t + HALFWAY < count:
                    k = ring[(t + HALFWAY) % _RING]
                    prefetch(v, pairs[k, 0])
                    prefetch(v, pairs[k, 1])
                k = ring[t % _RING]
                hit, m = tried(v, units, masses, params, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], tau, m)
                if hit:
                    if LOG:
                        log[made, 0], log[made, 1] = base + t + 1, k
                    made += 1
                    last = t
                    at_last = (m[1], m[3])
                    if made == collisions_left:
                        taken = t + 1
                        break
            return taken, made, last, (rng, m, at_last, free)

        return chunk

    def rows_chunk(LOG):
        """`prefetched_chunk`'s, reading each contact from the row ``pattern``: picks drawn and decoded
        `ROWS_AHEAD` steps early, their two velocity rows fetched then."""

        @njit(inline="always")
        def chunk(data, carry, count, collisions_left, before, collisions):
            v, pairs, ends, units, masses, params, pattern, state, aux, n, saved, log, base, first, tau, _ = data[:16]
            rng, m, at_last, free = carry
            log, base = log[collisions - first:], base + before
            made, last, taken = 0, -1, count
            at_last = (m[1], m[3])
            ring = np.empty((_RING, 5), dtype=np.int64)  # (k, i, j, a, b) of the picks drawn ahead
            for t in range(min(ROWS_AHEAD, count)):
                k, _, rng = select(state, aux, rng, n, np.int64(1))
                i, j, a, b = decode(pattern, np.int64(k))
                ring[t, 0], ring[t, 1], ring[t, 2], ring[t, 3], ring[t, 4] = k, i, j, a, b
                prefetch(v, i)
                prefetch(v, j)
            for t in range(count):
                if t + ROWS_AHEAD < count:
                    k, _, rng = select(state, aux, rng, n, np.int64(1))
                    i, j, a, b = decode(pattern, np.int64(k))
                    s = (t + ROWS_AHEAD) % _RING
                    ring[s, 0], ring[s, 1], ring[s, 2], ring[s, 3], ring[s, 4] = k, i, j, a, b
                    prefetch(v, i)
                    prefetch(v, j)
                s = t % _RING
                hit, m = tried(v, units, masses, params, ring[s, 1], ring[s, 2], ring[s, 3], ring[s, 4], tau, m)
                if hit:
                    if LOG:
                        log[made, 0], log[made, 1] = base + t + 1, ring[s, 0]
                    made += 1
                    last = t
                    at_last = (m[1], m[3])
                    if made == collisions_left:
                        taken = t + 1
                        break
            return taken, made, last, (rng, m, at_last, free)

        return chunk

    def make_limited(MODE, LOG):
        """MODE 0: the tables; 1: the tables, prefetched; 2: the row pattern, prefetched. The run to the
        limits is `engine.harness`'s, compiled here with ``data`` and ``carry`` as tuples:
        ``data = (v, pairs, ends, units, masses, params, pattern, state, aux, n, saved, log, base, first, tau,
        flags, rng_words, counters, margin, tune)``, ``carry = (rng, margin, margin's remnant side as of the last
        collision, branch-free next)``."""
        AHEAD = MODE > 0
        BLOCKS = MODE == 0 and FREE and not LOG  # the tables in blocks, some without a branch (`chunk_blocks`)

        @njit(inline="always")
        def mark(data, carry, count, left):
            """The chunk's start: the stream in ``carry`` (a value), the scheduler's state copied."""
            state, saved = data[7], data[10]
            copy_into(saved, state)
            return carry

        advance = rows_chunk(LOG) if MODE == 2 else prefetched_chunk(LOG) if MODE == 1 else \
            chunk_blocks if BLOCKS else table_chunk(LOG)

        @njit(inline="always")
        def live(data, carry):
            return any_live(data[0], data[1], data[2], data[3], data[4], data[5])

        @njit(inline="always")
        def settle(data, start, carry, used, count, frozen):
            """A frozen chunk's margin as of its last collision; picks drawn past the chunk's end replayed up to it."""
            state, aux, n, saved, flags = data[7], data[8], data[9], data[10], data[15]
            rng, m, at_last, free = carry
            if frozen:
                m = (m[0], at_last[0], m[2], at_last[1])
            if used < count and (AHEAD or frozen):
                copy_into(state, saved)
                begin(state, aux, flags)
                rng = replay(state, aux, start[0], n, used)
            return rng, m, at_last, free

        prepare = limited_prepare(begin, dim, LOG)

        @njit(inline="always")
        def finish(data, carry, taken, collisions, frozen, last):
            base, rng_words, counters, margin = data[12], data[16], data[17], data[18]
            store(rng_words, carry[0])
            margin[SMALLEST], margin[LARGEST], margin[NEAR_COLLISIONS], margin[NEAR_REMNANTS] = carry[1]
            counters[STEPS] += taken
            counters[COLLISIONS] = collisions
            counters[LIVE] = 0 if frozen else UNKNOWN
            if last >= 0:
                counters[LAST] = base + last
            return taken

        run = jit_cached_if_possible(limits_loop(mark, advance, live, settle, prepare, finish))
        return run

    def make_tracked(LOG):
        @jit_cached_if_possible
        def tracked(v, pairs, ends, units, masses, params, state, aux, rng_words, counters, margin,
                    max_steps, max_collisions, until_frozen, ptr, inc, flags, log):
            v, pairs, ends, units = shaped(v, pairs, ends, units)
            n, rng = pairs.shape[0], load(rng_words)
            tau = params[params.shape[0] - 1]
            m = (margin[SMALLEST], margin[LARGEST], margin[NEAR_COLLISIONS], margin[NEAR_REMNANTS])
            begin(state, aux, flags)
            taken, collisions, live = 0, counters[COLLISIONS], counters[LIVE]
            start_collisions, base = collisions, counters[STEPS]
            if LOG:
                max_collisions = min(max_collisions, collisions + log.shape[0])
            while taken < max_steps and collisions < max_collisions and not (until_frozen and live == 0):
                k, g, rng = select(state, aux, rng, n, max_steps - taken)
                taken += g
                if SKIPS and k < 0:
                    break
                hit, m = tried(v, units, masses, params, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], tau, m)
                if hit:
                    if LOG:
                        log[collisions - start_collisions, 0], log[collisions - start_collisions, 1] = base + taken, k
                    collisions += 1
                    counters[LAST] = base + taken
                    # contact k is re-tested once, with ball i's contacts: ball j's pass would find the same
                    live += refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, pairs[k, 0], -1,
                                    changed, state, aux)
                    live += refresh(v, pairs, ends, units, masses, params, ptr, inc, flags, pairs[k, 1], k,
                                    changed, state, aux)
            store(rng_words, rng)
            margin[SMALLEST], margin[LARGEST], margin[NEAR_COLLISIONS], margin[NEAR_REMNANTS] = m
            counters[STEPS] += taken
            counters[COLLISIONS], counters[LIVE] = collisions, live
            return taken
        return tracked

    return Loops(make_limited(0, False), make_limited(1, False), make_limited(2, False), make_tracked(False), picks,
                 make_limited(0, True), make_limited(1, True), make_limited(2, True), make_tracked(True))
