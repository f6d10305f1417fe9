"""numba's on-disk cache for loops that are closures over jitted functions.

A compiled loop is a closure over a rule's ``collide`` and a scheduler's
``pick``, so that numba inlines them. numba keys a closure's cache entry on a
pickle of the values it captures, and a pickled dispatcher carries a
per-process id: every process would miss and compile again (seconds each).
`jit_cached_if_possible` keys them by name and source instead: a function's
source file, or, for one no file holds (a notebook's cell), its source as
`linecache` keeps it and the values of the globals it reads (`function_key`),
so a notebook's rule compiles once, not in every new kernel.

Where: ``NUMBA_CACHE_DIR`` if it is set (numba's own rule), else a per-user cache directory of the
package's (`cache_root`: ``~/.cache/pinnedballs/numba/<version>`` on Linux, the platform's user cache
directory elsewhere), never the ``__pycache__`` beside the sources, which numba's default fills in a
source checkout (``python3 -m pinnedballs`` run inside one wrote into the tree). Only where that
directory cannot be written does numba's next choice, beside the sources, apply.
"""

from __future__ import annotations

import functools
import hashlib
import inspect
import itertools
import os
import secrets
import sys
import types
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numba import njit
from numba.core import caching
from numba.core.bytecode import FunctionIdentity
from numba.core.caching import FunctionCache, IndexDataCacheFile
from numba.core.dispatcher import Dispatcher
from numba.misc.appdirs import AppDirs

from ..._version import __version__

__all__ = ["jit_cached_if_possible", "njit_cached", "function_key", "source_key", "code_names", "cache_root",
           "INLINED"]

#: the options of a kernel compiled on its own and inlined by LLVM into every function that calls it
#: (``forceinline``), never called from Python (no wrappers to build)
INLINED = dict(forceinline=True, no_cpython_wrapper=True, no_cfunc_wrapper=True)


#: numba names a compiled function's symbols (its code and its environment, which holds the objects
#: it returns: an array's dtype) after its qualified name, argument types and a per-process counter.
#: Two closures of one function (one loop for two rules, one order kernel for two dimensions)
#: compiled by two processes at the same count share every name, and once both are loaded from the
#: disk cache into one process the second resolves to the first's environment: a wrong dtype, a
#: SystemError, or worse. Counting from a random 62-bit start in each process makes names shared by
#: two processes' compilations as unlikely as a 62-bit collision; the cache's keys do not use it.
FunctionIdentity._unique_ids = itertools.count(secrets.randbits(62))


def cache_root() -> str:
    """The package's own numba cache directory: ``<user cache directory>/pinnedballs/numba/<version>``
    (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux; numba's `AppDirs`, as its own user-wide cache uses,
    elsewhere). ``NUMBA_CACHE_DIR``, when set, comes first (`_Locating`)."""
    return os.path.join(AppDirs(appname="pinnedballs", appauthor=False).user_cache_dir, "numba", __version__)


def _numba_class(name: str) -> type:
    """numba's cache class ``name`` (``_name`` before numba 0.62). These classes are numba's internals, alike from
    0.61 to 0.68: pyproject.toml bounds numba to the versions read and tested."""
    return getattr(caching, name, None) or getattr(caching, f"_{name}")


class _UserCacheLocator(_numba_class("UserWideCacheLocator")):
    """numba's user-wide locator, in the package's own directory (`cache_root`) instead of numba's."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        self._cache_path = os.path.join(cache_root(), self.get_suitable_cache_subpath(py_file))


class _Locating(caching.CompileResultCacheImpl):
    """numba's cache of compile results, its locators in this order: ``NUMBA_CACHE_DIR`` (numba's), the
    package's user cache directory, then numba's own choices where that cannot be written (beside the
    sources, numba's user-wide directory, IPython's, a zip's). ``NUMBA_CACHE_LOCATOR_CLASSES`` still
    overrides them all, as numba has it."""

    _locator_classes = [_numba_class("UserProvidedCacheLocator"), _UserCacheLocator,
                        *map(_numba_class, ("InTreeCacheLocator", "UserWideCacheLocator", "IPythonCacheLocator",
                                            "ZipCacheLocator"))]


class _KeyedCache(FunctionCache):
    """numba's on-disk cache with `_KeyedFiles`: safe when processes fill it at once; in the package's
    user cache directory, not beside its sources (`_Locating`)."""

    _impl_class = _Locating

    def __init__(self, py_func):
        super().__init__(py_func)
        self._cache_file = _KeyedFiles(self._cache_path, self._impl.filename_base,
                                       self._impl.locator.get_source_stamp())


class _ClosureCache(_KeyedCache):
    """numba's on-disk cache, keyed so that closures over jitted functions hit across processes.

    numba keys a closure on a pickle of its captured values, and a pickled
    dispatcher carries a per-process id: every process would miss and compile
    again. Here every jitted function the loop reaches (through closures or
    globals, recursively) counts by its module, name, bytecode and a hash of its
    source file and of the engine's files, so an edit to a rule, a scheduler or a
    helper they call, in any module, invalidates the entry.
    """

    def _index_key(self, sig, codegen):
        parts = [self._py_func.__code__.co_code, *map(_constant, _cells(self._py_func))]
        for f in reachable_functions(self._py_func):
            parts += [f"{f.__module__}.{f.__qualname__}".encode(), f.__code__.co_code,
                      function_key(f) or b"", *map(_constant, _cells(f))]
        return (sig, codegen.magic_tuple(), hashlib.sha256(b"\0".join(parts)).hexdigest())


class _KeyedFiles(IndexDataCacheFile):
    """numba's index and data files, with each entry's data file named after its key.

    numba numbers a new entry's data file after the entries its index lists, and writes the index
    before the data: two processes filling one cache at once (the test suite's workers) can give
    two keys the same number, and the index one key while the file holds the other's machine code:
    a loop compiled for one rule loaded for another. Named after the key, an entry's file holds
    only that key's code; an index that loses a key to a concurrent write only costs a compile.
    """

    def save(self, key, data):
        overloads = self._load_index()
        name = self._data_name_pattern.replace("{number:d}", hashlib.sha256(repr(key).encode()).hexdigest()[:20])
        if overloads.get(key) != name:
            overloads[key] = name
            self._save_index(overloads)
        self._save_data(name, data)


#: the package's files whose functions a loop inlines: an edit to one invalidates every loop
_PACKAGE = Path(__file__).resolve().parents[2]
_ENGINE_FILES = tuple(str(_PACKAGE / name) for name in (
    "engine/jit/cache.py", "engine/jit/intrinsics.py", "engine/chain.py", "engine/sequential/loops.py",
    "engine/streams/xoshiro.py", "engine/closing.py", "engine/margin.py", "engine/rows.py", "engine/harness.py",
    "engine/selector.py", "rules.py", "schedulers/base.py", "schedulers/simple.py", "schedulers/rejection_free.py",
    "schedulers/colored_sweep.py", "schedulers/replay.py"))


def _cells(f: Callable) -> list:
    return [cell.cell_contents for cell in f.__closure__ or ()]


def _constant(value) -> bytes:
    """A captured value as key material (a captured jitted function is keyed separately; an array by all its
    elements, which its repr leaves out beyond a thousand)."""
    if isinstance(value, Dispatcher):
        return b"<jitted>"
    return _array_key(value) if isinstance(value, np.ndarray) else repr(value).encode()


def _array_key(a: np.ndarray) -> bytes:
    data = a.tobytes() if a.dtype != object else repr(a.tolist()).encode()
    return f"array {a.dtype} {a.shape} ".encode() + hashlib.sha256(data).hexdigest().encode()


def reachable_functions(py_func: Callable) -> list[Callable]:
    """The Python functions behind every jitted function ``py_func`` uses, through its
    closure or its globals, and the ones those use, in a fixed order."""
    found, seen, stack = [], set(), [py_func]
    while stack:
        f = stack.pop()
        used = _cells(f) + [f.__globals__.get(name) for name in f.__code__.co_names]
        for value in used:
            if isinstance(value, Dispatcher) and id(value.py_func) not in seen:
                seen.add(id(value.py_func))
                found.append(value.py_func)
                stack.append(value.py_func)
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


def function_key(f: Callable) -> bytes | None:
    """How ``f``, a Python function a loop reaches, is known on disk (beside its name, bytecode and closure):
    its source file with the engine's files (`_source_digest`); for a function no file holds (a notebook's
    cell, an IPython prompt), its source as `linecache` keeps it (IPython does) with the engine's files and the
    values of the globals it reads, which numba compiles in as constants (`_global_key`). None when neither
    can be had (``exec`` of a string): no disk cache."""
    path = _source_file(f)
    if path is not None:
        return _source_digest(path)
    try:
        source = inspect.getsource(f)
    except (OSError, TypeError):
        return None
    names = [(name, _global_key(f.__globals__[name])) for name in sorted(code_names(f.__code__))
             if name in f.__globals__]
    if any(key is None for _, key in names):
        return None
    h = hashlib.sha256(_source_digest(_ENGINE_FILES[0]) + source.encode())  # the engine's files alone
    for name, key in names:
        h.update(b"\0" + name.encode() + b"=" + key)
    return h.hexdigest().encode()


def source_key(py_func: Callable) -> str | None:
    """A hex digest of ``py_func`` and of every jitted function it reaches, as the disk cache knows them (their
    names, bytecode, sources with the engine's files, and captured values: `function_key`); None where one of
    them has no source to key (``exec`` of a string). What a verdict on a rule's code is kept under."""
    parts = [py_func.__code__.co_code, *map(_constant, _cells(py_func))]
    for f in [py_func, *reachable_functions(py_func)]:
        key = function_key(f)
        if key is None:
            return None
        parts += [f"{f.__module__}.{f.__qualname__}".encode(), f.__code__.co_code, key, *map(_constant, _cells(f))]
    return hashlib.sha256(b"\0".join(parts)).hexdigest()


def code_names(code: types.CodeType) -> set[str]:
    """The global (and attribute) names ``code`` and the code objects inside it read."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= code_names(const)
    return names


def _global_key(value) -> bytes | None:
    """A global a function without a source file reads, as key material; None for one that cannot be keyed
    (an object numba would compile in whose value a key cannot see: no disk cache)."""
    if isinstance(value, Dispatcher):
        return b"<jitted>"  # keyed as a reachable function of its own
    if isinstance(value, types.ModuleType):
        return b"module " + value.__name__.encode()
    if value is None or isinstance(value, (bool, int, float, complex, str, bytes, np.generic)):
        return f"{type(value).__name__} {value!r}".encode()
    if isinstance(value, np.ndarray):
        return _array_key(value)
    if isinstance(value, tuple):
        parts = [_global_key(v) for v in value]
        return None if None in parts else b"(" + b",".join(parts) + b")"
    module = getattr(value, "__module__", None)
    if callable(value) and isinstance(module, str) and module != "__main__" and \
            getattr(sys.modules.get(module), "__file__", None):
        return f"{module}.{getattr(value, '__qualname__', getattr(value, '__name__', ''))}".encode()  # a library's
    return None


def njit_cached(py_func: Callable | None = None, **options) -> Callable:
    """``njit(cache=True, **options)``, its disk cache safe when processes fill it at once
    (`_KeyedFiles`): numba's own numbers two signatures compiled at once in two processes alike,
    and one process then loads the other's machine code."""
    if py_func is None:
        return functools.partial(njit_cached, **options)
    dispatcher = njit(py_func, **options)
    dispatcher._cache = _KeyedCache(py_func)
    return dispatcher


def jit_cached_if_possible(py_func: Callable | None = None, **options) -> Callable:
    """``njit(**options)`` with `_ClosureCache` on disk, or no disk cache when a function it reaches
    cannot be keyed (`function_key`: it is then compiled once per process).

    ``parallel=True`` compiles ``prange`` loops for all numba threads; the cached code
    does not depend on the number of threads, which is chosen at run time."""
    if py_func is None:
        return functools.partial(jit_cached_if_possible, **options)
    dispatcher = njit(py_func, **options)
    if all(function_key(f) is not None for f in reachable_functions(py_func)):
        dispatcher._cache = _ClosureCache(py_func)
    return dispatcher
