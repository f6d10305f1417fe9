"""The subcommands of ``pinnedballs``: each is one function ``(args) -> int`` registered with
`subcommand`, which names it, gives its help and its arguments; `main.main` finds it in `COMMANDS`.
Each imports what it needs inside it: loading this module loads no engine (``schema`` needs none)."""

from __future__ import annotations

import argparse
import contextlib
import json
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from ...engine.devices import DEVICE_NAMES

__all__ = ["COMMANDS", "subcommand", "arg", "UsageError", "EXIT_OK", "EXIT_ERROR", "EXIT_INPUT", "EXIT_INTERRUPTED"]

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


#: the flag of every subcommand that may run a user's code (a spec's factories)
TRACEBACK = arg("--traceback", action="store_true",
                help="when a user's code named by the spec, or an engine, fails, print its traceback too "
                     "(for debugging it)")

DEVICE = arg("--device", choices=tuple(DEVICE_NAMES), default="cpu",
             help="where the chain runs: cpu, or cuda (an NVIDIA GPU, pip install \".[cuda]\"; the counter "
                  "stream's scheduler, float or certified arithmetic, any rule numba-cuda compiles with the CPU's "
                  "rounding; the same bits as on the CPU)")


# ---------------------------------------------------------------- subcommands


@subcommand("run", "run a spec into a directory: results.h5, spec.json, figures",
            arg("spec", metavar="SPEC.json", help="the run spec"),
            arg("--out", required=True, metavar="DIR", help="the run directory (created)"),
            arg("--force", action="store_true", help="write into a non-empty directory, replacing a run there"),
            arg("--resume", action="store_true", help="continue the run in DIR from its last checkpoint, or start it "
                                                      "if DIR holds none yet (one command line for every life of a "
                                                      "requeued job)"),
            arg("--quiet", action="store_true", help="no progress bar, no summary"),
            arg("--no-figures", action="store_true", help="write no figures (draw them later with plot)"),
            DEVICE, TRACEBACK)
def run(args: argparse.Namespace) -> int:
    """``pinnedballs run``; a Ctrl-C or SIGTERM gives the exit status the results file agrees with
    (`interrupts.exit_status`)."""
    from ..execute import Interrupted
    from .interrupts import exit_status, fingerprint, interrupted_by, running, sigint_ignored

    if args.force and args.resume:
        raise UsageError("run: give --force or --resume, not both")
    before = fingerprint(Path(args.out))
    running(Path(args.out), args.resume)  # a Ctrl-C while numba compiles may end it at once
    try:
        return _run(args)
    except (KeyboardInterrupt, Interrupted):
        pass
    except Exception as exc:
        if not interrupted_by(exc):
            raise
    with sigint_ignored():
        return exit_status(Path(args.out), before, new_run=not args.resume,
                           figures=not args.no_figures and _plots_available())


def _run(args: argparse.Namespace) -> int:
    from ..execute import execute
    from .status import Status

    with Status(show=False if args.quiet else None) as status:
        status("reading the spec")
        from ...specs.run import load_spec
        from ...util.compiling import CompileClock

        spec = load_spec(args.spec)
        with CompileClock() as clock:  # the geometry's checks, the loop: what numba compiled, and kept
            path = execute(spec, args.out, force=args.force, resume=args.resume, progress=_progress(args),
                           figures=not args.no_figures and _plots_available(), status=status,
                           log=lambda message: print(f"{PROG}: {message}", file=sys.stderr, flush=True),
                           device=args.device)
    if not args.quiet:
        from ...results.load import load

        res = load(path)
        reason = res.stop_reason or res.status
        frozen = "" if reason == "frozen" else f", {'frozen' if res.frozen else 'not frozen'}"  # said once
        print(f"{reason}: {res.steps:,} steps, {res.collisions:,} collisions, energy {res.energy:.12g}{frozen}; "
              f"wrote {path.parent}")
    _say_compiled(clock, status)
    return EXIT_OK


def _say_compiled(clock, status) -> None:
    """Once, on a terminal (where the bar said what compiled), after a command that compiled a second or more:
    how long, and that numba's disk cache spares the next run (`util.compiling.CompileClock.note`)."""
    note = clock.note()
    if note is not None and status.shown:
        print(f"{PROG}: {note}", file=sys.stderr, flush=True)


@subcommand("validate", "check a spec, and that it builds; print a one-line summary",
            arg("spec", metavar="SPEC.json", help="the run spec"), TRACEBACK)
def validate(args: argparse.Namespace) -> int:
    from ...specs.run import describe, load_spec

    spec = load_spec(args.spec)
    print(f"ok: {describe(spec, spec.build())}")
    return EXIT_OK


@subcommand("schema", "print the JSON Schema of run specs (of study specs with --study)",
            arg("--study", action="store_true", help="the schema of study specs (pinnedballs study) instead"))
def schema(args: argparse.Namespace) -> int:
    if args.study:
        from ...specs.study import study_schema

        print(json.dumps(study_schema(), indent=2))
        return EXIT_OK
    from ...specs.run import RunSpec

    print(json.dumps(RunSpec.model_json_schema(), indent=2))
    return EXIT_OK


@subcommand("plot", "draw the figures of a run again from its results file: the first and last states, a contact "
                    "sheet of the snapshots, the energy and the velocity histograms (of an ensemble: the "
                    "correlation histograms; of a study: an observable against a parameter, mean ± se by point)",
            arg("dir", metavar="DIR", help="a run directory (or its results.h5), an ensemble's or a study's directory"),
            arg("--every-snapshot", action="store_true", help="also one picture per snapshot (state_step_N.png)"),
            arg("--observable", default="collisions", help="a study's: the observable drawn (default collisions)"),
            arg("--against", default="n_balls", help="a study's: against n_balls (the default; log-log, with the "
                                                     "fit) or a path the study varies"))
def plot(args: argparse.Namespace) -> int:
    from ..study_dir import is_study_dir, load_study

    if is_study_dir(args.dir):  # the observable against the parameter, mean ± se by point (StudyResult.plot)
        path = Path(args.dir) / "figures" / f"{args.observable}_against_{args.against}.png"
        load_study(args.dir).plot(args.observable, args.against, path=path)
        print(path)
        return EXIT_OK
    from ...results.load import load
    from ..ensemble_dir import is_ensemble_dir, load_ensemble
    from ..execute import write_figures

    if is_ensemble_dir(args.dir) and not (Path(args.dir) / "results.h5").exists():
        from ..ensemble_files import write_figures as ensemble_figures

        paths = ensemble_figures(load_ensemble(args.dir), args.dir)
        print("\n".join(map(str, paths)) if paths else f"{args.dir}: no correlation to draw; no figures written")
        return EXIT_OK

    run_dir = load(args.dir).path.parent  # checks the file before drawing
    paths = write_figures(run_dir, every_snapshot=args.every_snapshot)
    print("\n".join(map(str, paths)) if paths else f"{run_dir}: no figures fit this geometry; none written")
    return EXIT_OK


@subcommand("animate", "a movie of a run's snapshots (GIF; MP4 with the 'movies' extra)",
            arg("dir", metavar="DIR", help="a run directory (or its results.h5)"),
            arg("--out", metavar="MOVIE", help="movie.gif or movie.mp4 (default: DIR/movie.gif)"),
            arg("--fps", type=float, default=4.0, metavar="N", help="frames per second (default 4)"),
            arg("--max-frames", type=int, metavar="N", help="at most N frames, evenly spaced among the states "
                                                            "(default 300)"))
def animate(args: argparse.Namespace) -> int:
    import warnings

    from ...results.load import load
    from ...util.errors import FieldError

    res = load(args.dir)
    try:
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always", UserWarning)
            path = res.animate(args.out, args.fps, args.max_frames)
    except FieldError as exc:  # name the flag, not the Python argument
        if exc.field not in ("out", "fps", "max_frames"):
            raise
        raise UsageError(f"animate: --{exc.field.replace('_', '-')}: {exc.problem}") from None
    for warning in said:  # the frames chosen when the run has more states than the movie takes
        print(f"pinnedballs: {str(warning.message).replace('max_frames=', '--max-frames ')}", file=sys.stderr)
    print(path)
    return EXIT_OK


@subcommand("export", "the snapshots of a run as a GSD trajectory (HOOMD schema: OVITO, freud, MDAnalysis)",
            arg("dir", metavar="DIR", help="a run directory (or its results.h5)"),
            arg("out", metavar="OUT.gsd", help="the trajectory to write: one frame per snapshot"),
            arg("--force", action="store_true", help="replace OUT.gsd if it exists"))
def export(args: argparse.Namespace) -> int:
    from ...results.load import load
    from ...results.tables import rows
    from ...results.trajectory import check_output
    from ...results.trajectory import export as write_gsd

    check_output(args.out, force=args.force, hint="use --force to replace it")  # before reading the run
    res = load(args.dir)
    path = write_gsd(res, args.out, force=args.force, hint="use --force to replace it")
    frames = len(rows(res)[1])
    final = "" if frames == len(res.snapshots) else " and the final state"
    print(f"{path}: {frames} frames (the {len(res.snapshots)} snapshots{final}), {len(res.positions)} balls")
    return EXIT_OK


@subcommand("info", "summarise a results file, an ensemble directory or a study directory (its points done)",
            arg("dir", metavar="DIR", help="a run directory (or its results.h5), an ensemble's or a study's directory"))
def info(args: argparse.Namespace) -> int:
    from .. import study_dir

    if study_dir.is_study_dir(args.dir):
        print("\n".join(study_dir.describe(study_dir.load_study(args.dir), Path(args.dir))))
        return EXIT_OK
    from ...results.load import load
    from ...results.remains import lost_index
    from ...util.provenance import lines as provenance_lines
    from ..ensemble_dir import describe, is_ensemble_dir, load_ensemble

    if is_ensemble_dir(args.dir) and not (Path(args.dir) / "results.h5").exists():
        print("\n".join(describe(load_ensemble(args.dir), Path(args.dir))))
        return EXIT_OK
    remains = lost_index(args.dir)  # a run whose index is lost: what its segments hold
    if remains is not None:
        print("\n".join(remains))
        return EXIT_OK
    res = load(args.dir)
    kinds = res.kinds
    made = "built in Python" if res.spec is None else f"seed {res.spec.seed}" + (
        "" if res.spec.replica is None else f", replica {res.spec.replica}")
    lines = [
        f"results:     {res.path}",
        f"status:      {_status(res)}",
        f"geometry:    {kinds['geometry']}: {len(res.positions)} balls, {len(res.pairs)} contacts, "
        f"dim {res.velocities.shape[1]}",
        f"run:         {kinds.get('initial', 'given velocities')}, {kinds['rule']}, {kinds['scheduler']}, {made}",
        f"random:      {_stream(res)}",
        f"device:      {res.device}{' (simulated)' if res.simulated else ''}",
        f"steps:       {res.steps:,}",
        f"collisions:  {res.collisions:,}",
        f"energy:      {res.energy:.12g} (initially {res.initial_energy:.12g})",
        f"approaching: {_approaching(res)}",
        *_arithmetic(res),
        f"snapshots:   {len(res.snapshots)}" + (f" at steps {_few(res.snapshots.steps.tolist())}"
                                                if len(res.snapshots) else ""),
        *_margin(res),
        f"time:        {_duration(res.elapsed_seconds)} running the chain in {res.checkpoints} checkpoint(s) "
        f"(building, compiling and figures not counted); written by pinnedballs {res.version}",
        *provenance_lines(res.provenance),
    ]
    print("\n".join(lines))
    return EXIT_OK


def _progress(args) -> bool | None:
    """A command's bar: none with ``--quiet``; on a terminal at once, beside the status line (a Python
    call waits 2 s before showing one); elsewhere none (`pinnedballs.util.progress`)."""
    return False if args.quiet else (True if sys.stderr.isatty() else None)


def _margin(res) -> list[str]:
    """The closing margin of a run (`engine.margin`) in two lines, or why it has none."""
    m = res.closing_margin
    if m is None:
        arithmetic = res.spec.arithmetic if res.spec is not None else res.run.get("arithmetic", "float")
        if arithmetic == "certified":
            smallest = getattr(res, "smallest_exact_collision", None)
            said = "unknown (a file written before certified runs kept it)" if smallest is None else \
                f"{smallest:.3g} thresholds of the float criterion"
            return [f"margin:      every closing speed's sign proved exact; the smallest collision: {said}"]
        if arithmetic == "exact":
            return [f"margin:      none kept ({arithmetic} arithmetic: every closing speed's sign is exact)"]
        return ["margin:      unknown (this run began before runs kept their closing margin)"]
    from ...engine.margin import NEAR
    from ...rules import DEFAULT_RESOLUTION

    low = "no collision yet" if m.smallest_collision is None else \
        f"smallest collision {m.smallest_collision:.3g} thresholds"
    high = "no remnant set aside" if m.largest_remnant is None else \
        f"largest remnant {m.largest_remnant:.3g} thresholds"
    default = " (the default)" if m.resolution == DEFAULT_RESOLUTION else ""
    verdict = ": thin, so the count depends on the criterion" if m.thin else " (wide)"
    return [f"margin:      {low}, {high}; resolution {m.resolution:.3g}{default}",
            f"             {_counted(m.near_collisions, 'collision')} and {_counted(m.near_remnants, 'remnant')} "
            f"within a factor {NEAR:,.0f} of the threshold{verdict}"]


def _counted(n: int, noun: str) -> str:
    return f"{n:,} {noun}{'' if n == 1 else 's'}"


def _approaching(res) -> str:
    if res.approaching < 0:  # a failed run's state, whose live contacts certified arithmetic could not count
        return "unknown (certified arithmetic could not count the live contacts at these bits)"
    return f"{res.approaching:,} contacts ({'frozen' if res.frozen else 'not frozen'})"


def _stream(res) -> str:
    """The random stream a run's scheduler draws its picks from, in words."""
    scheduler = res.spec.scheduler.model_dump() if res.spec is not None else res.run.get("scheduler")
    scheduler = scheduler if isinstance(scheduler, dict) else {}
    if scheduler.get("stream") == "counter":
        return "counter (Philox4x64-10: the pick of step s a function of the seed and s alone)"
    fixed = scheduler.get("kind") == "sweep" or (scheduler.get("kind") == "colored_sweep"
                                                 and not scheduler.get("shuffle"))
    return "xoshiro256**" + (" (unused: this scheduler's order is fixed)" if fixed else "")


def _arithmetic(res) -> list[str]:
    """The arithmetic: its name and what it keeps; for a certified run, what it proves, its bits and its error
    bounds in words."""
    name = res.run.get("arithmetic") or (res.spec.arithmetic if res.spec is not None else "float")
    certified = res.latest.certified
    if certified is not None:
        G, largest = certified.error_bound()
        what = ("no rounding yet: the certified velocities are exact arithmetic's" if G == 0 else
                f"bounds how far all the certified velocities together (the length of the whole difference) are "
                f"from exact arithmetic's; {largest:.3g} bounds each ball's")
        return [f"arithmetic:  certified (every decision proved equal to exact arithmetic's: exact counts); "
                f"velocities within {largest:.3g} of exact arithmetic's (error bound G = {G:.3g}), "
                f"{64 * certified.limbs.shape[-1]} bits{_bits(res.spec, certified)}",
                f"             G = {G:.3g} (in the velocities' units) {what}" if G else f"             G = 0: {what}"]
    if name == "exact":
        return ["arithmetic:  exact (every velocity held exactly: exact counts)"]
    return [f"arithmetic:  {name}" + (" (64-bit floating point)" if name == "float" else "")]


def _bits(spec, certified) -> str:
    """The bits a certified run ran at through its first wave and behind it, where it narrowed or found them."""
    from ...engine.field.arithmetic import AUTO

    auto = spec is not None and spec.precision == AUTO and certified.precision
    if not (certified.late_precision or auto):
        return ""
    late = f", {certified.late_precision} behind the first wave" if certified.late_precision else ""
    return (f" ({certified.precision} through the first wave{late}"
            f"{', found by the run: precision auto' if auto else ''})")


def _status(res) -> str:
    """What a run is doing: done (and why), failed (where, why and what to do instead), interrupted, running
    (and who writes it), or stopped without a word (killed: no process holds its directory)."""
    if res.complete:
        return f"done ({res.stop_reason})"
    if res.failure is not None:
        from ...results.format import failed_run

        remedy = res.failure.get("remedy")
        return f"{failed_run(res.failure)}; it cannot go on" + (f": {remedy}" if isinstance(remedy, str) else "")
    if res.cannot_resume:
        return f"{res.status} at its last checkpoint; it cannot go on: {res.cannot_resume}"
    how = "--resume" if res.spec is not None else "pb.load(DIR).simulation()"
    if res.status == "interrupted":
        return f"interrupted (continue with {how})"
    from ...results.rundir import holder

    pid = holder(res.run_dir)
    if pid is not None:
        return f"running (pid {pid}; this is its last checkpoint)"
    return f"stopped (killed: no process is writing it; this is its last checkpoint: continue with {how})"


def _duration(seconds: float) -> str:
    """Wall time to three significant figures: ``"5.29 ms"``, ``"12.3 s"``, ``"2 min 05 s"``, ``"3 h 07 min"``."""
    milliseconds = float(f"{seconds * 1000:.3g}")
    if milliseconds < 1000:
        return f"{milliseconds:g} ms"
    if seconds < 60:
        return f"{seconds:.3g} s"
    minutes = int(seconds // 60)
    if minutes < 60:
        return f"{minutes} min {int(seconds % 60):02d} s"
    return f"{minutes // 60} h {minutes % 60:02d} min"


def _few(values: list[int]) -> str:
    shown = ", ".join(f"{v:,}" for v in values[:5])
    return shown + (f", ... ({len(values)} in all)" if len(values) > 5 else "")


def _plots_available() -> bool:
    import importlib.util

    return importlib.util.find_spec("pinnedballs.plot") is not None


@subcommand("ensemble", "run N independent replicas of a spec: replicas.csv, summary.json, correlation histograms",
            arg("spec", metavar="SPEC.json", help="the run spec (its seed seeds the replicas)"),
            arg("--replicas", type=int, required=True, metavar="N", help="number of replicas (>= 1)"),
            arg("--workers", type=int, metavar="K", help="local processes (default: all cores; 1 runs in-process)"),
            arg("--dask", metavar="ADDRESS", help="run on the Dask scheduler at ADDRESS (e.g. tcp://host:8786)"),
            arg("--out", required=True, metavar="DIR", help="output directory (created)"),
            arg("--force", action="store_true", help="write into a non-empty directory"),
            arg("--quiet", action="store_true", help="no progress bar, no summary line"), DEVICE, TRACEBACK)
def ensemble_command(args) -> int:
    """``pinnedballs ensemble``: exit 0, 1 if a replica failed (after writing the others), 2 on bad input."""
    from .status import Status

    began = time.perf_counter()  # the command's time, beside the replicas' own
    with Status(show=False if args.quiet else None) as status:
        status("reading the spec")
        return _ensemble(args, status, began)


def _ensemble(args, status, began: float) -> int:
    from ...results.rundir import DirLock, check_out_dir, made_for
    from ...specs.run import load_spec
    from ...util.errors import InputError
    from ..ensemble import (
        ERROR_COLUMN,
        SPEC_NAME,
        _check_replicas_memory,
        check_count,
        ensemble_plan,
        replica_seed,
        run_ensemble,
    )
    from ..ensemble_files import remove_old_outputs, write_outputs
    from ..executors import dask_client

    replicas = check_count("--replicas", args.replicas)
    _check_replicas_memory(replicas, "--replicas")
    if args.workers is not None:
        check_count("--workers", args.workers)
        if args.dask is not None:
            raise InputError("--workers, --dask: give one of them, not both")
    spec = load_spec(args.spec)
    seeded = args.spec if spec.seed is not None else str(Path(args.out) / SPEC_NAME)  # a spec that repeats it
    spec = spec.seeded()  # one seed for the whole ensemble, recorded in its spec.json
    out = check_out_dir(args.out, args.force)
    status("building the geometry")
    sim = spec.build(seed=replica_seed(spec, 0))  # a spec that cannot build fails here, before any output
    # where the replicas run (the stream, and a GPU): before the lock makes the directory
    if ensemble_plan(spec, sim, args.device, on_cluster=args.dask is not None) != "processes" \
            and args.workers is not None:
        raise InputError(f"--device {args.device} runs the replicas on a GPU (this machine's, or each Dask worker's "
                         f"with --dask): give no --workers")
    status.clear()
    client = None
    if args.dask is not None:
        client, _ = dask_client(args.dask, None, "--dask")
    # refused on the cluster (workers without a GPU), or stopped: the directories made for --out go again
    with made_for(out), DirLock(out, "--out"):  # one ensemble at a time writes into a directory
        try:
            result = run_ensemble(spec, replicas, workers=args.workers, cluster=client,
                                  progress=_progress(args), device=args.device)
        finally:
            if client is not None:
                client.close()
        status("writing the tables and histograms")
        if args.force and out.is_dir():
            remove_old_outputs(out)
        write_outputs(result, out)
        status.clear()
    for row in result.failures:  # its rows depend on the spec and its index only: it can be run alone
        print(f"pinnedballs: replica {row['replica']} (seed entropy {row['seed_entropy']}, spawn key "
              f"{row['spawn_key']}) failed: {row[ERROR_COLUMN]}; rerun it alone with pinnedballs.run.ensemble."
              f"run_replica(pinnedballs.specs.load_spec({seeded!r}), {row['replica']}), which gives the rows it "
              f"would have had", file=sys.stderr)
    if not args.quiet:
        print(f"{replicas - len(result.failures)} of {replicas} replicas done in {result.wall_seconds:.1f} s "
              f"({result.where}), {time.perf_counter() - began:.1f} s for the whole command; wrote {out}")
    return 1 if result.failures else 0


@subcommand("reproduce", "every figure of the paper as PNG, and report.md comparing its numbers with ours",
            arg("--out", required=True, metavar="DIR", help="output directory (created)"),
            arg("--quick", action="store_true",
                help="smaller sizes and fewer replicas (about 10 seconds on a quiet 2-core machine)"),
            arg("--extended", action="store_true",
                help="then the studies beyond the paper (about 25 minutes on 2 cores, 9 of them the exact "
                     "counts of 1000x500 and 6 the 2000x1000 half-plane; with --quick under a minute)"),
            arg("--workers", type=int, metavar="K", help="local processes for the ensembles (default: all cores)"),
            arg("--force", action="store_true", help="write into a non-empty directory"),
            arg("--quiet", action="store_true", help="no progress messages"),
            arg(*DEVICE[0], **{**DEVICE[1], "help": (
                "cpu, or cuda (an NVIDIA GPU, pip install \".[cuda]\"): the paper's figures keep their published "
                "seeds on the xoshiro stream and run on the CPU; --extended's scaling study runs on the counter stream "
                "(the same law, other picks) on the GPU, up to 4000x2000 without --quick (measured figures: "
                "docs/gpu.md), its exact counts (certified arithmetic) on the CPU")}))
def reproduce_command(args) -> int:
    """``pinnedballs reproduce``: exit 0, 1 if a replica failed (the report is still written), 2 on bad input."""
    from .status import Status

    with Status(show=False if args.quiet else None) as status:
        status("loading the reproduction")
        from ...engine import door
        from ...results.rundir import check_out_dir
        from .. import reproduction
        from ..ensemble import check_count

        if args.workers is not None:
            check_count("--workers", args.workers)
        check_out_dir(args.out, args.force)
        door.ready(args.device)  # a GPU: numba-cuda and one, before anything runs (with --extended or not)
    shown = status.shown  # the stages and bars on a terminal only
    stage: list[str] = []  # the stage running: a note names the run it is about, on a terminal or not

    def log(message: str) -> None:
        stage[:] = [message.partition("] ")[2] or message]  # "[  2.4 s] half-plane 200x100: single run"
        if shown:
            print(message, file=sys.stderr, flush=True)

    with _naming_notes(stage):
        report = reproduction.reproduce(args.out, quick=args.quick, force=args.force, workers=args.workers,
                                        progress=shown, log=log, extended=args.extended, device=args.device)
    results = json.loads((report.parent / "results.json").read_text(encoding="utf-8"))
    if not args.quiet:
        print(f"wrote {report} in {results['wall_seconds']:.1f} s")
    return 1 if results["failures"] else 0


@contextlib.contextmanager
def _naming_notes(stage: list[str]) -> Iterator[None]:
    """A thin-margin note (`engine.margin.MarginWarning`, which `main` says in one line) prefixed with the stage
    that ran when it came (``stage[0]``: "half-plane 200x100: single run"), so that it names its run."""
    import warnings

    from ...engine.margin import MarginWarning

    with warnings.catch_warnings():  # keeps the filters; puts the outer showwarning back after
        outer = warnings.showwarning

        def named(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, MarginWarning) and stage:
                message = category(f"{stage[0]}: {message}")
            outer(message, category, filename, lineno, file, line)

        warnings.showwarning = named
        yield
