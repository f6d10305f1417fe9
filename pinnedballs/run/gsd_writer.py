"""`GSDWriter`: a run's snapshots as frames of a GSD trajectory (HOOMD-blue's schema), written as it runs.

::

    sim.run(steps=10**7, writers=[pb.GSDWriter("traj.gsd", snapshots=pb.EverySteps(10**5)),
                                  pb.ResultsWriter("DIR", snapshots={"every_steps": 10**5})])

Each frame is laid out as `pinnedballs.results.trajectory` says (positions, velocities, types,
box, observables under ``log/``) and flushed at once, so a kill loses no frame a checkpoint has
recorded: list the GSDWriter before the `ResultsWriter` (``pinnedballs run`` does). The state a run
stops in (its stop reached) is the last frame (``final=False``: the trigger's frames only). With
``resume=True`` frames are appended: the run continued from a checkpoint skips the frames the file
already holds, so none is written twice. ``pinnedballs run`` writes ``DIR/trajectory.gsd`` this
way when its spec has a ``"trajectory"``.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..analysis import observables as named
from ..engine.driver import Writer
from ..engine.triggers import Counts
from ..results.trajectory import Layout, Trajectory, check_speeds_fit, gsd_hoomd
from .writers import _trigger

__all__ = ["GSDWriter"]


def layout(sim) -> Layout:
    """The `Layout` of ``sim``'s frames; a `FieldError` on ``trajectory`` if its geometry or speeds
    do not fit a GSD file's 32-bit floats (`trajectory.check_speeds_fit`); a `MissingExtra` without gsd."""
    gsd_hoomd()
    check_speeds_fit(sim.velocities, sim.masses)
    return Layout.of(sim.geometry, sim.masses)


class GSDWriter(Writer):
    """Write a frame of a GSD trajectory at ``path`` each time ``snapshots`` fires (the module's docstring).

    Parameters
    ----------
    path : str or os.PathLike
        The trajectory file.
    snapshots : Trigger or dict
        A `Trigger` or a dict like a spec's ``"snapshots"`` (``{"every_steps": 1000}``, ...).
    observables : list of str, optional
        Names from `pinnedballs.analysis.observables.OBSERVABLES` logged with each frame (default: all built-ins).
    force : bool
        Replace an existing file.
    resume : bool
        Append to it, skipping the frames it already holds (the simulation continues the run that wrote them).
    final : bool
        Also write the state each run stops in (its stop reached; not a kill) unless a frame was just taken
        there; pass False when one run is split into several calls with this writer and the file must hold
        only the trigger's frames (as the run in one call writes them).
    hint : str
        What an error about an existing file advises.

    Raises
    ------
    ValueError
        On ``force`` with ``resume``, or no ``snapshots``.
    pinnedballs.util.extras.MissingExtra
        Without gsd, naming the extra that installs it.

    Examples
    --------
    >>> import numpy as np
    >>> import gsd.hoomd
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, seed=1)
    >>> sim.run_until_frozen(100_000, writers=[pb.GSDWriter("traj.gsd", {"every_steps": 200})])
    True
    >>> with gsd.hoomd.open("traj.gsd") as frames:
    ...     [int(f.configuration.step) for f in frames]
    [200, 400, 556]
    """

    def __init__(self, path: str | os.PathLike, snapshots, observables=None, *, force: bool = False,
                 resume: bool = False, final: bool = True,
                 hint: str = "pass force=True to replace it or resume=True to append to it"):
        if force and resume:
            raise ValueError("force, resume: give one of them, not both")
        gsd_hoomd()  # where a user first asks for a trajectory: the extra named at once
        self.path = Path(path)
        self.trigger = _trigger(snapshots)
        if self.trigger is None:
            raise ValueError("snapshots: a GSDWriter needs a trigger, e.g. {'every_steps': 1000}")
        self.names = named.check_names(named.DEFAULT if observables is None else observables)
        self.force, self.resume, self.final, self.hint = force, resume, bool(final), hint
        self.file: Trajectory | None = None
        self._started = False       #: a run has opened the file (later runs append to it)
        self._checked: Counts | None = None

    def attach(self, sim) -> Counts | None:
        """Open the file: a new one, or appended to (`Writer.attach`).

        Parameters
        ----------
        sim : Simulation
            The simulation run.

        Returns
        -------
        tuple of int or None
            The counts at which the trigger was already checked (a resumed run whose state is on disk), else None.

        Raises
        ------
        FieldError
            On ``trajectory``, where the geometry or the speeds do not fit a GSD file's 32-bit floats.
        """
        resume = self.resume or self._started
        self.file = Trajectory.open(self.path, layout(sim), force=self.force and not resume, resume=resume,
                                    hint=self.hint)
        if not self._started and self.resume and self.file.last_steps is not None:
            # the run stopped after this state was checked (this writer fires before a checkpoint)
            self._checked = (sim.steps, sim.collisions)
        self._started = True
        checked, self._checked = self._checked, None
        return checked if checked == (sim.steps, sim.collisions) else None

    def write(self, sim) -> None:
        """Append a frame of the current state (`Writer.write`).

        Parameters
        ----------
        sim : Simulation
            The simulation, at the frame's count.
        """
        self.file.append(sim.steps, sim.velocities, named.measure(sim, self.names))

    def finish(self, sim, reason: str) -> None:
        """The run reached its stop: its state is the last frame (``final``; `Trajectory.append` skips a
        state already on disk).

        Parameters
        ----------
        sim : Simulation
            The simulation, at its stop.
        reason : str
            Why it stopped.
        """
        if self.final:
            self.write(sim)
        self._checked = (sim.steps, sim.collisions)
        self.close()

    def close(self) -> None:
        """Close the file (a later run with this writer appends to it)."""
        if self.file is not None:
            self.file.close()
            self.file = None
