"""The threads of the parallel sweep (`pinnedballs.ColoredSweep`): how they wait, and how many.

A sweep runs each colour class on all of numba's threads, and a class ends at a barrier: every
thread waits there for the last. numba's OpenMP layer (GNU libgomp) waits by spinning. On a busy
machine the OS deschedules one of our threads for another process's time slice, and the thread
that spins at the barrier holds a core the late thread needs: with one busy process on 2 cores, 2 threads
ran slower than 1 (``benchmarks/bench_parallel.py``, ``docs/performance.md``). Dynamic chunks do not help (the
wait is at the barrier, not in the split); sleeping at the barrier does: 2 threads then run at least as fast
as 1 under load, and nearly twice as fast on an idle machine.

So importing pinnedballs sets ``OMP_WAIT_POLICY=passive`` unless the environment already says
otherwise; libgomp reads it when numba first starts its threads (later settings are ignored, so
set it before any parallel numba code runs in the process).

Sleeping at the barrier gives the core to the other process, so beside one busy process 2
threads still use about one core and only match 1 thread. A long run therefore lets `ThreadTuner`
choose, as HOOMD-blue's autotuner chooses block sizes: it times a short segment on each thread count
now and then and runs the rest on the faster. The bits never depend on the count.

How many threads: ``NUMBA_NUM_THREADS`` (default: every core) caps them for the process and must
be set before Python starts; `ColoredSweep(threads=k)` fixes the count for its runs (no tuning).
"""

from __future__ import annotations

import contextlib
import os
import time

from ...util.errors import FieldError

__all__ = ["WAIT_POLICY", "ThreadTuner", "most_threads", "using", "TUNED_SEGMENT"]

#: steps of one segment of a long run whose thread count `ThreadTuner` chooses (about 20-40 ms)
TUNED_SEGMENT = 1 << 23

#: the wait policy pinnedballs asks libgomp for, unless the environment chose one
WAIT_POLICY = "passive"
os.environ.setdefault("OMP_WAIT_POLICY", WAIT_POLICY)


def most_threads() -> int:
    """The most threads a run may use: ``NUMBA_NUM_THREADS`` (every core unless set)."""
    from numba import config

    return int(config.NUMBA_NUM_THREADS)


def check_threads(threads: int | None) -> None:
    """Raise a `FieldError` on ``threads`` if it is more than `most_threads` allows."""
    if threads is not None and threads > most_threads():
        raise FieldError("threads", f"must be at most NUMBA_NUM_THREADS = {most_threads()}; set that environment "
                                    f"variable before starting Python to use more, got {threads}")


@contextlib.contextmanager
def using(threads: int | None):
    """Run the body on ``threads`` of numba's threads (None: as many as numba is set to use), then
    restore the count numba had."""
    if threads is None:
        yield
        return
    import numba

    check_threads(threads)
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        yield
    finally:
        numba.set_num_threads(before)


class ThreadTuner:
    """Chooses how many threads each segment of a long parallel run uses: it times every segment,
    runs on the count with the best rate, and every ``period`` segments tries each other count once
    more, on a segment `TRIAL_SHARE` times shorter (so a count that loses costs little to try). The
    period starts at `PERIOD` and doubles (to `MAX_PERIOD`) each time the same count wins again, so a
    settled choice pays for few trials; a change of winner resets it. The running count's rate is
    always fresh: if the machine gets busy and it drops below another count's latest rate, the tuner
    moves to that count at once.

    The first segment on each count is not timed, only run (a trial's share of the units): it may compile
    or load the count's loops and start numba's threads. Nor is a trial shorter than `MIN_TRIAL_SECONDS`
    kept. Both once made the threads' first trial, a single batch of a run's first small chunk, look
    slower than one thread's, so that a run on idle cores stayed on one until its next trial, hundreds of
    millions of steps later (`benchmarks/results/measurements.md`).

    ``candidates``: the thread counts to try (default: `most_threads` and 1).
    """

    #: segments between two trials of the other counts, at first and after a change of winner
    PERIOD = 24
    #: the longest such interval (about 10 s of `TUNED_SEGMENT` segments)
    MAX_PERIOD = 384
    #: a trial (a count without a fresh rate) runs this many times fewer units than it is offered
    TRIAL_SHARE = 8
    #: a segment shorter than this (seconds) says little of its count's rate (a parallel call's start, a
    #: threads' wake-up): a trial that short is not kept, and the count is tried again on the next offer
    MIN_TRIAL_SECONDS = 0.01

    def __init__(self, candidates: tuple[int, ...] | None = None):
        most = most_threads()
        self.candidates = candidates or ((most, 1) if most > 1 else (1,))
        self.rates: dict[int, float] = {}  # the latest units per second on each count
        self.since = 0  # segments since the latest trial
        self.period = self.PERIOD
        self.winner: int | None = None  # the best count at the latest trial
        self.warm: set[int] = set()  # the counts that ran a first, untimed segment
        self.ran: dict[int, int] = {}  # the units run on each count so far (`shares`)

    def choose(self) -> int:
        """The thread count for the next segment: an untimed candidate, else the fastest."""
        for count in self.candidates:
            if count not in self.rates:
                return count
        return max(self.rates, key=self.rates.get)

    def shares(self) -> dict[int, float]:
        """``{count: share}``: the share of the units run so far that each count ran (what the tuner chose,
        recorded with a run's provenance, `util.provenance`); empty before the first segment."""
        total = sum(self.ran.values())
        return {count: self.ran[count] / total for count in sorted(self.ran, reverse=True)} if total else {}

    def run(self, segment, units: int) -> int:
        """``segment(n)`` on the chosen count, timed, for ``n = units`` (``units >= 1``: steps, blocks,
        whatever ``segment`` counts, the same for every call) or, on a trial, ``max(1, units //
        TRIAL_SHARE)``; returns ``n``: the caller offers the rest again."""
        count = self.choose()
        n = units if count in self.rates else max(1, units // self.TRIAL_SHARE)
        self.ran[count] = self.ran.get(count, 0) + n
        if count not in self.warm:  # its first segment: run, not timed (class docstring)
            with using(count):
                segment(n)
            self.warm.add(count)
            return n
        start = time.perf_counter()
        with using(count):
            segment(n)
        elapsed = time.perf_counter() - start
        if count not in self.rates and elapsed < self.MIN_TRIAL_SECONDS:
            return n  # too short to judge by: tried again on the next offer
        self.rates[count] = n / max(elapsed, 1e-9)
        self.since += 1
        if self.since >= self.period and len(self.rates) == len(self.candidates):
            best = self.choose()
            self.period = min(2 * self.period, self.MAX_PERIOD) if best == self.winner else self.PERIOD
            self.winner, self.since = best, 0
            self.rates = {best: self.rates[best]}  # the others are tried again
        return n
