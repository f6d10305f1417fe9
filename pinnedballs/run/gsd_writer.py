"""`GSDWriter`: a run's snapshots as frames of a GSD trajectory (HOOMD-blue's schema), written as it runs.

::

    sim.run(steps=10**7, writers=[pb.GSDWriter("traj.gsd", snapshots=pb.EverySteps(10**5)),
                                  pb.ResultsWriter("DIR", snapshots={"every_steps": 10**5})])

Each frame is laid out as `pinnedballs.results.trajectory` says (positions, velocities, types,
box, observables under ``log/``) and flushed at once, so a kill loses no frame a checkpoint has
recorded: list the GSDWriter before the `ResultsWriter` (``pinnedballs run`` does). With
``resume=True`` frames are appended: the run continued from a checkpoint skips the frames the file
already holds, so none is written twice. ``pinnedballs run`` writes ``DIR/trajectory.gsd`` this
way when its spec has a ``"trajectory"``.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..analysis import observables as named
from ..results.trajectory import Layout, Trajectory
from ..engine.driver import Writer
from .triggers import Counts
from .writers import _trigger

__all__ = ["GSDWriter"]


class GSDWriter(Writer):
    """Write a frame of a GSD trajectory at ``path`` each time ``snapshots`` fires.

    snapshots: a `Trigger` or a dict like a spec's ``"snapshots"`` (``{"every_steps": 1000}``, ...).
    observables: names from `pinnedballs.analysis.observables.OBSERVABLES` logged with each frame
    (default: all built-ins). force: replace an existing file; resume: append to it, skipping the
    frames it already holds (the simulation continues the run that wrote them). ``hint``: what an
    error about an existing file advises.
    """

    def __init__(self, path: str | os.PathLike, snapshots, observables=None, *, force: bool = False,
                 resume: bool = False, hint: str = "pass force=True to replace it or resume=True to append to it"):
        if force and resume:
            raise ValueError("force, resume: give one of them, not both")
        self.path = Path(path)
        self.trigger = _trigger(snapshots)
        if self.trigger is None:
            raise ValueError("snapshots: a GSDWriter needs a trigger, e.g. {'every_steps': 1000}")
        self.names = named.check_names(named.DEFAULT if observables is None else observables)
        self.force, self.resume, self.hint = force, resume, hint
        self.file: Trajectory | None = None
        self._started = False       #: a run has opened the file (later runs append to it)
        self._checked: Counts | None = None

    def attach(self, sim) -> Counts | None:
        resume = self.resume or self._started
        self.file = Trajectory.open(self.path, Layout.of(sim.geometry, sim.masses), force=self.force and not resume,
                                    resume=resume, hint=self.hint)
        if not self._started and self.resume and self.file.last_steps is not None:
            # the run stopped after this state was checked (this writer fires before a checkpoint)
            self._checked = (sim.steps, sim.collisions)
        self._started = True
        checked, self._checked = self._checked, None
        return checked if checked == (sim.steps, sim.collisions) else None

    def write(self, sim) -> None:
        self.file.append(sim.steps, sim.velocities, named.measure(sim, self.names))

    def finish(self, sim, reason: str) -> None:
        self._checked = (sim.steps, sim.collisions)
        self.close()

    def close(self) -> None:
        """Close the file (a later run with this writer appends to it)."""
        if self.file is not None:
            self.file.close()
            self.file = None
