"""The parallel sweep's threads: the wait policy pinnedballs asks for, the thread count a run
uses, and the tuner that chooses it (the bits never depend on it: test_colored_sweep.py)."""

from __future__ import annotations

import os
import subprocess
import sys

import numba
import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.threads import tuning as threads
from pinnedballs.engine.threads.tuning import ThreadTuner


@pytest.mark.parametrize("given,expected", [(None, "passive"), ("active", "active")])
def test_import_asks_for_passive_waiting_unless_the_environment_chose(given, expected):
    """The threads' module (which every threaded loop imports, before numba's threading layer starts) asks
    OpenMP's waiting threads to sleep, unless the environment chose."""
    env = {k: v for k, v in os.environ.items() if k != "OMP_WAIT_POLICY"}
    if given:
        env["OMP_WAIT_POLICY"] = given
    out = subprocess.run([sys.executable, "-c", "import os, pinnedballs.engine.threads.tuning; "
                                                "print(os.environ['OMP_WAIT_POLICY'])"],
                         env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == expected


def test_using_sets_the_count_and_restores_it():
    before = numba.get_num_threads()
    with threads.using(1):
        assert numba.get_num_threads() == 1
    assert numba.get_num_threads() == before
    with threads.using(None):
        assert numba.get_num_threads() == before


def test_more_threads_than_numba_has_is_refused():
    most = threads.most_threads()
    with pytest.raises(pb.FieldError, match=rf"^threads: must be at most NUMBA_NUM_THREADS = {most}; set that "
                                            rf"environment variable before starting Python to use more, "
                                            rf"got {most + 1}"):
        pb.Simulation(pb.FlatTorus(4, 4), np.ones((16, 2)), scheduler=pb.ColoredSweep(threads=most + 1))
    with pytest.raises(pb.FieldError, match="^threads: must be an integer >= 1, got 0"):
        pb.ColoredSweep(threads=0)


class _Clock:
    """A fake ``time.perf_counter`` whose segments take ``seconds[count]`` per 100 units on ``count``
    threads; ``units`` lists what each segment was handed."""

    def __init__(self, seconds):
        self.now, self.seconds, self.count, self.units = 0.0, seconds, None, []

    def __call__(self):
        return self.now

    def segment(self, steps):
        self.count = numba.get_num_threads()
        self.now += self.seconds[self.count] * steps / 100
        self.units.append(steps)


def warmed(tuner: ThreadTuner) -> ThreadTuner:
    """``tuner`` past the first, untimed segment of each of its counts."""
    tuner.warm.update(tuner.candidates)
    return tuner


def _tune(tuner, clock, segments: int) -> list[int]:
    used = []
    for _ in range(segments):
        tuner.run(clock.segment, 100)
        used.append(clock.count)
    return used


def test_tuner_times_each_count_then_runs_on_the_faster_and_tries_again(monkeypatch):
    clock = _Clock({2: 1.0, 1: 3.0})
    monkeypatch.setattr(threads.time, "perf_counter", clock)
    monkeypatch.setattr(threads, "using", _pretend_using(clock))
    tuner = warmed(ThreadTuner(candidates=(2, 1)))
    p = ThreadTuner.PERIOD
    used = _tune(tuner, clock, p)
    assert used == [2, 1] + [2] * (p - 2)  # timed both, then the faster until the period ends
    assert clock.units == [100 // ThreadTuner.TRIAL_SHARE] * 2 + [100] * (p - 2)  # trials are short
    assert tuner.rates == {2: 100.0} and tuner.winner == 2 and tuner.period == p
    used = _tune(tuner, clock, p)
    assert used == [1] + [2] * (p - 1)  # 1 thread tried once more, then 2; 2 won again: a longer period
    assert tuner.period == 2 * p
    assert _tune(tuner, clock, 2 * p) == [1] + [2] * (2 * p - 1)


def test_a_trial_runs_a_share_of_the_units_and_says_how_many(monkeypatch):
    """A count without a fresh rate runs ``units // TRIAL_SHARE`` (at least 1), the winner all it is
    offered; `run` returns what it ran, so a caller offering the rest again runs every unit once."""
    clock = _Clock({2: 1.0, 1: 3.0})
    monkeypatch.setattr(threads.time, "perf_counter", clock)
    monkeypatch.setattr(threads, "using", _pretend_using(clock))
    tuner = warmed(ThreadTuner(candidates=(2, 1)))
    left, ran = 1000, []
    while left > 0:
        ran.append(tuner.run(clock.segment, left))
        left -= ran[-1]
    share = ThreadTuner.TRIAL_SHARE
    assert ran == clock.units == [1000 // share, (1000 - 1000 // share) // share,
                                  1000 - 1000 // share - (1000 - 1000 // share) // share]
    assert tuner.run(clock.segment, 3) == 3  # the winner's rate is fresh: no trial
    tuner.rates.pop(1)
    assert tuner.choose() == 1 and tuner.run(clock.segment, 3) == 1  # a trial of fewer units than the share


def test_tuner_backs_off_to_its_longest_period_and_resets_on_a_new_winner(monkeypatch):
    clock = _Clock({2: 1.0, 1: 3.0})
    monkeypatch.setattr(threads.time, "perf_counter", clock)
    monkeypatch.setattr(threads, "using", _pretend_using(clock))
    tuner = warmed(ThreadTuner(candidates=(2, 1)))
    used = _tune(tuner, clock, 4000)
    assert tuner.period == ThreadTuner.MAX_PERIOD
    assert used.count(1) <= 1 + 4000 // ThreadTuner.PERIOD  # few trials of the slower count
    assert used[-ThreadTuner.MAX_PERIOD // 2:].count(1) <= 1
    clock.seconds = {2: 5.0, 1: 3.0}  # the machine got busy: 1 thread is faster now
    used = _tune(tuner, clock, 3)
    assert used[1:] == [1, 1]  # the running count's fresh rate fell below 1 thread's: moved at once
    while tuner.since:  # to the end of this period
        _tune(tuner, clock, 1)
    assert tuner.winner == 1 and tuner.period == ThreadTuner.PERIOD  # a new winner: short periods again


def test_the_first_segment_on_each_count_is_run_not_timed(monkeypatch):
    """A count's first segment may compile or load its loops (seconds, on a first run) and start numba's
    threads: timed, it made 2 threads lose to 1 on an idle 2-core machine, where they are 1.28x faster."""
    clock = _Clock({2: 1.0, 1: 3.0})
    monkeypatch.setattr(threads.time, "perf_counter", clock)
    monkeypatch.setattr(threads, "using", _pretend_using(clock))
    tuner = ThreadTuner(candidates=(2, 1))
    first, seen = clock.segment, set()

    def compiling(steps):  # the first call on 2 threads compiles: 100 s more
        first(steps)
        if clock.count not in seen:
            seen.add(clock.count)
            clock.now += 100.0 if clock.count == 2 else 0.0

    used = []
    for _ in range(6):
        tuner.run(compiling, 100)
        used.append(clock.count)
    assert used == [2, 2, 1, 1, 2, 2]  # each count run once untimed, then tried; 2 threads won
    assert clock.units[:4] == [100 // ThreadTuner.TRIAL_SHARE] * 4 and clock.units[4:] == [100, 100]
    assert tuner.rates == pytest.approx({2: 100.0, 1: 100 / 3})


def _pretend_using(clock):
    """``threads.using`` that only records the count (the fake clock's segment reads it)."""
    import contextlib

    @contextlib.contextmanager
    def using(count):
        before = numba.get_num_threads
        numba.get_num_threads = lambda: count
        try:
            yield
        finally:
            numba.get_num_threads = before

    return using


def test_one_candidate_means_no_timing():
    tuner = ThreadTuner(candidates=(1,))
    assert [tuner.choose() for _ in range(3)] == [1, 1, 1]


def test_shares_are_the_work_each_count_ran(monkeypatch):
    """What a run's provenance records of the tuner's choice (`ThreadTuner.shares`): of the units it was handed,
    the share each count ran, the untimed first segments and the short trials included."""
    clock = _Clock({2: 1.0, 1: 3.0})
    monkeypatch.setattr(threads.time, "perf_counter", clock)
    monkeypatch.setattr(threads, "using", _pretend_using(clock))
    tuner = ThreadTuner(candidates=(2, 1))
    assert tuner.shares() == {}
    used = _tune(tuner, clock, 3 * ThreadTuner.PERIOD)
    on = {count: sum(u for u, c in zip(clock.units, used) if c == count) for count in (2, 1)}
    assert tuner.shares() == {2: on[2] / sum(clock.units), 1: on[1] / sum(clock.units)}
    assert list(tuner.shares()) == [2, 1] and tuner.shares()[2] > 0.9  # 2 threads won: nearly all the work
