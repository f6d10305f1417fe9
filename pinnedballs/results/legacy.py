"""Results files of formats 1 and 2, read and brought to format 3: the one module that knows them.

Format 2 is format 3 without the digests (of the index, the static file and each segment) and without the
statuses "interrupted" and "failed". Format 1 is a single file, copied whole at each checkpoint: its snapshots'
velocities in the file itself (``/snapshots/velocities (F, n, d)``), the observables `OBSERVABLES` and no
``run``, ``checked``, ``observables`` or ``segments`` attributes. Both load: `check_index` and `scan_frames`
check them for `check.check_results`, `observable_names` and `frame_files` say where `load.read` finds their
data. Continuing such a run goes on in format 3 (`upgrade`, for `store.ResultsStore.reopen`): a format-2 run
gets the digests of its files, a format-1 run its static file and one segment written beside it.

The rest of the package reads and writes format 3 alone, asking `older` first.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import h5py
import numpy as np

from ..engine.state import RunState
from ..geometry.graph import StoredGeometry
from .digest import file_digest
from .files import scalar
from .format import FORMAT_VERSION, STATIC_NAME, Record, data_dir
from .frames import FrameFile
from .index import (
    ROOT,
    Damage,
    check_attributes,
    check_links,
    check_provenance,
    check_sources,
    data_files,
    segment_list,
)
from .segments import write_segment, write_static

__all__ = ["OBSERVABLES", "older", "check_index", "scan_frames", "observable_names", "frame_files", "Upgrade",
           "upgrade"]

#: the observables a format-1 file records, in its order
OBSERVABLES = ("steps", "collisions", "energy", "momentum", "approaching")
#: what ``status`` may say before format 3
_STATUSES = ("running", "done")
#: the root attributes of each older format: format 3's less the digests, and format 1's less what segments
#: and recorded observables brought
_ROOT = {2: {k: v for k, v in ROOT.items() if k != "digests"},
         1: {k: v for k, v in ROOT.items() if k not in ("digests", "run", "checked", "observables", "segments")}}
#: the snapshot velocities `scan_frames` holds at once
_SCAN_BYTES = 16 << 20


def older(version: int) -> bool:
    """True for a format before the current one (1 or 2), which this module reads."""
    return version < FORMAT_VERSION


def check_index(p: Path, f: h5py.File, version: int, sealed: bool) -> None:
    """What the index of a format-1 or -2 file ``f`` (at ``p``) says of itself, as `check.check_results` checks
    format 3's: no digest (``sealed`` False), the attributes of its format, its provenance, and (format 2) its
    static file and segments present, each with the rows the index says, under its virtual datasets."""
    if sealed:
        raise Damage("/ (attribute format_version)", f"is {version}, but the index has the digest of format 3")
    check_attributes(f, _ROOT[version], _STATUSES)
    check_provenance(f)
    if version == 2:
        data, segments = data_files(p, f)
        check_sources(segments, data)
        check_links(f, data, segments, json.loads(f.attrs["observables"]))


def scan_frames(f: h5py.File) -> None:
    """Every snapshot's velocities are finite, read a few frames at a time (bounded memory): no digest vouches
    for the frames of formats 1 and 2 (`frames.Snapshots` checks format 3's as it reads each)."""
    frames = f["snapshots/velocities"]
    rows = max(1, _SCAN_BYTES // max(1, 8 * int(np.prod(frames.shape[1:]))))
    for start in range(0, frames.shape[0], rows):
        if not np.isfinite(frames[start:start + rows]).all():
            raise Damage("snapshots/velocities", "holds non-finite values (NaN or inf)")


def observable_names(f: h5py.File, version: int) -> list[str]:
    """The observables the file records: format 1's fixed `OBSERVABLES`, or those format 2 lists."""
    return list(OBSERVABLES) if version == 1 else json.loads(f.attrs["observables"])


def frame_files(p: Path, f: h5py.File, version: int) -> list[FrameFile]:
    """Where each snapshot's velocities are: a format-1 file itself, or format 2's segments (as format 3's)."""
    if version == 1:
        return [FrameFile.at(p, "snapshots/velocities", 0, len(f["snapshots/velocities"]))]
    data = data_dir(p)
    return [FrameFile.at(data / name, "velocities", first, count) for name, first, count in segment_list(f)]


class Upgrade(NamedTuple):
    """An older run as format 3 continues it: the index's root ``attrs`` (format 3's), the ``columns``
    (name -> (dtype str, shape)) of its observables, its ``segments`` ``[file, first, count]`` and the
    ``digests`` of its data files; ``written``: files were written beside it (format 1's static file and
    segment), which only an index of format 3 lists, to be written at once."""

    attrs: dict
    columns: dict
    segments: list
    digests: dict
    written: bool


def upgrade(p: Path, f: h5py.File, res) -> Upgrade:
    """The older run in the open, checked file ``f`` (at ``p``; ``res``: its `load.Results`) as format 3 goes on
    with it: format 2's files get their digests, format 1's static data and frames are written as format 3's
    files beside it (``static.h5``, one segment) and ``f`` is closed."""
    attrs = {k: scalar(v) for k, v in f.attrs.items()}
    attrs["format_version"] = FORMAT_VERSION
    if res.format_version == 2:
        segments = json.loads(f.attrs["segments"])
        columns = {name: (f["observables"][name].dtype.str, f["observables"][name].shape[1:])
                   for name in json.loads(f.attrs["observables"])}
        data = data_dir(p)
        return Upgrade(attrs, columns, segments,
                       {name: file_digest(data / name) for name in [STATIC_NAME, *(s[0] for s in segments)]}, False)
    return _format_1(p, f, res, attrs)


def _format_1(p: Path, f: h5py.File, res, attrs: dict) -> Upgrade:
    """A format-1 run's static file and its frames, as one segment, written as format 3's (``f`` closed first)."""
    names = list(OBSERVABLES)
    start = RunState(res.initial_velocities, 0, 0, res.rng_state, res.scheduler_state)
    initial = Record(start, res.initial_energy, f["initial/momentum"][()], int(f["initial"].attrs["approaching"]))
    geometry = StoredGeometry(res.positions, res.pairs, res.t_i, res.t_j)
    frames = [Record(RunState(s.velocities, s.steps, s.collisions, res.rng_state, res.scheduler_state), 0.0,
                     None, 0, {k: res.observables[k][i] for k in names}) for i, s in enumerate(res.snapshots)]
    f.close()
    data = data_dir(p)
    data.mkdir(exist_ok=True)
    digests = {STATIC_NAME: write_static(data / STATIC_NAME, geometry, res.masses, initial)}
    columns = {k: (res.observables[k].dtype.str, res.observables[k].shape[1:]) for k in names}
    attrs.update(run="", checked=True, observables=json.dumps(names))
    segments = []
    if frames:
        name = f"frames_{0:09d}.h5"
        digests[name] = write_segment(data / name, frames, names)
        segments = [[name, 0, len(frames)]]
    return Upgrade(attrs, columns, segments, digests, True)
