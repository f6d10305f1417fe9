"""Progress of a long call: a bar over a known total, or a count and its rate when the end is unknown.

Every long call takes ``progress``: ``True`` shows it (a widget in a Jupyter notebook with
ipywidgets, a line of text on stderr elsewhere, a log file included), ``False`` never, and ``None``
(the default) only where it helps: in a terminal or a notebook, and only once the call has run
`DELAY` seconds. A call that ends sooner builds no bar at all (no tqdm object, no widget): a loop of
many short calls costs nothing and leaves a notebook small. The display is `util.bars`'.

While numba compiles (`util.compiling`) the bar says what it compiles and how far it is ("compiling the
chain's loop (compile 2; 14 functions inside)"), drawn by a thread since the compiling call holds the
caller's, and no rate; its rate counts from the end of the last compile.

`Progress` is updated with absolute counts (`Progress.update`) and closed when its block ends, showing
its final state: in a notebook, red only when the block ended by an exception (an error, a Ctrl-C), not
when the call ended below its total (a search that ran out of states before its bound).
"""

from __future__ import annotations

import sys
import threading
import time

from .bars import close_bar, open_bar, widgets_available
from .compiling import CompileWatch
from .errors import FieldTypeError

__all__ = ["Progress", "shown", "DELAY", "COMPILING"]

#: seconds a call runs before ``progress=None`` shows it
DELAY = 2.0
#: how the bar's description begins while numba compiles (`CompileWatch.doing`)
COMPILING = "compiling"
#: seconds between two redraws of a bar while numba compiles
_TICK = 0.5


def _in_notebook() -> bool:
    """True inside a Jupyter kernel (notebook, lab, VS Code, Colab), as tqdm.autonotebook tells."""
    return "ipykernel.zmqshell" in sys.modules


def _on_a_terminal() -> bool:
    try:
        return sys.stderr is not None and sys.stderr.isatty()
    except (AttributeError, ValueError):  # a replaced or closed stderr
        return False


def shown(progress) -> tuple[bool, float]:
    """``(shown, delay in seconds)`` for a call's ``progress`` argument (True, False or None)."""
    if progress is None:
        return (_in_notebook() or _on_a_terminal()), DELAY
    if not isinstance(progress, bool):
        raise FieldTypeError("progress", f"must be True, False or None (shown where it helps), got {progress!r}")
    return progress, 0.0


class Progress:
    """A bar of ``done`` out of ``total`` ``unit``s (None: the count, its rate and the time, no end).

    progress: the call's argument (see the module's docstring); desc: a word or two before the bar;
    initial: the count already done; scale: counts in k, M, G (for millions of steps, not for a few
    replicas). A context manager: the bar is closed when the block ends. ``bar``: the tqdm bar once
    built (None before its delay, and after `close`).
    """

    def __init__(self, progress, total: int | None, unit: str, desc: str, initial: int = 0, *, scale: bool = True):
        self.visible, delay = shown(progress)
        self.bar = None
        if not self.visible:
            return
        self._args = dict(total=total, unit=unit, desc=desc, scale=scale)
        self._start = time.time()  # tqdm's clock
        self._due, self._done, self._postfix = self._start + delay, initial, ""
        self._since: tuple[float, int] | None = (self._start, initial)  # the rate counts from here
        self._lock = threading.Lock()
        self._ticker: tuple[threading.Thread, threading.Event] | None = None
        self._watch = CompileWatch(self._began, self._ended)
        self._watch.start()
        if delay <= 0:
            with self._lock:
                self._opened()

    def update(self, done: int, postfix: str = "") -> None:
        """The count is now ``done``; ``postfix`` (e.g. ``"collisions=1,234"``) follows the bar."""
        if not self.visible:
            return
        with self._lock:
            self._done, self._postfix = done, postfix or self._postfix
            if self.bar is None and time.time() < self._due:
                return
            bar = self._opened()
            if self._postfix:
                bar.set_postfix_str(self._postfix, refresh=False)
            bar.update(done - bar.n)

    def close(self, failed: bool = False) -> None:
        """Stop hearing compiles; the bar, if built, shows its final state: a notebook's widget in its
        normal colour, or red where the call ``failed`` (an error or an interruption), whatever the count
        (a call may end normally below its total)."""
        if not self.visible:
            return
        self._watch.stop()
        with self._lock:
            self.visible = False  # a compile in another thread draws nothing more
        self._stop_ticker()
        with self._lock:
            if self.bar is not None:
                close_bar(self.bar, failed)
                self.bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, kind, value, traceback) -> None:
        self.close(failed=kind is not None)

    # ------------------------------------------------------------ the bar, under the lock
    def _opened(self):
        if self.bar is None:
            self.bar = open_bar(widget=_in_notebook() and widgets_available(), count=self._done, start=self._start,
                                since=self._since, **self._args)
            if self._postfix:
                self.bar.set_postfix_str(self._postfix)
        return self.bar

    def _compiling(self) -> None:
        """Say what is compiling (`CompileWatch.doing`), once the bar's delay has passed."""
        if self.visible and time.time() >= self._due:
            bar = self._opened()
            bar.set_description_str(self._watch.doing, refresh=False)  # as it is: set_description adds a colon
            bar.refresh()

    # ------------------------------------------------------------ compiles (from the compiling thread)
    def _began(self) -> None:
        with self._lock:
            if not self.visible:
                return
            self._since = None
            if self.bar is not None:
                self.bar.since = None
            self._compiling()
            stop = threading.Event()
            self._ticker = (threading.Thread(target=self._tick, args=(stop,), daemon=True,
                                             name="pinnedballs-progress"), stop)
            self._ticker[0].start()

    def _tick(self, stop: threading.Event) -> None:
        while not stop.wait(_TICK):
            with self._lock:
                self._compiling()

    def _ended(self) -> None:
        self._stop_ticker()
        with self._lock:
            self._since = (time.time(), self._done)
            if self.visible and self.bar is not None:
                self.bar.since = self._since
                self.bar.set_description_str(self._args["desc"], refresh=False)
                self.bar.refresh()

    def _stop_ticker(self) -> None:
        with self._lock:
            ticker, self._ticker = self._ticker, None
        if ticker is not None:
            ticker[1].set()
            ticker[0].join()
