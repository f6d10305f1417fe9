"""Carry out a run spec: the driver with a `ResultsWriter`, progress, signals, resuming, figures.

`execute` runs a spec into a run directory (``spec.json``, ``results.h5`` (see
`pinnedballs.results`), ``trajectory.gsd`` if the spec asks for one, and the figures
(``*.png``, `pinnedballs.plot`)) through the one driver (`driver.drive`) and the same
`ResultsWriter` and `GSDWriter` a Python run uses,
adding a progress bar, SIGINT/SIGTERM handling and resuming. `run_to_stop` runs a
spec's simulation to its stop with any writers (ensembles, the reproduction).
The final state equals that of the plain calls ``sim.run(steps=S)``,
``sim.run(collisions=C)`` (which also stops at a freeze) or ``sim.run_until_frozen(max_steps=M)``.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from ..engine.driver import Writer, drive
from ..engine.field.arithmetic import AUTO, auto_failure, until_proved
from ..engine.field.fixed import UncertifiedDecision
from ..engine.jit.failures import CompileFailure, compiling
from ..engine.stop import Stop
from ..results.format import DATA_DIR, RESULTS_NAME, Record, failed_run
from ..results.load import Results, load
from ..results.rundir import DirLock, check_resumable, first_missing, remove_made
from ..results.trajectory import TRAJECTORY_NAME
from ..simulation import Simulation
from ..specs.run import RunSpec, load_spec
from ..util.atomic import remove, tmp_path, write_text_atomic
from ..util.errors import InputError
from ..util.provenance import python_call
from .gsd_writer import GSDWriter
from .gsd_writer import layout as gsd_layout
from .writers import OnSnapshot, ResultsWriter

__all__ = ["Interrupted", "run_to_stop", "execute", "run_spec", "write_figures", "SILENT"]


class _Silent:
    """A status line that says nothing (the command line hands `execute` a real one)."""

    def __call__(self, message: str) -> None:
        pass

    def clear(self) -> None:
        pass


#: the default ``status`` of `execute`: a callable told each stage, with ``clear()``
SILENT = _Silent()


class Interrupted(RuntimeError):
    """The run was stopped by SIGINT/SIGTERM after writing a complete checkpoint (marked "interrupted",
    or "done" if the run had finished)."""


def run_to_stop(spec: RunSpec, sim: Simulation, *, on_snapshot: Callable[[Record], None] | None = None,
                writers: Sequence[Writer] = (), after_chunk: Callable[[Simulation], None] | None = None) -> str:
    """Run ``sim`` (built from ``spec``) to ``spec.stop`` with ``writers``, calling ``on_snapshot``
    at each of the spec's snapshots; returns the stop reason."""
    writers = list(writers)
    if on_snapshot is not None and spec.snapshots is not None:
        writers.append(OnSnapshot(spec.snapshots.build(), on_snapshot))
    reason = drive(sim, spec.stop.build(), writers, after_chunk=after_chunk)
    sim.warn_if_thin(reason)  # a run that froze: its count is the observable
    return reason


# ---------------------------------------------------------------- run directories


def execute(spec: RunSpec, out_dir: str | os.PathLike, *, force: bool = False, resume: bool = False,
            progress: bool | None = None, figures: bool = True, status=SILENT,
            log: Callable[[str], None] | None = None, device: str = "cpu") -> Path:
    """Run ``spec`` into the directory ``out_dir``; return the path of its ``results.h5``.

    The spec is built once into what runs it (the simulation, its stop, the writer's trigger), and what the run
    compiles first compiled (`_compile`), before anything is written: bad input fails first, a rule or a scheduler
    numba cannot compile included (a `UserCodeError` naming its factory). A spec without a seed gets one drawn
    (`RunSpec.seeded`), recorded with the run. A non-empty ``out_dir`` is refused (`InputError`) unless ``force``
    (which replaces our files) or ``resume``: that continues the run there from its last checkpoint (the same spec;
    a finished run is left as it is), or starts it where none is yet (a missing or empty ``out_dir``, or one a run
    killed before its first checkpoint left), telling ``log`` so in one line; anything else is refused
    (`check_resumable`), and so is a run that failed where it cannot go on (a decision certified arithmetic cannot
    make: the file says "failed", `ResultsWriter`), which continuing would only fail again. A new run that fails
    before its first step (a user's scheduler refused at its first pick) leaves nothing: what it wrote, and the
    directories made for it, are removed (a run ``force`` replaced is gone). ``progress``: the run driver's bar
    (True, False, or None: in a terminal or a notebook, once the run has taken 2 s; `pinnedballs.util.progress`).
    ``status``: a callable told each stage (building, compiling, drawing).

    SIGINT/SIGTERM (main thread) while the spec is built or a checkpoint read (a user's factory
    may run there) raise KeyboardInterrupt at once: nothing has been written. During the run they ask
    it to stop at the end of its chunk: the state is saved, marked "interrupted", and `Interrupted`
    raised. A second SIGINT raises KeyboardInterrupt at once, and the state the simulation is in is
    saved the same way. A request that comes as the run finishes leaves it done, without its
    figures (``pinnedballs plot`` draws them). ``device``: where the chain runs (``"cpu"`` or ``"cuda"``,
    `Simulation`), recorded as information in the results file; a run may resume on another device.

    A spec whose ``precision`` is ``"auto"``: where certified arithmetic cannot prove a decision, the run
    starts again from its first step with more bits (`engine.field.arithmetic.next_precisions`), replacing what
    the attempt wrote, and tells ``log`` so in one line; its results record the bits it ran at, which
    ``resume`` continues at. Where no more bits can help, the `UncertifiedDecision` is raised as without.
    """
    spec = spec if resume else spec.seeded()  # every attempt of a fresh run on the same seed
    how = dict(progress=progress, figures=figures, status=status, log=log, device=device)
    if spec.precision != AUTO:
        return _execute(spec, out_dir, None, force=force, resume=resume, **how)

    def attempt(bits: tuple[int, int | None] | None) -> Path:
        """The first attempt as asked (a resumed run at the bits its file records: `Results.simulation`), a
        later one afresh at ``bits``, replacing what the one before wrote."""
        nonlocal spec, force, resume
        if bits is not None:
            spec, force, resume = _recorded(Path(out_dir), spec), True, False
        return _execute(spec, out_dir, bits, force=force, resume=resume, **how)

    def told(failure: UncertifiedDecision, bits: tuple[int, int | None]) -> None:
        status.clear()
        if log is not None:
            log(f"precision auto: {auto_failure(failure, bits)}")

    return until_proved(attempt, spec.late_precision, told)


def _recorded(out: Path, spec: RunSpec) -> RunSpec:
    """The spec the run in ``out`` recorded (``spec.json``: seeded), or ``spec`` if it left none."""
    try:
        return load_spec(out / "spec.json")
    except (OSError, ValueError):
        return spec


def _execute(spec: RunSpec, out_dir: str | os.PathLike, attempt: tuple[int, int | None] | None, *, force: bool,
             resume: bool, progress: bool | None, figures: bool, status, log: Callable[[str], None] | None,
             device: str) -> Path:
    """`execute` once: a fresh run built at ``attempt``'s ``(precision, late_precision)`` (None: the spec's)."""
    out = Path(out_dir)
    path = out / RESULTS_NAME
    starting = check_resumable(out) if resume else None  # None: a run to continue (or no --resume)
    fresh = not resume or starting is not None
    stop = spec.stop.build()
    snapshots = spec.snapshots.build() if spec.snapshots else None
    with _refusable(out) as refused, _deferred_signals() as signals:
        sim = None
        if fresh:
            spec = spec.seeded()  # a spec without a seed: one drawn now, recorded with the run
            status("building the geometry")
            with signals.at_once():
                sim = (spec if attempt is None else spec.at_precisions(*attempt)).build(device=device)
            if spec.trajectory is not None:
                gsd_layout(sim)  # a trajectory GSD's 32-bit floats cannot hold is refused before anything is written
            _compile(spec, sim, stop, status)  # a rule numba cannot compile is refused before anything is written
            if starting is not None and log is not None:
                status.clear()
                log(f"--resume: {out} holds no run yet ({starting}): starting it")
        with DirLock(out, "--out") as lock:  # held to the end: one run at a time in a directory
            writer = ResultsWriter(out, snapshots=snapshots, checkpoint_seconds=spec.checkpoint.every_seconds,
                                   spec=spec, force=force, resume=resume, lock=lock)
            try:
                if fresh:
                    writer.attach(sim)      # takes the directory and writes the static data
                    _remove_figures(out)    # a replaced run's pictures would pass for this one's
                    remove(out / TRAJECTORY_NAME)
                    write_text_atomic(out / "spec.json", spec.to_json() + "\n")
                else:
                    status("reading the last checkpoint")
                    with signals.at_once():
                        sim = _resumed(spec, path, device)
                if sim is not None:         # None: that run had finished
                    if not fresh:
                        _compile(spec, sim, stop, status)
                    _drive(sim, stop, [*_trajectory(spec, out, fresh), writer], progress, status,
                           signals.requested)
            except BaseException as exc:
                writer.abort(sim, None)  # once attached, before the loop (the loop's own abort makes it a no-op)
                if fresh and writer.store is not None and sim.steps == 0 and not signals.requested() \
                        and _an_error(exc):  # e.g. a user's scheduler refused at its first pick: no output
                    _withdraw(out)
                    refused.append(exc)
                raise
        stopping = signals.requested()
    if figures and stopping:
        raise Interrupted(f"the run in {out} is done; interrupted before its figures: draw them with "
                          f"pinnedballs plot {out}")
    if figures:
        status("drawing figures")
        write_figures(out)
    status.clear()
    return path


@contextlib.contextmanager
def _refusable(out: Path) -> Iterator[list]:
    """A run into ``out`` that may be refused before its first step: once it says so (appending to the
    list yielded) and raises, the directories made for it (``out``, and parents it made) are removed
    again, where they hold nothing else."""
    made = first_missing(out)
    refused: list = []
    try:
        yield refused
    except BaseException:
        if refused:
            remove_made(out, made)  # one that holds something else stays
        raise


def _an_error(exc: BaseException) -> bool:
    """Whether ``exc`` is an error, not an interrupt (nor an exception that an interrupt turned into another)."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, (KeyboardInterrupt, Interrupted)) or not isinstance(exc, Exception):
            return False
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return True


def _withdraw(out: Path) -> None:
    """Remove what a fresh run wrote in ``out`` (its results, their data, its spec and trajectory); the
    user's own files stay."""
    for name in (RESULTS_NAME, "spec.json", TRAJECTORY_NAME):
        remove(out / name)
        remove(tmp_path(out / name))
    data = out / DATA_DIR
    for p in [*data.glob("static.h5*"), *data.glob("frames_*.h5*")]:
        remove(p)
    with contextlib.suppress(OSError):
        data.rmdir()


def run_spec(spec: RunSpec | str | os.PathLike, out: str | os.PathLike, *, resume: bool = False, force: bool = False,
             progress: bool | None = None, figures: bool = True, device: str = "cpu") -> Results:
    """Run a spec into a directory, as ``pinnedballs run SPEC --out DIR`` does, and return its `Results`.

    The same driver and files as the command line (`execute`): ``spec.json``, ``results.h5`` and
    ``results.data/``, ``trajectory.gsd`` where the spec asks for one, the figures.

    Parameters
    ----------
    spec : RunSpec or str or os.PathLike
        A spec, or the path of its JSON file.
    out : str or os.PathLike
        The run directory.
    resume : bool
        Continue the run in ``out`` from its last checkpoint (or start it where none is yet).
    force : bool
        Replace a run there.
    progress : bool or None
        A bar on stderr (None: only when stderr is a terminal).
    figures : bool
        Draw the figures beside the results.
    device : Device or {"cpu", "cuda"}
        Where the chain runs (`Simulation`).

    Returns
    -------
    Results

    Raises
    ------
    SpecError
        For a bad spec file, with the command line's one line (a ValueError), e.g. ``geometry.lenght: unknown
        key; did you mean 'length'?``.
    InputError
        On ``out`` that holds something, without ``force`` or ``resume``; on ``force`` with ``resume``.

    Examples
    --------
    >>> import json
    >>> import pinnedballs as pb
    >>> run = {"geometry": {"kind": "half_plane", "rows": 4, "cols": 6}, "seed": 1,
    ...        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 0.5},
    ...        "stop": {"frozen": True, "max_steps": 100000}, "snapshots": {"every_collisions": 25}}
    >>> with open("run.json", "w") as f:
    ...     json.dump(run, f)
    >>> pb.run_spec("run.json", "out", figures=False)
    Results('out/results.h5', done, steps=556, collisions=50, snapshots=2, frozen=True)
    >>> pb.run_spec("run.json", "out", resume=True, figures=False).steps  # done: left as it is
    556
    """
    if not isinstance(spec, RunSpec):
        if not isinstance(spec, (str, os.PathLike)):
            raise InputError(f"spec: must be a RunSpec or the path of a spec file, got {type(spec).__name__}")
        spec = load_spec(spec)
    if force and resume:
        raise InputError("force, resume: give one of them, not both")
    with python_call("pinnedballs.run_spec"):  # what its results' provenance records (`run.lineage`)
        path = execute(spec, out, force=force, resume=resume, progress=progress, figures=figures, device=device)
    return load(path)


def _resumed(spec: RunSpec, path: Path, device: str = "cpu") -> Simulation | None:
    """The simulation at the last checkpoint in ``path`` of the same ``spec``, or None if that run is complete;
    an `InputError` saying why and what to do if that run failed where it cannot go on."""
    res = load(path)
    if res.failure is not None:
        raise InputError(f"--resume: the run in {res.run_dir} {failed_run(res.failure)}; continuing it would fail "
                         f"the same way: {res.failure.get('remedy') or 'run it again with --force'}")
    _check_same_run(res, spec)
    if not (path.parent / "spec.json").exists():
        write_text_atomic(path.parent / "spec.json", res.spec.to_json() + "\n")
    return None if res.complete else res.simulation(device=device)


def _trajectory(spec: RunSpec, out: Path, fresh: bool) -> list[GSDWriter]:
    """The writer of ``out/trajectory.gsd`` if ``spec`` asks for one: a new file for a ``fresh`` run,
    else appended to (a resumed run skips the frames it holds)."""
    if spec.trajectory is None:
        return []
    return [GSDWriter(out / TRAJECTORY_NAME, spec.trajectory.build(), spec.observables, force=fresh, resume=not fresh)]


def _drive(sim: Simulation, stop: Stop, writers: list[Writer], progress: bool | None, status,
           stop_requested: Callable[[], bool]) -> None:
    """``sim`` to ``stop`` recording into ``writers`` (the `ResultsWriter` last, so every other writer
    has recorded a state before it is checkpointed), with the driver's progress; a stop requested by a
    signal raises `Interrupted` between chunks (the driver has the writers save the state first)."""
    writer = writers[-1]

    def after_chunk(s: Simulation) -> None:
        if stop_requested():
            raise Interrupted(f"interrupted at step {s.steps:,}; the checkpoint in {writer.out_dir} is complete: "
                              f"continue with --resume")

    try:
        sim.warn_if_thin(drive(sim, stop, writers, after_chunk=after_chunk, progress=progress))
    finally:
        for other in writers[:-1]:
            other.close()


def _compile(spec: RunSpec, sim: Simulation, stop: Stop, status) -> None:
    """Compile what ``sim``'s run to ``stop`` runs first (the loop, and the count of live contacts its results
    record), changing no bit of its state: a rule or a scheduler numba cannot compile is refused in the spec's
    words (`RunSpec.not_compiled`: a user's names its factory), numba's error its cause."""
    status("compiling the loop (once: numba caches it on disk)")
    try:
        sim.run(steps=0, until_frozen=stop.until_frozen, progress=False)  # the driver's compiling call
        with compiling(sim.engine.model):
            sim.approaching()
    except CompileFailure as exc:
        raise spec.not_compiled(exc) from exc.__cause__
    status.clear()


def _check_same_run(res: Results, spec: RunSpec) -> None:
    """Refuse to resume ``res`` with a different spec (checkpoint settings and description may differ)."""
    if res.spec is None:
        raise InputError(f"--resume: the run in {res.path.parent} was built in Python, not from a spec; "
                         f"continue it in Python (pb.load(...).simulation())")
    ignore = {"checkpoint", "description"} | ({"seed"} if spec.seed is None else set())  # None: the run's own
    old, new = res.spec.model_dump(exclude=ignore), spec.model_dump(exclude=ignore)
    where = _first_difference(old, new)
    if where is not None:
        path, a, b = where
        raise InputError(f"{path}: differs from the run in {res.path.parent} ({a!r} there, {b!r} here); "
                         f"run without --resume, and with --force to overwrite it")


def _first_difference(a, b, path: str = "") -> tuple[str, object, object] | None:
    if isinstance(a, dict) and isinstance(b, dict):
        for key in list(a) + [k for k in b if k not in a]:
            found = _first_difference(a.get(key), b.get(key), f"{path}.{key}" if path else key)
            if found:
                return found
        return None
    return None if a == b else (path, a, b)


class _Signals:
    """SIGINT and SIGTERM as `_deferred_signals` handles them: `requested` says whether a stop was asked
    for; within `at_once` they raise KeyboardInterrupt at once instead (the code there writes nothing)."""

    def __init__(self):
        self.signals: list[int] = []
        self.immediate = False

    def requested(self) -> bool:
        return bool(self.signals)

    @contextlib.contextmanager
    def at_once(self) -> Iterator[None]:
        self.immediate = True
        try:
            yield
        finally:
            self.immediate = False

    def handler(self, signum, frame) -> None:
        if self.immediate or (self.signals and signum == signal.SIGINT):
            raise KeyboardInterrupt
        self.signals.append(signum)


@contextlib.contextmanager
def _deferred_signals() -> Iterator[_Signals]:
    """Turn SIGINT/SIGTERM into a request the loop honours between chunks (main thread only).

    A second SIGINT interrupts at once, as does either within `_Signals.at_once`.
    """
    signals = _Signals()
    if threading.current_thread() is not threading.main_thread():
        yield signals
        return
    old = {s: signal.signal(s, signals.handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield signals
    finally:
        for s, h in old.items():
            signal.signal(s, h)


# ---------------------------------------------------------------- figures


def write_figures(run_dir: str | os.PathLike, every_snapshot: bool = False) -> list[Path]:
    """Draw the figures of the run in ``run_dir`` (PNG files beside its results), first removing
    any figures an earlier run left there; the paths written. ``every_snapshot``: also a picture
    of each snapshot (else the first and last states and a contact sheet of the snapshots)."""
    from ..plot.run import write_figures as draw

    res = load(run_dir)
    _remove_figures(Path(run_dir))
    return list(draw(res, Path(run_dir), every_snapshot=every_snapshot))


def _remove_figures(run_dir: Path) -> None:
    from ..plot.names import figure_files  # names only: a run without figures never imports matplotlib

    for old in figure_files(run_dir):
        old.unlink()
