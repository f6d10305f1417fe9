"""`ResultsWriter`: record a run into a results directory, from Python or the command line.

::

    w = pb.ResultsWriter("DIR", snapshots={"every_steps": 100_000}, checkpoint_seconds=60)
    sim.run(steps=10**7, writers=[w])

writes the directory ``pinnedballs run`` writes (``results.h5``, see `pinnedballs.results.format`):
the spec (or, for a run built in Python, a description of its components), the geometry,
the snapshots with their observables, and the latest state, checkpointed every
``checkpoint_seconds`` and after snapshots. ``pinnedballs info`` and ``plot`` and `pb.load`
read it; ``pb.load("DIR").simulation()`` continues the run bit for bit, and
``ResultsWriter("DIR", resume=True, ...)`` goes on recording into the same directory.

A run stopped by Ctrl-C (KeyboardInterrupt) or by any other exception is saved as it stopped:
the writer checkpoints the state the simulation is in, with every snapshot due at it, marks
the results "interrupted", releases the directory and lets the exception go on. A Ctrl-C
during a checkpoint is held until the checkpoint is written (`held_signals`). A run stopped by a
decision certified arithmetic cannot make (`UncertifiedDecision`), or by an engine that failed
(`pinnedballs.util.errors.InternalError`: its loop stopped short of its chunk), cannot go on: it is saved
the same way at the last state the chain passed through, marked "failed", with the failure's words, step
(and bits) and what to do instead (`failure`); its own error goes on, never one of saving it, and
continuing it is refused.
"""

from __future__ import annotations

import json
import os
import sys
import time
import weakref
from pathlib import Path

import numpy as np

from .._version import __version__
from ..analysis import observables as named
from ..engine import door
from ..engine.devices import as_device
from ..engine.driver import Writer
from ..engine.field.arithmetic import AUTO, next_precisions
from ..engine.field.fixed import UncertifiedDecision
from ..engine.triggers import Counts, Trigger
from ..results.files import held_signals
from ..results.format import RESULTS_NAME, Record, failed_run
from ..results.index import UNKNOWN
from ..results.rundir import BIRTH, DirLock, check_resumable, take_run_dir
from ..results.store import ResultsStore
from ..rules import DEFAULT_RESOLUTION
from ..util import checks
from ..util.errors import InputError, InternalError
from . import lineage

__all__ = ["ResultsWriter", "OnSnapshot", "describe_run", "failure", "simulated"]

#: the Python call a run recorded by a writer is, where no command line or other call is recorded (`lineage`)
CALL = "pinnedballs.ResultsWriter"
#: a snapshot's checkpoint is skipped (kept for the next one) if the last write was
#: more recent than this many times its own duration: checkpoints stay under ~10 % of the time
WRITE_COST_RATIO = 10.0


def _trigger(snapshots) -> Trigger | None:
    """A `Trigger` from a trigger, None, or a dict of `SnapshotsSpec` fields."""
    if snapshots is None or isinstance(snapshots, Trigger):
        return snapshots
    if isinstance(snapshots, dict):
        from pydantic import ValidationError

        from ..specs.errors import SpecError, first_error
        from ..specs.stop import SnapshotsSpec

        try:
            return SnapshotsSpec.model_validate(snapshots).build()
        except ValidationError as exc:
            error = first_error(exc, SnapshotsSpec)
            raise SpecError(f"snapshots.{error.path}" if error.path else "snapshots", error.problem) from None
    raise TypeError(f"snapshots: must be a Trigger, a dict such as {{'every_steps': 1000}}, or None, "
                    f"got {type(snapshots).__name__}")


class ResultsWriter(Writer):
    """Record a run into the directory ``out_dir`` (see the module's docstring).

    The writer holds an exclusive lock on ``out_dir`` (`pinnedballs.results.rundir.DirLock`) from the
    start of a run to its stop (or `close`).

    Parameters
    ----------
    out_dir : str or os.PathLike
        The run directory.
    snapshots : Trigger or dict or None
        A `Trigger`, a dict like a spec's ``"snapshots"`` (``{"at_steps": [...]}``, ``{"every_collisions":
        100}``, ...), or None for no snapshots.
    checkpoint_seconds : float
        Wall time between checkpoints (0: after every chunk).
    observables : list of str, optional
        Names from `pinnedballs.analysis.observables.OBSERVABLES` recorded with each snapshot (default: all
        built-ins; a spec's, with ``spec``).
    force : bool
        Replace a run already in ``out_dir``.
    resume : bool
        Append to it (the simulation must be at its latest state, as ``pb.load(out_dir).simulation()`` gives it).
    spec : RunSpec, optional
        The spec the run was built from, recorded with it (``pinnedballs run`` gives it).
    lock : optional
        A lock on ``out_dir`` the caller holds instead.

    Raises
    ------
    ValueError
        On ``force`` with ``resume``, ``checkpoint_seconds`` below 0 (a `FieldError`), a ``snapshots`` dict that
        is no spec's (a `SpecError`) or an unknown observable; a TypeError for ``snapshots`` of another type.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, seed=1)
    >>> sim.run(steps=200, writers=[pb.ResultsWriter("run", snapshots={"every_steps": 100})])
    200
    >>> more = pb.load("run").simulation()
    >>> more.run_until_frozen(100_000, writers=[pb.ResultsWriter("run", {"every_steps": 100}, resume=True)])
    True
    >>> res = pb.load("run")
    >>> res.complete, res.steps, [s.steps for s in res.snapshots][:3]
    (True, 556, [100, 200, 300])
    """

    def __init__(self, out_dir: str | os.PathLike, snapshots=None, checkpoint_seconds: float = 60.0,
                 observables=None, *, force: bool = False, resume: bool = False, spec=None, lock=None):
        checks.number("checkpoint_seconds", checkpoint_seconds, 0.0)
        if force and resume:
            raise ValueError("force, resume: give one of them, not both")
        self.out_dir = Path(out_dir)
        self.trigger = _trigger(snapshots)
        self.every = float(checkpoint_seconds)
        if observables is None:
            observables = spec.observables if spec is not None else named.DEFAULT
        self.names = named.check_names(observables)
        self.force, self.resume, self.spec = force, resume, spec
        self.store: ResultsStore | None = None
        self._running = False  #: between attach and finish or abort
        self._lock, self._own_lock = lock, lock is None
        self.pending: list[Record] = []
        self._checked: Counts | None = None
        self._saved: Counts | None = None  #: the counts of the state last checkpointed
        self._elapsed0, self._start, self._last, self._cost = 0.0, time.monotonic(), time.monotonic(), 0.0
        self._sim = lambda: None  # the simulation attached (a weak reference), whose resources a checkpoint records

    @property
    def path(self) -> Path:
        return self.out_dir / RESULTS_NAME

    def to_spec(self) -> dict:
        """What this writer records, in a run spec's words.

        Returns
        -------
        dict
            ``snapshots`` (None if its trigger has no spec), ``checkpoint`` and ``observables``.
        """
        return {"snapshots": None if self.trigger is None else self.trigger.to_spec(),
                "checkpoint": {"every_seconds": self.every}, "observables": list(self.names[2:])}

    # ------------------------------------------------------------ the driver's calls
    def attach(self, sim) -> Counts | None:
        """Take the directory and open the results (`Writer.attach`): a new run's, or the one to resume.

        Parameters
        ----------
        sim : Simulation
            The simulation run.

        Returns
        -------
        tuple of int or None
            The counts at which the trigger was already checked, else None.

        Raises
        ------
        InputError
            On ``out_dir``: not empty without ``force`` or ``resume``, held by another run, or nothing to resume.
        """
        if self.resume and self.store is None and self._own_lock:  # else the caller checked
            check_resumable(self.out_dir, "out_dir", start=False,
                            hint="check the path, or pass resume=False to start one")
        with held_signals():  # a Ctrl-C lands once the store is open and the run is ours to save
            if self._own_lock and self._lock is None:
                self._lock = DirLock(self.out_dir, "--out" if self.spec is not None else "out_dir").acquire()
            if self.store is None:
                try:
                    self.store = self._open(sim)
                except BaseException:
                    self.close()
                    raise
            elif (sim.steps, sim.collisions) != self._checked:
                self._checked = None  # the simulation moved on without us: check its state afresh
            self._sim = weakref.ref(sim)  # what it runs on, for this life's provenance at each checkpoint
            self._start = self._last = time.monotonic()
            self._running = True
        return self._checked

    def write(self, sim) -> None:
        """Keep a snapshot, written at the next checkpoint (`Writer.write`).

        Parameters
        ----------
        sim : Simulation
            The simulation, at the snapshot's count.
        """
        record = Record.of(sim, self.names)
        self.pending.append(record)
        if time.monotonic() - self._last >= min(self.every, WRITE_COST_RATIO * self._cost):
            self._checkpoint(record)

    def after_chunk(self, sim) -> None:
        """Checkpoint when ``checkpoint_seconds`` have passed (`Writer.after_chunk`).

        Parameters
        ----------
        sim : Simulation
            The simulation, between two chunks.
        """
        if time.monotonic() - self._last >= self.every and self._saved != (sim.steps, sim.collisions):
            self.checkpoint(sim)

    def finish(self, sim, reason: str) -> None:
        """Write the final state, marked "done", and release the directory (`Writer.finish`).

        Parameters
        ----------
        sim : Simulation
            The simulation, at its stop.
        reason : str
            Why it stopped (`Stop.reason`).
        """
        self._checked = (sim.steps, sim.collisions)
        self._checkpoint(Record.of(sim, self.names), status="done", reason=reason)
        self._stopped()

    def abort(self, sim, checked: Counts | None) -> None:
        """Checkpoint the state ``sim`` stopped in, marked "interrupted", with the snapshot due at it
        if the driver had not recorded it yet; release the directory (see the module's docstring).

        The exception being handled is the one that stopped the run: an `UncertifiedDecision`, or an engine that
        failed (`InternalError`), marks the state "failed" (`failure`).

        Parameters
        ----------
        sim : Simulation
            The simulation, as the exception left it.
        checked : tuple of int or None
            The counts at which the driver last finished checking the trigger (None: never).
        """
        if not self._running:
            self.close()
            return
        stopping = sys.exc_info()[1]
        failed = stopping if isinstance(stopping, (UncertifiedDecision, InternalError)) else None
        broken = getattr(getattr(getattr(sim, "engine", None), "state", None), "broken", "")
        try:
            with held_signals():
                if broken:  # stopped between two states (a user's pick out of range): the last sound one, failed
                    state, was_checked = self._last_sound()
                    said = " ".join(str(stopping).split()) or broken
                    self._checkpoint(state, status="failed", checked=was_checked, failure={
                        "error": type(stopping).__name__, "message": said, "decision": said, "steps": int(sim.steps),
                        "remedy": "mend what failed, then run it again (--force)" if self.spec is not None else
                        "mend what failed, then run it again"})
                else:
                    state, was_checked = self._stopped_state(sim, checked, failed is not None)
                    self._checkpoint(state, status="interrupted" if failed is None else "failed", checked=was_checked,
                                     failure=None if failed is None else failure(failed, sim.steps, self.spec))
                self._checked = (state.state.steps, state.state.collisions) if was_checked else None
        finally:
            self._stopped()

    def _last_sound(self) -> tuple[Record, bool]:
        """The last state recorded whole (a snapshot pending, else the last checkpoint) and whether its trigger
        was checked."""
        return (self.pending[-1], True) if self.pending else (self.store.state, bool(self.store.attrs["checked"]))

    def _stopped_state(self, sim, checked: Counts | None, failed: bool = False) -> tuple[Record, bool]:
        """The state to save when the run stopped, and whether the trigger was checked at its counts:
        ``sim``'s own, once any snapshot due at it is recorded; if that snapshot cannot be taken (the
        error that stopped the run?) or its live contacts cannot be counted, the last state whose snapshots
        all are; but a run that ``failed`` (`abort`), which never goes on, keeps ``sim``'s own (the trigger
        unchecked where its snapshot could not be taken; ``approaching`` `UNKNOWN` where certified
        arithmetic cannot count the live contacts)."""
        now = (sim.steps, sim.collisions)
        last = self.pending[-1].state.steps if self.pending else self.store.last_step
        before = self._last_sound()
        was_checked = True
        if self.trigger is not None and checked != now and last != now[0] and self.trigger.fires(checked, now):
            try:
                self.pending.append(Record.of(sim, self.names))
            except Exception:  # noqa: BLE001 - saving what is sound comes first
                if not failed:
                    return before
                was_checked = False
        try:
            return Record.of(sim, ()), was_checked
        except UncertifiedDecision:  # its live contacts cannot be counted at these bits
            if not failed:
                return before
            momentum = np.asarray(sim.momentum(), dtype=np.float64)
            return Record(sim.get_state(), sim.energy(), momentum, UNKNOWN), was_checked

    def _stopped(self) -> None:
        self._running = False
        self._elapsed0 = self.elapsed()
        self.close()

    def close(self) -> None:
        """Release the lock on ``out_dir`` if this writer took it (the next run takes it again)."""
        if self._own_lock and self._lock is not None:
            self._lock.release()
            self._lock = None

    # ------------------------------------------------------------ checkpoints
    def elapsed(self) -> float:
        """The wall time spent in runs recorded here, over every session.

        Returns
        -------
        float
            Seconds.
        """
        return self._elapsed0 + time.monotonic() - self._start

    def checkpoint(self, sim) -> None:
        """Write the pending snapshots and ``sim``'s state now.

        Parameters
        ----------
        sim : Simulation
            The simulation recorded.
        """
        self._checked = (sim.steps, sim.collisions)
        self._checkpoint(Record.of(sim, self.names))

    def _checkpoint(self, state: Record, status: str = "running", reason: str = "", checked: bool = True,
                    failure: dict | None = None) -> None:
        t = time.monotonic()
        with held_signals():  # a Ctrl-C lands after the checkpoint, never inside it
            life = None if self.store.life is None else \
                lineage.checkpointed(self.store.life, self._sim(), state.state.steps)
            self.store.checkpoint([r for r in self.pending if r.state.steps <= state.state.steps], state,
                                  status=status, stop_reason=reason, elapsed_seconds=self.elapsed(), checked=checked,
                                  failure=failure, life=life)
            self.pending = [r for r in self.pending if r.state.steps > state.state.steps]
            self._saved = (state.state.steps, state.state.collisions)
            self._running = status == "running"  # a run saved as done, interrupted or failed is never saved again
        self._last = time.monotonic()
        self._cost = self._last - t

    def _open(self, sim) -> ResultsStore:
        if self.resume and self.path.exists():
            store = ResultsStore.reopen(self.path)
            if store.attrs["status"] == "failed":
                said = json.loads(store.attrs["failure"])
                raise InputError(f"resume: the run in {self.out_dir} {failed_run(said)}; continuing it would fail "
                                 f"the same way: {said.get('remedy') or 'run it again'}")
            _check_continues(store, sim, self.path)
            device = as_device(getattr(sim, "device", None))
            store.attrs["device"], store.attrs["simulated"] = device.kind, simulated(device)
            self._elapsed0 = float(store.attrs["elapsed_seconds"])
            stored = tuple(json.loads(store.attrs["observables"]))
            if stored != self.names:
                raise ValueError(f"observables: {list(self.names)} differ from the {list(stored)} recorded in "
                                 f"{self.path}")
            self._checked = (sim.steps, sim.collisions) if store.attrs.get("checked") else None
            store.life = lineage.life(sim, CALL)  # a new life, after those the file holds
            return store
        # what a run killed at birth leaves may be resumed over
        cli = self.spec is not None
        take_run_dir(self.out_dir, force=self.force, may_hold=BIRTH if self.resume else frozenset(),
                     option="--out" if cli else "out_dir",
                     hint="use --force to overwrite or --resume to continue" if cli else
                     "pass force=True to overwrite or resume=True to continue")
        initial = Record.of(sim, self.names)
        spec = self.spec.model_dump_json() if self.spec is not None else ""
        run = "" if self.spec is not None else json.dumps(describe_run(sim, self))
        device = as_device(getattr(sim, "device", None))
        return ResultsStore.create(self.path, spec=spec, run=run, geometry=sim.geometry, masses=sim.masses,
                                   initial=initial, version=__version__, criterion=(sim.threshold, sim.resolution),
                                   device=device.kind, simulated=simulated(device), life=lineage.life(sim, CALL))


simulated = door.simulated  # whether a run on a device runs under numba-cuda's simulator


def failure(exc: UncertifiedDecision | InternalError, steps: int, spec=None) -> dict:
    """What a results file keeps of a run that failed on ``exc`` at step ``steps`` (`results.format`): the
    error's words, the step, the bits, and what to do instead (``spec``: the run's `RunSpec`, None for a run
    built in Python, which is told in Python's words); of an engine that failed (`InternalError`), its words,
    the step, and to run it again."""
    if isinstance(exc, InternalError):
        said = " ".join(str(exc).split())
        again = "run it again (--force)" if spec is not None else "run it again"
        return {"error": type(exc).__name__, "message": said, "decision": said, "steps": int(steps),
                "remedy": f"{again}; one that fails the same way is a fault of pinnedballs, to report"}
    return {"error": type(exc).__name__, "message": " ".join(str(exc).split()),
            "decision": " ".join((exc.decision or str(exc)).split()), "steps": int(steps),
            "precision": int(exc.precision), "late_precision": int(exc.late_precision), "narrowed": bool(exc.narrowed),
            "remedy": _remedy(exc, spec)}


def _remedy(exc: UncertifiedDecision, spec) -> str:
    """What to do instead of continuing a run that failed on ``exc`` (``spec``: its `RunSpec`, None for a run built
    in Python): more bits where they can help (through the first wave, or behind it where the state had narrowed),
    else exact arithmetic."""
    cli = spec is not None
    exact = '"arithmetic": "exact"' if cli else 'arithmetic="exact"'
    again = "run it again (--force)" if cli else "run it again"
    late = int(exc.late_precision)
    if next_precisions(exc, late or None) is None:
        return f"{again} with {exact}: no more bits can help"
    if cli and spec.precision == AUTO:  # stopped before it could start again with more bits
        return f'{again}: "precision": "auto" starts again with more bits'
    if exc.narrowed and late:
        more = f'a "late_precision" above {late} bits' if cli else f"late_precision above {late} bits"
    else:
        more = f"more than {int(exc.precision)} bits" if cli else f"precision above {int(exc.precision)} bits"
    if cli:
        return f'{again} with "precision": "auto" (the run finds its bits) or {more}, or with {exact}'
    return f"{again} with {more}, or with {exact}"


class OnSnapshot(Writer):
    """Hands a `Record` of each snapshot ``trigger`` fires on to ``on_snapshot`` (ensembles, the
    reproduction: snapshots kept in memory)."""

    def __init__(self, trigger: Trigger, on_snapshot, names=named.DEFAULT):
        self.trigger, self.on_snapshot, self.names = trigger, on_snapshot, tuple(names)

    def write(self, sim) -> None:
        self.on_snapshot(Record.of(sim, self.names))


def _check_continues(store: ResultsStore, sim, path: Path) -> None:
    """A ValueError unless ``sim`` is at the state stored in ``path`` (counters and velocities)."""
    import h5py

    with h5py.File(path, "r") as f:
        steps, collisions = int(f["state"].attrs["steps"]), int(f["state"].attrs["collisions"])
        same = (sim.steps, sim.collisions) == (steps, collisions) and \
            np.array_equal(f["state/velocities"][()], sim.velocities)
    if not same:
        raise ValueError(f"resume: the simulation is at step {sim.steps:,}, not at the state stored in {path} "
                         f"(step {steps:,}); continue from pb.load(...).simulation()")


def describe_run(sim, writer: Writer | None = None) -> dict:
    """What a run built in Python was made of: its geometry, rule and scheduler as their own specs
    (`to_spec`), or ``{"class": "module.Name", "repr": ...}`` for one that has none; whether it has
    masses; its arithmetic and resolution (None: the default); and the ``writer``'s own spec."""
    out = {name: _described(getattr(sim, name)) for name in ("geometry", "rule", "scheduler")}
    out["masses"] = sim.masses is not None
    out["arithmetic"] = sim.arithmetic
    out["resolution"] = None if sim.resolution == DEFAULT_RESOLUTION else sim.resolution
    if writer is not None:
        out["writer"] = writer.to_spec()
    return out


def _described(component) -> dict:
    spec = component.to_spec()
    if spec is not None:
        return spec
    return {"class": f"{type(component).__module__}.{type(component).__qualname__}", "repr": repr(component)}
