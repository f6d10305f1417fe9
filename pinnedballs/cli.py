"""The ``pinnedballs`` command line.

Each subcommand is one function ``(args) -> int`` registered with `subcommand`,
which names it, gives its help and its arguments; `main` finds it in `COMMANDS`.

Exit status: 0 done; 2 bad input (one line on stderr naming the field or file);
1 anything else; 130 interrupted (after a complete checkpoint).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import traceback
from dataclasses import dataclass
from typing import Callable

__all__ = ["main", "subcommand", "arg", "COMMANDS", "EXIT_OK", "EXIT_ERROR", "EXIT_INPUT"]

EXIT_OK, EXIT_ERROR, EXIT_INPUT, EXIT_INTERRUPTED = 0, 1, 2, 130
PROG = "pinnedballs"


@dataclass(frozen=True)
class Subcommand:
    name: str
    help: str
    arguments: tuple[tuple[tuple, dict], ...]
    run: Callable[[argparse.Namespace], int]


#: the subcommands, in the order ``--help`` lists them
COMMANDS: dict[str, Subcommand] = {}


def arg(*flags: str, **options) -> tuple[tuple, dict]:
    """One ``add_argument(*flags, **options)`` of a subcommand."""
    return flags, options


def subcommand(name: str, help: str, *arguments: tuple[tuple, dict]):
    """Register the decorated ``run(args) -> int`` as ``pinnedballs NAME``."""
    def register(run: Callable[[argparse.Namespace], int]) -> Callable[[argparse.Namespace], int]:
        COMMANDS[name] = Subcommand(name, help, arguments, run)
        return run
    return register


class UsageError(Exception):
    """Bad command-line arguments (exit 2, one line)."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):
        command = self.prog.partition(" ")[2]  # "pinnedballs run" -> "run"
        raise UsageError(f"{command}: {message}" if command else message)


def _parser() -> argparse.ArgumentParser:
    from . import __version__

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
    """Run the command line with ``argv`` (default ``sys.argv[1:]``); return the exit status."""
    from .spec import InputError

    try:
        args = _parser().parse_args(argv)
        return COMMANDS[args.command].run(args)
    except SystemExit as exc:  # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_OK
    except (UsageError, InputError, FileNotFoundError) as exc:
        _say(f"error: {_one_line(exc)}")
        return EXIT_INPUT
    except KeyboardInterrupt:
        _say("interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # the reader (e.g. ``| head``) has had enough: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error at exit
        return EXIT_OK
    except Exception as exc:  # noqa: BLE001 - the catch-all of a command line
        from .runner import Interrupted

        if isinstance(exc, Interrupted):
            _say(str(exc))
            return EXIT_INTERRUPTED
        traceback.print_exc(file=sys.stderr)
        _say(f"error: {type(exc).__name__}: {_one_line(exc)}")
        return EXIT_ERROR


def _say(message: str) -> None:
    print(f"{PROG}: {message}", file=sys.stderr)


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


# ---------------------------------------------------------------- subcommands


@subcommand("run", "run a spec into a directory: results.h5, spec.json, figures",
            arg("spec", metavar="SPEC.json", help="the run spec"),
            arg("--out", required=True, metavar="DIR", help="the run directory (created)"),
            arg("--force", action="store_true", help="write into a non-empty directory, replacing a run there"),
            arg("--resume", action="store_true", help="continue the run in DIR from its last checkpoint"),
            arg("--quiet", action="store_true", help="no progress bar, no summary"),
            arg("--no-figures", action="store_true", help="write no figures (draw them later with plot)"))
def run(args: argparse.Namespace) -> int:
    from .runner import execute
    from .spec import load_spec

    if args.force and args.resume:
        raise UsageError("run: give --force or --resume, not both")
    spec = load_spec(args.spec)
    path = execute(spec, args.out, force=args.force, resume=args.resume,
                   progress=False if args.quiet else None,
                   figures=not args.no_figures and _plots_available())
    if not args.quiet:
        from .io import load

        res = load(path)
        print(f"{res.stop_reason or res.status}: {res.steps:,} steps, {res.collisions:,} collisions, "
              f"energy {res.energy:.12g}, {'frozen' if res.frozen else 'not frozen'}; wrote {path.parent}")
    return EXIT_OK


@subcommand("validate", "check a spec, and that it builds; print a one-line summary",
            arg("spec", metavar="SPEC.json", help="the run spec"))
def validate(args: argparse.Namespace) -> int:
    from .spec import describe, load_spec

    spec = load_spec(args.spec)
    print(f"ok: {describe(spec, spec.build())}")
    return EXIT_OK


@subcommand("schema", "print the JSON Schema of run specs")
def schema(args: argparse.Namespace) -> int:
    from .spec import RunSpec

    print(json.dumps(RunSpec.model_json_schema(), indent=2))
    return EXIT_OK


@subcommand("plot", "draw the figures of a run again from its results file",
            arg("dir", metavar="DIR", help="a run directory (or its results.h5)"))
def plot(args: argparse.Namespace) -> int:
    from .io import load
    from .runner import write_figures

    run_dir = load(args.dir).path.parent  # checks the file before drawing
    paths = write_figures(run_dir)
    print("\n".join(map(str, paths)) if paths else f"{run_dir}: no figures fit this geometry; none written")
    return EXIT_OK


@subcommand("info", "summarise a results file",
            arg("dir", metavar="DIR", help="a run directory (or its results.h5)"))
def info(args: argparse.Namespace) -> int:
    from .io import load

    res = load(args.dir)
    g = res.spec.geometry
    lines = [
        f"results:     {res.path}",
        f"status:      {res.status}" + (f" ({res.stop_reason})" if res.stop_reason else " (last checkpoint)"),
        f"geometry:    {g.kind}: {len(res.positions)} balls, {len(res.pairs)} contacts, dim {res.velocities.shape[1]}",
        f"run:         {res.spec.initial.kind}, {res.spec.rule.kind}, {res.spec.scheduler.kind}, seed {res.spec.seed}",
        f"steps:       {res.steps:,}",
        f"collisions:  {res.collisions:,}",
        f"energy:      {res.energy:.12g} (initially {res.initial_energy:.12g})",
        f"approaching: {res.approaching:,} contacts ({'frozen' if res.frozen else 'not frozen'})",
        f"snapshots:   {len(res.snapshots)}" + (f" at steps {_few([s.step for s in res.snapshots])}"
                                                if res.snapshots else ""),
        f"time:        {res.elapsed_seconds:.1f} s in {res.checkpoints} checkpoint(s); "
        f"written by pinnedballs {res.version}",
    ]
    print("\n".join(lines))
    return EXIT_OK


def _few(values: list[int]) -> str:
    shown = ", ".join(f"{v:,}" for v in values[:5])
    return shown + (f", ... ({len(values)} in all)" if len(values) > 5 else "")


def _plots_available() -> bool:
    import importlib.util

    return importlib.util.find_spec("pinnedballs.plots") is not None


# subcommands that live in their own modules register themselves on import
from . import ensemble as _ensemble, reproduce as _reproduce  # noqa: E402,F401
