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

Compiling counts as a chunk: numba's typing registries are left half made by an exception raised
inside the compiler (a later compile in the process fails with StopIteration), so a first call's
compilation runs inside a block too.

Nothing is deferred off the main thread (Python delivers signals to the main thread only), nor
when SIGINT is ignored or left to the operating system (`SIG_IGN`, `SIG_DFL`): that choice stands.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Callable, Iterator

try:  # the C functions under `signal`'s: without its enum conversions, 20 times faster (a run pays it once)
    from _signal import getsignal as _get, signal as _set
except ImportError:  # another Python
    _get, _set = signal.getsignal, signal.signal

__all__ = ["Deferred", "deferred"]


class Deferred:
    """The SIGINTs noted while a run's chunks ran, and the handler they are for."""

    def __init__(self, previous: Callable | None):
        self.previous = previous  #: the handler before, or None when nothing is deferred
        self.pending: list = []   #: the frames the noted signals came in

    def note(self, signum, frame) -> None:
        """The handler while the chunks run: note the signal, nothing more."""
        self.pending.append(frame)

    def deliver(self) -> None:
        """Hand each noted signal to the handler before (which may raise KeyboardInterrupt)."""
        while self.pending:
            self.previous(signal.SIGINT, self.pending.pop(0))


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
