"""A Ctrl-C before the command line's `main` runs (``python -m pinnedballs`` and the ``pinnedballs``
program): one line, ``pinnedballs: interrupted``, and exit status 130, not Python's traceback of the
import it landed in. The program's ``__main__`` calls `from_the_first_instant` before its heavy imports
(numpy, numba, h5py: the first second or so), so only the standard library may be imported here.

A Ctrl-C inside the command line's ``main._main`` raises KeyboardInterrupt as Python's handler does,
which ``main`` turns into its own line (`pinnedballs.run.cli.interrupts`)."""

from __future__ import annotations

import os
import signal
import sys
import threading

__all__ = ["from_the_first_instant", "end_at_once", "EXIT_INTERRUPTED"]

EXIT_INTERRUPTED = 130
#: the command line's ``main._main``, found on the stack of a Ctrl-C that came while it runs (its file, not
#: an import: this module is loaded before the package's others)
_MAIN = os.path.join(os.path.dirname(os.path.dirname(os.path.realpath(__file__))), "run", "cli", "main.py")


def from_the_first_instant() -> None:
    """The program's Ctrl-C outside ``main._main`` (before it, while the command line imports, and after it):
    ``pinnedballs: interrupted`` on stderr and exit status 130 at once. Inside ``main._main``
    KeyboardInterrupt, as Python's handler raises it. Main thread only; a SIGINT the caller ignores, or
    handles its own way, is left so. Called by the program's ``__main__``, never by the library's import."""
    if threading.current_thread() is threading.main_thread() and \
            signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _at_once_outside_main)


def end_at_once(message: str, prefix: str = "") -> None:
    """``prefix`` and ``pinnedballs: message`` on stderr and the process ended at once, status 130: no
    handler, no cleanup, no Python shutdown (``prefix``: what clears a terminal's status line)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 - interrupted in the middle of a write: the line goes out anyway
            pass
    try:
        fd = sys.stderr.fileno()
    except Exception:  # noqa: BLE001 - a replaced stderr
        fd = 2
    try:
        os.write(fd, f"{prefix}pinnedballs: {message}\n".encode())
    finally:
        os._exit(EXIT_INTERRUPTED)


def _at_once_outside_main(signum, frame) -> None:
    if _inside_main(sys._getframe()):
        raise KeyboardInterrupt
    end_at_once("interrupted")


def _inside_main(frame) -> bool:
    """Whether ``frame`` runs inside the command line's ``main._main``."""
    while frame is not None:
        code = frame.f_code
        if code.co_name == "_main" and os.path.realpath(code.co_filename) == _MAIN:
            return True
        frame = frame.f_back
    return False
