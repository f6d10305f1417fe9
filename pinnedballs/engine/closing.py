"""The closing speed of a contact, ``w = v_i . t_i + v_j . t_j``: what every rule and every loop
computes first (positive: the balls approach). Here, below the rules, so the engine's loops can
keep each pick's closing speed (the margin, `engine.margin`) with the rule's own arithmetic.

A loop computes ``w`` once per pick and hands it to the rule's *closing form*
``collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w) -> bool``: the built-in
rules register theirs (`register_closing_form`), the same arithmetic as their ``collide`` given its
first step; any other rule's ``collide`` is wrapped and recomputes ``w`` itself (`closing_form`).
"""

from __future__ import annotations

import functools
from typing import Callable

from numba import njit

from .jitcache import njit_cached

__all__ = ["closing_speed", "t_j", "closing_form", "register_closing_form"]

#: ``collide -> collide_at`` for the rules that compute ``w`` with `closing_speed` first
_FORMS: dict = {}


def register_closing_form(collide: Callable, collide_at: Callable) -> None:
    """Say that ``collide(...)`` is ``collide_at(..., closing_speed(...))``, bit for bit."""
    _FORMS[collide] = collide_at


@functools.cache
def closing_form(collide: Callable) -> Callable:
    """The closing form of a rule's ``collide``: its registered one, or ``collide`` ignoring ``w``."""
    if collide in _FORMS:
        return _FORMS[collide]

    @njit(inline="always")
    def collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w):
        return collide(v, units, i, j, a, b, masses, params, dim, flat, write)

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
