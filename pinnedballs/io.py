"""Results files: one HDF5 file per run, written atomically, read back with `load`.

Layout of ``results.h5`` (``n`` balls, ``d`` velocity components, ``E`` contacts,
``F`` snapshots)::

    /                 attrs: format, format_version, version (package), spec (JSON),
                             status ("running" | "done"), stop_reason, created, updated,
                             elapsed_seconds, checkpoints
    /geometry         positions (n, k), pairs (E, 2) int32, t_i (E, d), t_j (E, d),
                      masses (n,) [only if the spec gives masses]
    /initial          velocities (n, d), momentum (d,); attrs energy, approaching
    /snapshots        velocities (F, n, d) (resizable), steps (F,), collisions (F,)
                      (the last two are links to the columns of /observables)
    /observables      one row per snapshot: steps, collisions, energy (F,),
                      momentum (F, d), approaching (F,)
    /state            the latest state, enough to resume bit for bit: velocities (n, d),
                      rng_state (4,) uint64, scheduler_state (L,) int64, momentum (d,);
                      attrs steps, collisions, energy, approaching, frozen

Static data is written once; every checkpoint copies the file to ``results.h5.tmp``,
appends the new snapshots, replaces ``/state`` and renames the copy over the
original (`os.replace`), so a killed run always leaves a complete, readable file.
"""

from __future__ import annotations

import functools
import json
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import h5py
import numpy as np

from .geometry import Geometry
from .simulation import Simulation
from .errors import InputError
from .specs import RunSpec

__all__ = ["FORMAT", "FORMAT_VERSION", "RESULTS_NAME", "ResultsError", "Snapshot", "Record", "Results",
           "results_path", "create", "checkpoint", "load"]

FORMAT = "pinnedballs-results"
FORMAT_VERSION = 1
RESULTS_NAME = "results.h5"
_OBSERVABLES = ("steps", "collisions", "energy", "momentum", "approaching")


class ResultsError(InputError):
    """A results file that is not one, or is damaged."""


class Snapshot(NamedTuple):
    """The velocities ``(n_balls, dim)`` after ``step`` steps and ``collisions`` collisions."""

    step: int
    collisions: int
    velocities: np.ndarray


@dataclass(frozen=True)
class Record:
    """A state and its observables, as the runner hands it to the writer.

    state: `Simulation.get_state` (``velocities (n, d)``, ``steps``, ``collisions``,
    ``rng_state (4,)``, ``scheduler_state (L,)``, ...); energy, momentum ``(d,)``,
    approaching and frozen are measured on it.
    """

    state: dict
    energy: float
    momentum: np.ndarray
    approaching: int

    @classmethod
    def of(cls, sim: Simulation) -> "Record":
        """The current state of ``sim`` and its observables."""
        return cls(sim.get_state(), sim.energy(), np.asarray(sim.momentum(), dtype=np.float64), sim.approaching())

    @property
    def frozen(self) -> bool:
        return self.approaching == 0


def results_path(path: str | os.PathLike) -> Path:
    """``path`` itself, or ``path/results.h5`` if ``path`` is a directory."""
    path = Path(path)
    return path / RESULTS_NAME if path.is_dir() else path


# ---------------------------------------------------------------- writing


def create(path: Path, spec: RunSpec, geometry: Geometry, masses: np.ndarray | None,
           initial: Record, version: str) -> None:
    """Write a new results file at ``path``: spec, geometry, initial state, no snapshots yet."""
    tmp = _tmp(path)
    n, d = initial.state["velocities"].shape
    with h5py.File(tmp, "w") as f:
        now = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        f.attrs.update(format=FORMAT, format_version=FORMAT_VERSION, version=version, spec=spec.model_dump_json(),
                       status="running", stop_reason="", created=now, updated=now, elapsed_seconds=0.0, checkpoints=0)
        g = f.create_group("geometry")
        c = geometry.contacts
        g["positions"] = geometry.positions
        g["pairs"] = np.ascontiguousarray(c.pairs)
        g["t_i"], g["t_j"] = c.t_i, c.t_j
        if masses is not None:
            g["masses"] = np.broadcast_to(np.asarray(masses, dtype=np.float64), (n,))
        i = f.create_group("initial")
        i["velocities"] = initial.state["velocities"]
        i["momentum"] = initial.momentum
        i.attrs.update(energy=initial.energy, approaching=initial.approaching)
        s = f.create_group("snapshots")
        s.create_dataset("velocities", shape=(0, n, d), maxshape=(None, n, d), chunks=(1, n, d), dtype=np.float64)
        o = f.create_group("observables")
        for name, dtype in (("steps", np.int64), ("collisions", np.int64), ("energy", np.float64),
                            ("approaching", np.int64)):
            o.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(1024,), dtype=dtype)
            if name in ("steps", "collisions"):
                s[name] = h5py.SoftLink(f"/observables/{name}")
        o.create_dataset("momentum", shape=(0, d), maxshape=(None, d), chunks=(1024, d), dtype=np.float64)
        _write_state(f, initial)
    _commit(tmp, path)


def checkpoint(path: Path, snapshots: list[Record], state: Record, *, done: bool = False,
               stop_reason: str = "", elapsed_seconds: float | None = None) -> None:
    """Append ``snapshots`` and replace the state in the results file at ``path``, atomically."""
    tmp = _tmp(path)
    shutil.copyfile(path, tmp)
    with h5py.File(tmp, "r+") as f:
        _append(f, snapshots)
        _write_state(f, state)
        f.attrs["status"] = "done" if done else "running"
        f.attrs["stop_reason"] = stop_reason
        f.attrs["updated"] = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        f.attrs["checkpoints"] = int(f.attrs["checkpoints"]) + 1
        if elapsed_seconds is not None:
            f.attrs["elapsed_seconds"] = float(elapsed_seconds)
    _commit(tmp, path)


def _append(f: h5py.File, records: list[Record]) -> None:
    if not records:
        return
    v = f["snapshots/velocities"]
    start, k = v.shape[0], len(records)
    v.resize(start + k, axis=0)
    v[start:] = np.stack([r.state["velocities"] for r in records])
    o = f["observables"]
    columns = {"steps": [r.state["steps"] for r in records], "collisions": [r.state["collisions"] for r in records],
               "energy": [r.energy for r in records], "approaching": [r.approaching for r in records],
               "momentum": np.stack([r.momentum for r in records])}
    for name, values in columns.items():
        o[name].resize(start + k, axis=0)
        o[name][start:] = values


def _write_state(f: h5py.File, record: Record) -> None:
    """Replace ``/state`` by ``record``: arrays as datasets, numbers as attributes."""
    if "state" in f:
        del f["state"]
    s = f.create_group("state")
    for key, value in record.state.items():
        if isinstance(value, np.ndarray):
            s[key] = value
        else:
            s.attrs[key] = value
    s.attrs["keys"] = json.dumps(list(record.state))
    s["momentum"] = record.momentum
    s.attrs.update(energy=record.energy, approaching=record.approaching, frozen=record.frozen)


def _tmp(path: Path) -> Path:
    return path.with_name(path.name + ".tmp")


def check_out_dir(out: str | os.PathLike, force: bool, *, may_hold: frozenset[str] = frozenset(),
                  hint: str = "use --force to write into it", option: str = "--out") -> Path:
    """``out`` as a Path; an `InputError` naming ``option`` if it is a file, or a directory
    holding anything beyond ``may_hold`` without ``force``."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{option} {out}: exists and is not a directory")
    if out.is_dir() and not force:
        entries = sorted(p.name for p in out.iterdir())
        if not set(entries) <= may_hold:
            shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
            raise InputError(f"{option} {out}: directory is not empty ({shown}); {hint}")
    return out


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: a kill leaves the
    old file or the new one, never half of one."""
    path = Path(path)
    tmp = _tmp(path)
    tmp.write_text(text, encoding="utf-8")
    _commit(tmp, path)


def _commit(tmp: Path, path: Path) -> None:
    """Flush ``tmp`` to disk and rename it over ``path`` (atomic on POSIX)."""
    fd = os.open(tmp, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
    os.replace(tmp, path)
    try:
        fd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# ---------------------------------------------------------------- reading


@dataclass(eq=False)
class Results:
    """A run read back from its results file (finished, or the last checkpoint of an unfinished one).

    velocities ``(n, d)``, steps, collisions, rng_state, scheduler_state: the latest
    state (views of `state`'s single copy); positions ``(n, k)``,
    pairs ``(E, 2)``, t_i / t_j ``(E, d)``: the geometry; snapshots: list of
    `Snapshot` ``(step, collisions, velocities (n, d))``; observables: dict of
    per-snapshot columns ``steps, collisions, energy, approaching (F,)``, ``momentum (F, d)``.
    """

    path: Path
    spec: RunSpec
    version: str
    status: str
    stop_reason: str
    energy: float
    momentum: np.ndarray
    approaching: int
    frozen: bool
    positions: np.ndarray
    pairs: np.ndarray
    t_i: np.ndarray
    t_j: np.ndarray
    masses: np.ndarray | None
    initial_velocities: np.ndarray
    initial_energy: float
    snapshots: list[Snapshot]
    observables: dict[str, np.ndarray]
    elapsed_seconds: float
    checkpoints: int
    created: str
    updated: str
    raw_state: dict = field(default_factory=dict, repr=False)  #: as from `Simulation.get_state`

    @property
    def velocities(self) -> np.ndarray:
        return self.raw_state["velocities"]

    @property
    def steps(self) -> int:
        return int(self.raw_state["steps"])

    @property
    def collisions(self) -> int:
        return int(self.raw_state["collisions"])

    @property
    def rng_state(self) -> np.ndarray:
        return self.raw_state["rng_state"]

    @property
    def scheduler_state(self) -> np.ndarray:
        return self.raw_state["scheduler_state"]

    @property
    def complete(self) -> bool:
        """True once the run reached its stop (False for a checkpoint of a run still going or killed)."""
        return self.status == "done"

    @property
    def run_dir(self) -> Path:
        return self.path.parent

    @functools.cached_property
    def geometry(self) -> Geometry:
        """The run's geometry, rebuilt from the spec (from the stored positions for ``graph_positions``)."""
        g = self.spec.geometry
        return g.build_from(self.positions) if g.kind == "graph_positions" else g.build()

    def state(self) -> dict:
        """The latest state in the form of `Simulation.get_state`."""
        return {k: np.copy(v) if isinstance(v, np.ndarray) else v for k, v in self.raw_state.items()}

    def simulation(self) -> Simulation:
        """A `Simulation` at the latest state, ready to go on exactly where this run stopped."""
        s = self.spec
        sim = Simulation(self.geometry, self.velocities, rule=s.rule.build(), scheduler=s.scheduler.build(),
                         masses=self.masses, seed=s.seed)
        sim.set_state(self.state())
        return sim

    def __repr__(self) -> str:
        return (f"Results({str(self.path)!r}, {self.status}, steps={self.steps}, collisions={self.collisions}, "
                f"snapshots={len(self.snapshots)}, frozen={self.frozen})")


def load(path: str | os.PathLike) -> Results:
    """Read a results file, or ``DIR/results.h5`` given a run directory.

    Raises FileNotFoundError if there is none, `ResultsError` (a ValueError) if the
    file is not a pinnedballs results file or is damaged; both name the path.
    """
    p = results_path(path)
    if not p.exists():
        where = f"{path}: no {RESULTS_NAME} in this directory" if Path(path).is_dir() else f"{p}: no such file"
        raise FileNotFoundError(where)
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise ResultsError(f"{p}: not a readable HDF5 file (truncated or not HDF5): {exc}") from None
    with f:
        if f.attrs.get("format") != FORMAT:
            raise ResultsError(f"{p}: not a pinnedballs results file (no format={FORMAT!r} attribute)")
        if int(f.attrs.get("format_version", -1)) > FORMAT_VERSION:
            raise ResultsError(f"{p}: written by a newer pinnedballs (format {f.attrs['format_version']}); upgrade")
        try:
            return _read(p, f)
        except (KeyError, OSError) as exc:
            raise ResultsError(f"{p}: damaged results file ({exc})") from None


def _read(p: Path, f: h5py.File) -> Results:
    try:
        spec = RunSpec.model_validate_json(f.attrs["spec"])
    except ValueError as exc:
        raise ResultsError(f"{p}: its stored spec is not valid for this version of pinnedballs ({exc})") from None
    s, g, o = f["state"], f["geometry"], f["observables"]
    raw = {k: s[k][()] if k in s else _scalar(s.attrs[k]) for k in json.loads(s.attrs["keys"])}
    frames = f["snapshots/velocities"][()]
    steps, collisions = o["steps"][()], o["collisions"][()]
    return Results(
        path=p, spec=spec, version=str(f.attrs["version"]), status=str(f.attrs["status"]),
        stop_reason=str(f.attrs["stop_reason"]),
        energy=float(s.attrs["energy"]), momentum=s["momentum"][()], approaching=int(s.attrs["approaching"]),
        frozen=bool(s.attrs["frozen"]), positions=g["positions"][()], pairs=g["pairs"][()], t_i=g["t_i"][()], t_j=g["t_j"][()],
        masses=g["masses"][()] if "masses" in g else None,
        initial_velocities=f["initial/velocities"][()], initial_energy=float(f["initial"].attrs["energy"]),
        snapshots=[Snapshot(int(a), int(b), v) for a, b, v in zip(steps, collisions, frames)],
        observables={name: o[name][()] for name in _OBSERVABLES},
        elapsed_seconds=float(f.attrs["elapsed_seconds"]), checkpoints=int(f.attrs["checkpoints"]),
        created=str(f.attrs["created"]), updated=str(f.attrs["updated"]),
        raw_state=raw,
    )


def _scalar(value):
    """An HDF5 attribute as a plain Python number."""
    return value.item() if isinstance(value, np.generic) else value
