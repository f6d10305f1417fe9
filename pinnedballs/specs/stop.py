"""When a run ends (`StopSpec`), when it stores snapshots (`SnapshotsSpec`), how often it checkpoints."""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, Field, model_validator

from ..engine.stop import Stop
from ..engine.triggers import AtCollisions, AtSteps, EveryCollisions, EverySteps, Trigger
from .base import Count, _only_one, _Spec

__all__ = ["StopSpec", "SnapshotsSpec", "CheckpointSpec"]


class StopSpec(_Spec):
    """When the run ends: after ``steps``, at ``collisions`` in total, or when ``frozen`` (within ``max_steps``).

    A ``collisions`` target the system cannot reach because it froze first ends the
    run at the freeze.
    """

    steps: Count | None = None
    collisions: Count | None = None
    frozen: bool = False
    max_steps: Count | None = None

    @model_validator(mode="after")
    def _one_stop(self) -> StopSpec:
        _only_one(self, ("steps", "collisions", "frozen"), "steps, collisions or frozen")
        if self.frozen and self.max_steps is None:
            raise ValueError("max_steps: required with frozen (a flat torus never freezes)")
        if not self.frozen and self.max_steps is not None:
            raise ValueError("max_steps: only allowed with frozen")
        return self

    @property
    def kind(self) -> str:
        """``"steps"``, ``"collisions"`` or ``"frozen"``."""
        return "steps" if self.steps is not None else "collisions" if self.collisions is not None else "frozen"

    def build(self) -> Stop:
        """The driver's `Stop` (counts from the start of the run)."""
        if self.kind == "steps":
            return Stop(steps=self.steps)
        if self.kind == "collisions":
            return Stop(collisions=self.collisions, until_frozen=True)
        return Stop(steps=self.max_steps, until_frozen=True, steps_reason="max_steps")


def _sorted_unique(values: list[int] | None) -> list[int] | None:
    return None if values is None else sorted(set(values))


class SnapshotsSpec(_Spec):
    """When to store the velocities: at listed step or collision counts, or every N of them."""

    at_steps: Annotated[list[Count], AfterValidator(_sorted_unique)] | None = None
    at_collisions: Annotated[list[Count], AfterValidator(_sorted_unique)] | None = None
    every_steps: Annotated[int, Field(ge=1)] | None = None
    every_collisions: Annotated[int, Field(ge=1)] | None = None

    @model_validator(mode="after")
    def _one_rule(self) -> SnapshotsSpec:
        _only_one(self, ("at_steps", "at_collisions", "every_steps", "every_collisions"),
                  "at_steps, at_collisions, every_steps or every_collisions")
        return self

    @property
    def counter(self) -> str:
        """``"steps"`` or ``"collisions"``: the counter the snapshots are placed on."""
        return "steps" if self.at_steps is not None or self.every_steps is not None else "collisions"

    def target(self, n: int) -> int | None:
        """The count at which snapshot ``n`` (from 0) is taken, or None if there are fewer."""
        listed = self.at_steps if self.at_steps is not None else self.at_collisions
        if listed is not None:
            return listed[n] if n < len(listed) else None
        return (n + 1) * (self.every_steps or self.every_collisions)

    def build(self) -> Trigger:
        """The `Trigger` that fires at these counts."""
        if self.at_steps is not None:
            return AtSteps(self.at_steps)
        if self.at_collisions is not None:
            return AtCollisions(self.at_collisions)
        return EverySteps(self.every_steps) if self.every_steps is not None else EveryCollisions(self.every_collisions)


class CheckpointSpec(_Spec):
    """How often a running simulation saves its state (also at every snapshot); 0 means after every chunk."""

    every_seconds: Annotated[float, Field(ge=0)] = 60.0
