"""A limited loop's start (`limited_prepare`, `engine.harness`'s ``prepare``) and the shape of the arrays
every loop reads (`fixed_rows`): the parts of `loops` that read no rule, compiled once for every rule."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import njit

from ..chain import COLLISIONS, STEPS
from ..jit.cache import INLINED, jit_cached_if_possible
from ..jit.intrinsics import fixed_width
from ..margin import LARGEST, NEAR_COLLISIONS, NEAR_REMNANTS, SMALLEST
from ..streams.xoshiro import load

__all__ = ["fixed_rows", "limited_prepare"]


@functools.cache
def fixed_rows(dim: int) -> Callable:
    """``shaped(v, pairs, ends, units) -> (v, pairs, ends, units)``: the same arrays (views,
    same memory) with their row lengths ``dim`` and 2 as compile-time constants, so the loop
    finds a row with a shift or ``lea`` instead of a multiply by a shape held in memory."""
    D = dim

    @njit(inline="always")
    def shaped(v, pairs, ends, units):
        if v.shape[1] != D or units.shape[1] != D or pairs.shape[1] != 2 or ends.shape[1] != 2:
            raise ValueError("the loop's tables do not have the row lengths it was built for")
        return fixed_width(v, D), fixed_width(pairs, 2), fixed_width(ends, 2), fixed_width(units, D)

    return shaped


@functools.cache
def limited_prepare(begin: Callable, dim: int, LOG: bool) -> Callable:
    """``prepare(v, pairs, ends, units, masses, params, pattern, state, aux, rng_words, counters, margin,
    max_steps, max_collisions, until_frozen, chunk, saved, log, tune)``: a limited loop's start (`engine.harness`'s
    ``prepare``: ``data`` and ``carry`` as `loops`' ``make_limited`` says), compiled on its own and inlined by
    LLVM. It reads no rule: one for every rule of a selector, ``dim`` and ``LOG``, cached on disk, so a new
    rule's loops do not compile it again."""
    shaped = fixed_rows(dim)

    @jit_cached_if_possible(**INLINED)
    def prepare(v, pairs, ends, units, masses, params, pattern, state, aux, rng_words, counters, margin,
                max_steps, max_collisions, until_frozen, chunk_steps, saved, log, tune):
        v, pairs, ends, units = shaped(v, pairs, ends, units)
        n, rng = pairs.shape[0], load(rng_words)
        m = (margin[SMALLEST], margin[LARGEST], margin[NEAR_COLLISIONS], margin[NEAR_REMNANTS])
        flags = np.empty(0, dtype=np.uint8)
        begin(state, aux, flags)
        collisions, base = counters[COLLISIONS], counters[STEPS]
        if LOG:  # no more collisions in this call than the log holds
            max_collisions = min(max_collisions, collisions + log.shape[0])
        data = (v, pairs, ends, units, masses, params, pattern, state, aux, n, saved, log, base, collisions,
                params[params.shape[0] - 1], flags, rng_words, counters, margin, tune)
        free = False  # the first block of the table loop has a branch (`chunk_blocks`)
        return data, (rng, m, (m[1], m[3]), free), collisions, max_steps, max_collisions, until_frozen, chunk_steps

    return prepare
