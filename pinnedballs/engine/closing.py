"""The closing speed of a contact, ``w = v_i . t_i + v_j . t_j``: what every rule and every loop
computes first (positive: the balls approach). Here, below the rules, so the engine's loops can
keep each pick's closing speed (the margin, `engine.margin`) with the rule's own arithmetic.

A loop computes ``w`` once per pick and hands it to the rule's *closing form*
``collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w) -> bool``: the built-in
rules register theirs (`register_closing_form`), the same arithmetic as their ``collide`` given its
first step; any other rule's ``collide`` is wrapped and recomputes ``w`` itself (`closing_form`).

**Compiled once per rule.** `compiled_form` compiles a rule's closing form for one ``dim`` and
``flat`` on its own (and caches it on disk), with ``write`` a run-time flag: every loop, freeze scan
and live-set update calls it, and LLVM inlines it there, where ``write`` is a constant again. A new
rule therefore goes through numba's pipeline once, not once per loop that tries a contact.
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np
from numba import njit

from .jitcache import INLINED, jit_cached_if_possible, njit_cached

__all__ = ["closing_speed", "t_j", "closing_form", "register_closing_form", "compiled_form", "WRITE", "TEST",
           "ELASTIC", "EQUAL", "MASSES", "register_device_rule", "device_rule"]

#: ``write`` as run-time flags (numba compiles a function once for all values of a ``numpy.bool_``,
#: but once per value of a ``bool`` constant): True writes the collision, False only tests for one
WRITE, TEST = np.bool_(True), np.bool_(False)

#: ``collide -> collide_at`` for the rules that compute ``w`` with `closing_speed` first
_FORMS: dict = {}

#: the built-in rules as the GPU's kernels number them (`engine.gpu`): the paper's exchange, equal masses
#: with restitution ``params[0] = (1 + r) / 2``, any masses with ``params[0] = 1 + r``
ELASTIC, EQUAL, MASSES = 0, 1, 2
#: ``collide -> number`` of the rules a GPU runs, registered by `pinnedballs.rules`
_DEVICE_RULES: dict = {}


def register_closing_form(collide: Callable, collide_at: Callable) -> None:
    """Say that ``collide(...)`` is ``collide_at(..., closing_speed(...))``, bit for bit."""
    _FORMS[collide] = collide_at


def register_device_rule(collide: Callable, number: int) -> None:
    """Say that a GPU runs ``collide`` as its kernel rule ``number`` (`ELASTIC`, `EQUAL`, `MASSES`)."""
    _DEVICE_RULES[collide] = number


def device_rule(collide: Callable) -> int | None:
    """The GPU's number of a rule's ``collide``, None for a rule a GPU does not run (a user's)."""
    return _DEVICE_RULES.get(collide)


@functools.cache
def closing_form(collide: Callable) -> Callable:
    """The closing form of a rule's ``collide``: its registered one, or ``collide`` ignoring ``w``."""
    if collide in _FORMS:
        return _FORMS[collide]

    @njit(inline="always")
    def collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w):
        return collide(v, units, i, j, a, b, masses, params, dim, flat, write)

    return collide_at


@functools.cache
def compiled_form(collide: Callable, dim: int, flat: bool) -> Callable:
    """``collide_at(v, units, i, j, a, b, masses, params, write, w) -> bool``: the closing form of a
    rule's ``collide`` with ``dim`` and ``flat`` built in, compiled once (``write`` a `WRITE` or `TEST`
    flag) and inlined by LLVM into its callers."""
    form, D, FLAT = closing_form(collide), dim, flat

    @jit_cached_if_possible(**INLINED)
    def collide_at(v, units, i, j, a, b, masses, params, write, w):
        return form(v, units, i, j, a, b, masses, params, D, FLAT, write, w)

    return collide_at


@njit_cached(inline="always")
def t_j(units, a, b, k, flat):
    """Component ``k`` of ``t_j``: ``-t_i`` in flat space, else ``units[b]``."""
    return -units[a, k] if flat else units[b, k]


@njit_cached(inline="always")
def closing_speed(v, units, i, j, a, b, dim, flat):
    """``w = v_i . t_i + v_j . t_j``, summed component by component; positive means approaching.

    The sum is ``(v_i0 t_i0 + v_j0 t_j0) + (v_i1 t_i1 + v_j1 t_j1) + ...``, left to right.
    """
    w = v[i, 0] * units[a, 0] + v[j, 0] * t_j(units, a, b, 0, flat)
    for k in range(1, dim):
        w += v[i, k] * units[a, k] + v[j, k] * t_j(units, a, b, k, flat)
    return w
