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
from llvmlite import ir
from numba import config, njit, types
from numba.core import cgutils
from numba.core.caching import FunctionCache
from numba.core.dispatcher import Dispatcher
from numba.extending import intrinsic

from .random import load, store
from .rules import closing_speed

__all__ = ["chain_kernel", "approaching_flags", "incidence", "STEPS", "COLLISIONS", "APPROACHING"]

#: indices into the ``counters`` array shared by Python and the loop
STEPS, COLLISIONS, APPROACHING = 0, 1, 2

NO_LIMIT = np.iinfo(np.int64).max  #: "no limit" for max_steps or max_collisions

#: picks drawn ahead, and how far ahead the velocity rows are fetched, in the lookahead loop
LOOKAHEAD, HALFWAY = 8, 4
_RING = 16  # ring buffer of drawn picks: a power of two > LOOKAHEAD

#: above this many bytes of tables and velocities the loop prefetches (they no longer fit in cache)
LOOKAHEAD_BYTES = 4 << 20


@intrinsic
def _prefetch_intrinsic(typingctx, arr, index):
    """Ask the CPU to bring row ``index`` of ``arr`` into cache; no effect on any value."""
    if not isinstance(arr, types.Array) or not isinstance(index, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        aryty, idxty = signature.args
        ary = context.make_array(aryty)(context, builder, args[0])
        row = builder.mul(context.cast(builder, args[1], idxty, types.intp),
                          cgutils.unpack_tuple(builder, ary.strides)[0])
        addr = builder.inttoptr(builder.add(builder.ptrtoint(ary.data, cgutils.intp_t), row), cgutils.voidptr_t)
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [cgutils.voidptr_t, i32, i32, i32]), "llvm.prefetch.p0")
        builder.call(fn, [addr, i32(0), i32(3), i32(1)])  # read, keep in all cache levels, data
        return context.get_dummy_value()

    return types.void(arr, index), codegen


def _prefetch_python(arr, index):
    """Without the JIT (``NUMBA_DISABLE_JIT=1``) a prefetch is nothing."""


prefetch = _prefetch_python if config.DISABLE_JIT else _prefetch_intrinsic


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
        parts = [self._py_func.__code__.co_code, *_closure_parts(self._py_func)]
        return (sig, codegen.magic_tuple(), hashlib.sha256(b"\0".join(parts)).hexdigest())


_ENGINE_FILES = tuple(str(Path(__file__).with_name(name)) for name in ("kernels.py", "random.py", "rules.py"))


def _captured(py_func: Callable) -> list:
    return [cell.cell_contents for cell in py_func.__closure__ or ()]


def _closure_parts(py_func: Callable) -> list[bytes]:
    """What identifies the values ``py_func`` captures, recursing into captured jitted closures."""
    parts = []
    for value in _captured(py_func):
        if isinstance(value, Dispatcher):
            f = value.py_func
            parts += [f"{f.__module__}.{f.__qualname__}".encode(), _source_digest(_source_file(f)),
                      f.__code__.co_code, b"(", *_closure_parts(f), b")"]
        else:
            parts.append(repr(value).encode())
    return parts


def _all_captured_functions(py_func: Callable) -> list[Callable]:
    """Every Python function behind the jitted functions ``py_func`` captures, recursively."""
    found = []
    for value in _captured(py_func):
        if isinstance(value, Dispatcher):
            found += [value.py_func, *_all_captured_functions(value.py_func)]
    return found


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
    if all(_source_file(f) for f in _all_captured_functions(py_func)):
        dispatcher._cache = _ClosureCache(py_func)
    return dispatcher


@functools.cache
def chain_kernel(collide: Callable, pick: Callable, dim: int, flat: bool) -> Callable:
    """The compiled loop for one rule's ``collide``, one scheduler's ``pick``, ``dim`` and
    ``flat`` (every ``t_j == -t_i``, so the loop reads one unit vector per contact).

    ``chain(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
    max_steps, max_collisions, track, ptr, inc, flags, lookahead) -> steps taken`` runs in
    place and stops after ``max_steps`` picks, at ``max_collisions`` in total, or (when
    ``track``) as soon as no contact approaches (``max_collisions = NO_LIMIT``: none).
    ``lookahead`` (only with no collision limit and no tracking) prefetches the rows of picks drawn a few steps early: the
    same results, faster when the tables do not fit in cache. Shapes: v ``(n_balls, dim)``, pairs/ends ``(E, 2)``,
    units ``(K, dim)``, rng_words ``(4,) uint64``, counters ``(3,) int64`` totals
    ``[steps, collisions, approaching]``; approaching is kept exact only when ``track``,
    from ``flags (E,) uint8`` and the incidence ``ptr, inc``.
    """

    D, FLAT = dim, flat  # constants of the compiled loop: component loops unroll

    @njit(inline="always")
    def attempt(v, pairs, ends, units, masses, params, k):
        return collide(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], masses, params, D, FLAT)

    @_jit_cached_if_possible
    def chain(v, pairs, ends, units, masses, params, sched_state, rng_words, counters,
              max_steps, max_collisions, track, ptr, inc, flags, lookahead):
        n = pairs.shape[0]
        rng = load(rng_words)
        collisions = counters[COLLISIONS]
        approaching = counters[APPROACHING]
        steps = 0
        if not track and max_collisions == NO_LIMIT and not lookahead:
            for t in range(max_steps):  # steps only: the plainest loop
                k, rng = pick(sched_state, rng, n)
                if attempt(v, pairs, ends, units, masses, params, k):
                    collisions += 1
            steps = max_steps
        elif lookahead:
            # Steps only: the picks are drawn LOOKAHEAD steps early and their rows
            # prefetched, hiding memory latency on large systems. Every drawn pick is
            # used before returning, so the state left behind is the plain loop's.
            ring = np.empty(_RING, dtype=np.uint64)
            for t in range(min(LOOKAHEAD, max_steps)):
                k, rng = pick(sched_state, rng, n)
                ring[t] = k
                prefetch(pairs, k)
                prefetch(ends, k)
            for t in range(max_steps):
                if t + LOOKAHEAD < max_steps:
                    k, rng = pick(sched_state, rng, n)
                    ring[(t + LOOKAHEAD) % _RING] = k
                    prefetch(pairs, k)
                    prefetch(ends, k)
                if t + HALFWAY < max_steps:
                    k = ring[(t + HALFWAY) % _RING]
                    prefetch(v, pairs[k, 0])
                    prefetch(v, pairs[k, 1])
                if attempt(v, pairs, ends, units, masses, params, ring[t % _RING]):
                    collisions += 1
            steps = max_steps
        while steps < max_steps and collisions < max_collisions:
            if track and approaching == 0:
                break
            k, rng = pick(sched_state, rng, n)
            steps += 1
            if attempt(v, pairs, ends, units, masses, params, k):
                collisions += 1
                if track:
                    approaching += _refresh(v, pairs, ends, units, ptr, inc, flags, pairs[k, 0], D, FLAT)
                    approaching += _refresh(v, pairs, ends, units, ptr, inc, flags, pairs[k, 1], D, FLAT)
        store(rng_words, rng)
        counters[STEPS] += steps
        counters[COLLISIONS] = collisions
        counters[APPROACHING] = approaching
        return steps

    return chain
