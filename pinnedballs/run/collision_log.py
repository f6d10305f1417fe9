"""`CollisionLog`: the step and the contact of every collision of a run, appended to an HDF5 file.

::

    log = pb.CollisionLog("events.h5")
    sim.run(steps=10**7, writers=[log, pb.ResultsWriter("DIR", ...)])
    ev = pb.CollisionLog.read("events.h5")      # {"step": (C,) int64, "contact": (C,) int64}

The engine tells the log of every collision (`Simulation.collision_listeners`); between chunks
the log appends what it heard as a *segment* (``events.data/events_<first>.h5``, written to a
temporary name and renamed) and replaces the small index ``events.h5`` (virtual datasets
``step`` and ``contact`` over the segments, and the step the log is complete to), as the
results files do: a kill at any moment leaves the last complete index. With ``resume=True`` the
log continues a run resumed from a checkpoint: events after the simulation's step (recorded after
that checkpoint) are dropped, so none is lost or doubled. Replaying ``ev["contact"]`` with
`pinnedballs.Replay` from the same start reproduces the run's velocities bit for bit.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import h5py
import numpy as np

from ..engine.driver import Writer
from ..results.files import h5_image, virtual_rows
from ..util.atomic import write_bytes_atomic
from ..util.errors import FieldError, InputError

__all__ = ["CollisionLog", "FORMAT"]

#: the index's ``format`` attribute
FORMAT = "pinnedballs-collision-log"
#: a segment is written once this many collisions are waiting (and at every chunk's end)
SEGMENT_EVENTS = 1 << 20


class CollisionLog(Writer):
    """Record ``(step, contact)`` of every collision into the index file ``path`` (see the module docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The index file (its segments go to ``<stem>.data/`` beside it).
    force : bool
        Replace a log already at ``path``.
    resume : bool
        Continue it (the simulation must be at a step the log has reached: a checkpoint of the same run).

    Raises
    ------
    FieldError
        On ``force`` with ``resume``.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, seed=1)
    >>> sim.run_until_frozen(100_000, writers=[pb.CollisionLog("events.h5")])
    True
    >>> ev = pb.CollisionLog.read("events.h5")
    >>> len(ev["step"]), ev["step"][:3].tolist(), ev["complete_to"]
    (50, [40, 80, 91], 556)
    >>> again = pb.Simulation(g, v, scheduler=pb.Replay(ev["contact"]))
    >>> again.run(steps=len(ev["contact"])), bool((again.velocities == sim.velocities).all())
    (50, True)
    """

    def __init__(self, path: str | os.PathLike, *, force: bool = False, resume: bool = False):
        if force and resume:
            raise FieldError("force, resume", "give one of them, not both")
        self.path, self.force, self.resume = Path(path), force, resume
        self.data = self.path.with_name(self.path.stem + ".data")
        self.segments: list[list] = []     #: [file, first, count]
        self.pending: list[tuple[np.ndarray, np.ndarray]] = []
        self.complete_to = 0               #: the step to which every collision is recorded
        self._sim, self._opened = None, False

    # ------------------------------------------------------------ the driver's calls
    def attach(self, sim) -> None:
        """Open the log and listen to ``sim``'s collisions (`Writer.attach`).

        Parameters
        ----------
        sim : Simulation
            The simulation run (at its start, or at a step the log has reached with ``resume``).

        Raises
        ------
        InputError
            Naming the file: a log already there (without ``force`` or ``resume``), a simulation past its
            start (a new log would miss its collisions) or at a step the log has not reached.
        """
        if self._sim is None:
            if not self._opened:
                self._open(sim)
                self._opened = True
            elif sim.steps != self.complete_to:  # the same log carried on to another run
                raise InputError(f"{self.path}: the log is complete to step {self.complete_to:,}, but this "
                                 f"simulation is at step {sim.steps:,}")
            sim.collision_listeners.append(self)
            self._sim = sim
        return None

    def __call__(self, steps: np.ndarray, contacts: np.ndarray) -> None:
        """The engine heard collisions: ``steps, contacts (C,) int64``."""
        self.pending.append((steps, contacts))
        if sum(len(s) for s, _ in self.pending) >= SEGMENT_EVENTS:
            self._flush(self._sim.steps)

    def after_chunk(self, sim) -> None:
        """Append what it heard as a segment (`Writer.after_chunk`).

        Parameters
        ----------
        sim : Simulation
            The simulation, between two chunks.
        """
        self._flush(sim.steps)

    def finish(self, sim, reason: str) -> None:
        """Append what it heard and stop listening (`Writer.finish`).

        Parameters
        ----------
        sim : Simulation
            The simulation, at its stop.
        reason : str
            Why it stopped.
        """
        self._flush(sim.steps)
        self.close()

    def close(self) -> None:
        """Stop listening (the file stays complete to the last flushed step)."""
        if self._sim is not None:
            self._sim.collision_listeners.remove(self)
            self._sim = None

    def to_spec(self) -> dict:
        """What this writer records, for the run's description.

        Returns
        -------
        dict
            ``{"collision_log": path}``.
        """
        return {"collision_log": str(self.path)}

    # ------------------------------------------------------------ reading
    @staticmethod
    def read(path: str | os.PathLike) -> dict[str, np.ndarray]:
        """Read a log.

        Parameters
        ----------
        path : str or os.PathLike
            Its index file.

        Returns
        -------
        dict
            ``{"step": (C,) int64, "contact": (C,) int64}``, and ``"complete_to"``: the step to which it holds
            every collision.

        Raises
        ------
        InputError
            Naming the file if it is not one, or is damaged.
        """
        path = Path(path)
        try:
            with h5py.File(path, "r") as f:
                if f.attrs.get("format") != FORMAT:
                    raise InputError(f"{path}: not a pinnedballs collision log")
                out = {name: f[name][()].astype(np.int64) for name in ("step", "contact")}
                out["complete_to"] = int(f.attrs["complete_to"])
        except (OSError, KeyError, ValueError) as exc:
            raise InputError(f"{path}: not a readable collision log ({' '.join(str(exc).split())})") from None
        if len(out["step"]) != len(out["contact"]) or (np.diff(out["step"]) <= 0).any():
            raise InputError(f"{path}: damaged collision log (steps out of order)")
        return out

    # ------------------------------------------------------------ the files
    def _open(self, sim) -> None:
        if self.path.exists() and self.resume:
            self._continue(sim)
            return
        if self.path.exists() and not self.force:
            raise InputError(f"{self.path}: a collision log is already there; pass force=True to replace it "
                             f"or resume=True to continue it")
        if sim.steps != 0 and not self.force:
            raise InputError(f"{self.path}: the simulation is at step {sim.steps:,}, not at its start: a new log "
                             f"would miss its earlier collisions (pass force=True to log from here)")
        self.data.mkdir(parents=True, exist_ok=True)
        for p in self.data.iterdir():
            p.unlink()
        self.complete_to = sim.steps
        self.write_index()

    def _continue(self, sim) -> None:
        """Keep the events up to ``sim.steps`` (a log ahead of the checkpoint resumed from drops the rest)."""
        with h5py.File(self.path, "r") as f:
            self.segments = json.loads(f.attrs["segments"])
            self.complete_to = int(f.attrs["complete_to"])
        if self.complete_to < sim.steps:
            raise InputError(f"{self.path}: the log is complete to step {self.complete_to:,} but the simulation is "
                             f"at step {sim.steps:,}: the collisions in between were never recorded")
        kept = []
        for name, first, count in self.segments:
            with h5py.File(self.data / name, "r") as g:
                steps = g["step"][()]
            keep = int(np.searchsorted(steps, sim.steps, side="right"))
            if keep == count:
                kept.append([name, first, count])
            elif keep:
                with h5py.File(self.data / name, "r") as g:
                    contacts = g["contact"][:keep]
                self._write_segment(f"events_{first:012d}_{keep}.h5", steps[:keep], contacts)
                kept.append([f"events_{first:012d}_{keep}.h5", first, keep])
        self.segments, self.complete_to = kept, sim.steps
        self.write_index()
        listed = {s[0] for s in self.segments}
        for p in self.data.iterdir():
            if p.name not in listed:
                p.unlink()

    def _flush(self, step: int) -> None:
        """Append the waiting events as a segment and record that the log is complete to ``step``."""
        if not self.pending and step == self.complete_to:
            return
        if self.pending:
            steps = np.concatenate([s for s, _ in self.pending])
            contacts = np.concatenate([c for _, c in self.pending])
            first = sum(s[2] for s in self.segments)
            name = f"events_{first:012d}.h5"
            self._write_segment(name, steps, contacts)
            self.segments.append([name, first, len(steps)])
            self.pending = []
        self.complete_to = step
        self.write_index()

    def _write_segment(self, name: str, steps: np.ndarray, contacts: np.ndarray) -> None:
        def fill(f: h5py.File) -> None:
            f["step"], f["contact"] = steps.astype(np.int64), contacts.astype(np.int64)

        write_bytes_atomic(self.data / name, h5_image(fill))

    def write_index(self) -> None:
        """Replace the index ``path`` (the segments and the step the log is complete to), atomically."""
        rel = f"{self.data.name}/"

        def fill(f: h5py.File) -> None:
            f.attrs.update(format=FORMAT, format_version=1, segments=json.dumps(self.segments),
                           complete_to=self.complete_to)
            for name in ("step", "contact"):
                virtual_rows(f, name, name, np.dtype(np.int64), (), self.segments, rel)

        write_bytes_atomic(self.path, h5_image(fill))
