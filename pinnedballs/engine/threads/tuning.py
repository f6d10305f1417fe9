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
choose (`engine.tuner.Tuner`, as HOOMD-blue's autotuner chooses block sizes): it times about 10 ms of the
run's own work on each thread count now and then (rounds further apart as the same count keeps winning, and
never so often that the trials cost more than 1 % of the run) and runs the rest on the fastest, more
threads only where they run at least 1.3 times faster than one: two threads busy cost two cores' seconds.
Where one thread wins, the threaded chains hand the sequential loop whole stretches, until the next round
(`engine.threads.stretches`). The bits never depend on the count.

How many threads: ``NUMBA_NUM_THREADS`` (default: every core) caps them for the process and must
be set before Python starts; `ColoredSweep(threads=k)` fixes the count for its runs (no tuning).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable

from ...util.errors import FieldError
from ..tuner import Tuner

__all__ = ["WAIT_POLICY", "ThreadTuner", "thread_counts", "most_threads", "using", "TUNED_SEGMENT"]

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


def thread_counts(threads: int) -> tuple[int, ...]:
    """The thread counts a `ThreadTuner` tries for a chain built for ``threads``: one, half of them (from 4 on:
    a machine's other work, or its memory, may make fewer run faster), all."""
    return (1,) + ((threads // 2,) if threads >= 4 else ()) + ((threads,) if threads > 1 else ())


class ThreadTuner(Tuner):
    """How many threads each stretch of a long parallel run uses (`Tuner`), by the wall clock (what a user waits
    for); more threads than the fewest must run at least `PAYS` times faster to be chosen: two threads hold two
    cores, and a count that gains less is not worth its CPU seconds (nor the risk that a noisy trial chose it).
    The bits never depend on the count.

    ``candidates``: the thread counts to try, the fewest first (default: `thread_counts` of `most_threads`);
    ``clock``: seconds.
    """

    #: more threads must run at least this many times faster than the fewest to be chosen
    PAYS = 1.3
    #: one thread alone for the first second: a trial of two threads beside a busy process costs tens of
    #: milliseconds (each of its barriers waits for a thread the operating system has not yet run), a third of
    #: a 0.2 s run; a longer run tries them after a second
    DEFER = 1.0

    def __init__(self, candidates: tuple[int, ...] | None = None, clock: Callable[[], float] | None = None):
        super().__init__(candidates or thread_counts(most_threads()), clock)

    def pays(self, count: int) -> float:
        return 1.0 if count == min(self.candidates) else self.PAYS

    def within(self, count: int):
        return using(count)
