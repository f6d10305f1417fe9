"""Whether numba is compiling: its compile events, heard while a call shows its progress.

numba announces each compile (``"numba:compile"``): a cache miss only, a load from the disk cache is
none. A compile compiles the jitted functions it calls inside it, so only the outermost one counts.
`util.progress` says what is compiling meanwhile (`CompileWatch.doing`: "compiling the chain's loop
(compile 2; 14 functions)"), and takes no speed from the time it took; `CompileClock` adds up a
command's compiles, for the one line it says after them (`CompileClock.note`).
"""

from __future__ import annotations

import threading
import time
import warnings
from collections.abc import Callable

from numba.core import event

__all__ = ["CompileWatch", "CompileClock", "compiled_words", "compiling_text", "compiled_note"]

_KIND = "numba:compile"

#: what is compiled, in a user's words: by a function (its module and name), else by the longest module
#: prefix; anything else is named by its function (`compiled_words`)
WORDS = {
    "pinnedballs.engine.sequential.loops.live_flags": "the freeze scan",
    "pinnedballs.engine.sequential.loops.any_live": "the freeze scan",
    "pinnedballs.engine.rows._matches": "the check of the lattice's rows",
    "pinnedballs.geometry.checks": "the contact checks",
    "pinnedballs.engine.harness": "the chain's loop",
    "pinnedballs.engine.sequential": "the chain's kernels",
    "pinnedballs.engine.threads": "the threaded chain",
    "pinnedballs.engine.field": "the exact arithmetic's kernels",
    "pinnedballs.engine.streams": "the random stream",
    "pinnedballs.engine.gpu": "the GPU's kernels",
    "pinnedballs.engine": "the engine's kernels",
    "pinnedballs.analysis": "the search's kernels",
    "pinnedballs.schedulers": "the scheduler",
    "pinnedballs.rules": "the rule",
}


def compiled_words(dispatcher) -> str:
    """What ``dispatcher`` (a numba dispatcher) is to a user, from `WORDS`: "the chain's loop"; a function
    of the package's not listed, or of the user's own, by its name ("collide")."""
    func = getattr(dispatcher, "py_func", None)
    module = getattr(func, "__module__", None) or ""
    name = (getattr(func, "__qualname__", None) or getattr(func, "__name__", None) or "a function").split(".")[-1]
    if f"{module}.{name}" in WORDS:
        return WORDS[f"{module}.{name}"]
    prefixes = [k for k in WORDS if module == k or module.startswith(k + ".")]
    return WORDS[max(prefixes, key=len)] if prefixes else name



class CompileWatch(event.Listener):
    """Calls ``began()`` when numba starts a compile and ``ended()`` when it is done (or failed), from
    the compiling thread, between `start` and `stop`; `doing` says what it compiles meanwhile."""

    def __init__(self, began: Callable[[], None], ended: Callable[[], None]):
        self.began, self.ended, self.depth = began, ended, 0
        #: the outermost compiles begun (this one included); the functions the current one has compiled inside it
        self.compiles, self.functions = 0, 0
        self.words = ""  #: what the current (or last) compile compiles (`compiled_words`)

    def on_start(self, ev) -> None:
        self.depth += 1
        if self.depth == 1:
            self.compiles, self.functions = self.compiles + 1, 0
            self.words = compiled_words((ev.data or {}).get("dispatcher"))
            _told(self.began)
        else:
            self.functions += 1

    def on_end(self, ev) -> None:
        if self.depth == 0:  # a compile under way when the watch started
            return
        self.depth -= 1
        if self.depth == 0:
            _told(self.ended)

    @property
    def doing(self) -> str:
        """What is compiling, in words: ``compiling the chain's loop (compile 2; 14 functions)``."""
        return compiling_text(self.words, self.compiles, self.functions)

    def start(self) -> None:
        event.register(_KIND, self)

    def stop(self) -> None:
        event.unregister(_KIND, self)


def compiling_text(words: str, compiles: int, functions: int) -> str:
    """``compiling WORDS (compile N; M functions)``: the ``compiles``-th outermost compile, which has compiled
    ``functions`` others inside it so far (none said while there are none)."""
    inside = f"; {functions} function{'s' * (functions != 1)} inside" if functions else ""
    return f"compiling {words or 'a function'} (compile {compiles}{inside})"


class CompileClock(CompileWatch):
    """The seconds a process spends in numba's outermost compiles between `start` and `stop`, and those of
    compiles whose code numba keeps in its disk cache (the next process loads them instead)."""

    def __init__(self):
        super().__init__(self._began, self._ended)
        self.seconds, self.cached_seconds = 0.0, 0.0
        self._lock = threading.Lock()
        self._since, self._cached = 0.0, False

    def on_start(self, ev) -> None:
        if self.depth == 0:
            self._cached = _disk_cached((ev.data or {}).get("dispatcher"))
        super().on_start(ev)

    def _began(self) -> None:
        self._since = time.perf_counter()

    def _ended(self) -> None:
        took = time.perf_counter() - self._since
        with self._lock:
            self.seconds += took
            self.cached_seconds += took if self._cached else 0.0

    def __enter__(self) -> CompileClock:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def note(self, least: float = 1.0) -> str | None:
        """The line a command says once after compiling for ``least`` seconds or more (None before):
        ``compiled in 67 s; cached on disk: the next run will not compile``."""
        return compiled_note(self.seconds, self.cached_seconds, least)


def compiled_note(seconds: float, cached_seconds: float, least: float = 1.0) -> str | None:
    """`CompileClock.note` of ``seconds`` compiling, ``cached_seconds`` of them kept in numba's disk cache."""
    if seconds < least:
        return None
    said = f"compiled in {seconds:.0f} s"
    if cached_seconds > 0 and cached_seconds >= seconds - 0.5:
        return f"{said}; cached on disk: the next run will not compile"
    if cached_seconds < min(0.5, seconds / 2):
        return f"{said}, none of it cached on disk (functions without a source file): the next run compiles again"
    return (f"{said}, {cached_seconds:.0f} s of it cached on disk; the rest (functions without a source file) "
            f"compiles again in the next run")


def _disk_cached(dispatcher) -> bool:
    """Whether numba keeps what ``dispatcher`` compiles in its disk cache (not its `NullCache`)."""
    cache = getattr(dispatcher, "_cache", None)
    return cache is not None and type(cache).__name__ != "NullCache"


def _told(callback: Callable[[], None]) -> None:
    """``callback()``; its failure (a display's) is a warning, never an error inside numba's compile."""
    try:
        callback()
    except Exception as exc:  # noqa: BLE001 - the compile must go on
        warnings.warn(f"the progress display failed while numba compiled: {exc!r}", RuntimeWarning, stacklevel=2)
