"""The results format: one run directory per run, written append-only (`store`), read back with
`load.load`, checked before use (`check`).

A run directory holds ``results.h5``, a small *index*, and ``results.data/``:
``static.h5`` (written once) and one *segment* ``frames_<first>.h5`` per checkpoint
that had new snapshots. Layout of the index (``n`` balls, ``d`` velocity components,
``E`` contacts, ``F`` snapshots), format 3::

    (512 bytes)       the digest of the rest of the file (`digest`: an HDF5 user block)
    /                 attrs: format, format_version, version (package), spec (JSON, "" for a run
                             built in Python), run (JSON: what a Python run was built from),
                             status ("running" | "done" | "interrupted": stopped by an exception
                             or a signal, at the state saved here | "failed": stopped where it
                             cannot go on, at the state saved here), stop_reason, created, updated,
                             elapsed_seconds, checkpoints, checked (the snapshot trigger was
                             checked at the state's counts), observables (JSON names),
                             segments (JSON [[file, first, count], ...]),
                             digests (JSON {file: SHA-256} of static.h5 and every segment),
                             device ("cpu" | "cuda": where the run's last stretch ran; information only,
                             absent from files written before it was kept), simulated (true where
                             numba-cuda's simulator stood in for the GPU; absent from older files),
                             failure (a failed run's only: JSON {"error": the exception's class,
                             "message": its one line, "steps": the step the run stood at, "precision",
                             "late_precision": certified arithmetic's bits (0: none), "narrowed",
                             "remedy": what to do instead})
    /geometry         -> static.h5: positions (n, k), pairs (E, 2) int32, t_i (E, d), t_j (E, d),
                         masses (n,) [only if given], boundary_distance (n,) and boundary_outward
                         (n, d) [with a boundary], frames (n, d, k) [curved]; attrs radius, view,
                         rigid (`Geometry.rigid`, which a geometry read back from the file keeps;
                         absent from older files: false)
    /initial          -> static.h5: velocities (n, d), momentum (d,); attrs energy, approaching
    /snapshots        velocities (F, n, d); steps, collisions (links to /observables)
    /observables      one column per recorded observable (`pinnedballs.analysis.observables`): (F,) or (F, ...)
    /state            the latest state, enough to resume bit for bit: velocities (n, d),
                      rng_state (4,) uint64, scheduler_state (L,) int64, momentum (d,);
                      attrs steps, collisions, energy, approaching (-1, `index.UNKNOWN`: a failed
                      run whose live contacts certified arithmetic could not count), frozen;
                      margin (4,) float64 [a float run's]: its closing margin so far (`engine.margin`:
                      the smallest closing speed of a collision, inf before the first; the largest
                      positive one set aside; the counts within a factor 1e4 of the threshold), with
                      attrs threshold and resolution (the run's criterion);
                      exact (n, d, m) text [a run in exact arithmetic's]: its exact velocities;
                      certified [a run in certified arithmetic's] (`CertifiedState`): limbs
                      (n, d, m, P) uint64, bounds (n, 2, L); attrs scale, rounding, bound_scale,
                      precision, late_precision, margin (3,) float64: its decisions' closing margin
                      since the run began (the smallest closing speed of a collision, inf before the
                      first; the largest nonzero one set aside, -inf: none; the picks set aside at
                      closing speed exactly 0), absent from files written before it was kept and
                      from runs continued from them (unknown); bound_batch, bound_at, pending (2,)
                      uint64, unfolded: the batched bound rule's state (`CertifiedState`), absent from
                      files written before it (the step-order rule of pinnedballs < 1.0: they load, and do not resume)
    /provenance       (L,) text, absent from files written before runs kept it: one JSON object a life of the run
                      (the first, then each resumed one), how it was made (`pinnedballs.util.provenance`: versions,
                      command, host, CPU, the device and threads used, steps, started and ended); a resumed life
                      is appended, the earlier ones kept as they were written

``/geometry`` and ``/initial`` are external links, ``/snapshots`` and ``/observables``
virtual datasets over the segments, so ``h5py`` reads the index like one file.

Why segments and an index: a checkpoint writes only what is new (its frames, into a
segment written to a temporary name, flushed and renamed) and then replaces the index
(temporary file, flush, rename), so the bytes a run writes grow with its final size,
not with snapshots x size, and a kill at any moment leaves the last complete index,
whose segments all exist. A segment the index does not list (a kill between the two
renames) is removed when the run continues. An HDF5 file appended in place would be
smaller to describe but can be left unreadable by a kill in the middle of a write.

Formats 1 and 2 are `legacy`'s alone (format 2 is format 3 without the digests and the statuses "interrupted"
and "failed"; format 1 is a single file, copied whole at each checkpoint): both still load, and continuing such
a run goes on in format 3. A file written before runs kept their margin (of any format) has no
``/state/margin``: its margin is unknown (`Results.closing_margin` is None), and stays so when
the run is continued, whose later picks alone the margin could not speak for.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..analysis import observables
from ..engine.state import RunState
from ..util.errors import InputError

__all__ = ["FORMAT", "FORMAT_VERSION", "RESULTS_NAME", "DATA_DIR", "STATIC_NAME", "ResultsError", "Snapshot",
           "Record", "results_path", "data_dir", "STATE_KEYS", "failed_run"]

FORMAT = "pinnedballs-results"
FORMAT_VERSION = 3
RESULTS_NAME = "results.h5"
#: the directory beside the index holding ``static.h5`` and the segments
DATA_DIR = "results.data"
STATIC_NAME = "static.h5"
#: the fields of ``/state`` a results file holds (its attribute ``keys`` lists them)
STATE_KEYS = ("velocities", "steps", "collisions", "rng_state", "scheduler_state")


class ResultsError(InputError):
    """A results file that is not one, or is damaged."""


class Snapshot(NamedTuple):
    """The velocities ``(n_balls, dim)`` after ``steps`` steps and ``collisions`` collisions."""

    steps: int
    collisions: int
    velocities: np.ndarray

    @property
    def step(self) -> int:
        """Deprecated name of `steps` (the name `Results.steps` and run specs use); still works."""
        warnings.warn("Snapshot.step is deprecated: use Snapshot.steps", DeprecationWarning, stacklevel=2)
        return self.steps


@dataclass(frozen=True)
class Record:
    """A state and its observables, as the driver hands it to the writer.

    state: the `RunState`; energy, momentum ``(d,)``, approaching and frozen are measured on it;
    values: the selected observables by name.
    """

    state: RunState
    energy: float
    momentum: np.ndarray
    approaching: int
    values: dict = field(default_factory=dict)

    @classmethod
    def of(cls, sim, names=observables.DEFAULT) -> Record:
        """The current state of the `Simulation` ``sim`` and its observables ``names``."""
        values = observables.measure(sim, names)
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


def data_dir(path: Path) -> Path:
    """The directory of the static file and the segments beside the index ``path``."""
    return path.with_name(DATA_DIR) if path.name == RESULTS_NAME else path.with_name(path.stem + ".data")


def failed_run(failure: dict) -> str:
    """A failed run's ``failure`` (the attribute, `Results.failure`) in words: ``"failed at step 25,158 at 64 bits:
    certified arithmetic cannot decide contact ..."`` (what the file does not say is left out)."""
    def whole(key: str) -> int | None:
        value = failure.get(key)
        return int(value) if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else None

    steps, top, late = whole("steps"), whole("precision"), whole("late_precision")
    where = "" if steps is None else f" at step {steps:,}"
    if failure.get("narrowed") is True and late:
        where += f" at {late} bits behind the first wave"
    elif top:
        where += f" at {top} bits"
    said = failure.get("decision") or failure.get("message")
    return f"failed{where}" + (f": {' '.join(said.split())}" if isinstance(said, str) and said else "")
