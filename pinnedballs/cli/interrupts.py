"""What a Ctrl-C means for the exit status of ``pinnedballs run``: the status says what the results
file says (issue 20). 0 when the run is done, even if the Ctrl-C came during its final write or
its figures; 130 when it stopped before its end, the file then saying "interrupted" at the state
it stopped in (or, if this command never touched it, as it was)."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from pathlib import Path
from typing import Iterator

from ..results.format import RESULTS_NAME, ResultsError

__all__ = ["fingerprint", "exit_status", "interrupted_by", "sigint_ignored", "EXIT_OK", "EXIT_INTERRUPTED"]

EXIT_OK, EXIT_INTERRUPTED = 0, 130


def fingerprint(out: Path) -> tuple | None:
    """What identifies the version of ``out/results.h5`` on disk (None if there is none): each
    checkpoint replaces the file, so a new one has another inode."""
    try:
        st = os.stat(out / RESULTS_NAME)
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_mtime_ns, st.st_size


def exit_status(out: Path, before: tuple | None, new_run: bool, figures: bool) -> int:
    """The exit status of a ``run`` into ``out`` that a Ctrl-C or SIGTERM stopped, with one line on stderr.

    before: the `fingerprint` of its results file when the command began; new_run: the command was
    to start a run (not ``--resume``), so a finished run it never touched is not its own; figures:
    the command was to draw them."""
    from ..results.load import load

    touched = fingerprint(out) != before
    try:
        res = load(out) if touched or not new_run else None
    except (FileNotFoundError, ResultsError):
        res = None
    if res is None:
        _say(f"interrupted before the run wrote anything in {out}")
        return EXIT_INTERRUPTED
    if res.complete:
        _say(f"the run in {out} is done ({res.stop_reason}); " + (
            f"interrupted before its figures: draw them with pinnedballs plot {out}" if figures else
            "the interrupt came as it finished"))
        return EXIT_OK
    if touched and res.status == "interrupted":
        _say(f"interrupted at step {res.steps:,}; the checkpoint in {out} is complete: continue with --resume")
    else:
        _say(f"interrupted before the run went on; {out} is as it was (step {res.steps:,}): continue with --resume")
    return EXIT_INTERRUPTED


def interrupted_by(exc: BaseException) -> bool:
    """Whether ``exc`` stands for a Ctrl-C: a KeyboardInterrupt that code it interrupted turned into
    another exception (e.g. Python's RuntimeError "Error calling __set_name__" when the Ctrl-C lands
    in the middle of importing a module), found in its chain of causes and contexts."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ctrl-C ignored while the exit status is settled (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def _say(message: str) -> None:
    print(f"pinnedballs: {message}", file=sys.stderr)
