"""The ``pinnedballs`` command line: `main` parses the arguments, runs the subcommand (`commands`)
and turns every failure into one line on stderr and an exit status.

Exit status: 0 done; 2 bad input (one line on stderr naming the field or file), a user's code
that fails included (naming the factory; ``--traceback`` prints its traceback first); 1 anything
else (an engine that failed, `InternalError`, in one line, ``--traceback`` printing its traceback
first; any other error with its traceback); 130 interrupted (Ctrl-C or SIGTERM; a run after a
complete checkpoint).

A float run until frozen whose count depends on its collision criterion (`engine.margin.MarginWarning`, a
`util.notes.Note`) says so once, as one line on stderr: ``pinnedballs: note: the closing margin is thin (...)``.
This module imports no numba, scipy or h5py: each command imports what it needs (``schema``, ``validate`` and
``info`` start in about a second).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import signal
import sys
import threading
import traceback
import warnings
from collections.abc import Iterator
from pathlib import Path

from ..._version import __version__
from ...util import provenance
from ...util.errors import InputError, InternalError
from ...util.notes import Note
from .commands import COMMANDS, EXIT_ERROR, EXIT_INPUT, EXIT_INTERRUPTED, EXIT_OK, PROG, UsageError
from .status import CLEAR, is_terminal
from .study import study_command as _study  # noqa: F401 - registers ``pinnedballs study``

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):
        command = self.prog.partition(" ")[2]  # "pinnedballs run" -> "run"
        raise UsageError(f"{command}: {message}" if command else message)


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="Simulate pinned billiard balls from JSON run specs.")
    parser.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    subs = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    subs.required = True
    for command in COMMANDS.values():
        p = subs.add_parser(command.name, help=command.help, description=command.help)
        for flags, options in command.arguments:
            p.add_argument(*flags, **options)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv`` (default ``sys.argv[1:]``: the program itself, which from
    then on ignores Ctrl-C: one that comes as it exits must not change its status); return the exit status.
    SIGTERM stops a command as Ctrl-C does (a run saves its state first)."""
    try:
        with _sigterm_interrupts():
            return _main(argv)
    finally:
        if argv is None and threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)


def _main(argv: list[str] | None) -> int:
    show_traceback = False
    try:
        args = _parser().parse_args(argv)
        show_traceback = getattr(args, "traceback", False)
        line = sys.argv[1:] if argv is None else argv  # what the outputs' provenance records (`util.provenance`)
        with _user_modules(getattr(args, "spec", None)), _notes(), provenance.command_line(line):
            return COMMANDS[args.command].run(args)
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_OK
    except (UsageError, InputError, FileNotFoundError) as exc:
        if show_traceback:  # a user's code that failed: its own traceback, then what it means here
            traceback.print_exception(exc, file=sys.stderr)
        _say(f"error: {_one_line(exc)}")
        return EXIT_INPUT
    except KeyboardInterrupt:
        _say("interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # the reader (e.g. ``| head``) has had enough: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return EXIT_OK
    except Exception as exc:  # noqa: BLE001 - the catch-all of a command line
        from ..execute import Interrupted  # here: a command that never runs a spec never imports it

        if isinstance(exc, Interrupted):
            _say(str(exc))
            return EXIT_INTERRUPTED
        if isinstance(exc, OSError) and exc.errno in _DISK_FULL:  # the last checkpoint is intact
            _say(f"error: {_one_line(exc)}; free some space, then continue a run with --resume")
            return EXIT_ERROR
        if isinstance(exc, InternalError):  # what failed, in its own words; the run is saved "failed"
            if show_traceback:
                traceback.print_exception(exc, file=sys.stderr)
            _say(f"error: {_one_line(exc)}")
            return EXIT_ERROR
        traceback.print_exc(file=sys.stderr)
        _say(f"error: {type(exc).__name__}: {_one_line(exc)}")
        return EXIT_ERROR


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt, as Ctrl-C does, while the command runs (main thread; not
    where it is ignored, as a launcher may ask): code that runs long outside the run loop, a user's
    factory that never returns, stops at once with exit status 130."""
    if threading.current_thread() is not threading.main_thread() or \
            signal.getsignal(signal.SIGTERM) in (signal.SIG_IGN, None):
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


@contextlib.contextmanager
def _user_modules(spec: str | None) -> Iterator[None]:
    """Let a spec's ``"kind": "python"`` factory live in a module beside the spec file or in the
    working directory, as ``python -m pinnedballs`` finds one in the working directory.

    Both directories go at the end of ``sys.path`` (``python -m`` puts the working directory
    first): a user's module is found, but a stray file in the working directory never shadows
    a library pinnedballs imports later. They are removed again when the command ends.
    """
    wanted = [str(Path(spec).resolve().parent)] if spec else []
    added = [d for d in dict.fromkeys([*wanted, os.getcwd()]) if d not in sys.path]
    sys.path.extend(added)
    try:
        yield
    finally:
        for d in added:
            if d in sys.path:
                sys.path.remove(d)


@contextlib.contextmanager
def _notes() -> Iterator[None]:
    """While a command runs, a `Note` (`engine.margin.MarginWarning`) is said once, as one line
    ``pinnedballs: note: ...`` on stderr (clearing a status line or progress bar first), instead of Python's
    warning with a file and a line; later ones are left out. Other warnings are shown as Python shows them."""
    said = []
    with warnings.catch_warnings():
        warnings.simplefilter("always", Note)  # each simulation warns once; the command says it once
        show = warnings.showwarning

        def note(message, category, filename, lineno, file=None, line=None):
            if not issubclass(category, Note):
                show(message, category, filename, lineno, file, line)
            elif not said:
                said.append(message)
                from tqdm import tqdm

                with tqdm.external_write_mode(file=sys.stderr):
                    sys.stderr.write(f"{CLEAR if is_terminal(sys.stderr) else ''}{PROG}: note: {_one_line(message)}\n")
                    sys.stderr.flush()

        warnings.showwarning = note
        yield


#: errors of a full disk or quota: one line, not a traceback
_DISK_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}


def _say(message: str) -> None:
    print(f"{PROG}: {message}", file=sys.stderr)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
