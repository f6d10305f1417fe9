"""Scheduler specs: ``build()`` returns the `Scheduler`."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field

from ..schedulers import RandomSweep, Scheduler, Sweep, UniformRandomPair
from .base import _Spec
from .python import PythonSchedulerSpec

__all__ = ["UniformRandomPairSpec", "SweepSpec", "RandomSweepSpec", "SchedulerSpec"]


class UniformRandomPairSpec(_Spec):
    """The paper's scheduler: one contact uniformly at random per step."""

    kind: Literal["uniform_random_pair"] = "uniform_random_pair"

    def build(self) -> Scheduler:
        return UniformRandomPair()


class SweepSpec(_Spec):
    """Every contact once per sweep, in a fixed order."""

    kind: Literal["sweep"] = "sweep"

    def build(self) -> Scheduler:
        return Sweep()


class RandomSweepSpec(_Spec):
    """Every contact once per sweep, in a fresh random order."""

    kind: Literal["random_sweep"] = "random_sweep"

    def build(self) -> Scheduler:
        return RandomSweep()


SchedulerSpec = Annotated[Union[UniformRandomPairSpec, SweepSpec, RandomSweepSpec, PythonSchedulerSpec],
                          Field(discriminator="kind")]
