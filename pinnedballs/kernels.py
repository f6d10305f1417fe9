"""The compiled loop (numba) and its helpers for tracking frozen states.

`chain_kernel(collide, pick)` builds the one hot loop for a collision rule and
a scheduler: pick a contact, try to collide it, count. The rule's ``collide``
and the scheduler's ``pick`` are compiled into the loop (inlined, not called
through pointers); each combination is built once per process and cached on
disk by numba, so later processes load it instead of compiling.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
from pathlib import Path
from typing import Callable

import numpy as np
from numba import njit
from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher

from .random import load, store
from .rules import closing_speed

__all__ = ["chain_kernel", "approaching_flags", "incidence", "STEPS", "COLLISIONS", "APPROACHING"]

#: indices into the ``counters`` array shared by Python and the loop
STEPS, COLLISIONS, APPROACHING = 0, 1, 2


@njit(cache=True)
def approaching_flags(v, pairs, ends, units, flags):
    """Set ``flags[k] = 1`` where contact ``k`` approaches; return how many do."""
    count = 0
    for k in range(pairs.shape[0]):
        w = closing_speed(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], v.shape[1], False)
        flags[k] = 1 if w > 0.0 else 0
        count += flags[k]
    return count


def incidence(pairs: np.ndarray, n_balls: int) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of each ball in CSR form: ``(ptr (n_balls+1,) int64, contacts (2E,) uint32)``."""
    balls = pairs.ravel()
    contacts = (np.argsort(balls, kind="stable") // 2).astype(np.uint32)
    ptr = np.zeros(n_balls + 1, dtype=np.int64)
    np.cumsum(np.bincount(balls.astype(np.intp), minlength=n_balls), out=ptr[1:])
    return ptr, contacts


@njit(cache=True, inline="always")
def _refresh(v, pairs, ends, units, ptr, inc, flags, ball, dim, flat):
    """Re-test the contacts of ``ball``; return the change in the number approaching."""
    delta = 0
    for m in range(ptr[ball], ptr[ball + 1]):
        c = inc[m]
        w = closing_speed(v, units, pairs[c, 0], pairs[c, 1], ends[c, 0], ends[c, 1], dim, flat)
        new = 1 if w > 0.0 else 0
        delta += new - flags[c]
        flags[c] = new
    return delta


class _ClosureCache(FunctionCache):
    """numba's on-disk cache, keyed so that closures over jitted functions hit across processes.

    numba keys a closure on a pickle of its captured values, and a pickled
    dispatcher carries a per-process id: every process would miss and compile
    again. Here a captured dispatcher counts by its module, name and a hash of
    its source file (and of the engine files the loop inlines), so an edit to a
    rule or scheduler also invalidates the entry.
    """

    def _index_key(self, sig, codegen):
        parts = [self._py_func.__code__.co_code]
        for value in _captured(self._py_func):
            if isinstance(value, Dispatcher):
                f = value.py_func
                parts += [f"{f.__module__}.{f.__qualname__}".encode(), _source_digest(_source_file(f))]
            else:
                parts.append(repr(value).encode())
        return (sig, codegen.magic_tuple(), hashlib.sha256(b"\0".join(parts)).hexdigest())


_ENGINE_FILES = tuple(str(Path(__file__).with_name(name)) for name in ("kernels.py", "random.py", "rules.py"))


def _captured(py_func: Callable) -> list:
    return [cell.cell_contents for cell in py_func.__closure__ or ()]


def _source_file(f: Callable) -> str | None:
    """The readable source file defining ``f``, or None (a notebook cell, ``exec``)."""
    try:
        path = inspect.getsourcefile(f)
    except TypeError:
        return None
    return path if path and Path(path).is_file() else None


@functools.cache
def _source_digest(path: str) -> bytes:
    """Hash of a source file and of the engine files every loop inlines."""
    h = hashlib.sha256()
    for name in sorted({path, *_ENGINE_FILES}):
        h.update(Path(name).read_bytes())
    return h.hexdigest().encode()


def _jit_cached_if_possible(py_func: Callable) -> Callable:
    """``njit`` with `_ClosureCache` on disk, or no disk cache when a captured
    function has no source file to key it by (it is then compiled once per process)."""
    dispatcher = njit(py_func)
    if all(_source_file(v.py_func) for v in _captured(py_func) if isinstance(v, Dispatcher)):
        dispatcher._cache = _ClosureCache(py_func)
    return dispatcher


@functools.cache
def chain_kernel(collide: Callable, pick: Callable, dim: int, flat: bool) -> Callable:
    """The compiled loop for one rule's ``collide``, one scheduler's ``pick``, ``dim`` and
    ``flat`` (every ``t_j == -t_i``, so the loop reads one unit vector per contact).

    ``chain(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
    max_steps, max_collisions, track, ptr, inc, flags) -> steps taken`` runs in place and
    stops after ``max_steps`` picks, at ``max_collisions`` in total, or (when ``track``)
    as soon as no contact approaches. Shapes: v ``(n_balls, dim)``, pairs/ends ``(E, 2)``,
    units ``(K, dim)``, rng_words ``(4,) uint64``, counters ``(3,) int64`` totals
    ``[steps, collisions, approaching]``; approaching is kept exact only when ``track``,
    from ``flags (E,) uint8`` and the incidence ``ptr, inc``.
    """

    D, FLAT = dim, flat  # constants of the compiled loop: component loops unroll

    @_jit_cached_if_possible
    def chain(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
              max_steps, max_collisions, track, ptr, inc, flags):
        n = pairs.shape[0]
        rng = load(rng_words)
        collisions = counters[COLLISIONS]
        approaching = counters[APPROACHING]
        steps = 0
        while steps < max_steps and collisions < max_collisions:
            if track and approaching == 0:
                break
            k, rng = pick(sched_state, rng, n)
            steps += 1
            i = pairs[k, 0]
            j = pairs[k, 1]
            if collide(v, units, i, j, ends[k, 0], ends[k, 1], masses, params, D, FLAT):
                collisions += 1
                if track:
                    approaching += _refresh(v, pairs, ends, units, ptr, inc, flags, i, D, FLAT)
                    approaching += _refresh(v, pairs, ends, units, ptr, inc, flags, j, D, FLAT)
        store(rng_words, rng)
        counters[STEPS] += steps
        counters[COLLISIONS] = collisions
        counters[APPROACHING] = approaching
        return steps

    return chain
