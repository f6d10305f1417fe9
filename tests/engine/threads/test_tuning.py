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
    """A fake clock whose segments take ``seconds[count]`` per 100 units on ``count`` threads (read from numba's
    count, which `_pretend_using` sets); ``units`` and ``counts`` list what each segment was handed."""

    def __init__(self, seconds):
        self.now, self.seconds, self.count, self.units, self.counts = 0.0, seconds, None, [], []

    def __call__(self):
        return self.now

    def segment(self, units):
        self.count = numba.get_num_threads()
        self.now += self.seconds[self.count] * units / 100
        self.units.append(units)
        self.counts.append(self.count)


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


def _tuner(monkeypatch, seconds, defer: float = 0.0) -> tuple[ThreadTuner, _Clock]:
    """A tuner of 1 and 2 threads on the fake clock; ``defer``: its `ThreadTuner.DEFER` (0: trials from the start)."""
    clock = _Clock(seconds)
    monkeypatch.setattr(threads, "using", _pretend_using(clock))
    monkeypatch.setattr(ThreadTuner, "DEFER", defer)
    return ThreadTuner(candidates=(1, 2), clock=clock), clock


def _offer(tuner, clock, units: int, until: float) -> None:
    """Offer ``units`` at a time until the clock reads ``until`` seconds."""
    while clock.now < until:
        tuner.run(clock.segment, units)


def test_each_count_runs_once_untimed_then_a_trial_then_the_best(monkeypatch):
    """A count's first segment may compile or load its loops and start numba's threads (seconds, on a first
    run): it is run, not timed. Then each count's trial (about TRIAL_SECONDS of work), then the faster."""
    tuner, clock = _tuner(monkeypatch, {1: 0.003, 2: 0.001})  # 2 threads 3x faster; 100 units in 3 ms on one
    first = clock.segment

    def compiling(units):  # the first segment on 2 threads compiles: 100 s more
        first(units)
        if clock.counts.count(2) == 1 and clock.count == 2:
            clock.now += 100.0

    while tuner.rounds == 0:
        tuner.run(compiling, 100)
    for _ in range(3):
        tuner.run(compiling, 100)
    assert clock.counts[:2] == [1, 1] and clock.units[0] == 100 // ThreadTuner.TRIAL_SHARE  # 1: untimed, trial
    assert tuner.rates[1] == pytest.approx(100 / 0.003)
    assert tuner.rates[2] == pytest.approx(100 / 0.001)  # the compile left out
    assert tuner.winner == 2 and clock.counts[-3:] == [2, 2, 2] and clock.units[-1] == 100
    assert len(clock.counts) < 30  # each trial about TRIAL_SECONDS of work (10 ms: 10 offers on 2 threads)


def test_short_trial_segments_add_up(monkeypatch):
    """A trial offered fewer units than TRIAL_SECONDS takes (a chunk's rest) keeps its units and seconds until
    together they last long enough: it is never thrown away and tried again from nothing."""
    tuner, clock = _tuner(monkeypatch, {1: 0.002, 2: 0.004})
    for _ in range(2):  # each count's untimed segment
        tuner.run(clock.segment, 2)
    while 2 not in tuner.rates:
        tuner.run(clock.segment, 2)  # 2 units: 0.04 ms on one thread, 0.08 on two
    assert tuner.rates[2] == pytest.approx(100 / 0.004)
    two = [u for u, c in zip(clock.units, clock.counts) if c == 2]
    assert len(two) > 100 and sum(two[1:]) * 0.004 / 100 == pytest.approx(ThreadTuner.TRIAL_SECONDS, rel=0.01)


@pytest.mark.parametrize("faster, chosen", [(1.2, 1), (1.5, 2)])
def test_more_threads_must_pay(monkeypatch, faster, chosen):
    """Two threads hold two cores: they are chosen only where they run at least PAYS times faster than one."""
    tuner, clock = _tuner(monkeypatch, {1: 0.003, 2: 0.003 / faster})
    _offer(tuner, clock, 100, 0.5)
    assert tuner.best() == chosen and clock.counts[-1] == chosen


def test_trials_come_again_later_and_later_and_cost_little(monkeypatch):
    """A round of trials again after INTERVAL seconds, twice as long each time the same count wins, back to
    INTERVAL on a new winner; a slower count's trials cost at most BUDGET of the run (a second of work at
    least between rounds)."""
    tuner, clock = _tuner(monkeypatch, {1: 0.001, 2: 0.004})  # 2 threads 4x slower: one wins
    _offer(tuner, clock, 100, 200.0)
    assert tuner.winner == 1 and tuner.interval == ThreadTuner.MAX_INTERVAL
    two = sum(u for u, c in zip(clock.units, clock.counts) if c == 2) * 0.004 / 100  # seconds on 2 threads
    assert two * 0.75 <= ThreadTuner.BUDGET * clock.now  # the trials' loss (3/4 of their time) within the budget
    rounds = tuner.rounds
    clock.seconds = {1: 0.001, 2: 0.0001}  # the machine's other work ended: now 2 threads are 10x faster
    _offer(tuner, clock, 100, 240.0)
    assert tuner.rounds > rounds and tuner.winner == 2 and clock.counts[-1] == 2
    assert tuner.interval < ThreadTuner.MAX_INTERVAL  # a new winner: short intervals again


def test_the_running_count_moves_at_once_when_it_slows(monkeypatch):
    """The running count's rate is kept fresh: if the machine gets busy and it falls below another's latest,
    the tuner moves to that count at once, without waiting for the next round."""
    tuner, clock = _tuner(monkeypatch, {1: 0.003, 2: 0.001})
    _offer(tuner, clock, 100, 0.5)
    assert clock.counts[-1] == 2
    clock.seconds = {1: 0.003, 2: 0.01}  # a busy process took a core: 2 threads now 3x slower than one
    before = len(clock.counts)
    _offer(tuner, clock, 100, 0.6)
    assert clock.counts[before:before + 3].count(2) <= 2 and clock.counts[-1] == 1


def test_a_stretch_on_one_thread_lasts_until_the_next_round(monkeypatch):
    """`ThreadTuner.stretch`: once one thread has won a round, how long a caller may run it without asking."""
    tuner, clock = _tuner(monkeypatch, {1: 0.001, 2: 0.004})
    assert tuner.stretch() == (1, 0.0)  # no rates yet: ask segment by segment
    while tuner.rounds == 0:
        tuner.run(clock.segment, 100)
    count, seconds = tuner.stretch()
    assert count == 1 and seconds == pytest.approx(tuner.due - clock.now) and seconds >= ThreadTuner.INTERVAL * 0.99
    clock.now = tuner.due
    assert tuner.stretch() == (2, 0.0)  # the next round: 2 threads are tried again


def test_one_thread_runs_alone_for_the_first_second(monkeypatch):
    """A trial of two threads beside a busy process costs tens of milliseconds: a run shorter than DEFER seconds
    pays for none; after it, a round of trials, and two threads win where they pay."""
    tuner, clock = _tuner(monkeypatch, {1: 0.003, 2: 0.001}, defer=ThreadTuner.DEFER)
    _offer(tuner, clock, 100, 0.5)
    assert set(clock.counts) == {1} and 1 in tuner.rates
    count, seconds = tuner.stretch()
    assert count == 1 and seconds == pytest.approx(ThreadTuner.DEFER - clock.now)  # one thread until then
    _offer(tuner, clock, 100, ThreadTuner.DEFER + 0.5)
    assert tuner.rounds == 1 and tuner.winner == 2 and clock.counts[-1] == 2


def test_one_candidate_means_no_timing():
    tuner = ThreadTuner(candidates=(1,))
    assert [tuner.choose() for _ in range(3)] == [1, 1, 1]


def test_shares_are_the_work_each_count_ran(monkeypatch):
    """What a run's provenance records of the tuner's choice (`ThreadTuner.shares`): of the units it was handed,
    the share each count ran, the untimed first segments, the trials and the stretches noted included."""
    tuner, clock = _tuner(monkeypatch, {1: 0.003, 2: 0.001})
    assert tuner.shares() == {}
    _offer(tuner, clock, 100, 1.0)
    tuner.note(1, 50)
    on = {count: sum(u for u, c in zip(clock.units, clock.counts) if c == count) for count in (2, 1)}
    on[1] += 50
    total = on[1] + on[2]
    assert tuner.shares() == pytest.approx({2: on[2] / total, 1: on[1] / total})
    assert list(tuner.shares()) == [2, 1] and tuner.shares()[2] > 0.9  # 2 threads won: nearly all the work


def test_the_counts_tried_are_one_half_and_all():
    """A chain built for k threads tries 1 and k, and from 4 on k // 2 (the machine's other work may leave fewer
    cores than numba was given)."""
    assert [threads.thread_counts(k) for k in (1, 2, 3, 16)] == [(1,), (1, 2), (1, 3), (1, 8, 16)]
