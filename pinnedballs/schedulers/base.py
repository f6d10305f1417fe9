"""Schedulers: which contacts are tried, in which order.

The simple kind (`pinnedballs.schedulers.simple`) answers "which contact next": its `kernel` hands the compiled
loop a jitted function ``pick(state, rng, n_contacts) -> (k, rng)`` and its
`initial_state` gives its ``int64`` state array. ``rng`` is the simulation's one
random stream, a 4-tuple of uint64 words (`pinnedballs.engine.random`); ``pick``
returns the advanced tuple. The default `Scheduler.loops` and
`Scheduler.advance` compile that ``pick`` into `kernels.chain_kernel`'s loops.

A scheduler that owns its loop (`rejection_free`,
`colored_sweep`) overrides `loops` and `advance` instead, and says
with `needs_live` whether it wants the live-contact set (`kernels.LiveSet`),
which the `Simulation` owns and refreshes for it. Either way everything that
changes lives in ``state`` and ``rng``, so a checkpoint of the two resumes it
exactly; `check_state` (and `check_resume`) refuse a state it cannot resume from.
"""

from __future__ import annotations

from abc import ABC
from typing import Callable

import numpy as np

from ..engine.chain import NO_LIMIT, Chain, LiveSet
from ..engine.errors import FieldError, FieldTypeError, check_jitted
from ..engine.loops import LOOKAHEAD_BYTES, chain_kernel

__all__ = ["Scheduler"]


class Scheduler(ABC):
    """Chooses which contact the loop tries next (`kernel`), or runs its own loops
    (`loops` and `advance`)."""

    def kernel(self) -> Callable:
        """The jitted ``pick(state, rng, n_contacts) -> (k, rng)``."""
        raise FieldTypeError("scheduler", f"{type(self).__name__} must define kernel() (a pick function) "
                        f"or loops() and advance()")

    def loops(self, collide: Callable, geometry) -> object:
        """The compiled loops for a rule's ``collide`` on ``geometry``; built once per `Simulation`
        and handed back to `advance`. Default: `kernels.chain_kernel` around `kernel`'s ``pick``."""
        pick = check_jitted(self.kernel(), "scheduler", f"{type(self).__name__}.kernel()'s pick")
        return chain_kernel(collide, pick, geometry.dim, geometry.contacts.flat)

    def needs_live(self, track: bool) -> bool:
        """Whether `advance` wants the live set, freshly computed, for a call with this ``track``."""
        return track

    def advance(self, loops, chain: Chain, live: LiveSet | None, state: np.ndarray, rng: np.ndarray,
                counters: np.ndarray, max_steps: int, max_collisions: int, track: bool) -> int:
        """Run the loops: at most ``max_steps`` steps, until ``max_collisions`` collisions in total
        (`kernels.NO_LIMIT`: none) and, when ``track``, until no contact is live.

        ``chain`` is read and its velocities written in place; ``state`` (this scheduler's),
        ``rng`` ``(4,) uint64`` and ``counters`` ``(3,) int64`` (steps, collisions, live) are
        advanced in place; ``live`` is given when `needs_live` says so, with ``counters[LIVE]``
        exact. Returns the number of steps taken.
        """
        if not track and max_collisions == NO_LIMIT:
            large = chain.pairs.nbytes + chain.ends.nbytes + chain.v.nbytes > LOOKAHEAD_BYTES
            return (loops.steps_prefetched if large else loops.steps)(*chain, state, rng, counters, max_steps)
        ptr, inc, flags = live if track else (_EMPTY_PTR, _EMPTY_INC, _EMPTY_FLAGS)
        return loops.limited(*chain, state, rng, counters, max_steps, max_collisions, track, ptr, inc, flags)

    def check_resume(self, state: np.ndarray, loops, flags: np.ndarray | None) -> None:
        """Raise ValueError unless ``state`` (already through `check_state`) fits the tables of
        ``loops`` and, when `needs_live`, the live contacts ``flags (E,)`` of the velocities it is
        restored with. Nothing to check for a ``pick`` scheduler."""

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """The ``int64`` state array ``pick`` starts from."""
        return np.zeros(1, dtype=np.int64)

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """Raise ValueError unless ``state`` is one this scheduler can resume from.

        The compiled loop indexes with it unchecked, so a corrupt checkpoint must stop here.
        """
        expected = self.initial_state(n_contacts).shape
        if state.shape != expected:
            raise FieldError("scheduler_state", f"must have shape {expected} for {self!r}, got {state.shape}")

    def to_spec(self) -> dict | None:
        """The scheduler as a run spec's ``"scheduler"`` (a dict with its ``"kind"``), or None if it
        has none. A run built in Python records this spec, so that ``pb.load(dir).simulation()``
        rebuilds the scheduler; one of your own may return ``{"kind": "python", "factory": ..., "args": ...}``.
        """
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __eq__(self, other) -> bool:
        """Same class and same parameters (attributes, arrays compared element by element)."""
        if type(other) is not type(self) or vars(other).keys() != vars(self).keys():
            return False
        return all(np.array_equal(value, vars(other)[key]) for key, value in vars(self).items())

    def __hash__(self) -> int:
        return hash(type(self))


_EMPTY_PTR = np.zeros(1, dtype=np.int64)
_EMPTY_INC = np.zeros(0, dtype=np.uint32)
_EMPTY_FLAGS = np.zeros(0, dtype=np.uint8)
