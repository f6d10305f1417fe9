"""Feedback from the first second: one status line on a terminal, saying what a command is doing.

`Status` rewrites a single line of stderr in place ("building the geometry", "compiling the
loop", ...) and clears it before a progress bar takes the line over or the command prints its
summary. Off a terminal, or when told to be quiet, it writes nothing.
"""

from __future__ import annotations

import sys
from typing import TextIO

__all__ = ["Status", "CLEAR", "is_terminal"]

#: carriage return, then erase to the end of the line (ANSI)
CLEAR = "\r\x1b[K"


class Status:
    """``status("message")`` shows ``pinnedballs: message ...`` on stderr's line; ``status.clear()``
    erases it. ``show``: None means only when the stream is a terminal; False writes nothing."""

    def __init__(self, show: bool | None = None, stream: TextIO | None = None):
        self.stream = sys.stderr if stream is None else stream
        self.shown = is_terminal(self.stream) if show is None else bool(show)
        self._on = False

    def __call__(self, message: str) -> None:
        if self.shown:
            self.stream.write(f"{CLEAR}pinnedballs: {message} ...")
            self.stream.flush()
            self._on = True

    def clear(self) -> None:
        """Erase the line (before a bar or a summary), if a message is on it."""
        if self._on:
            self.stream.write(CLEAR)
            self.stream.flush()
            self._on = False

    def __enter__(self) -> Status:
        return self

    def __exit__(self, *exc) -> None:
        self.clear()


def is_terminal(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


#: a `Status` that never writes
SILENT = Status(show=False)
