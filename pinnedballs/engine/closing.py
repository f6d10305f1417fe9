"""A rule's arithmetic, written once and compiled for every engine: the closing speed of a contact, the
kick of a collision, and the forms of a rule each engine runs.

A contact ``(i, j)`` closes at ``w = v_i . t_i + v_j . t_j`` (`closing_speed`; positive: the balls
approach); a collision *kicks* both balls, ``v_i -= c_i t_i`` and ``v_j -= c_j t_j`` (`kick`). A rule's
``collide(v, units, i, j, a, b, masses, params, dim, flat, write) -> bool`` (`pinnedballs.rules`) is written
in one of two ways:

* **by its impulse** (`impulse_rule`): ``impulse(w, i, j, masses, params) -> (c_i, c_j)``, the kick of a
  collision closing at ``w``. The engine supplies the rest: the test against the threshold
  (``params[-1]``) and the kick. The built-in rules are written so, and so may a user's;
* **by its whole** ``collide`` (docs/extending.md), which computes its closing speed itself.

From either, the engine builds the forms its loops run, each compiled where it runs, from this one source:

* the *closing form* (`closing_form`) ``collide_at(..., write, w)``: ``collide`` given the closing speed
  the loop computed already (for the margin, `engine.margin`); a rule written whole recomputes it;
* the *compiled form* (`compiled_form`): the closing form with ``dim`` and ``flat`` built in, compiled on its
  own once (``write`` a run-time `WRITE` or `TEST` flag) and inlined by LLVM into each loop that calls it,
  so a new rule goes through numba's pipeline once, not once per loop;
* the *branch-free form* (`branch_free_form`, rules written by their impulse): the closing form's collision
  without a branch on it: the new velocities computed for every pick, written where the rule writes them
  and the old ones written back elsewhere (`kick_where`: the same bits). Where about half the picks collide
  (a lattice in equilibrium) a branch on the collision is mispredicted about as often;
* the *trial* (`trial_form`), ``(hit, w)`` of one contact: what the threaded chains and the GPU's kernels
  run. On a GPU numba-cuda compiles these same functions for the device (with contraction into fused
  multiply-adds off, `engine.gpu.device`), so a rule runs there with the CPU's bits.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import config, njit, types
from numba.extending import intrinsic

from .jit.cache import INLINED, jit_cached_if_possible, njit_cached

__all__ = ["closing_speed", "t_j", "kick", "kick_where", "impulse_rule", "impulse_of", "closing_form",
           "compiled_form", "branch_free_form", "trial_form", "WRITE", "TEST", "choose"]

#: ``write`` as run-time flags (numba compiles a function once for all values of a ``numpy.bool_``,
#: but once per value of a ``bool`` constant): True writes the collision, False only tests for one
WRITE, TEST = np.bool_(True), np.bool_(False)

#: ``collide -> impulse`` of the rules written by their impulse, and ``collide -> collide_at``, their closing forms
_IMPULSES: dict = {}
_FORMS: dict = {}


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


@njit_cached(inline="always")
def kicked(v, units, i, j, a, b, ci, cj, k, flat):
    """Component ``k`` of both balls before and after the kick ``(c_i, c_j)``: ``(old_i, old_j, new_i, new_j)``."""
    old_i, old_j = v[i, k], v[j, k]
    return old_i, old_j, old_i - ci * units[a, k], old_j - cj * t_j(units, a, b, k, flat)


@njit_cached(inline="always")
def kick(v, units, i, j, a, b, ci, cj, dim, flat, write):
    """``v_i -= c_i t_i``, ``v_j -= c_j t_j`` (only if ``write``); True if any component changes."""
    changed = False
    for k in range(dim):
        old_i, old_j, new_i, new_j = kicked(v, units, i, j, a, b, ci, cj, k, flat)
        changed |= (new_i != old_i) | (new_j != old_j)
        if write:
            v[i, k] = new_i
            v[j, k] = new_j
    return changed


@njit_cached(inline="always")
def kick_where(v, units, i, j, a, b, ci, cj, go, dim, flat):
    """`kick` with ``write = go``, without a branch: the new components are computed either way and written
    where ``go``, the old ones written back elsewhere. True if any component changes (whether or not ``go``)."""
    changed = False
    for k in range(dim):
        old_i, old_j, new_i, new_j = kicked(v, units, i, j, a, b, ci, cj, k, flat)
        changed |= (new_i != old_i) | (new_j != old_j)
        v[i, k] = choose(go, new_i, old_i)
        v[j, k] = choose(go, new_j, old_j)
    return changed


@functools.cache
def impulse_rule(impulse: Callable) -> Callable:
    """The ``collide`` of a rule given by its ``impulse(w, i, j, masses, params) -> (c_i, c_j)`` (a jitted
    function): a pick collides when its closing speed ``w`` exceeds the threshold ``params[-1]``, and then
    kicks its balls by ``(c_i, c_j)`` (`kick`). The engine also builds its branch-free form from it
    (`branch_free_form`). One ``collide`` per impulse (cached), so a rule's loops compile once."""

    @njit(inline="always")
    def collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w):
        tau = params[params.shape[0] - 1]  # read before any branch (`pinnedballs.rules.remnant_threshold`)
        if w <= tau:  # an early return: `w > tau and kick(...)` compiles to a slower loop
            return False
        ci, cj = impulse(w, i, j, masses, params)
        return kick(v, units, i, j, a, b, ci, cj, dim, flat, write)

    @njit(inline="always")
    def collide(v, units, i, j, a, b, masses, params, dim, flat, write):
        return collide_at(v, units, i, j, a, b, masses, params, dim, flat, write,
                          closing_speed(v, units, i, j, a, b, dim, flat))

    _IMPULSES[collide], _FORMS[collide] = impulse, collide_at
    return collide


def impulse_of(collide: Callable) -> Callable | None:
    """The impulse a rule's ``collide`` was built from (`impulse_rule`), or None for a rule written whole."""
    return _IMPULSES.get(collide)


@functools.cache
def closing_form(collide: Callable) -> Callable:
    """``collide_at(v, units, i, j, a, b, masses, params, dim, flat, write, w) -> bool``: a rule's ``collide``
    given the closing speed ``w`` its caller computed (the same bits); a rule written whole ignores ``w``."""
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


@functools.cache
def branch_free_form(collide: Callable, dim: int, flat: bool) -> Callable | None:
    """``collide_free(v, units, i, j, a, b, masses, params, tau, w) -> bool``: what a rule written by its
    impulse does with `WRITE` (``tau = params[-1]``, read once by the caller: the same bits in ``v``, the
    same answer), without a branch; None for a rule written whole. Inlined by numba; it writes every
    pick's two velocity rows, changed or not."""
    impulse = impulse_of(collide)
    if impulse is None:
        return None
    D, FLAT = dim, flat

    @njit(inline="always")
    def collide_free(v, units, i, j, a, b, masses, params, tau, w):
        go = not (w <= tau)
        ci, cj = impulse(w, i, j, masses, params)
        return go & kick_where(v, units, i, j, a, b, ci, cj, go, D, FLAT)

    return collide_free


@functools.cache
def trial_form(collide: Callable, dim: int, flat: bool) -> Callable:
    """``trial(v, units, masses, params, i, j, a, b, write) -> (hit, w)``: the closing speed ``w`` of contact
    ``(i, j, a, b)`` and whether picking it collides (writing the collision when ``write``), by the rule's
    closing form. What the threaded chains run, and what numba-cuda compiles into the GPU's kernels."""
    collide_at, D, FLAT = closing_form(collide), dim, flat

    @njit(inline="always")
    def trial(v, units, masses, params, i, j, a, b, write):
        w = closing_speed(v, units, i, j, a, b, D, FLAT)
        return collide_at(v, units, i, j, a, b, masses, params, D, FLAT, write, w), w

    return trial


# ---------------------------------------------------------------- a select without a branch


@intrinsic
def _choose_intrinsic(typingctx, c, a, b):
    """``a if c else b`` as one LLVM ``select``: no branch for the compiler to keep or make."""
    if not isinstance(c, types.Boolean) or a != b or not isinstance(a, (types.Number, types.Boolean)):
        return None

    def codegen(context, builder, signature, args):
        return builder.select(args[0], args[1], args[2])

    return a(c, a, b), codegen


def choose_python(c, a, b):
    """``choose`` in plain Python (``NUMBA_DISABLE_JIT=1``, and the GPU simulator's twins): ``a if c else b``."""
    return a if c else b


#: ``choose(c, a, b)``: ``a if c else b`` for a boolean ``c`` and two numbers of one type, without a branch
choose = choose_python if config.DISABLE_JIT else _choose_intrinsic
