"""Ensembles: many independent replicas of one run spec, on local processes or a Dask cluster.

Replica ``k`` of ``N`` is seeded with child ``k`` of ``SeedSequence(spec.seed).spawn(N)``
(entropy ``spec.seed``, spawn key ``(k,)``; `replica_seed`), so its result depends
on the spec and ``k`` only: not on ``N``, the number of workers, or where it ran.
A spec without a seed gets one drawn for the whole ensemble (`RunSpec.seeded`), which
``summary.json`` and ``spec.json`` record.
Each replica runs the spec's stop rule (`execute.run_to_stop`) and gives one table
row per snapshot and one for the final state (`state_row`: `observables.summary`
and a few more), with the closing margin so far (`MARGIN_COLUMNS`, `engine.margin`).
Rows are ordered by replica, then by time, so the same spec and ``N`` give a
bit-identical table however the replicas were spread. A float ensemble at the default
resolution that runs until frozen (its counts the observable), in which any replica's margin
is thin, says so once (`MarginWarning`), not once per replica.

A replica that raises becomes one row with its index, seed and the error; the
others are kept. `ensemble_files.write_outputs` writes ``replicas.csv``, ``summary.json``,
``spec.json`` and histograms of the correlations over replicas into a directory.
"""

from __future__ import annotations

import json
import math
import os
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engine import door
from ..engine.devices import Device, as_device
from ..engine.field.arithmetic import AUTO, until_proved
from ..engine.margin import NEAR, ClosingMargin, MarginWarning
from ..engine.protocol import Refused
from ..geometry.base import Geometry
from ..rules import DEFAULT_RESOLUTION
from ..specs.run import RunSpec
from ..util import checks
from ..util.errors import InputError
from ..util.extras import need
from ..util.limits import check_memory
from ..util.progress import Progress
from . import executors, lineage, profiles
from .ensemble_files import (
    CORRELATIONS,
    ERROR_COLUMN,
    FIGURES_DIR,
    FINAL,
    KEY_COLUMNS,
    MARGIN_COLUMNS,
    SPEC_NAME,
    SUMMARY_NAME,
    TABLE_NAME,
    write_outputs,
)

__all__ = ["EnsembleResult", "run_ensemble", "ensemble_plan", "run_replica", "replica_row", "replica_seed", "state_row",
           "margin_columns", "KEY_COLUMNS", "MARGIN_COLUMNS", "ERROR_COLUMN", "FINAL", "CORRELATIONS", "TABLE_NAME",
           "SUMMARY_NAME", "SPEC_NAME", "FIGURES_DIR"]


#: ``task(spec, index, seed) -> rows`` of one replica; module-level (it is pickled to workers)
Task = Callable[[RunSpec, int, np.random.SeedSequence], list[dict]]
#: ``observe(geometry, velocities (n_balls, dim), masses (n_balls,) | None) -> {column: value}``
Observe = Callable[[Geometry, np.ndarray, "np.ndarray | None"], dict]


# ---------------------------------------------------------------- one replica


def replica_seed(spec: RunSpec, index: int) -> np.random.SeedSequence:
    """The seed of replica ``index``: child ``index`` of ``SeedSequence(spec.seed).spawn(N)`` for any ``N > index``."""
    return np.random.SeedSequence(spec.seed, spawn_key=(index,))


def state_row(geometry: Geometry, velocities: np.ndarray, masses=None) -> dict[str, float]:
    """The observables of one state: `observables.summary`, and `far_shares` and the energy profile
    (`profiles.PROFILE`, apart from the table's columns) on a geometry with a boundary."""
    from ..analysis import observables as obs

    row = obs.summary(velocities, geometry, masses)
    if geometry.boundary is not None:
        row.update(obs.far_shares(geometry.boundary.distance, velocities, masses))
        row[profiles.PROFILE] = profiles.energy_shares(geometry, velocities, masses)
    return row


def margin_columns(sim, margin: np.ndarray | None) -> dict:
    """`MARGIN_COLUMNS` of a state of ``sim`` whose margin is ``margin (4,)`` (`engine.margin`):
    ``smallest_collision`` and ``largest_remnant`` in thresholds (left out while there is none),
    ``near_collisions`` and ``near_remnants``; for a state that keeps no margin (exact or certified
    arithmetic) only ``smallest_collision``, where the engine keeps it (`Simulation.smallest_exact_collision`)."""
    if margin is None:
        smallest = sim.smallest_exact_collision
        return {} if smallest is None else {"smallest_collision": smallest}
    m = ClosingMargin.of(margin, sim.threshold, sim.resolution).to_dict()
    return {name: m[name] for name in MARGIN_COLUMNS if m[name] is not None}


def _head(index: int, seed: np.random.SeedSequence) -> dict:
    return {"replica": index, "seed_entropy": seed.entropy, "spawn_key": json.dumps(list(seed.spawn_key))}


def run_replica(spec: RunSpec, index: int, seed: np.random.SeedSequence | None = None,
                observe: Observe = state_row) -> list[dict]:
    """Run replica ``index`` of ``spec`` to its stop; its rows: one per snapshot reached, then the final state.

    ``seed`` defaults to `replica_seed`. Each row holds `KEY_COLUMNS` and ``observe``'s columns.
    Snapshots the run never reaches (it froze first) have no row. A spec whose ``precision`` is ``"auto"``
    starts again with more bits where certified arithmetic cannot prove a decision (`execute.execute`).
    """
    seed = replica_seed(spec, index) if seed is None else seed
    if spec.precision != AUTO:
        return _run_replica(spec, index, seed, observe)

    def attempt(bits: tuple[int, int | None] | None) -> list[dict]:
        """Its rows at ``bits`` (None: the first attempt's), saying at which (0: none behind the first wave)."""
        precision, late = bits or spec.precisions()
        rows = _run_replica(spec.at_precisions(precision, late), index, seed, observe)
        return [{**row, "precision": precision, "late_precision": late or 0} for row in rows]

    return until_proved(attempt, spec.late_precision)


def _run_replica(spec: RunSpec, index: int, seed: np.random.SeedSequence, observe: Observe) -> list[dict]:
    """`run_replica` once, at ``spec``'s precision."""
    from .execute import run_to_stop

    sim = spec.build(seed=seed)
    sim.warns_thin_margin = False  # the ensemble says once that margins are thin, not each replica (`run_ensemble`)
    rows: list[dict] = []
    counter = spec.snapshots.counter if spec.snapshots else ""

    def on_snapshot(record) -> None:
        rows.append(replica_row(sim, index, seed, f"{counter}={getattr(record.state, counter)}", record.state,
                                record.frozen, "", observe))

    reason = run_to_stop(spec, sim, on_snapshot=on_snapshot)
    rows.append(replica_row(sim, index, seed, FINAL, sim.get_state(), sim.is_frozen(), reason, observe))
    return rows


def replica_row(sim, index: int, seed: np.random.SeedSequence, at: str, state, frozen: bool, reason: str,
                observe: Observe = state_row) -> dict:
    """One row of replica ``index``: `KEY_COLUMNS` of ``state`` (a `RunState`), its margin (`margin_columns`,
    with ``sim``'s threshold) and ``observe``'s columns of its velocities."""
    return {**_head(index, seed), "at": at, "steps": int(state.steps), "collisions": int(state.collisions),
            "frozen": int(frozen), "stop_reason": reason, **margin_columns(sim, state.margin),
            **observe(sim.geometry, state.velocities, sim.masses)}


def _error_row(index: int, seed: np.random.SeedSequence, exc: BaseException) -> dict:
    message = " ".join(str(exc).split())
    return {**_head(index, seed), ERROR_COLUMN: f"{type(exc).__name__}: {message}" if message else type(exc).__name__}


def _attempt(task: Task, spec: RunSpec, index: int, seed: np.random.SeedSequence) -> list[dict]:
    """``task``'s rows, or one error row if it raises (runs on the worker)."""
    try:
        return task(spec, index, seed)
    except Exception as exc:  # noqa: BLE001 - a failed replica is reported, not fatal
        return [_error_row(index, seed, exc)]


# ---------------------------------------------------------------- many replicas


@dataclass(frozen=True)
class EnsembleResult:
    """The rows of an ensemble, ordered by replica then time, and how it ran (`run_ensemble`, `load_ensemble`).

    Parameters
    ----------
    spec : RunSpec
        The spec every replica ran, seeded.
    replicas : int
        How many.
    rows : list of dict
        Dicts with `KEY_COLUMNS` (and `MARGIN_COLUMNS` where the run keeps its margin) and observables, one per
        snapshot of each replica and one for its final state (the module's docstring); for a failed replica,
        only ``replica``, ``seed_entropy``, ``spawn_key`` and `ERROR_COLUMN`.
    where : str
        Where it ran (``"in-process"``, ``"2 local processes"``, ``"dask tcp://..."``, ``"GPU"``...).
    wall_seconds : float
        The replicas' time.
    provenance : dict or None
        How the ensemble was made (`pinnedballs.util.provenance`, as a run's `Results.provenance` entry):
        ``versions``, ``command`` (the command line or the Python call), ``argv``, ``host``, ``platform``, ``cpu``,
        ``device`` (``kind`` "cpu" or "cuda" and ``where``: ``workers``, or ``dask``, ``workers`` and ``hosts`` on a
        cluster, or the ``gpu``), ``started`` and ``ended`` (UTC, ISO 8601). None for a directory written before
        ensembles kept their provenance.
    """

    spec: RunSpec
    replicas: int
    rows: list[dict]
    where: str
    wall_seconds: float
    provenance: dict | None = field(default=None, compare=False)

    @property
    def columns(self) -> list[str]:
        """Column names: `KEY_COLUMNS`, `MARGIN_COLUMNS` (of a run that keeps its margin), observables in
        first-seen order, `ERROR_COLUMN`."""
        seen = dict.fromkeys(KEY_COLUMNS)
        if any(c in row for row in self.rows for c in MARGIN_COLUMNS):  # a run that keeps its margin
            seen.update(dict.fromkeys(MARGIN_COLUMNS))
        for row in self.rows:
            seen.update(dict.fromkeys(k for k in row if k not in (ERROR_COLUMN, profiles.PROFILE)))
        return [*seen, ERROR_COLUMN]

    def thin(self) -> list[dict]:
        """The final rows of the replicas whose closing margin is thin.

        Returns
        -------
        list of dict
            Those where a collision closed within a factor `engine.margin.NEAR` of the threshold, so their
            counts depend on the criterion.
        """
        return [row for row in self.rows if not row.get(ERROR_COLUMN) and row["at"] == FINAL
                and row.get("near_collisions", 0) > 0]

    @property
    def failures(self) -> list[dict]:
        """The error rows, one per failed replica."""
        return [row for row in self.rows if row.get(ERROR_COLUMN)]

    def stages(self) -> list[str]:
        """The ``at`` labels present.

        Returns
        -------
        list of str
            Snapshots in time order (``"steps=N"``, ``"collisions=N"``), then `FINAL`.
        """
        labels = dict.fromkeys(row["at"] for row in self.rows if not row.get(ERROR_COLUMN))
        snaps = sorted((a for a in labels if a != FINAL), key=lambda a: int(a.partition("=")[2]))
        return snaps + ([FINAL] if FINAL in labels else [])

    def column(self, name: str, at: str = FINAL) -> np.ndarray:
        """A column's values over the replicas that have it, by replica.

        Parameters
        ----------
        name : str
            One of `columns`.
        at : str
            One of `stages` (the final state by default).

        Returns
        -------
        numpy.ndarray
            ``(n,) float64``.
        """
        return np.array([float(row[name]) for row in self.rows
                         if not row.get(ERROR_COLUMN) and row["at"] == at and name in row], dtype=np.float64)

    def to_pandas(self, at: str | None = FINAL):
        """The rows as a table; ``frozen`` is a boolean column.

        Parameters
        ----------
        at : str or None
            A stage (default the final state): a row per replica indexed by ``replica`` (a failed one has its
            ``error`` and no numbers); None: every row, indexed by ``(replica, at)``.

        Returns
        -------
        pandas.DataFrame
        """
        pd = need("pandas", "to_pandas", "pandas")

        columns = self.columns if at is None else [c for c in self.columns if c != "at"]
        rows = self.rows if at is None else [r for r in self.rows if r.get(ERROR_COLUMN) or r.get("at") == at]
        df = pd.DataFrame([{c: r.get(c) for c in columns} for r in rows], columns=columns)
        df["frozen"] = df["frozen"].map(lambda x: pd.NA if x is None or x != x else bool(x)).astype("boolean")
        if not df[ERROR_COLUMN].notna().any():
            df = df.drop(columns=ERROR_COLUMN)
        return df.set_index(["replica", "at"] if at is None else "replica")

    def save(self, out_dir, figures: bool = True) -> list[Path]:
        """Write the ensemble's directory, as `pinnedballs ensemble` does (`ensemble_files.write_outputs`).

        Parameters
        ----------
        out_dir : str or os.PathLike
            Created.
        figures : bool
            Also the figures: the correlation histograms over replicas (and, with a boundary, the mean energy
            profile).

        Returns
        -------
        list of pathlib.Path
            ``replicas.csv``, ``summary.json``, ``spec.json`` (``profiles.csv`` with a boundary), the figures.
        """
        return write_outputs(self, out_dir, figures=figures)

    def _repr_html_(self) -> str:  # notebooks: replicas, where, and the final states' counts as a table
        from ..plot.display import ensemble_html

        return ensemble_html(self)

    def __repr__(self) -> str:
        failed = len(self.failures)
        seconds = f", {self.wall_seconds:.3g} s" if math.isfinite(self.wall_seconds) else ""
        return (f"EnsembleResult({self.replicas} replicas of {self.spec.geometry.kind}, seed {self.spec.seed}: "
                f"{self.replicas - failed} done, {failed} failed; {len(self.rows)} rows; {self.where}{seconds})")

    def statistics(self) -> dict[str, dict[str, dict[str, float]]]:
        """The statistics of every numeric column at every stage.

        Returns
        -------
        dict
            ``{at: {column: {n, mean, std, min, max}}}`` (``std`` with ``ddof=1``).
        """
        skip = {"replica", "seed_entropy", "spawn_key", "at", "stop_reason", ERROR_COLUMN}
        out: dict[str, dict[str, dict[str, float]]] = {}
        for at in self.stages():
            out[at] = {}
            for name in self.columns:
                if name in skip:
                    continue
                x = self.column(name, at)
                x = x[np.isfinite(x)]
                if len(x):
                    out[at][name] = {"n": int(len(x)), "mean": float(x.mean()),
                                     "std": float(x.std(ddof=1)) if len(x) > 1 else math.nan,
                                     "min": float(x.min()), "max": float(x.max())}
        return out


def check_count(name: str, value, minimum: int = 1) -> int:
    return checks.integer(name, value, minimum)


#: bytes held per replica while an ensemble runs: its seed, its job and a row (upper estimate)
REPLICA_BYTES = 4096


def _check_replicas_memory(replicas: int, name: str) -> None:
    """Refuse (naming ``name``) more replicas than the memory can track at once."""
    check_memory(replicas * REPLICA_BYTES, name, f"an ensemble of {replicas:,} replicas")


def run_ensemble(spec: RunSpec, replicas: int, *, workers: int | None = None, dask_address: str | None = None,
                 cluster=None, progress: bool | None = None, task: Task | None = None,
                 device: str = "cpu") -> EnsembleResult:
    """Run ``replicas`` independent replicas of ``spec``; see the module docstring for seeds and rows.

    Parameters
    ----------
    spec : RunSpec
        The run every replica makes (a spec without a seed gets one drawn: `RunSpec.seeded`).
    replicas : int
        How many, at least 1.
    workers : int, optional
        Local processes (default ``os.cpu_count()``; 1 runs in this process). They are forked, except after this
        process has run numba's threads (a `ColoredSweep`, a chain on >= 65,536 contacts), which a forked child
        cannot run again: they then start from a fork server, so a script must keep its top level under
        ``if __name__ == "__main__":``, as with any multiprocessing start method but fork.
    dask_address : str, optional
        The Dask scheduler to run on instead.
    cluster : optional
        A Dask cluster or ``Client`` to run on instead.
    progress : bool or None
        A bar over the replicas (True, False, or None: in a terminal or a notebook, once the ensemble has taken
        2 s; `pinnedballs.util.progress`).
    task : callable, optional
        ``task(spec, index, seed) -> rows`` replaces `run_replica` (e.g. ``functools.partial(run_replica,
        observe=f)``); it must be picklable to run elsewhere.
    device : Device or {"cpu", "cuda"}
        ``"cuda"``: on an NVIDIA GPU (`run.ensemble_gpu`): small systems one replica a GPU thread, large ones one
        after another on the whole GPU; the same rows as on the CPU for the same seeds. It runs specs a GPU runs
        (float arithmetic, ``UniformRandomPair(stream="counter")``, any rule that compiles for one), with the
        built-in task: in this process (``workers`` does not apply), or, with ``dask_address`` or ``cluster``, on
        the GPUs of a Dask cluster whose workers each own one (dask-cuda's ``LocalCUDACluster`` on one machine,
        or a cluster's GPU nodes: docs/gpu.md), the replicas in groups of at most `ensemble_gpu.WORKER_GROUP`, a
        group a job; a group whose worker is lost runs again elsewhere. A certified spec on ``"cuda"`` runs its
        replicas one at a time on this process's GPU, with any task (every simulation it builds from the spec is
        built there: `RunSpec.on_device`), the CPU's rows; not on a cluster.

    Returns
    -------
    EnsembleResult

    Raises
    ------
    InputError
        On bad arguments: ``spec`` not a `RunSpec`, more than one of ``workers``, ``dask_address`` and
        ``cluster``, a task a GPU does not run.
    SpecError
        On ``device``, where no engine runs the spec's replicas there (in the spec's words).
    KeyboardInterrupt
        On Ctrl-C, within a second or so; the replicas done so far are discarded (each can be run again alone,
        `run_replica`, to the same rows). Local processes are killed at once; on Dask the jobs not finished are
        cancelled (one already running on a worker runs to its end there: Dask cannot stop it).

    Warns
    -----
    MarginWarning
        Once, not once per replica: a float ensemble at the default resolution that runs until frozen (its
        counts the observable), in which any replica's margin is thin.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.specs.run import parse_spec
    >>> spec = parse_spec({"geometry": {"kind": "half_plane", "rows": 4, "cols": 6}, "seed": 1,
    ...                    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1],
    ...                                "energy": 0.5},
    ...                    "stop": {"frozen": True, "max_steps": 100000}})
    >>> ens = pb.run_ensemble(spec, replicas=3, workers=1)
    >>> ens.stages(), ens.column("collisions").tolist(), bool(ens.to_pandas()["frozen"].all())
    (['final'], [46.0, 52.0, 60.0], True)
    """
    if not isinstance(spec, RunSpec):
        raise InputError(f"spec: must be a RunSpec, got {type(spec).__name__}")
    spec = spec.seeded()
    replicas = check_count("replicas", replicas)
    _check_replicas_memory(replicas, "replicas")
    if (dask_address is not None) + (cluster is not None) + (workers is not None) > 1:
        raise InputError("workers, dask_address, cluster: give at most one")
    device = as_device(device)
    seeds = np.random.SeedSequence(spec.seed).spawn(replicas)
    on_cluster = dask_address is not None or cluster is not None
    plan = ensemble_plan(spec, spec.build(seed=seeds[0]), device, on_cluster=on_cluster) if device.gpu \
        else "processes"
    observe = _gpu_observe(task) if plan == "together" else None
    if plan == "together" and observe is None:
        raise InputError("device: 'cuda' runs the built-in replica task (run_replica, or a functools.partial of it "
                         "giving observe=)")
    task = run_replica if task is None else task
    built_there = spec.on_device(device)  # whatever the task, it builds its simulation on the device
    jobs = {k: (_attempt, task, built_there, k, seeds[k]) for k in range(replicas)}

    def lost(k: int, exc: BaseException) -> list[dict]:  # its worker died or was lost
        return [_error_row(k, seeds[k], exc)]

    made = lineage.ensemble("pinnedballs.run_ensemble", {"kind": device.kind}, gpu=device.gpu)  # begun now
    start = time.perf_counter()
    with Progress(progress, replicas, "replicas", "replicas", scale=False) as bar:
        done = []

        def tick() -> None:
            done.append(1)
            bar.update(len(done))

        if plan == "one_by_one":
            where = "GPU, one replica at a time"
            results = executors.in_process(jobs, tick)
            used = _this_gpu()
        elif plan == "together" and on_cluster:
            where, results, used = _on_cluster_gpus(spec, seeds, observe, dask_address, cluster, bar)
        elif plan == "together":
            from .ensemble_gpu import run_on_gpu

            where = "GPU"
            results = run_on_gpu(spec, seeds, observe, replica_row, tick)
            used = _this_gpu()
        elif on_cluster:
            client, own = executors.dask_client(dask_address, cluster)
            try:
                where, used = f"dask {client.scheduler.address}", lineage.dask_facts(client)
                results = executors.on_dask(client, jobs, tick, lost)
            finally:
                if own:
                    client.close()
        else:
            workers = (os.cpu_count() or 1) if workers is None else check_count("workers", workers)
            workers = min(workers, replicas)
            where, used = "in-process" if workers == 1 else f"{workers} local processes", {"workers": workers}
            results = executors.in_process(jobs, tick) if workers == 1 else \
                executors.on_processes(jobs, workers, tick, lost)
    rows = [row for k in range(replicas) for row in results[k]]
    result = EnsembleResult(spec, replicas, rows, where, time.perf_counter() - start,
                            lineage.ended(made, device={"where": where, **used}))
    if spec.stop.frozen and spec.arithmetic == "float" and spec.resolution is None and result.thin():
        warnings.warn(_thin_note(result), MarginWarning, stacklevel=2)
    return result


def _this_gpu() -> dict:
    """The GPU of this process that an ensemble ran on (`engine.gpu.describe`), for its provenance."""
    from ..engine.gpu import describe

    return describe()


def _on_cluster_gpus(spec: RunSpec, seeds: list, observe: Observe, dask_address, cluster,
                     bar) -> tuple[str, dict, dict]:
    """``(where, rows by replica, what provenance records of the cluster)`` of the replicas run on the GPUs of a
    Dask cluster (`run_ensemble`'s ``device="cuda"`` with ``dask_address`` or ``cluster``): the spec checked here
    (this process needs no GPU), every worker asked whether it sees one, then the replicas in groups
    (`ensemble_gpu.groups`), a group a job on a worker's GPU; a group whose worker is lost runs again elsewhere
    (`executors.on_dask`), and the rows are the same however the replicas were grouped."""
    from .ensemble_gpu import gpu_workers, groups, on_worker_gpu

    client, own = executors.dask_client(dask_address, cluster)
    try:
        parts = groups(len(seeds), gpu_workers(client))
        jobs = {g: (on_worker_gpu, spec, r.start, [seeds[k] for k in r], observe, replica_row)
                for g, r in enumerate(parts)}
        done = []

        def tick() -> None:  # a group done: its replicas on the bar
            done.append(1)
            bar.update(min(len(seeds), sum(len(parts[g]) for g in range(len(done)))))

        def lost(g: int, exc: BaseException) -> dict:  # its worker died or was lost, twice
            return {k: [_error_row(k, seeds[k], exc)] for k in parts[g]}

        out = executors.on_dask(client, jobs, tick, lost)
        where, used = f"dask {client.scheduler.address} (a GPU a worker)", lineage.dask_facts(client)
    finally:
        if own:
            client.close()
    return where, {k: rows for part in out.values() for k, rows in part.items()}, used


def ensemble_plan(spec: RunSpec, sim, device: str | Device, *, on_cluster: bool = False) -> str:
    """How an ensemble of ``spec``'s replicas runs on ``device``, asked of the engine's door (`engine.door`) with
    ``sim``, replica 0 built on the CPU: ``"together"`` (an engine that runs replicas together: a GPU thread
    each, on this process's GPU or, ``on_cluster``, on each Dask worker's), ``"one_by_one"`` (a chain an engine of
    this process's GPU runs: certified arithmetic, one replica a call in this process) or ``"processes"`` (the
    CPU's engines: a replica a process, or a Dask job). A `SpecError` on ``device`` saying why none does, in the
    spec's words."""
    from ..specs.errors import SpecError

    device = as_device(device)
    model = sim.engine.model
    try:
        door.check(model, spec.arithmetic, device, replicas=True, here=not on_cluster)
        return "together"
    except Refused as together:
        try:
            door.check(model, spec.arithmetic, device)
        except Refused:
            raise spec.refused(together.refusal) from None
    if not device.gpu:
        return "processes"
    if on_cluster:
        raise SpecError("device", f"{device.kind!r} runs a {spec.arithmetic} ensemble's replicas one at a time on "
                                  f"this process's GPU; on a Dask cluster, {spec.arithmetic} replicas run on its CPUs "
                                  f"(device='cpu')")
    return "one_by_one"


def _gpu_observe(task: Task | None) -> Observe | None:
    """The ``observe`` of a task a GPU ensemble can run: `run_replica` itself (`state_row`), or a
    ``functools.partial(run_replica, observe=f)`` (``f``); None for any other task."""
    import functools

    if task is None or task is run_replica:
        return state_row
    if isinstance(task, functools.partial) and task.func is run_replica and not task.args \
            and set(task.keywords) <= {"observe"}:
        return task.keywords.get("observe", state_row)
    return None


def _thin_note(result: EnsembleResult) -> str:
    """The one line an ensemble with thin margins says (`MarginWarning`)."""
    thin = result.thin()
    smallest = min(row["smallest_collision"] for row in thin)
    done = sum(1 for row in result.rows if not row.get(ERROR_COLUMN) and row["at"] == FINAL)
    return (f"the closing margin is thin in {len(thin)} of {done} replicas (collisions closing within a factor "
            f"{NEAR:,.0f} of the threshold, the smallest at {smallest:.3g} thresholds; replicas.csv has each "
            f"replica's margin): their collision counts depend on the float criterion (resolution "
            f"{DEFAULT_RESOLUTION:.3g}); count them exactly with \"arithmetic\": \"exact\" on the same seed")
