"""Schedulers: which contacts are tried, in which order.

The simple kind answers "which contact next": its `kernel` hands the compiled
loop a jitted function ``pick(state, rng, n_contacts) -> (k, rng)`` and its
`initial_state` gives its ``int64`` state array. ``rng`` is the simulation's one
random stream, a 4-tuple of uint64 words (`pinnedballs.random`); ``pick``
returns the advanced tuple. The default `Scheduler.loops` and
`Scheduler.advance` compile that ``pick`` into `kernels.chain_kernel`'s loops.

A scheduler that owns its loop (`pinnedballs.rejection_free`,
`pinnedballs.colored_sweep`) overrides `loops` and `advance` instead, and says
with `needs_live` whether it wants the live-contact set (`kernels.LiveSet`),
which the `Simulation` owns and refreshes for it. Either way everything that
changes lives in ``state`` and ``rng``, so a checkpoint of the two resumes it
exactly; `check_state` (and `check_resume`) refuse a state it cannot resume from.
"""

from __future__ import annotations

from abc import ABC
from typing import Callable

import numpy as np
from numba import njit

from .errors import FieldError, FieldTypeError, check_jitted
from .kernels import LOOKAHEAD_BYTES, NO_LIMIT, Chain, LiveSet, chain_kernel
from .random import bounded

__all__ = ["Scheduler", "UniformRandomPair", "Sweep", "RandomSweep"]


@njit(cache=True, inline="always")
def pick_uniform(state, rng, n_contacts):
    """The paper's Algorithm 2: a contact uniformly at random."""
    return bounded(rng, n_contacts)


@njit(cache=True, inline="always")
def pick_sweep(state, rng, n_contacts):
    """Contacts ``0, 1, ..., n-1, 0, 1, ...``; ``state[0]`` is the next one."""
    k = state[0]
    state[0] = k + 1 if k + 1 < n_contacts else 0
    return np.uint64(k), rng


@njit(cache=True, inline="always")
def pick_random_sweep(state, rng, n_contacts):
    """Every contact once per sweep in a fresh random order (Fisher-Yates).

    ``state[0]`` is the position in the sweep, ``state[1:]`` the current order.
    """
    order = state[1:]
    if state[0] >= n_contacts:
        for m in range(n_contacts - 1, 0, -1):
            r, rng = bounded(rng, m + 1)
            order[m], order[r] = order[r], order[m]
        state[0] = 0
    k = order[state[0]]
    state[0] += 1
    return np.uint64(k), rng


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

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __eq__(self, other) -> bool:
        """Same class and same parameters (attributes, arrays compared element by element)."""
        if type(other) is not type(self) or vars(other).keys() != vars(self).keys():
            return False
        return all(np.array_equal(value, vars(other)[key]) for key, value in vars(self).items())

    def __hash__(self) -> int:
        return hash(type(self))


class UniformRandomPair(Scheduler):
    """Each step tries one contact chosen uniformly at random (the paper's scheduler)."""

    def kernel(self) -> Callable:
        return pick_uniform


class Sweep(Scheduler):
    """Tries every contact once per sweep, in the geometry's fixed contact order."""

    def kernel(self) -> Callable:
        return pick_sweep

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        super().check_state(state, n_contacts)
        if not 0 <= state[0] < n_contacts:
            raise FieldError("scheduler_state", f"the next contact must be in [0, {n_contacts}), got {state[0]}")


class RandomSweep(Scheduler):
    """Tries every contact once per sweep, in a fresh uniformly random order each sweep."""

    def kernel(self) -> Callable:
        return pick_random_sweep

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        super().check_state(state, n_contacts)
        if not 0 <= state[0] <= n_contacts:
            raise FieldError("scheduler_state",
                             f"the position in the sweep must be in [0, {n_contacts}], got {state[0]}")
        if not np.array_equal(np.sort(state[1:]), np.arange(n_contacts)):
            raise FieldError("scheduler_state", f"the sweep order must be a permutation of 0..{n_contacts - 1}")

    def initial_state(self, n_contacts: int) -> np.ndarray:
        state = np.empty(n_contacts + 1, dtype=np.int64)
        state[0] = n_contacts  # shuffle before the first pick
        state[1:] = np.arange(n_contacts)
        return state


_EMPTY_PTR = np.zeros(1, dtype=np.int64)
_EMPTY_INC = np.zeros(0, dtype=np.uint32)
_EMPTY_FLAGS = np.zeros(0, dtype=np.uint8)
