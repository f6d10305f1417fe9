"""Writing a results file: `ResultsStore` creates a run directory's static data and index, appends
each checkpoint's snapshots as a segment and replaces the index (see `format` for the layout)."""

from __future__ import annotations

import json
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ..analysis import observables
from ..engine.state import RunState
from ..geometry.base import Geometry
from ..util.atomic import remove, tmp_path, write_bytes_atomic
from . import legacy
from .digest import seal
from .files import h5_image, scalar, virtual_rows
from .format import FORMAT, FORMAT_VERSION, STATE_KEYS, STATIC_NAME, Record, data_dir, results_path
from .load import open_checked, read
from .segments import write_segment, write_static

__all__ = ["ResultsStore"]


def _now() -> str:
    return time.strftime("%Y-%m-%dT%H:%M:%S%z")


@dataclass
class ResultsStore:
    """A results file open for appending: what the index lists, and how to add to it.

    `create` starts one, `reopen` continues one (removing what a kill left half-written);
    `checkpoint` appends frames as a new segment and replaces the index. A checkpoint changes
    this object only once both are on disk, and never stores a frame twice, so one that failed
    (a full disk, a signal) can simply be made again.
    """

    path: Path
    attrs: dict                      #: the index's root attributes
    shape: tuple[int, int]           #: (n_balls, dim)
    columns: dict                    #: name -> (dtype str, shape) of each observable
    segments: list = field(default_factory=list)  #: [file, first, count]
    frames: int = 0
    digests: dict = field(default_factory=dict)   #: file -> SHA-256 of static.h5 and each segment
    last_step: int = -1              #: the step of the last frame stored (-1: none)
    state: Record | None = None      #: the state the index holds
    #: (threshold, resolution) of the run, whose margin the index keeps; None: it keeps none (a run
    #: begun before runs kept their margin: its margin is unknown)
    criterion: tuple[float, float] | None = None
    #: the provenance of the run's earlier lives (`util.provenance`), as the index holds them, kept as they are
    lives: list = field(default_factory=list)
    #: the provenance of this life, written after them with each index (None: none yet)
    life: dict | None = None

    @property
    def data_dir(self) -> Path:
        return data_dir(self.path)

    @classmethod
    def create(cls, path: str | os.PathLike, *, spec: str, run: str, geometry: Geometry, masses,
               initial: Record, version: str, criterion: tuple[float, float] | None = None,
               device: str = "cpu", simulated: bool = False, life: dict | None = None) -> ResultsStore:
        """Write ``static.h5`` and an index with no snapshots. ``spec``: the run spec as JSON, or "";
        ``run``: JSON describing a run built in Python, or ""; ``criterion``: the simulation's
        ``(threshold, resolution)``, kept with the margin of each state that has one; ``device``: where the
        run goes, and ``simulated``: whether numba-cuda's simulator stood in for the GPU (information, in
        the attributes ``device`` and ``simulated``); ``life``: the provenance of this life (``/provenance``)."""
        path = Path(path)
        data = data_dir(path)
        data.mkdir(parents=True, exist_ok=True)
        static = write_static(data / STATIC_NAME, geometry, masses, initial)
        n, d = initial.state.velocities.shape
        now = _now()
        attrs = dict(format=FORMAT, format_version=FORMAT_VERSION, version=version, spec=spec, run=run,
                     status="running", stop_reason="", created=now, updated=now, elapsed_seconds=0.0,
                     checkpoints=0, checked=False, observables=json.dumps(list(initial.values)), device=device,
                     simulated=bool(simulated))
        columns = {k: (v.dtype.str, v.shape) for k, v in initial.values.items()}
        store = cls(path, attrs, (n, d), columns, digests={STATIC_NAME: static}, criterion=criterion, life=life)
        store.write_index(initial, attrs, store.segments, store.digests)
        store.state = initial
        return store

    @classmethod
    def reopen(cls, path: str | os.PathLike) -> ResultsStore:
        """The store of an existing results file, ready to append. A file of an older format goes on in
        format 3 (`legacy.upgrade`): a format-2 file gets the digests of its files (`digest`) with its next
        index, a format-1 file its data files and a format-3 index at once."""
        path = results_path(path)
        with open_checked(path) as f:
            res = read(path, f)
            if legacy.older(res.format_version):
                attrs, columns, segments, digests, written = legacy.upgrade(path, f, res)
            else:
                attrs = {k: scalar(v) for k, v in f.attrs.items()}
                segments = json.loads(f.attrs["segments"])
                columns = {name: (f["observables"][name].dtype.str, f["observables"][name].shape[1:])
                           for name in json.loads(f.attrs["observables"])}
                digests, written = json.loads(attrs.pop("digests")), False
        margin = res.closing_margin
        state = Record(res.state(), res.energy, res.momentum, res.approaching)
        store = cls(path, attrs, res.velocities.shape, columns, segments, sum(s[2] for s in segments), digests,
                    int(res.snapshots.steps[-1]) if len(res.snapshots) else -1, state,
                    None if margin is None else (margin.threshold, margin.resolution), res.provenance)
        store.remove_strays()
        if written:  # data files only an index of format 3 lists
            store.write_index(state, attrs, segments, digests)
        return store

    def checkpoint(self, frames: list[Record], state: Record, *, status: str = "running", stop_reason: str = "",
                   elapsed_seconds: float | None = None, checked: bool = True, failure: dict | None = None,
                   life: dict | None = None) -> None:
        """Append ``frames`` (as one new segment; those already stored are skipped) and replace the
        state: the new index is renamed over the old one only once the segment is on disk.
        ``status``: "running", "done", "interrupted" or "failed" (a run that cannot go on: ``failure``
        says why, in the attribute ``failure`` as JSON, see `format`); ``checked``: the snapshot trigger
        was checked at the state's counts; ``life``: this life's provenance now (None: as it was)."""
        if (status == "failed") != (failure is not None):
            raise ValueError("failure: a failed run's checkpoint says why, and only a failed run's")
        frames = [r for r in frames if r.state.steps > self.last_step]
        segments, digests, count = list(self.segments), dict(self.digests), self.frames
        if frames:
            name = f"frames_{count:09d}.h5"
            digests[name] = write_segment(self.data_dir / name, frames, list(self.columns))
            segments.append([name, count, len(frames)])
            count += len(frames)
        attrs = {k: v for k, v in self.attrs.items() if k != "failure"}
        attrs.update(status=status, stop_reason=stop_reason, updated=_now(),
                     checkpoints=int(self.attrs["checkpoints"]) + 1, checked=checked)
        if failure is not None:
            attrs["failure"] = json.dumps(failure)
        if elapsed_seconds is not None:
            attrs["elapsed_seconds"] = float(elapsed_seconds)
        life = self.life if life is None else life
        self.write_index(state, attrs, segments, digests, life)
        self.attrs, self.segments, self.digests, self.frames, self.state = attrs, segments, digests, count, state
        self.life = life
        if frames:
            self.last_step = frames[-1].state.steps

    def write_index(self, state: Record, attrs: dict, segments: list, digests: dict, life: dict | None = None) -> None:
        """Replace the index: ``attrs``, ``segments``, ``digests``, ``state``, and the provenance of the earlier
        lives with ``life`` (default: `life`) after them."""
        n, d = self.shape
        life = self.life if life is None else life
        lives = [*self.lives, *([] if life is None else [life])]
        rel = f"{self.data_dir.name}/"

        def fill(f: h5py.File) -> None:
            f.attrs.update(attrs)
            f.attrs["segments"] = json.dumps(segments)
            f.attrs["digests"] = json.dumps(digests)
            f["geometry"] = h5py.ExternalLink(rel + STATIC_NAME, "/geometry")
            f["initial"] = h5py.ExternalLink(rel + STATIC_NAME, "/initial")
            virtual_rows(f, "snapshots/velocities", "velocities", np.dtype(np.float64), (n, d), segments, rel)
            for name, (dtype, shape) in self.columns.items():
                virtual_rows(f, f"observables/{name}", f"observables/{name}", np.dtype(dtype), tuple(shape),
                             segments, rel)
            for name in observables.ALWAYS:
                f["snapshots"][name] = h5py.SoftLink(f"/observables/{name}")
            _write_state(f, state, self.criterion)
            if lives:  # one JSON text a life (`util.provenance`); files written before have none
                f.create_dataset("provenance", data=[json.dumps(x, sort_keys=True) for x in lives],
                                 dtype=h5py.string_dtype())

        write_bytes_atomic(self.path, seal(h5_image(fill)))

    def remove_strays(self) -> None:
        """Remove temporary files and segments the index does not list (left by a kill); what no run
        writes (a user's own file or folder) is left alone."""
        keep = {s[0] for s in self.segments} | {STATIC_NAME}
        for p in self.data_dir.iterdir():
            if p.name not in keep and _STRAY.fullmatch(p.name) and p.is_file():
                p.unlink()
        remove(tmp_path(self.path))


#: what a kill may leave in the data directory: a segment the index does not list, temporary files
_STRAY = re.compile(r"(static|frames_\d+)\.h5(\.tmp)?")


def _write_state(f: h5py.File, record: Record, criterion: tuple[float, float] | None) -> None:
    """``/state``: ``record``'s arrays as datasets, its counts as attributes, and its margin with the
    run's ``criterion`` (threshold, resolution) when it has one and the run keeps it."""
    s = f.create_group("state")
    state = record.state
    for name in RunState.ARRAYS:
        s[name] = getattr(state, name)
    s.attrs.update(steps=state.steps, collisions=state.collisions)
    s.attrs["keys"] = json.dumps(list(STATE_KEYS))  # what format 2 has always listed
    if state.exact is not None:  # a run in exact arithmetic: each component's coefficients, as text
        s.create_dataset("exact", data=np.asarray(state.exact, dtype=object), dtype=h5py.string_dtype())
    if state.certified is not None:  # a run in certified arithmetic: its fixed point and bounds
        c = s.create_group("certified")
        c["limbs"], c["bounds"] = state.certified.limbs, state.certified.bounds
        c.attrs.update(scale=state.certified.scale, rounding=state.certified.rounding,
                       bound_scale=state.certified.bound_scale,  # bounds in units of 2^-bound_scale
                       precision=state.certified.precision, late_precision=state.certified.late_precision)
        if state.certified.bound_batch:  # the batched bound rule (absent: the rule in step order, pinnedballs < 1.0)
            c.attrs.update(bound_batch=state.certified.bound_batch, bound_at=state.certified.bound_at,
                           pending=np.array(state.certified.pending, dtype=np.uint64),
                           unfolded=state.certified.unfolded)
        if state.certified.margin is not None:  # its decisions' margin (none: unknown, a run begun before it was kept)
            c.attrs["margin"] = np.asarray(state.certified.margin, dtype=np.float64)
    s["momentum"] = record.momentum
    s.attrs.update(energy=record.energy, approaching=record.approaching, frozen=record.frozen)
    if criterion is not None and state.margin is not None:
        s["margin"] = np.asarray(state.margin, dtype=np.float64)
        s["margin"].attrs.update(threshold=float(criterion[0]), resolution=float(criterion[1]))
