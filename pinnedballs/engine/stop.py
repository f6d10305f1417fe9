"""`Stop`: when a run ends, as a predicate of the simulation's counters and its freeze.

The run driver (`pinnedballs.engine.driver`) runs to a `Stop`; a run spec's ``"stop"`` builds one
(`pinnedballs.specs.stop.StopSpec.build`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Stop"]


@dataclass(frozen=True)
class Stop:
    """When a run ends, in absolute counts: ``steps`` in total (the reason is ``steps_reason``),
    ``collisions`` in total, or, with ``until_frozen``, right after the collision that freezes it.

    Reasons are checked in the order collisions, frozen, steps.
    """

    steps: int | None = None
    collisions: int | None = None
    until_frozen: bool = False
    steps_reason: str = "steps"

    def reason(self, sim, frozen: bool) -> str:
        """Why the run is over (``"collisions"``, ``"frozen"``, ``steps_reason``), or ``""``."""
        if self.collisions is not None and sim.collisions >= self.collisions:
            return "collisions"
        if frozen:
            return "frozen"
        if self.steps is not None and sim.steps >= self.steps:
            return self.steps_reason
        return ""
