"""How the table loop runs its blocks, with a branch on each collision or without one, chosen on the CPU
that runs it by what each way costs there (`next_free`), and the setting that forces a way
(``PINNEDBALLS_LOOP``, `loop_setting`).

**Why measure.** A block of `BLOCK` picks runs either with a branch on every pick's collision or without
one (`engine.closing.branch_free_form`: every pick's new velocities computed and written back where the
rule does not collide). Which is faster depends on the share of the picks that collide and on the CPU:
on a lattice in equilibrium about half the picks collide and a branch on them is mispredicted nearly as
often, yet one CPU runs the paper's 38x38 torus 2.1 times faster without the branch and another 1.4 times
faster with it (docs/performance.md). A threshold on the share measured on one CPU chose the wrong way on
the other. The way is a matter of speed only: both give the same bits (`tests/engine/sequential/test_branch_free.py`).

**How it chooses.** The loop reads the CPU's time-stamp counter (`engine.jit.intrinsics.ticks`, tens of
cycles) once per block and compares the two ways on *adjacent* blocks: when a block runs the other way than
the one before and both fall in the same band of their share of collisions (`BUCKETS` bands), the logarithm
of their costs a pick, without a branch over with one, is a sample of what the way costs in that band, taken
under the same conditions (the same cache contents, clock frequency and load: another process that ran on
the core between blocks slows both about alike). Each band keeps the running mean of its samples (the last
`MEMORY` at most, each clipped to ``[-1, 1]``, so that a block the operating system interrupted moves it
little). The next block runs the cheaper way of the band of the block before (a block's share of collisions
predicts the next's; a band with no sample yet follows the nearest band with one, but for one block in
`EXPLORE_MIN`: a band seldom visited is seldom followed by a block in the same band). Every so often it runs
the other way (then back), for new samples: every `EXPLORE_MIN` blocks of a band at first, twice as rarely
each time the same way wins again, down to one in `EXPLORE_MAX` (a tenth of a percent of the blocks then run
the dearer way). Costs compared by absolute estimates, each kept while the other way ran, drifted apart with
the machine's load (measured: runs settled on the dearer way on one block in ten). Where the counter does not
count (`TICKS` False: not x86-64), the loop keeps the former rule, `BRANCH_FREE_PERCENT`.

``tune`` is a ``(TUNE,) float64`` array the loop's owner keeps between calls (`new_tune`), so what was
learnt holds for the whole run: ``tune[POLICY]`` the way chosen (`TUNED`, `BRANCH`, `BRANCH_FREE`, `THRESHOLD`),
``tune[PICKS + w]`` the picks run each way (0: with a branch, 1: without), ``tune[PREVIOUS:PREVIOUS + 3]``
the block before (its cost a pick, way and band; cost 0: untimed), then each band's mean log ratio, samples,
exploration interval, blocks since its last exploration and latest winner.
"""

from __future__ import annotations

import os

import numpy as np

from ...util.errors import FieldError
from ..jit.cache import njit_cached
from ..jit.intrinsics import TICKS

__all__ = ["BLOCK", "BRANCH_FREE_PERCENT", "BUCKETS", "MEMORY", "TUNED", "BRANCH", "BRANCH_FREE", "THRESHOLD",
           "POLICIES", "LOOPS", "LOOP_SETTINGS", "ENV", "TUNE", "new_tune", "next_free", "loop_setting", "described"]

#: the table loop runs its steps in blocks of this many picks, each with a branch or without
BLOCK = 256
#: where the CPU cannot time its blocks: a block without a branch after one that collided on this
#: percentage of its picks or more (the former rule, measured on one CPU)
BRANCH_FREE_PERCENT = 30
#: bands of a block's share of collisions, each with its own comparison
BUCKETS = 8
#: a block shorter than this says little of its cost (a chunk's last)
MIN_TIMED = BLOCK // 2
#: a band's mean log ratio holds its last this many samples at most (a running mean, then a moving one)
MEMORY = 16.0
#: one block in this many of a band runs the other way: at first, and the rarest once the choice holds
EXPLORE_MIN, EXPLORE_MAX = 8.0, 1024.0

#: the ways: chosen by their measured cost, always with a branch, always without (but a call's first
#: block), by the share of collisions of the block before (`BRANCH_FREE_PERCENT`)
TUNED, BRANCH, BRANCH_FREE, THRESHOLD = 0, 1, 2, 3
POLICIES = {"tuned": TUNED, "branch": BRANCH, "branch_free": BRANCH_FREE, "threshold": THRESHOLD}

# the slots of `tune`
POLICY, PICKS = 0, 1
PREVIOUS = PICKS + 2
RATIO = PREVIOUS + 3
SAMPLES = RATIO + BUCKETS
EVERY = SAMPLES + BUCKETS
SINCE = EVERY + BUCKETS
WINNER = SINCE + BUCKETS
TUNE = WINNER + BUCKETS

#: the loops a CPU run chooses among by the system's size (`engine.sequential.sizes`)
LOOPS = ("tables", "prefetched", "rows")
#: the environment variable that forces a choice (benchmarks, tests), and what it takes: ``auto`` (or
#: unset) lets the engine choose; ``branch``, ``branch_free``, ``threshold``: the table loop, its blocks so;
#: ``tables``: the table loop, its blocks chosen by cost; ``prefetched``, ``rows``: those loops
ENV = "PINNEDBALLS_LOOP"
LOOP_SETTINGS = ("auto", "branch", "branch_free", "threshold", "tables", "prefetched", "rows")


def loop_setting() -> str:
    """``PINNEDBALLS_LOOP`` (`LOOP_SETTINGS`; ``"auto"`` where unset or empty); a `FieldError` naming it for
    any other value."""
    value = os.environ.get(ENV, "").strip() or "auto"
    if value not in LOOP_SETTINGS:
        raise FieldError(ENV, f"must be one of {', '.join(LOOP_SETTINGS)} (or unset), got {value!r}")
    return value


def new_tune(setting: str = "auto") -> np.ndarray:
    """A fresh ``(TUNE,) float64`` ``tune`` for the table loop under ``setting`` (`loop_setting`): the way
    that setting forces, else `TUNED` where the CPU's counter counts and `THRESHOLD` where it does not."""
    tune = np.zeros(TUNE)
    policy = POLICIES.get(setting, TUNED)
    tune[POLICY] = THRESHOLD if policy == TUNED and not TICKS else policy
    return tune


@njit_cached(inline="always")
def next_free(tune, free, hits, size, ticks):
    """Whether the block after this one runs without a branch. This block ran ``free`` (without a branch),
    collided on ``hits`` of its ``size`` picks and took ``ticks`` of the counter; beside the block before, a
    sample of the two ways' costs goes into ``tune`` (module docstring)."""
    policy = tune[POLICY]
    way = np.int64(free)
    tune[PICKS + way] += size
    if policy == BRANCH:
        return False
    if policy == BRANCH_FREE:
        return True
    if policy == THRESHOLD:
        return hits * 100 >= BRANCH_FREE_PERCENT * size
    band = (hits * BUCKETS) // (size + 1)
    cost = ticks / size if size >= MIN_TIMED and ticks > 0 else 0.0
    before, before_way, before_band = tune[PREVIOUS], tune[PREVIOUS + 1], tune[PREVIOUS + 2]
    tune[PREVIOUS], tune[PREVIOUS + 1], tune[PREVIOUS + 2] = cost, way, band
    if cost > 0.0 and before > 0.0 and before_band == band and before_way != way:  # a pair: one sample
        sample = np.log(cost / before) if free else np.log(before / cost)  # log(without / with a branch)
        sample = min(1.0, max(-1.0, sample))
        n = min(tune[SAMPLES + band] + 1.0, MEMORY)
        tune[SAMPLES + band] += 1.0
        tune[RATIO + band] += (sample - tune[RATIO + band]) / n
    if tune[SAMPLES + band] <= 0.0:  # no sample in this band yet: as the nearest band with one ...
        since = tune[SINCE + band] + 1.0
        tune[SINCE + band] = 0.0 if since >= EXPLORE_MIN else since
        if since < EXPLORE_MIN:
            for step in range(1, BUCKETS):
                for near in (band - step, band + step):
                    if 0 <= near < BUCKETS and tune[SAMPLES + near] > 0.0:
                        return tune[RATIO + near] < 0.0
        return not free  # ... but every `EXPLORE_MIN` visits, or where none has one, the other way: a sample
    best = tune[RATIO + band] < 0.0
    if free != best:
        return best  # back from a block the other way
    since, every = tune[SINCE + band] + 1.0, max(tune[EVERY + band], EXPLORE_MIN)
    if since < every:
        tune[SINCE + band] = since
        return best
    won = 2.0 if best else 1.0  # the winner as `tune[WINNER]` keeps it (0: none yet)
    tune[SINCE + band] = 0.0
    tune[EVERY + band] = min(2.0 * every, EXPLORE_MAX) if tune[WINNER + band] == won else EXPLORE_MIN
    tune[WINNER + band] = won
    return not best  # one block the other way


def described(tune: np.ndarray) -> dict:
    """What the table loop chose, as a run's provenance records it: ``{"blocks": how they were chosen
    ("measured", "forced", "threshold"), "branch_free": the share of its picks run without a branch}``; empty
    before it ran a block."""
    picks = tune[PICKS] + tune[PICKS + 1]
    if picks <= 0:
        return {}
    how = {TUNED: "measured", BRANCH: "forced", BRANCH_FREE: "forced", THRESHOLD: "threshold"}[int(tune[POLICY])]
    return {"blocks": how, "branch_free": round(float(tune[PICKS + 1] / picks), 4)}
