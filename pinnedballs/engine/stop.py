"""`Stop`: when a run ends, as a predicate of the simulation's counters and its freeze.

The run driver (`pinnedballs.engine.driver`) runs to a `Stop`; a run spec's ``"stop"`` builds one
(`pinnedballs.specs.stop.StopSpec.build`).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Stop"]


@dataclass(frozen=True)
class Stop:
    """When a run ends, in absolute counts. Reasons are checked in the order collisions, frozen, steps.

    Parameters
    ----------
    steps : int or None
        Steps in total (the reason is ``steps_reason``).
    collisions : int or None
        Collisions in total.
    until_frozen : bool
        Right after the collision that freezes it.
    steps_reason : str
        The reason a run stopped at ``steps`` gives (``"max_steps"`` for a spec's run until frozen).

    Examples
    --------
    >>> import pinnedballs as pb
    >>> stop = pb.Stop(steps=1000, until_frozen=True)
    >>> g = pb.HalfPlane(rows=2, cols=2)
    >>> sim = pb.Simulation(g, [[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], seed=0)
    >>> stop.reason(sim, frozen=False), stop.reason(sim, frozen=True)
    ('', 'frozen')
    """

    steps: int | None = None
    collisions: int | None = None
    until_frozen: bool = False
    steps_reason: str = "steps"

    def reason(self, sim, frozen: bool) -> str:
        """Why the run is over.

        Parameters
        ----------
        sim : Simulation
            Its counters.
        frozen : bool
            Whether it is frozen.

        Returns
        -------
        str
            ``"collisions"``, ``"frozen"``, ``steps_reason``, or ``""`` (not over).
        """
        if self.collisions is not None and sim.collisions >= self.collisions:
            return "collisions"
        if frozen:
            return "frozen"
        if self.steps is not None and sim.steps >= self.steps:
            return self.steps_reason
        return ""
