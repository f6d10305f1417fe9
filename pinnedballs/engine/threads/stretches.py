"""How a threaded chain runs to its limits with the bits of one thread (`engine.harness`'s limits), on the
count of threads a `ThreadTuner` chooses: `engine.threads.regions` and `engine.threads.reservations` run
their blocks through these.

* `run_in_chunks`: chunks of steps, each as whole blocks on the threads (never more than the collisions
  left could hold) and its rest on the sequential loop, the freeze scanned after a chunk with a collision;
* `tuned_blocks`: a chunk's blocks on the threads or, where the tuner finds one thread faster, on the
  sequential loop (the same picks);
* `tuned_run` (`tuned_limits`): a run in stretches: where the tuner has settled on one thread until its
  next trials, the stretch runs on the sequential loop whole, its chunks and freeze scans compiled, with
  no Python between them (a run that one thread wins costs what the sequential loop costs, and trials).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..chain import COLLISIONS, LAST, LIVE, STEPS
from ..harness import limits_loop
from ..sequential.choice import new_tune
from .tuning import ThreadTuner

__all__ = ["run_in_chunks", "tuned_blocks", "tuned_run", "tuned_limits", "STRETCH_CHUNKS"]


def tuned_blocks(tuner: ThreadTuner | None, block: int, count: int, sequential: Callable, threaded: Callable) -> int:
    """``count`` blocks of ``block`` steps: ``threaded(blocks)`` on all threads or, where ``tuner`` finds one
    thread faster, ``sequential(steps)`` (the same picks), in the segments the tuner takes (a trial is
    shorter); None: always all threads. The steps taken."""
    if tuner is None:
        return threaded(count)
    taken = []

    def segment(blocks):
        taken.append(sequential(blocks * block) if tuner.current == 1 else threaded(blocks))

    left = count
    while left > 0:
        left -= tuner.run(segment, left)
    return sum(taken)


#: chunks a threaded stretch of `tuned_run` runs before it asks the tuner again
STRETCH_CHUNKS = 4


def tuned_run(tuner: ThreadTuner | None, block: int, threaded: Callable, sequential: Callable, max_steps: int,
              chunk_steps: int) -> int:
    """At most ``max_steps`` steps in stretches: where ``tuner`` has settled on one thread until its next
    trials (`ThreadTuner.stretch`), the stretch runs on ``sequential(steps) -> taken`` (the sequential loop
    to the run's limits: its chunks and freeze scans compiled, no Python between them), else on ``threaded(steps)
    -> taken`` (`run_in_chunks`: the tuner asked chunk by chunk), `STRETCH_CHUNKS` chunks of ``chunk_steps`` at
    most. A stretch that takes fewer steps than it was given stopped at a limit: the run ends. None: all
    ``threaded``. The same bits however the stretches fall (`engine.harness`). Returns the steps taken."""
    if tuner is None:
        return threaded(max_steps)
    taken = 0
    while taken < max_steps:
        count, seconds = tuner.stretch()
        left = max_steps - taken
        if count == 1 and seconds > 0:
            steps = int(min(left, max(chunk_steps, tuner.rates[1] * block * seconds)))
            done = sequential(steps)
            tuner.note(1, done / block)
        else:
            steps = min(left, STRETCH_CHUNKS * chunk_steps)
            done = threaded(steps)
        taken += done
        if done < steps:
            break
    return taken


def run_in_chunks(whole: Callable, block: int, chain, pattern, limited, any_live, state, aux, rng, counters, margin,
                  max_steps: int, max_collisions: int, until_frozen: bool, chunk_steps: int,
                  tune: np.ndarray | None = None) -> int:
    """What the sequential ``limited`` loop (with ``pattern``) does for these limits, bit for bit, for a
    threaded chain whose ``whole(chain, pattern, rng, counters, margin, count, sequential)`` runs ``count``
    blocks of ``block`` steps (`ParallelChain`, `engine.threads.reservations.ReservationChain`), within the limits of
    `engine.harness`: chunks of ``chunk_steps`` steps, each as whole blocks on the threads (never more than the
    collisions left could hold) and its rest on ``limited``, the freeze scanned (``any_live``) after a chunk
    with a collision, and the chunk that froze run again on one thread from its start to its last collision,
    so the margin too ends there. ``tune``: the sequential loop's (`engine.sequential.choice`; None: a fresh
    one). Returns the steps taken."""
    saved = np.empty_like(state)
    tune = new_tune() if tune is None else tune

    def sequential(steps: int) -> int:
        return limited(*chain, pattern, state, aux, rng, counters, margin, steps, max_collisions, False, steps,
                       saved, _NO_LOG, tune)

    def mark(data, carry, count, left):
        return rng.copy(), state.copy(), counters.copy(), margin.copy(), chain.v.copy() if until_frozen else None

    def advance(data, carry, count, left, taken, collisions):
        start_steps, start_collisions = int(counters[STEPS]), int(counters[COLLISIONS])
        blocks = min(count, left) // block
        done = whole(chain, pattern, rng, counters, margin, blocks, sequential) if blocks > 0 else 0
        if done < count and counters[COLLISIONS] < max_collisions:
            done += sequential(count - done)
        made = int(counters[COLLISIONS]) - start_collisions
        return done, made, int(counters[LAST]) - start_steps - 1 if made else -1, carry

    def live(data, carry):
        return any_live(*chain)

    def settle(data, start, carry, used, count, frozen):
        if frozen:  # once per run: the chunk again on one thread from its start to its last collision
            rng[:], state[:], counters[:], margin[:], chain.v[:] = start
            sequential(used)
        return carry

    taken, _, frozen, _, _ = limits_loop(mark, advance, live, settle)(None, None, int(counters[COLLISIONS]), max_steps,
                                                                     max_collisions, until_frozen, chunk_steps)
    counters[LIVE] = 0 if frozen else -1
    return taken


def tuned_limits(tuner: ThreadTuner | None, whole: Callable, block: int, chain, pattern, limited, any_live, state,
                 aux, rng, counters, margin, max_steps: int, max_collisions: int, until_frozen: bool, chunk_steps: int,
                 tune: np.ndarray | None = None, choice=None) -> int:
    """`run_in_chunks` in the stretches of `tuned_run`: a stretch settled on one thread runs ``limited`` whole
    (its own chunks, freeze scans and rewinds, compiled) or, given ``choice`` (`engine.sequential.sizes.LoopChoice`),
    the loop it chooses for the system's size; the steps taken. The threaded chunks keep ``limited`` and
    ``pattern``, the loop and row pattern their blocks were built for (blocks built to decode a row pattern
    and handed none read outside it)."""
    tune = new_tune() if tune is None else tune

    def threaded(steps: int) -> int:
        return run_in_chunks(whole, block, chain, pattern, limited, any_live, state, aux, rng, counters, margin, steps,
                             max_collisions, until_frozen, chunk_steps, tune)

    saved = np.empty_like(state)

    def call(loop, loop_pattern, steps: int) -> int:
        return loop(*chain, loop_pattern, state, aux, rng, counters, margin, steps, max_collisions, until_frozen,
                    chunk_steps, saved, _NO_LOG, tune)

    def sequential(steps: int) -> int:
        return call(limited, pattern, steps) if choice is None else choice.run(call, steps)

    return tuned_run(tuner, block, threaded, sequential, max_steps, chunk_steps)


_NO_LOG = np.empty((0, 2), dtype=np.int64)
