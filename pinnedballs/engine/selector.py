"""What a scheduler gives the compiled loops (`engine.sequential.loops`): a `Selector`, its functions and flags, and
the selector of a scheduler that picks one contact a step (`pick_selector`)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from .jit.cache import INLINED, jit_cached_if_possible, njit_cached

__all__ = ["Selector", "pick_selector", "no_begin", "no_change", "NO_AUX"]


class Selector(NamedTuple):
    """What a scheduler gives the engine: its jitted functions (see `engine.sequential.loops`) and flags.

    aux: the arrays (or a tuple of them) its functions read besides ``state``.
    tracks: it needs the live set kept up to date after every collision (the ``tracked`` loop).
    skips: ``select`` may take more than one step per pick, or return no contact (``k < 0``).
    uniform: its picks are the paper's, one word of the stream each through `random.bounded`, so the
    parallel chain (`engine.threads.regions`) may draw them ahead on several threads.
    counter: its picks are the counter stream's (`engine.streams.philox`): the stream words are ``(k0, k1, s, 0)``,
    the pick of step ``s`` a function of the key and ``s``, so batches of picks may run by deterministic
    reservations on threads (`engine.threads.reservations`) or on a GPU (`engine.gpu`).
    steps: None, or ``steps(collide, dim, flat) -> loop``: its own compiled loop for plain steps
    (`ColoredSweep` runs a class in parallel), called as ``loop(v, pairs, ends, units, masses, params,
    state, aux, rng_words, counters, margin, max_steps) -> steps``.
    """

    select: Callable
    begin: Callable
    changed: Callable
    aux: object
    tracks: bool = False
    skips: bool = False
    steps: Callable | None = None
    uniform: bool = False
    counter: bool = False


@njit_cached(inline="always")
def no_begin(state, aux, flags):
    """Nothing to prepare."""


@njit_cached(inline="always")
def no_change(state, aux, c, live):
    """Nothing to hear."""


#: the ``aux`` of a selector that needs none
NO_AUX = np.zeros(0, dtype=np.int64)


@functools.cache
def pick_selector(pick: Callable) -> Selector:
    """The `Selector` of a scheduler that picks one contact per step: ``pick(state, rng, n) -> (k, rng)``."""

    @jit_cached_if_possible(**INLINED)
    def select(state, aux, rng, n, left):
        k, rng = pick(state, rng, n)
        return k, 1, rng

    return Selector(select, no_begin, no_change, NO_AUX)
