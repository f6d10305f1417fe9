"""Ctrl-C between chunks: SIGINT held while the engine's loop changes the state, handed on after.

The compiled loop cannot be interrupted: Python runs a signal's handler only once the loop returns,
at whatever line of Python comes next, which may be in the middle of updating the state (an exact
run's blocks, a collision log's batch, a writer's checkpoint). `deferred` therefore replaces the
SIGINT handler by one that only notes the signal, and the driver calls `Deferred.deliver` between
chunks, when the state is one the chain passed through: each noted signal then goes to the handler
that was there before, which for Python's default raises KeyboardInterrupt (a command line's own
handler may only ask the run to stop). Signals still noted when the block ends are delivered then.

A block inside another's shares the outer one's `Deferred`: a signal noted anywhere reaches the
handler at the first `Deferred.deliver` of either (each is a point where the state is whole).

Compiling: numba cannot be interrupted safely (an exception raised inside its compiler may leave its
typing registries half made, and a later compile in the process fail with StopIteration), so a compile
inside a block waits like a chunk. Two ways out of waiting for it:

* `Deferred.aside` runs a call that compiles and changes nothing (the driver's compiling call, which takes
  no step) on a thread of its own while the caller waits: a Ctrl-C meanwhile reaches the handler at once
  (Python's raises KeyboardInterrupt) and the call stops being waited for, the state as it was; the
  compile finishes on its thread, and the next `Deferred.aside` (the next run) waits for it first.
* `on_compile_interrupt` (a command line's, `cli.interrupts`): a Ctrl-C while numba compiles, on the main
  thread or in a call put aside, calls a function that ends the process at once.

Nothing is deferred off the main thread (Python delivers signals to the main thread only), nor
when SIGINT is ignored or left to the operating system (`SIG_IGN`, `SIG_DFL`): that choice stands.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

try:  # the C functions under `signal`'s: without its enum conversions, 20 times faster (a run pays it once)
    from _signal import getsignal as _get
    from _signal import signal as _set
except ImportError:  # another Python
    _get, _set = signal.getsignal, signal.signal

__all__ = ["Deferred", "deferred", "on_compile_interrupt"]


class _Woken(BaseException):
    """A SIGINT came while `Deferred.aside` waited (raised by `Deferred.note` into the wait, never further)."""


class Deferred:
    """The SIGINTs noted while a run's chunks ran, and the handler they are for."""

    def __init__(self, previous: Callable | None):
        self.previous = previous  #: the handler before, or None when nothing is deferred
        self.pending: list = []   #: the frames the noted signals came in
        self.waiting = False      #: `aside` is waiting: a signal wakes it

    def note(self, signum, frame) -> None:
        """The handler while the chunks run: note the signal, nothing more (but wake `aside`)."""
        self.pending.append(frame)
        if self.waiting:
            self.waiting = False
            raise _Woken

    def deliver(self) -> None:
        """Hand each noted signal to the handler before (which may raise KeyboardInterrupt)."""
        while self.pending:
            self.previous(signal.SIGINT, self.pending.pop(0))

    def aside(self, call: Callable, *args):
        """``call(*args)``, a call that compiles and leaves the state as it was, on a thread of its own while
        this one waits (module docstring). A SIGINT meanwhile: `on_compile_interrupt`'s function if one is
        set, else the signal handed on at once (`deliver`: Python's handler raises KeyboardInterrupt) and
        KeyboardInterrupt raised if the handler did not raise (one that only notes a request to stop: nothing
        has run, the run stops where it started). The call is then no longer waited for: it finishes on its
        thread, and every later `aside` waits for it first. Where nothing is deferred, ``call(*args)`` here."""
        if self.previous is None:
            return call(*args)
        self._wait(_unfinished)  # a call a Ctrl-C left running: the state is its until it ends
        done, out = threading.Event(), []

        def run() -> None:
            try:
                out.append((True, call(*args)))
            except BaseException as exc:  # noqa: BLE001 - handed to the waiting thread
                out.append((False, exc))
            finally:
                done.set()

        threading.Thread(target=run, name="pinnedballs-compile", daemon=True).start()
        try:
            self._wait([done])
        except BaseException:
            _unfinished.append(done)
            raise
        ok, value = out[0]
        if not ok:
            raise value
        return value

    def _wait(self, events: list) -> None:
        """Wait until every one of ``events`` is set; a SIGINT meanwhile as `aside` says."""
        while events:
            try:
                self.waiting = True
                if self.pending:  # noted before the wait began (as the thread started)
                    raise _Woken
                # an Event's wait may be left by an exception (a Thread's join may not, gh-90882); in slices,
                # because the signal may reach the compiling thread, and Python runs its handler only on the
                # main thread's next instruction, which a wait without end would never come to
                while not events[0].wait(_SLICE):
                    pass
                self.waiting = False
                events.pop(0)
            except _Woken:
                if _on_compile is not None:
                    _on_compile()  # returns only if it declines
                self.deliver()
                raise KeyboardInterrupt from None
            finally:
                self.waiting = False


#: seconds between two looks at a SIGINT while `Deferred.aside` waits
_SLICE = 0.05
#: the calls `Deferred.aside` stopped waiting for, still running (their `threading.Event`s)
_unfinished: list = []
#: what a SIGINT during a compile calls instead of waiting for it (`on_compile_interrupt`), or None
_on_compile: Callable[[], bool] | None = None


def on_compile_interrupt(callback: Callable[[], bool]) -> None:
    """From now on, a SIGINT while numba compiles calls ``callback()`` at once (from the main thread), instead
    of waiting for the compile: on the main thread while its SIGINT handler is a Python function (`SIG_IGN`
    stands), and in a call `Deferred.aside` waits for. For a program about to end: ``callback`` ends the
    process (``os._exit``; numba is left mid-compile), or returns False to decline (the signal then goes where
    it would have gone). Compiles run from other threads are not watched."""
    global _on_compile
    from .compiling import CompileWatch  # numba: imported here, not when a program starts

    if _on_compile is None:
        watch = _CompileInterrupts()
        CompileWatch(watch.began, watch.ended).start()
    _on_compile = callback


class _CompileInterrupts:
    """The SIGINT handler while the main thread compiles: `on_compile_interrupt`'s function."""

    def __init__(self):
        self.replaced = None  # the handler the compile's began() replaced, restored by ended()

    def began(self) -> None:
        if threading.current_thread() is threading.main_thread() and callable(handler := _get(signal.SIGINT)):
            held = getattr(handler, "__self__", None)
            if isinstance(held, Deferred) and held.pending and _on_compile is not None:
                _on_compile()  # a Ctrl-C noted before this compile began; if declined, it stays noted
            self.replaced = handler
            _set(signal.SIGINT, self.interrupt)

    def ended(self) -> None:
        if self.replaced is not None and threading.current_thread() is threading.main_thread():
            _set(signal.SIGINT, self.replaced)
            self.replaced = None

    def interrupt(self, signum, frame) -> None:
        if (_on_compile is None or not _on_compile()) and callable(self.replaced):
            self.replaced(signum, frame)


@contextlib.contextmanager
def deferred() -> Iterator[Deferred]:
    """SIGINT noted, not acted on, inside the block (see the module's docstring); the block calls
    `Deferred.deliver` wherever the state is complete."""
    previous = _get(signal.SIGINT) if threading.current_thread() is threading.main_thread() else None
    outer = getattr(previous, "__self__", None)
    if isinstance(outer, Deferred):  # inside another block: share its notes
        yield outer
        return
    if not callable(previous):  # off the main thread, SIG_IGN, SIG_DFL or a handler set outside Python
        yield Deferred(None)
        return
    held = Deferred(previous)
    _set(signal.SIGINT, held.note)
    try:
        yield held
    except BaseException:
        held.pending.clear()  # an exception is on its way out already
        raise
    finally:
        _set(signal.SIGINT, previous)
    held.deliver()
