"""Results files: one run directory per run, written append-only, read back with `load`.

A run directory holds ``results.h5``, a small *index*, and ``results.data/``:
``static.h5`` (written once) and one *segment* ``frames_<first>.h5`` per checkpoint
that had new snapshots. Layout of the index (``n`` balls, ``d`` velocity components,
``E`` contacts, ``F`` snapshots), format 2::

    /                 attrs: format, format_version, version (package), spec (JSON, "" for a run
                             built in Python), run (JSON: what a Python run was built from),
                             status ("running" | "done"), stop_reason, created, updated,
                             elapsed_seconds, checkpoints, checked, observables (JSON names),
                             segments (JSON [[file, first, count], ...])
    /geometry         -> static.h5: positions (n, k), pairs (E, 2) int32, t_i (E, d), t_j (E, d),
                         masses (n,) [only if given]
    /initial          -> static.h5: velocities (n, d), momentum (d,); attrs energy, approaching
    /snapshots        velocities (F, n, d); steps, collisions (links to /observables)
    /observables      one column per recorded observable (`pinnedballs.observe`): (F,) or (F, ...)
    /state            the latest state, enough to resume bit for bit: velocities (n, d),
                      rng_state (4,) uint64, scheduler_state (L,) int64, momentum (d,);
                      attrs steps, collisions, energy, approaching, frozen

``/geometry`` and ``/initial`` are external links, ``/snapshots`` and ``/observables``
virtual datasets over the segments, so ``h5py`` reads the index like one file.

Why segments and an index: a checkpoint writes only what is new (its frames, into a
segment written to a temporary name, flushed and renamed) and then replaces the index
(temporary file, flush, rename), so the bytes a run writes grow with its final size,
not with snapshots x size, and a kill at any moment leaves the last complete index,
whose segments all exist. A segment the index does not list (a kill between the two
renames) is removed when the run continues. An HDF5 file appended in place would be
smaller to describe but can be left unreadable by a kill in the middle of a write.

Format 1 (a single file, copied whole at each checkpoint) still loads; continuing such
a run converts it to format 2 first.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import h5py
import numpy as np

from . import observe
from .errors import InputError
from .results_check import check_results
from .geometry import Contacts, Geometry
from .simulation import Simulation
from .specs import RunSpec

__all__ = ["FORMAT", "FORMAT_VERSION", "RESULTS_NAME", "DATA_DIR", "ResultsError", "Snapshot", "Record",
           "ResultsStore", "Results", "StoredGeometry", "results_path", "take_run_dir", "load"]

FORMAT = "pinnedballs-results"
FORMAT_VERSION = 2
RESULTS_NAME = "results.h5"
#: the directory beside the index holding ``static.h5`` and the segments
DATA_DIR = "results.data"
STATIC_NAME = "static.h5"
_V1_OBSERVABLES = ("steps", "collisions", "energy", "momentum", "approaching")


class ResultsError(InputError):
    """A results file that is not one, or is damaged."""


class Snapshot(NamedTuple):
    """The velocities ``(n_balls, dim)`` after ``step`` steps and ``collisions`` collisions."""

    step: int
    collisions: int
    velocities: np.ndarray


@dataclass(frozen=True)
class Record:
    """A state and its observables, as the driver hands it to the writer.

    state: `Simulation.get_state` (``velocities (n, d)``, ``steps``, ``collisions``,
    ``rng_state (4,)``, ``scheduler_state (L,)``, ...); energy, momentum ``(d,)``,
    approaching and frozen are measured on it; values: the selected observables by name.
    """

    state: dict
    energy: float
    momentum: np.ndarray
    approaching: int
    values: dict = field(default_factory=dict)

    @classmethod
    def of(cls, sim: Simulation, names=observe.DEFAULT) -> "Record":
        """The current state of ``sim`` and its observables ``names``."""
        values = observe.measure(sim, names)
        energy = float(values["energy"]) if "energy" in values else sim.energy()
        momentum = values["momentum"] if "momentum" in values else np.asarray(sim.momentum(), dtype=np.float64)
        approaching = int(values["approaching"]) if "approaching" in values else sim.approaching()
        return cls(sim.get_state(), energy, np.asarray(momentum, dtype=np.float64), approaching, values)

    @property
    def frozen(self) -> bool:
        return self.approaching == 0


def results_path(path: str | os.PathLike) -> Path:
    """``path`` itself, or ``path/results.h5`` if ``path`` is a directory."""
    path = Path(path)
    return path / RESULTS_NAME if path.is_dir() else path


def _data_dir(path: Path) -> Path:
    return path.with_name(DATA_DIR) if path.name == RESULTS_NAME else path.with_name(path.stem + ".data")


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


# ---------------------------------------------------------------- writing


@dataclass
class ResultsStore:
    """A results file open for appending: what the index lists, and how to add to it.

    `create` starts one, `reopen` continues one (removing what a kill left half-written);
    `checkpoint` appends frames as a new segment and replaces the index.
    """

    path: Path
    attrs: dict                      #: the index's root attributes
    shape: tuple[int, int]           #: (n_balls, dim)
    columns: dict                    #: name -> (dtype str, shape) of each observable
    segments: list = field(default_factory=list)  #: [file, first, count]
    frames: int = 0

    @property
    def data_dir(self) -> Path:
        return _data_dir(self.path)

    @classmethod
    def create(cls, path: str | os.PathLike, *, spec: str, run: str, geometry: Geometry, masses,
               initial: Record, version: str) -> "ResultsStore":
        """Write ``static.h5`` and an index with no snapshots. ``spec``: the run spec as JSON, or "";
        ``run``: JSON describing a run built in Python, or ""."""
        path = Path(path)
        data = _data_dir(path)
        data.mkdir(parents=True, exist_ok=True)
        _write_static(data / STATIC_NAME, geometry, masses, initial)
        n, d = initial.state["velocities"].shape
        now = _now()
        attrs = dict(format=FORMAT, format_version=FORMAT_VERSION, version=version, spec=spec, run=run,
                     status="running", stop_reason="", created=now, updated=now, elapsed_seconds=0.0,
                     checkpoints=0, checked=False, observables=json.dumps(list(initial.values)))
        columns = {k: (v.dtype.str, v.shape) for k, v in initial.values.items()}
        store = cls(path, attrs, (n, d), columns)
        store._write_index(initial)
        return store

    @classmethod
    def reopen(cls, path: str | os.PathLike) -> "ResultsStore":
        """The store of an existing results file, ready to append; a format-1 file is converted."""
        path = results_path(path)
        with _open_checked(path) as f:
            version = int(f.attrs["format_version"])
            if version == 1:
                return _convert_v1(path, f)
            attrs = {k: _scalar(v) for k, v in f.attrs.items()}
            segments = json.loads(f.attrs["segments"])
            columns = {name: (f["observables"][name].dtype.str, f["observables"][name].shape[1:])
                       for name in json.loads(f.attrs["observables"])}
            shape = f["state/velocities"].shape
        store = cls(path, attrs, tuple(shape), columns, segments, sum(s[2] for s in segments))
        store._remove_strays()
        return store

    def checkpoint(self, frames: list[Record], state: Record, *, done: bool = False, stop_reason: str = "",
                   elapsed_seconds: float | None = None) -> None:
        """Append ``frames`` (as one new segment) and replace the state: the new index is renamed
        over the old one only once the segment is on disk."""
        if frames:
            name = f"frames_{self.frames:09d}.h5"
            _write_segment(self.data_dir / name, frames, list(self.columns))
            self.segments.append([name, self.frames, len(frames)])
            self.frames += len(frames)
        self.attrs.update(status="done" if done else "running", stop_reason=stop_reason, updated=_now(),
                          checkpoints=int(self.attrs["checkpoints"]) + 1, checked=True)
        if elapsed_seconds is not None:
            self.attrs["elapsed_seconds"] = float(elapsed_seconds)
        self._write_index(state)

    def _write_index(self, state: Record) -> None:
        n, d = self.shape
        rel = f"{self.data_dir.name}/"
        with _h5_file(self.path) as f:
            f.attrs.update(self.attrs)
            f.attrs["segments"] = json.dumps(self.segments)
            f["geometry"] = h5py.ExternalLink(rel + STATIC_NAME, "/geometry")
            f["initial"] = h5py.ExternalLink(rel + STATIC_NAME, "/initial")
            _virtual(f, "snapshots/velocities", "velocities", np.dtype(np.float64), (n, d), self.segments, rel)
            for name, (dtype, shape) in self.columns.items():
                _virtual(f, f"observables/{name}", f"observables/{name}", np.dtype(dtype), tuple(shape),
                         self.segments, rel)
            for name in observe.ALWAYS:
                f["snapshots"][name] = h5py.SoftLink(f"/observables/{name}")
            _write_state(f, state)

    def _remove_strays(self) -> None:
        """Remove temporary files and segments the index does not list (left by a kill)."""
        keep = {s[0] for s in self.segments} | {STATIC_NAME}
        for p in self.data_dir.iterdir():
            if p.name not in keep:
                p.unlink()
        _remove(_tmp(self.path))


def _write_static(path: Path, geometry: Geometry, masses, initial: Record) -> None:
    n = geometry.n_balls
    with _h5_file(path) as f:
        g = f.create_group("geometry")
        c = geometry.contacts
        g["positions"] = geometry.positions
        g["pairs"] = np.ascontiguousarray(c.pairs)
        g["t_i"], g["t_j"] = c.t_i, c.t_j
        g.attrs["radius"] = float(getattr(geometry, "radius", 1.0))
        if masses is not None:
            g["masses"] = np.broadcast_to(np.asarray(masses, dtype=np.float64), (n,))
        i = f.create_group("initial")
        i["velocities"] = initial.state["velocities"]
        i["momentum"] = initial.momentum
        i.attrs.update(energy=initial.energy, approaching=initial.approaching)


def _write_segment(path: Path, frames: list[Record], names: list[str]) -> None:
    with _h5_file(path) as f:
        f["velocities"] = np.stack([r.state["velocities"] for r in frames])
        for name in names:
            f[f"observables/{name}"] = np.stack([np.asarray(r.values[name]) for r in frames])


@contextlib.contextmanager
def _h5_file(path: Path):
    """An HDF5 file built in memory, then written to ``path`` (`write_bytes_atomic`) if the block succeeds.

    HDF5 never writes to disk itself: a full disk is a plain OSError from our own write,
    never a file HDF5 cannot close (h5py issue 2160: a native crash on closing a file
    whose write failed), and no partial file is left behind.
    """
    f = h5py.File(f"{path.name}.{id(path)}", "w", driver="core", backing_store=False)
    try:
        yield f
        f.flush()
        image = f.id.get_file_image()
    finally:
        f.close()
    write_bytes_atomic(path, image)


def _virtual(f: h5py.File, where: str, source: str, dtype: np.dtype, shape: tuple, segments: list, rel: str) -> None:
    """``where`` in ``f``: the rows ``source`` of every segment, one after another."""
    total = sum(s[2] for s in segments)
    if total == 0:
        f.create_dataset(where, shape=(0, *shape), dtype=dtype)
        return
    layout = h5py.VirtualLayout(shape=(total, *shape), dtype=dtype)
    for name, first, count in segments:
        layout[first:first + count] = h5py.VirtualSource(rel + name, source, shape=(count, *shape), dtype=dtype)
    f.create_virtual_dataset(where, layout)


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


def _convert_v1(path: Path, f: h5py.File) -> "ResultsStore":
    """A format-1 file rewritten as format 2 (static data, one segment of its frames, the index)."""
    res = _read(path, f)
    n, d = res.velocities.shape
    names = list(_V1_OBSERVABLES)
    initial = Record({"velocities": res.initial_velocities}, res.initial_energy, f["initial/momentum"][()],
                     int(f["initial"].attrs["approaching"]))
    geometry = StoredGeometry(res.positions, res.pairs, res.t_i, res.t_j)
    state = Record(res.state(), res.energy, res.momentum, res.approaching)
    frames = [Record({"velocities": s.velocities}, 0.0, None, 0, {k: res.observables[k][i] for k in names})
              for i, s in enumerate(res.snapshots)]
    attrs = {k: _scalar(v) for k, v in f.attrs.items()}
    f.close()
    data = _data_dir(path)
    data.mkdir(exist_ok=True)
    _write_static(data / STATIC_NAME, geometry, res.masses, initial)
    columns = {k: (res.observables[k].dtype.str, res.observables[k].shape[1:]) for k in names}
    attrs.update(format_version=FORMAT_VERSION, run="", checked=True, observables=json.dumps(names))
    store = ResultsStore(path, attrs, (n, d), columns)
    store._remove_strays()
    if frames:
        name = f"frames_{0:09d}.h5"
        _write_segment(data / name, frames, names)
        store.segments, store.frames = [[name, 0, len(frames)]], len(frames)
    store._write_index(state)
    return store


def _tmp(path: Path) -> Path:
    return path.with_name(path.name + ".tmp")


def _remove(path: Path) -> None:
    with contextlib.suppress(FileNotFoundError):
        path.unlink()


def take_run_dir(out: str | os.PathLike, *, force: bool = False, may_hold: frozenset[str] = frozenset(), hint: str = "use --force to overwrite or --resume to continue",
                 option: str = "--out") -> Path:
    """The run directory ``out``, made ready for a new run (the one place a run directory is taken).

    Refuses (`InputError` naming ``option``) a file, or a directory holding anything beyond
    ``may_hold`` unless ``force``; with ``force``, removes the results a run left there.
    """
    out = check_out_dir(out, force, may_hold=may_hold, hint=hint, option=option)
    out.mkdir(parents=True, exist_ok=True)
    _remove(out / RESULTS_NAME)
    _remove(_tmp(out / RESULTS_NAME))
    data = out / DATA_DIR
    if data.is_dir():
        for p in data.iterdir():
            p.unlink()
    return out


def check_out_dir(out: str | os.PathLike, force: bool, *, may_hold: frozenset[str] = frozenset(),
                  hint: str = "use --force to write into it", option: str = "--out") -> Path:
    """``out`` as a Path; an `InputError` naming ``option`` if it cannot be written (`check_writable`),
    or is a directory holding anything beyond ``may_hold`` (and a lock file) without ``force``."""
    from .rundir import LOCK_NAME, check_writable

    out = check_writable(out, option)
    if out.is_dir() and not force:
        entries = sorted(p.name for p in out.iterdir() if p.name != LOCK_NAME)
        if not set(entries) <= may_hold:
            shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
            raise InputError(f"{option} {out}: directory is not empty ({shown}); {hint}")
    return out


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename: a kill leaves the
    old file or the new one, never half of one."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_bytes_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename; if writing fails
    (a full disk), the temporary file is removed and ``path`` is as it was."""
    path = Path(path)
    tmp = _tmp(path)
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
        _commit(tmp, path)
    except BaseException:
        _remove(tmp)
        raise


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


class StoredGeometry(Geometry):
    """The geometry stored in a results file: ``positions (n, k)``, ``pairs (E, 2)``, ``t_i, t_j (E, d)``.

    What a run built in Python on a geometry without a spec continues on: the same
    contact arrays, so the same bits.
    """

    def __init__(self, positions, pairs, t_i, t_j, radius: float = 1.0):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.radius = float(radius)
        e = len(pairs)
        units = np.empty((2 * e, np.shape(t_i)[1]))
        units[0::2], units[1::2] = t_i, t_j
        self._contacts = Contacts.build(pairs, np.arange(2 * e).reshape(e, 2), units)

    def _build_contacts(self) -> Contacts:
        return self._contacts


@dataclass(eq=False)
class Results:
    """A run read back from its results file (finished, or the last checkpoint of an unfinished one).

    velocities ``(n, d)``, steps, collisions, rng_state, scheduler_state: the latest
    state (views of `state`'s single copy); positions ``(n, k)``,
    pairs ``(E, 2)``, t_i / t_j ``(E, d)``: the geometry; snapshots: list of
    `Snapshot` ``(step, collisions, velocities (n, d))``; observables: dict of
    per-snapshot columns (``steps, collisions (F,)`` and the recorded observables).
    spec: the `RunSpec`, or None for a run built in Python, which ``run`` describes
    (``geometry``, ``rule``, ``scheduler``: spec dicts where known, else ``{"class": ...}``).
    """

    path: Path
    spec: RunSpec | None
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
    run: dict = field(default_factory=dict, repr=False)
    format_version: int = FORMAT_VERSION
    radius: float = 1.0

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

    @property
    def kinds(self) -> dict[str, str]:
        """``geometry``, ``initial``, ``rule``, ``scheduler``: the kind of each component (or its class)."""
        if self.spec is not None:
            return {k: getattr(self.spec, k).kind for k in ("geometry", "initial", "rule", "scheduler")}
        return {k: v.get("kind") or v.get("class", "?") for k, v in self.run.items() if isinstance(v, dict)}

    @functools.cached_property
    def geometry(self) -> Geometry:
        """The run's geometry: rebuilt from the spec (from the stored positions for ``graph_positions``),
        or from the stored contacts for a run built in Python on a geometry without a spec."""
        from .specs.geometry import geometry_from_stored

        if self.spec is not None:
            return geometry_from_stored(self.spec.geometry, self.positions)
        described = self.run.get("geometry", {})
        if "kind" in described:
            return geometry_from_stored(_geometry_spec(described), self.positions)
        return StoredGeometry(self.positions, self.pairs, self.t_i, self.t_j, self.radius)

    def state(self) -> dict:
        """The latest state in the form of `Simulation.get_state`."""
        return {k: np.copy(v) if isinstance(v, np.ndarray) else v for k, v in self.raw_state.items()}

    def simulation(self, *, rule=None, scheduler=None) -> Simulation:
        """A `Simulation` at the latest state, ready to go on exactly where this run stopped.

        A run built in Python with a rule or scheduler that has no spec needs them given.
        """
        if self.spec is not None:
            sim = self.spec.build_with(self.geometry, self.initial_velocities, self.masses)
        else:
            from .specs import RuleSpec, SchedulerSpec

            rule = rule if rule is not None else _component(self.run.get("rule", {}), RuleSpec, "rule")
            scheduler = scheduler if scheduler is not None else \
                _component(self.run.get("scheduler", {}), SchedulerSpec, "scheduler")
            sim = Simulation(self.geometry, self.initial_velocities, rule=rule, scheduler=scheduler,
                             masses=self.masses, seed=0)
        sim.set_state(self.state())
        return sim

    def animate(self, out=None, fps: float = 4) -> Path:
        """A movie of this run's snapshots (default ``<run dir>/movie.gif``); see `pinnedballs.animation.animate`."""
        from .animation import animate

        return animate(self, out, fps)

    def __repr__(self) -> str:
        return (f"Results({str(self.path)!r}, {self.status}, steps={self.steps}, collisions={self.collisions}, "
                f"snapshots={len(self.snapshots)}, frozen={self.frozen})")


def _geometry_spec(described: dict):
    from pydantic import TypeAdapter

    from .specs import GeometrySpec

    return TypeAdapter(GeometrySpec).validate_python(described)


def _component(described: dict, slot, name: str):
    """The rule or scheduler a Python run described as a spec dict; a ValueError naming ``name`` if it has none."""
    from pydantic import TypeAdapter

    if "kind" not in described:
        raise ValueError(f"{name}: this run used {described.get('class', 'a component')}, which has no spec; "
                         f"pass {name}= to simulation()")
    return TypeAdapter(slot).validate_python(described).build()


def load(path: str | os.PathLike) -> Results:
    """Read a results file, or ``DIR/results.h5`` given a run directory.

    Raises FileNotFoundError if there is none, `ResultsError` (a ValueError) if the
    file is not a pinnedballs results file or is damaged; both name the path.
    """
    p = results_path(path)
    if not p.exists():
        where = f"{path}: no {RESULTS_NAME} in this directory" if Path(path).is_dir() else f"{p}: no such file"
        raise FileNotFoundError(where)
    with _open_checked(p) as f:
        try:
            return _read(p, f)
        except (KeyError, OSError) as exc:
            raise ResultsError(f"{p}: damaged results file ({exc})") from None


def _open_checked(p: Path) -> h5py.File:
    """The results file ``p`` opened for reading, after checking it is one this version reads,
    that every file it refers to is there, and its structure (`check_results`): the one place
    results files are opened."""
    try:
        f = h5py.File(p, "r")
    except OSError as exc:
        raise ResultsError(f"{p}: not a readable HDF5 file (truncated or not HDF5): {exc}") from None
    try:
        if f.attrs.get("format") != FORMAT:
            raise ResultsError(f"{p}: not a pinnedballs results file (no format={FORMAT!r} attribute)")
        version = int(f.attrs.get("format_version", -1))
        if version > FORMAT_VERSION:
            raise ResultsError(f"{p}: written by a newer pinnedballs (format {f.attrs['format_version']}); upgrade")
        if version < 1:
            raise ResultsError(f"{p}: damaged results file: / (attribute format_version): must be 1 or 2, "
                               f"got {f.attrs.get('format_version')!r}")
        if version >= 2:
            data = _data_dir(p)
            try:
                needed = [STATIC_NAME, *(s[0] for s in json.loads(f.attrs["segments"]))]
            except (KeyError, ValueError, TypeError) as exc:
                raise ResultsError(f"{p}: damaged results file (no segment list: {exc})") from None
            missing = [name for name in needed if not (data / name).is_file()]
            if missing:
                raise ResultsError(f"{p}: damaged results file ({data / missing[0]} is missing)")
        check_results(p, f, _data_dir(p) if version >= 2 else None)
    except BaseException:
        f.close()
        raise
    return f


def _read(p: Path, f: h5py.File) -> Results:
    try:
        spec = RunSpec.model_validate_json(f.attrs["spec"]) if f.attrs["spec"] else None
    except ValueError as exc:
        raise ResultsError(f"{p}: its stored spec is not valid for this version of pinnedballs ({exc})") from None
    version = int(f.attrs["format_version"])
    s, g, o = f["state"], f["geometry"], f["observables"]
    raw = {k: s[k][()] if k in s else _scalar(s.attrs[k]) for k in json.loads(s.attrs["keys"])}
    frames = f["snapshots/velocities"][()]
    names = _V1_OBSERVABLES if version == 1 else json.loads(f.attrs["observables"])
    observables = {name: o[name][()] for name in names}
    steps, collisions = observables["steps"], observables["collisions"]
    return Results(
        path=p, spec=spec, version=str(f.attrs["version"]), status=str(f.attrs["status"]),
        stop_reason=str(f.attrs["stop_reason"]),
        energy=float(s.attrs["energy"]), momentum=s["momentum"][()], approaching=int(s.attrs["approaching"]),
        frozen=bool(s.attrs["frozen"]), positions=g["positions"][()], pairs=g["pairs"][()], t_i=g["t_i"][()], t_j=g["t_j"][()],
        masses=g["masses"][()] if "masses" in g else None,
        initial_velocities=f["initial/velocities"][()], initial_energy=float(f["initial"].attrs["energy"]),
        snapshots=[Snapshot(int(a), int(b), v) for a, b, v in zip(steps, collisions, frames)],
        observables=observables,
        elapsed_seconds=float(f.attrs["elapsed_seconds"]), checkpoints=int(f.attrs["checkpoints"]),
        created=str(f.attrs["created"]), updated=str(f.attrs["updated"]),
        raw_state=raw, run=json.loads(f.attrs.get("run", "") or "{}"), format_version=version,
        radius=float(g.attrs.get("radius", 1.0)),
    )


def _scalar(value):
    """An HDF5 attribute as a plain Python number."""
    return value.item() if isinstance(value, np.generic) else value
