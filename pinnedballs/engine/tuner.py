"""A choice made on the machine that runs it: among ways of doing the same work with the same bits (thread
counts, `engine.threads.tuning.ThreadTuner`; loops for a system's size, `engine.backends.LoopBackend`), the one
that runs fastest here, found by timing each on the run's own work (as HOOMD-blue's autotuner chooses block
sizes, on the run itself rather than a calibration). `Tuner` says how.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable

__all__ = ["Tuner"]


class Tuner:
    """Chooses, stretch by stretch of a long run, among *candidates* that do the same work with the same bits
    (thread counts, `ThreadTuner`; loops, `engine.backends.LoopBackend`), from their rates measured on the
    run's own work (units per second of ``clock``).

    * **The first round**, after `DEFER` seconds of the first candidate alone (a run shorter than that pays
      for no trial of the others). Each candidate runs a first segment untimed (it may compile or load its loops and
      start numba's threads), then a *trial*: segments timed until together they have lasted `TRIAL_SECONDS`
      (a short segment is not thrown away: its units and seconds add up), the first of them short (an eighth
      of that at the fastest rate known), the next sized by the rate the trial has shown. Then the best runs.
    * **The best** is the fastest, its rate divided by `pays` (a candidate that costs more than the others,
      as more threads do, must gain more). The running candidate's rate is kept fresh (the mean of its latest
      and its previous); if the machine gets busy and it falls below another's, the tuner moves to that one
      at once.
    * **Trials again** after `INTERVAL` seconds at first, twice as long each time the same candidate wins
      again (to `MAX_INTERVAL`), back to `INTERVAL` on a new winner; never sooner than it takes for the trials
      to have cost at most `BUDGET` of the run (a trial of a candidate twice as slow costs its length).

    `stretch` says how long the running candidate may run without asking (a caller can then hand that stretch
    to a loop of its own, `engine.threads.stretches.tuned_run`).

    ``candidates``: what to try, in order; ``clock``: seconds (default: `time.perf_counter`).
    """

    #: a trial runs this long (over as many segments as it takes)
    TRIAL_SECONDS = 0.01
    #: without a rate to size a trial by, a trial runs this many times fewer units than it is offered
    TRIAL_SHARE = 8
    #: seconds between two rounds of trials, at first and after a change of winner, and the longest
    INTERVAL, MAX_INTERVAL = 1.0, 32.0
    #: the share of a run's time trials may lose to a slower count
    BUDGET = 0.01
    #: the first candidate runs alone for this many seconds before the others are tried (0: none)
    DEFER = 0.0

    def __init__(self, candidates: tuple, clock: Callable[[], float] | None = None):
        self.candidates = tuple(candidates)
        self.clock = clock or time.perf_counter
        self.rates: dict[int, float] = {}  # units per second: the running count's fresh, the others' latest
        self.pending: dict = {}  # a trial's units and seconds so far
        self.trials: dict = {}  # the seconds of each candidate's latest trial
        self.warm: set[int] = set()  # the counts that ran a first, untimed segment
        self.ran: dict[int, int] = {}  # the units run on each count so far (`shares`)
        self.interval = self.INTERVAL
        self.winner: int | None = None  # the best count at the latest round of trials
        self.due: float | None = None  # when the next round of trials begins (None: once the first is done)
        self.rounds = 0  # rounds of trials done
        self.current = None  # the candidate of the segment `run` is running
        self.started: float | None = None  # when the first segment was chosen

    def pays(self, candidate) -> float:
        """How many times faster than the others ``candidate`` must run to be chosen (1: none)."""
        return 1.0

    def within(self, candidate):
        """The context a segment of ``candidate`` runs in (none here)."""
        return contextlib.nullcontext()

    def _score(self, count) -> float:
        return self.rates[count] / self.pays(count)

    def best(self) -> int:
        """The best of the counts with a rate (class docstring)."""
        return max(self.rates, key=self._score)

    def choose(self):
        """The candidate for the next segment: the first alone for the first `DEFER` seconds, then a candidate
        without a rate (a trial), else the best."""
        now = self.clock()
        if self.started is None:
            self.started = now
        if now < self.started + self.DEFER:
            return self.candidates[0]
        if self.due is not None and now >= self.due and len(self.rates) > 1:
            keep = self.best()  # a new round: the others are tried again
            self.rates, self.due = {keep: self.rates[keep]}, None
        for count in self.candidates:
            if count not in self.rates:
                return count
        return self.best()

    def stretch(self) -> tuple[int, float]:
        """``(count, seconds)``: the count to run now and how long it may run before the tuner wants to be asked
        again (0: at once, a trial is under way or due)."""
        count = self.choose()
        deferred = self.started + self.DEFER - self.clock()
        if deferred > 0 and count in self.rates:
            return count, deferred
        if len(self.rates) < len(self.candidates) or self.due is None:
            return count, 0.0
        return count, max(0.0, self.due - self.clock())

    def shares(self) -> dict[int, float]:
        """``{count: share}``: the share of the units run so far that each count ran (what the tuner chose,
        recorded with a run's provenance, `util.provenance`); empty before the first segment."""
        total = sum(self.ran.values())
        return {count: self.ran[count] / total for count in sorted(self.ran, reverse=True)} if total else {}

    def note(self, count: int, units: float) -> None:
        """``units`` run on ``count`` threads by the caller, in a stretch (`stretch`): counted in `shares`."""
        self.ran[count] = self.ran.get(count, 0) + units

    def _trial_units(self, count: int, units: int) -> int:
        """Units for a segment of ``count``'s trial (or its first, untimed segment): what is left of `TRIAL_SECONDS`
        at the rate its trial has shown so far; before it has shown one, `TRIAL_SHARE` times less, at the fastest
        rate known (a count 50 times slower, as two threads beside busy processes can be, then costs a few
        milliseconds, not half a second), else `TRIAL_SHARE` of ``units``; at most ``units``."""
        done, took = self.pending.get(count, (0, 0.0))
        if took > 0:
            rate, seconds = done / took, self.TRIAL_SECONDS - took
        elif self.rates:
            rate, seconds = max(self.rates.values()), self.TRIAL_SECONDS / self.TRIAL_SHARE
        else:
            return max(1, units // self.TRIAL_SHARE)
        return int(min(units, max(1, round(rate * seconds))))

    def run(self, segment, units: int) -> int:
        """``segment(n)`` on the chosen count, timed, for ``n = units`` (``units >= 1``: steps, blocks,
        whatever ``segment`` counts, the same for every call) or, on a trial, about `TRIAL_SECONDS` of them;
        returns ``n``: the caller offers the rest again."""
        count = self.current = self.choose()
        trial = count not in self.rates
        n = self._trial_units(count, units) if trial else units
        start = self.clock()
        with self.within(count):
            segment(n)
        elapsed = self.clock() - start
        if count not in self.warm:  # its first segment: run, not timed (class docstring)
            self.warm.add(count)
            self.ran[count] = self.ran.get(count, 0) + n
        elif not trial:
            self.ran[count] = self.ran.get(count, 0) + n
            self.rates[count] = 0.5 * (self.rates[count] + n / max(elapsed, 1e-9))
        else:
            self.ran[count] = self.ran.get(count, 0) + n
            done, took = self.pending.get(count, (0, 0.0))
            done, took = done + n, took + elapsed
            if took < self.TRIAL_SECONDS:
                self.pending[count] = (done, took)
            else:
                self.pending.pop(count, None)
                self.rates[count], self.trials[count] = done / took, took
                if len(self.rates) == len(self.candidates):
                    self._round_done()
        return n

    def _round_done(self) -> None:
        """A round of trials is complete: the winner, and when the next round begins."""
        best = self.best()
        self.interval = min(2 * self.interval, self.MAX_INTERVAL) if best == self.winner else self.INTERVAL
        self.winner, self.rounds = best, self.rounds + 1
        lost = sum(max(0.0, 1.0 - self._score(c) / self._score(best)) * self.trials.get(c, 0.0)
                   for c in self.rates if c != best)
        self.due = self.clock() + max(self.interval, lost / self.BUDGET)
