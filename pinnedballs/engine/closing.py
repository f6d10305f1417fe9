"""The closing speed of a contact, ``w = v_i . t_i + v_j . t_j``: what every rule and every loop
computes first (positive: the balls approach). Here, below the rules, so the engine's loops can
keep each pick's closing speed (the margin, `engine.margin`) with the rule's own arithmetic.

A loop computes ``w`` once per pick and hands it to the rule's *closing form*
``collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w) -> bool``: the built-in
rules register theirs (`register_closing_form`), the same arithmetic as their ``collide`` given its
first step; any other rule's ``collide`` is wrapped and recomputes ``w`` itself (`closing_form`).

**Without a branch.** Where a pick collides about half the time (a lattice in equilibrium, the
paper's torus), the branch on ``w > threshold`` is mispredicted on most collisions. For the built-in
rules (those a GPU runs, `register_device_rule`) `branch_free_form` gives the same arithmetic with
the branch replaced by selects: the new velocities are computed for every pick and written where
the rule writes them, the old ones written back elsewhere (the same bits; `choose`).

**Compiled once per rule.** `compiled_form` compiles a rule's closing form for one ``dim`` and
``flat`` on its own (and caches it on disk), with ``write`` a run-time flag: every loop, freeze scan
and live-set update calls it, and LLVM inlines it there, where ``write`` is a constant again. A new
rule therefore goes through numba's pipeline once, not once per loop that tries a contact.
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np
from numba import config, njit, types
from numba.extending import intrinsic

from .jitcache import INLINED, jit_cached_if_possible, njit_cached

__all__ = ["closing_speed", "t_j", "closing_form", "register_closing_form", "compiled_form", "WRITE", "TEST",
           "ELASTIC", "EQUAL", "MASSES", "register_device_rule", "device_rule", "branch_free_form", "choose"]

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


# ---------------------------------------------------------------- without a branch


@intrinsic
def _choose_intrinsic(typingctx, c, a, b):
    """``a if c else b`` as one LLVM ``select``: no branch for the compiler to keep or make."""
    if not isinstance(c, types.Boolean) or a != b or not isinstance(a, (types.Number, types.Boolean)):
        return None

    def codegen(context, builder, signature, args):
        return builder.select(args[0], args[1], args[2])

    return a(c, a, b), codegen


def _choose_python(c, a, b):
    """Without the JIT (``NUMBA_DISABLE_JIT=1``): ``a if c else b``."""
    return a if c else b


#: ``choose(c, a, b)``: ``a if c else b`` for a boolean ``c`` and two numbers of one type, without a branch
choose = _choose_python if config.DISABLE_JIT else _choose_intrinsic


@njit_cached(inline="always")
def _impulse_where(v, units, i, j, a, b, ci, cj, go, dim, flat):
    """``pinnedballs.rules._impulse`` with ``write = go``, without a branch: the new components are
    computed either way and written where ``go``, the old ones written back elsewhere. True if any
    component changes (whether or not ``go``)."""
    changed = False
    for k in range(dim):
        old_i, old_j = v[i, k], v[j, k]
        new_i = old_i - ci * units[a, k]
        new_j = old_j - cj * t_j(units, a, b, k, flat)
        changed |= (new_i != old_i) | (new_j != old_j)
        v[i, k] = choose(go, new_i, old_i)
        v[j, k] = choose(go, new_j, old_j)
    return changed


@njit_cached(inline="always")
def _elastic_free(v, units, i, j, a, b, masses, factor, tau, dim, flat, w):
    """``rules.elastic_at`` with ``write``, without a branch."""
    go = not (w <= tau)
    return go & _impulse_where(v, units, i, j, a, b, w, w, go, dim, flat)


@njit_cached(inline="always")
def _equal_free(v, units, i, j, a, b, masses, factor, tau, dim, flat, w):
    """``rules.equal_at`` with ``write``, without a branch."""
    go = not (w <= tau)
    c = w * factor
    return go & _impulse_where(v, units, i, j, a, b, c, c, go, dim, flat)


@njit_cached(inline="always")
def _masses_free(v, units, i, j, a, b, masses, factor, tau, dim, flat, w):
    """``rules.masses_at`` with ``write``, without a branch."""
    go = not (w <= tau)
    s = factor * w / (masses[i] + masses[j])
    return go & _impulse_where(v, units, i, j, a, b, s * masses[j], s * masses[i], go, dim, flat)


_FREE = {ELASTIC: _elastic_free, EQUAL: _equal_free, MASSES: _masses_free}


@functools.cache
def branch_free_form(collide: Callable, dim: int, flat: bool) -> Callable | None:
    """``collide_free(v, units, i, j, a, b, masses, factor, tau, w) -> bool``: what the built-in rule's
    closing form does with `WRITE` given ``params = [factor, tau]`` (the same bits in ``v``, the same
    answer), without a branch; None for any other rule. Inlined by numba; it writes every pick's two
    velocity rows, changed or not. (The caller reads ``params`` once: read here, after each pick's
    writes to ``v``, they would be read again, as ``v`` might hold them.)"""
    number = device_rule(collide)
    if number is None:
        return None
    free, D, FLAT = _FREE[number], dim, flat

    @njit(inline="always")
    def collide_free(v, units, i, j, a, b, masses, factor, tau, w):
        return free(v, units, i, j, a, b, masses, factor, tau, D, FLAT, w)

    return collide_free
