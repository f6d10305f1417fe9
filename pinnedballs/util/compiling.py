"""Whether numba is compiling: its compile events, heard while a call shows its progress.

numba announces each compile (``"numba:compile"``): a cache miss only, a load from the disk cache is
none. A compile compiles the jitted functions it calls inside it, so only the outermost one counts.
`util.progress` says "compiling" meanwhile, and takes no speed from the time it took.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

from numba.core import event

__all__ = ["CompileWatch"]

_KIND = "numba:compile"


class CompileWatch(event.Listener):
    """Calls ``began()`` when numba starts a compile and ``ended()`` when it is done (or failed), from
    the compiling thread, between `start` and `stop`."""

    def __init__(self, began: Callable[[], None], ended: Callable[[], None]):
        self.began, self.ended, self.depth = began, ended, 0

    def on_start(self, ev) -> None:
        self.depth += 1
        if self.depth == 1:
            _told(self.began)

    def on_end(self, ev) -> None:
        if self.depth == 0:  # a compile under way when the watch started
            return
        self.depth -= 1
        if self.depth == 0:
            _told(self.ended)

    def start(self) -> None:
        event.register(_KIND, self)

    def stop(self) -> None:
        event.unregister(_KIND, self)


def _told(callback: Callable[[], None]) -> None:
    """``callback()``; its failure (a display's) is a warning, never an error inside numba's compile."""
    try:
        callback()
    except Exception as exc:  # noqa: BLE001 - the compile must go on
        warnings.warn(f"the progress display failed while numba compiled: {exc!r}", RuntimeWarning, stacklevel=2)
