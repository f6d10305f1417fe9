"""Writing a results file: `ResultsStore` creates a run directory's static data and index, appends
each checkpoint's snapshots as a segment and replaces the index (see `format` for the layout)."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ..analysis import observables
from ..geometry.base import Geometry
from ..geometry.graph import StoredGeometry
from ..simulation import RunState
from .files import h5_file, remove, tmp_path, virtual_rows
from .format import FORMAT, FORMAT_VERSION, STATE_KEYS, STATIC_NAME, V1_OBSERVABLES, Record, data_dir, results_path
from .load import open_checked, read, scalar

__all__ = ["ResultsStore"]


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


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
        return data_dir(self.path)

    @classmethod
    def create(cls, path: str | os.PathLike, *, spec: str, run: str, geometry: Geometry, masses,
               initial: Record, version: str) -> "ResultsStore":
        """Write ``static.h5`` and an index with no snapshots. ``spec``: the run spec as JSON, or "";
        ``run``: JSON describing a run built in Python, or ""."""
        path = Path(path)
        data = data_dir(path)
        data.mkdir(parents=True, exist_ok=True)
        _write_static(data / STATIC_NAME, geometry, masses, initial)
        n, d = initial.state.velocities.shape
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
        with open_checked(path) as f:
            version = int(f.attrs["format_version"])
            if version == 1:
                return _convert_v1(path, f)
            attrs = {k: scalar(v) for k, v in f.attrs.items()}
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
        with h5_file(self.path) as f:
            f.attrs.update(self.attrs)
            f.attrs["segments"] = json.dumps(self.segments)
            f["geometry"] = h5py.ExternalLink(rel + STATIC_NAME, "/geometry")
            f["initial"] = h5py.ExternalLink(rel + STATIC_NAME, "/initial")
            virtual_rows(f, "snapshots/velocities", "velocities", np.dtype(np.float64), (n, d), self.segments, rel)
            for name, (dtype, shape) in self.columns.items():
                virtual_rows(f, f"observables/{name}", f"observables/{name}", np.dtype(dtype), tuple(shape),
                         self.segments, rel)
            for name in observables.ALWAYS:
                f["snapshots"][name] = h5py.SoftLink(f"/observables/{name}")
            _write_state(f, state)

    def _remove_strays(self) -> None:
        """Remove temporary files and segments the index does not list (left by a kill)."""
        keep = {s[0] for s in self.segments} | {STATIC_NAME}
        for p in self.data_dir.iterdir():
            if p.name not in keep:
                p.unlink()
        remove(tmp_path(self.path))


def _write_static(path: Path, geometry: Geometry, masses, initial: Record) -> None:
    """The geometry (with its boundary, frames and view: all that reading the run needs) and the
    initial state."""
    n = geometry.n_balls
    with h5_file(path) as f:
        g = f.create_group("geometry")
        c = geometry.contacts
        g["positions"] = geometry.positions
        g["pairs"] = np.ascontiguousarray(c.pairs)
        g["t_i"], g["t_j"] = c.t_i, c.t_j
        g.attrs["radius"] = float(getattr(geometry, "radius", 1.0))
        g.attrs["view"] = geometry.view
        boundary = geometry.boundary
        if boundary is not None:
            g["boundary_distance"], g["boundary_outward"] = boundary.distance, boundary.outward
        if geometry.curved:
            g["frames"] = np.ascontiguousarray(geometry.frames())
        if masses is not None:
            g["masses"] = np.broadcast_to(np.asarray(masses, dtype=np.float64), (n,))
        i = f.create_group("initial")
        i["velocities"] = initial.state.velocities
        i["momentum"] = initial.momentum
        i.attrs.update(energy=initial.energy, approaching=initial.approaching)


def _write_segment(path: Path, frames: list[Record], names: list[str]) -> None:
    with h5_file(path) as f:
        f["velocities"] = np.stack([r.state.velocities for r in frames])
        for name in names:
            f[f"observables/{name}"] = np.stack([np.asarray(r.values[name]) for r in frames])


def _write_state(f: h5py.File, record: Record) -> None:
    """Replace ``/state`` by ``record``: arrays as datasets, counts as attributes."""
    if "state" in f:
        del f["state"]
    s = f.create_group("state")
    state = record.state
    for name in RunState.ARRAYS:
        s[name] = getattr(state, name)
    s.attrs.update(steps=state.steps, collisions=state.collisions)
    s.attrs["keys"] = json.dumps(list(STATE_KEYS))  # what format 2 has always listed
    if state.exact is not None:  # a run in exact arithmetic: each component's coefficients, as text
        s.create_dataset("exact", data=np.asarray(state.exact, dtype=object), dtype=h5py.string_dtype())
    s["momentum"] = record.momentum
    s.attrs.update(energy=record.energy, approaching=record.approaching, frozen=record.frozen)


def _convert_v1(path: Path, f: h5py.File) -> "ResultsStore":
    """A format-1 file rewritten as format 2 (static data, one segment of its frames, the index)."""
    res = read(path, f)
    n, d = res.velocities.shape
    names = list(V1_OBSERVABLES)
    start = RunState(res.initial_velocities, 0, 0, res.rng_state, res.scheduler_state)
    initial = Record(start, res.initial_energy, f["initial/momentum"][()], int(f["initial"].attrs["approaching"]))
    geometry = StoredGeometry(res.positions, res.pairs, res.t_i, res.t_j)
    state = Record(res.state(), res.energy, res.momentum, res.approaching)
    frames = [Record(RunState(s.velocities, s.steps, s.collisions, res.rng_state, res.scheduler_state), 0.0,
                     None, 0, {k: res.observables[k][i] for k in names}) for i, s in enumerate(res.snapshots)]
    attrs = {k: scalar(v) for k, v in f.attrs.items()}
    f.close()
    data = data_dir(path)
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
