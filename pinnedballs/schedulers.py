"""Schedulers: which contact to try next.

A scheduler is a Python object whose `kernel` hands the compiled loop a jitted
function ``pick(state, rng, n_contacts) -> (k, rng)`` and whose `initial_state`
gives its ``int64`` state array. ``rng`` is the simulation's one random stream,
a 4-tuple of uint64 words (`pinnedballs.random`); ``pick`` returns the advanced
tuple. A scheduler never owns randomness of its own, so a checkpoint of
``state`` and ``rng`` resumes it exactly.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Callable

import numpy as np
from numba import njit

from .errors import FieldValueError
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
    """Chooses which contact the loop tries next."""

    @abstractmethod
    def kernel(self) -> Callable:
        """The jitted ``pick(state, rng, n_contacts) -> (k, rng)``."""

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """The ``int64`` state array ``pick`` starts from."""
        return np.zeros(1, dtype=np.int64)

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """Raise ValueError unless ``state`` is one this scheduler can resume from.

        The compiled loop indexes with it unchecked, so a corrupt checkpoint must stop here.
        """
        expected = self.initial_state(n_contacts).shape
        if state.shape != expected:
            raise FieldValueError("scheduler_state", f"must have shape {expected} for {self!r}, got {state.shape}")

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
            raise FieldValueError("scheduler_state", f"the next contact must be in [0, {n_contacts}), got {state[0]}")


class RandomSweep(Scheduler):
    """Tries every contact once per sweep, in a fresh uniformly random order each sweep."""

    def kernel(self) -> Callable:
        return pick_random_sweep

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        super().check_state(state, n_contacts)
        if not 0 <= state[0] <= n_contacts:
            raise FieldValueError("scheduler_state", f"the position in the sweep must be in [0, {n_contacts}], got {state[0]}")
        if not np.array_equal(np.sort(state[1:]), np.arange(n_contacts)):
            raise FieldValueError("scheduler_state", f"the sweep order must be a permutation of 0..{n_contacts - 1}")

    def initial_state(self, n_contacts: int) -> np.ndarray:
        state = np.empty(n_contacts + 1, dtype=np.int64)
        state[0] = n_contacts  # shuffle before the first pick
        state[1:] = np.arange(n_contacts)
        return state
