"""Which limited loop a CPU run takes for its system's size, chosen on the CPU that runs it (`LoopChoice`).

The limited loops (`engine.sequential.loops`) give the same bits: ``tables`` reads a contact's two rows of the
``(E, 2)`` tables as its pick comes (in blocks, with a branch on each collision or without, as
`engine.sequential.choice` chooses); ``prefetched`` draws picks 8 steps early and fetches their table rows,
then their velocity rows; ``rows`` reads each contact from the lattice's row pattern (`engine.rows`), picks
drawn 16 steps early, so a step touches only the two velocity rows. Where the tables and velocities fit in a
core's L2 cache the table loop wins; far beyond the caches the prefetching loops do (on the 2-core
machine's CPU the two cross near 4 MB, 4 times its L2: docs/performance.md). Where between depends on the
CPU, so where the system's bytes lie between `LOW` and `HIGH` times the CPU's L2 cache, a `engine.tuner.Tuner`
times both on the run's own steps (by the thread's CPU time: the loop's own work, whatever else the machine
runs) and keeps the faster; below, the tables; above, the prefetching loop (``rows`` where the geometry
has a row pattern). ``PINNEDBALLS_LOOP`` forces one (`choice.loop_setting`).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable

from ...util.errors import FieldError
from ..tuner import Tuner
from .loops import LOOKAHEAD_BYTES, NO_PATTERN

__all__ = ["LoopChoice", "LOW", "HIGH", "SEGMENT", "l2_bytes"]

#: the loops are timed against each other where the bytes lie between these multiples of the L2 cache
LOW, HIGH = 1, 16
#: steps a segment of a timed run (a trial, or the stretch between two asks)
SEGMENT = 1 << 20
#: the setting's loop for each ``PINNEDBALLS_LOOP`` that names one
_FORCED = {"branch": "tables", "branch_free": "tables", "threshold": "tables", "tables": "tables",
           "prefetched": "prefetched", "rows": "rows"}


@functools.cache
def l2_bytes() -> int | None:
    """The bytes of a core's L2 cache (`util.provenance.cpu`), or None where unreadable."""
    from ...util.provenance import cpu

    return cpu().get("l2_cache")


class LoopChoice:
    """The limited loop of one chain (module docstring): ``loops`` (`Loops`), the selector's ``skips``, the
    contact tables' and velocities' ``nbytes``, ``pattern()`` the geometry's row pattern (None: none; asked only
    where a loop reading it may run) and the ``setting`` (`choice.loop_setting`)."""

    def __init__(self, loops, skips: bool, nbytes: int, pattern: Callable[[], tuple | None], setting: str):
        self.loops, self.setting, self._skips, self._nbytes, self._pattern = loops, setting, skips, nbytes, pattern
        self.ran = False  # whether a step ran through `run`
        if setting == "rows":  # refused at once where it cannot run
            self._decided()

    @property
    def pattern(self) -> tuple | None:
        """The geometry's row pattern (`engine.rows`), None where it has none: built on first need (for a large
        lattice its temporaries are several times the tables, so a `Simulation` built and not run pays none)."""
        if callable(self._pattern):
            self._pattern = self._pattern()
        return self._pattern

    @functools.cached_property
    def _decision(self) -> tuple[tuple[str, ...], str, Tuner | None]:
        """``(candidates, by, tuner)``, decided on first need (class docstring)."""
        setting, nbytes, l2 = self.setting, self._nbytes, l2_bytes()
        if self._skips:  # a selector that jumps over picks: the table loop (the others draw one step a pick)
            return ("tables",), "the scheduler", None
        if setting in _FORCED:
            if _FORCED[setting] == "rows" and self.pattern is None:
                raise FieldError("PINNEDBALLS_LOOP", "'rows' reads a lattice's row pattern, and this geometry has "
                                                     "none (a lattice of 16,384 balls or more has one)")
            return (_FORCED[setting],), f"PINNEDBALLS_LOOP={setting}", None
        near = nbytes <= (LOOKAHEAD_BYTES if l2 is None else LOW * l2)
        if l2 is None or not LOW * l2 < nbytes < HIGH * l2:
            return ("tables" if near else self._far(),), "size", None
        both = ("tables", self._far()) if nbytes <= LOOKAHEAD_BYTES else (self._far(), "tables")
        return both, "measured", Tuner(both, clock=time.thread_time)

    def _decided(self) -> None:
        self._decision  # noqa: B018 (decides, or refuses)

    def _far(self) -> str:
        return "rows" if self.pattern is not None else "prefetched"

    @property
    def candidates(self) -> tuple[str, ...]:
        """The loops it may run, in the order they are first tried."""
        return self._decision[0]

    @property
    def by(self) -> str:
        """What chose them: "size", "measured", "the scheduler" or "PINNEDBALLS_LOOP=..."."""
        return self._decision[1]

    @property
    def tuner(self) -> Tuner | None:
        """The `Tuner` timing two candidates, None where there is one."""
        return self._decision[2]

    def loop(self, name: str, logged: bool = False) -> tuple[Callable, tuple]:
        """``(loop, pattern)``: the limited loop ``name`` (`choice.LOOPS`) and the row pattern it reads."""
        lp = self.loops
        if name == "tables":
            return (lp.limited_logged if logged else lp.limited), NO_PATTERN
        if name == "prefetched":
            return (lp.limited_prefetched_logged if logged else lp.limited_prefetched), NO_PATTERN
        return (lp.limited_rows_logged if logged else lp.limited_rows), self.pattern

    @property
    def name(self) -> str:
        """The loop running now (the best measured so far, else the first candidate)."""
        if self.tuner is None or not self.tuner.rates:
            return self.candidates[0]
        return self.tuner.best()

    def run(self, call: Callable, max_steps: int) -> int:
        """``call(loop, pattern, steps) -> taken`` (the loop run to the call's limits) for at most ``max_steps``
        steps: on the one candidate, or in the tuner's segments and stretches (a stretch that takes fewer steps
        than it was given stopped at a limit: the run ends there). No steps: every candidate compiled."""
        self.ran = self.ran or max_steps > 0
        if self.tuner is None:
            return call(*self.loop(self.candidates[0]), max_steps)
        if max_steps <= 0:
            for name in self.candidates:
                call(*self.loop(name), 0)
            return 0
        taken, tuner, out = 0, self.tuner, []

        def segment(n: int) -> None:
            out.append(call(*self.loop(tuner.current), n))

        while taken < max_steps:
            left = max_steps - taken
            name, seconds = tuner.stretch()
            if seconds > 0:
                steps = int(min(left, max(SEGMENT, tuner.rates[name] * seconds)))
                done = call(*self.loop(name), steps)
                tuner.note(name, done)
            else:
                steps = tuner.run(segment, min(left, SEGMENT))
                done = out.pop()
            taken += done
            if done < steps:
                break
        return taken

    def described(self) -> dict:
        """What was chosen, as a run's provenance records it: ``{"name": the loop that ran the most steps, "by":
        what chose it ("size", "measured", "the scheduler", "PINNEDBALLS_LOOP=..."), "shares": {loop: share of
        the steps}}`` (shares where timed)."""
        said = {"name": self.name, "by": self.by}
        shares = self.tuner.shares() if self.tuner is not None else {}
        if shares:
            said["name"] = max(shares, key=shares.get)
            said["shares"] = {name: round(float(share), 4) for name, share in shares.items()}
        return said
