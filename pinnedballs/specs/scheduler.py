"""Scheduler specs: ``build()`` returns the `Scheduler`."""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field

from .base import _Spec
from .python import PythonSchedulerSpec

if TYPE_CHECKING:  # built when asked: a spec is validated (its schema written) without the engine
    from ..schedulers.base import Scheduler

__all__ = ["UniformRandomPairSpec", "SweepSpec", "RandomSweepSpec", "RejectionFreeSpec", "ColoredSweepSpec",
           "SchedulerSpec"]


class UniformRandomPairSpec(_Spec):
    """The paper's scheduler: one contact uniformly at random per step."""

    kind: Literal["uniform_random_pair"] = "uniform_random_pair"
    #: numba threads a run may use (None: every core, tuned; 1: the sequential loop); the results do not depend on it
    threads: Annotated[int, Field(ge=1)] | None = None
    #: "xoshiro" (the default): xoshiro256** words in order; "counter": Philox4x64-10, the pick of step s a
    #: function of (seed, s) alone, which runs on every core and on a GPU with the same bits
    stream: Literal["xoshiro", "counter"] = "xoshiro"

    def build(self) -> Scheduler:
        from ..schedulers.simple import UniformRandomPair

        return UniformRandomPair(threads=self.threads, stream=self.stream)


class SweepSpec(_Spec):
    """Every contact once per sweep, in a fixed order."""

    kind: Literal["sweep"] = "sweep"

    def build(self) -> Scheduler:
        from ..schedulers.simple import Sweep

        return Sweep()


class RandomSweepSpec(_Spec):
    """Every contact once per sweep, in a fresh random order."""

    kind: Literal["random_sweep"] = "random_sweep"

    def build(self) -> Scheduler:
        from ..schedulers.simple import RandomSweep

        return RandomSweep()


class RejectionFreeSpec(_Spec):
    """The paper's chain without its rejected picks (`RejectionFree`): same law, far fewer loop turns."""

    kind: Literal["rejection_free"] = "rejection_free"

    def build(self) -> Scheduler:
        from ..schedulers.rejection_free import RejectionFree

        return RejectionFree()


class ColoredSweepSpec(_Spec):
    """Colour classes of contacts sharing no ball in turn, each in parallel (`ColoredSweep`)."""

    kind: Literal["colored_sweep"] = "colored_sweep"
    shuffle: bool = False
    #: numba threads a run uses (None: ``NUMBA_NUM_THREADS``, every core); the results do not depend on it
    threads: Annotated[int, Field(ge=1)] | None = None

    def build(self) -> Scheduler:
        from ..schedulers.colored_sweep import ColoredSweep

        return ColoredSweep(shuffle=self.shuffle, threads=self.threads)


SchedulerSpec = Annotated[UniformRandomPairSpec | SweepSpec | RandomSweepSpec | RejectionFreeSpec | ColoredSweepSpec
                          | PythonSchedulerSpec, Field(discriminator="kind")]
