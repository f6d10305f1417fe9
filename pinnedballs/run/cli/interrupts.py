"""What a Ctrl-C means for the exit status of ``pinnedballs run``: the status says what the results
file says (issue 20). 0 when the run is done, even if the Ctrl-C came during its final write or
its figures; 130 when it stopped before its end, the file then saying "interrupted" at the state
it stopped in (or, if this command never touched it, as it was).

At any moment (issue 42): the package's ``__init__`` calls `util.startup.from_the_first_instant` before
anything else in the command line, so a Ctrl-C while the package is imported (the first second or so) is one
line, ``pinnedballs: interrupted``, and status 130, not Python's traceback of the import it landed in; and
``python -m pinnedballs`` calls `exit_while_compiling` (numba's compiles watched once ``run`` starts), so a Ctrl-C
while numba compiles (seconds on a first run; numba cannot be interrupted safely) ends ``pinnedballs run`` at once,
with one line saying what the run directory holds: every file of a run is written whole (`util.atomic`), its last
checkpoint (from step 0, written as the run starts) is complete, and ``--resume`` continues from it; a new run
compiles before it writes anything (`run.execute`). (Other commands, whose workers a process ended at once could
leave behind, wait for the compile as before.) This module imports no more than the standard library and
`util.startup` when it is loaded.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

from ...util.startup import EXIT_INTERRUPTED, end_at_once

__all__ = ["fingerprint", "exit_status", "interrupted_by", "sigint_ignored", "exit_while_compiling", "running",
           "EXIT_OK", "EXIT_INTERRUPTED"]

EXIT_OK = 0
#: when this command began (loaded before it runs): a results file changed since is its own
_BEGAN_NS = time.time_ns()
_RESULTS_NAME = "results.h5"  # `results.format.RESULTS_NAME`, without importing h5py before it is needed


def fingerprint(out: Path) -> tuple | None:
    """What identifies the version of ``out/results.h5`` on disk (None if there is none): each
    checkpoint replaces the file, so a new one has another inode."""
    try:
        st = os.stat(out / _RESULTS_NAME)
    except OSError:
        return None
    return st.st_dev, st.st_ino, st.st_mtime_ns, st.st_size


def exit_status(out: Path, before: tuple | None, new_run: bool, figures: bool) -> int:
    """The exit status of a ``run`` into ``out`` that a Ctrl-C or SIGTERM stopped, with one line on stderr.

    before: the `fingerprint` of its results file when the command began; new_run: the command was
    to start a run (not ``--resume``), so a finished run it never touched is not its own; figures:
    the command was to draw them."""
    from ...results.format import ResultsError
    from ...results.load import load

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


def exit_while_compiling() -> None:
    """From now on a Ctrl-C while numba compiles ends ``pinnedballs run`` at once with one line and status 130
    (`util.sigint.on_compile_interrupt`; module docstring): the program's, called once. numba's compiles are
    watched from when the command is known to be ``run`` (`running`): the other commands, which would decline
    anyway, import no numba for it (``validate``, ``schema`` and ``info`` start in a second)."""
    global _program
    _program = True
    if _running is not None:
        _watch()


def running(out: Path, resume: bool) -> None:
    """This command is ``pinnedballs run`` into ``out`` (``--resume``: continuing it): what a Ctrl-C while
    numba compiles may end at once (`exit_while_compiling`)."""
    global _running
    _running = (Path(out), bool(resume))
    if _program:
        _watch()


def _watch() -> None:
    from ...util.sigint import on_compile_interrupt  # numba

    on_compile_interrupt(_end_while_compiling)


#: ``(out, resume)`` of the ``run`` this command is (`running`), or None: another command
_running: tuple[Path, bool] | None = None
#: whether this process is the program, whose ``run`` a Ctrl-C while numba compiles ends at once
_program = False


def _end_while_compiling() -> bool:
    """A Ctrl-C while numba compiled in ``pinnedballs run``: the command ended at once, with one line saying
    what its directory holds (a results file this command wrote is a whole checkpoint of the run, from step 0
    on). Declined (False) for the other commands, whose workers a process ended at once could leave behind."""
    if _running is None:
        return False
    (out, resume), said = _running, "interrupted while numba compiled"
    try:
        written = os.stat(out / _RESULTS_NAME).st_mtime_ns >= _BEGAN_NS
    except OSError:
        written = False
    if written:
        _end(f"{said}; the checkpoint in {out} is complete: continue with --resume")
    if resume:
        _end(f"{said}, before the run went on; {out} is as it was: continue with --resume")
    _end(f"{said}, before the run wrote anything in {out}")


def _end(message: str) -> None:
    """``pinnedballs: message`` on stderr (clearing a status line or a bar on a terminal), status 130 at once."""
    from .status import CLEAR, is_terminal

    end_at_once(message, CLEAR if is_terminal(sys.stderr) else "")


def _say(message: str) -> None:
    print(f"pinnedballs: {message}", file=sys.stderr)
