"""`RunState`: all of a run that changes, as one record (what `Simulation.get_state` gives and
`set_state` takes, and what a results file keeps); `mass_array`, the masses a simulation uses;
`margin_problem`, what is wrong with a closing margin read back (`engine.margin`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..util.errors import FieldError, FieldTypeError
from .field.fixed_state import CertifiedState
from .margin import LARGEST, NEAR_COLLISIONS, NEAR_REMNANTS, SMALLEST

__all__ = ["RunState", "mass_array", "margin_problem"]


@dataclass(frozen=True, eq=False)
class RunState:
    """Everything that changes during a run: enough to resume it bit for bit (`Simulation.get_state`).

    Parameters
    ----------
    velocities : numpy.ndarray
        ``(n_balls, dim) float64``.
    steps, collisions : int
        The counts so far.
    rng_state : numpy.ndarray
        ``(4,) uint64``: the random stream.
    scheduler_state : numpy.ndarray
        ``(L,) int64``: the scheduler's own state.
    exact : numpy.ndarray or None
        For a run in exact arithmetic, the exact velocities as ``(n_balls, dim, m)`` strings, each velocity
        component's coefficients on its number field's basis (``velocities`` are then their roundings).
    margin : numpy.ndarray or None
        The closing margin so far, ``(4,) float64`` (`engine.margin`), of a float run (None: not kept, as in
        exact arithmetic or a results file written before margins were).
    certified : CertifiedState or None
        For a run in certified arithmetic, its fixed-point velocities, error bounds and the margin of its
        decisions (`pinnedballs.engine.field.fixed_state.CertifiedState`; ``velocities`` are their nearest
        floats).

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=2, cols=2)
    >>> sim = pb.Simulation(g, [[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], seed=0)
    >>> state = sim.get_state()
    >>> sim.run(steps=100)
    100
    >>> sim.set_state(state)
    >>> sim.steps, state.identical(sim.get_state())
    (0, True)
    """

    velocities: np.ndarray
    steps: int
    collisions: int
    rng_state: np.ndarray
    scheduler_state: np.ndarray
    exact: np.ndarray | None = None
    margin: np.ndarray | None = None
    certified: CertifiedState | None = None

    #: the arrays among the fields (the rest are counts)
    ARRAYS = ("velocities", "rng_state", "scheduler_state")

    def copy(self) -> RunState:
        """A copy whose arrays share no memory with this one's.

        Returns
        -------
        RunState
        """
        return RunState(self.velocities.copy(), self.steps, self.collisions, self.rng_state.copy(),
                        self.scheduler_state.copy(), None if self.exact is None else self.exact.copy(),
                        None if self.margin is None else self.margin.copy(),
                        None if self.certified is None else self.certified.copy())

    def replace(self, **changes) -> RunState:
        """This state with some fields replaced.

        Parameters
        ----------
        **changes
            Fields and their new values.

        Returns
        -------
        RunState
        """
        return dataclasses.replace(self, **changes)

    def identical(self, other: RunState) -> bool:
        """Whether ``other`` is this state bit for bit.

        Parameters
        ----------
        other : RunState
            Another state.

        Returns
        -------
        bool
            True when every array, dtype and count, the exact velocities, the margin and the certified state
            are the same.
        """
        return (self.steps, self.collisions) == (other.steps, other.collisions) \
            and _same(self.exact, other.exact) and _same(self.margin, other.margin) \
            and (self.certified is None) == (other.certified is None) \
            and (self.certified is None or self.certified.identical(other.certified)) and all(
                getattr(self, name).dtype == getattr(other, name).dtype
                and np.array_equal(getattr(self, name), getattr(other, name)) for name in self.ARRAYS)


def _same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    """Both None, or arrays equal element for element (``inf`` equals ``inf``)."""
    return (a is None) == (b is None) and (a is None or np.array_equal(a, b))


def margin_problem(margin) -> str | None:
    """What is wrong with ``margin`` as a closing margin (`engine.margin`), or None when it is one:
    ``(4,)`` floats; the smallest collision's closing speed > 0 (``inf``: none yet); the largest
    remnant's finite and >= 0 (0: none); the counts near the threshold whole numbers >= 0, no
    collision near it when there is no collision at all."""
    m = np.asarray(margin)
    if m.shape != (4,) or m.dtype.kind != "f":
        return f"must be 4 floating-point numbers, got {m.dtype} {m.shape}"
    smallest, largest, near = float(m[SMALLEST]), float(m[LARGEST]), m[[NEAR_COLLISIONS, NEAR_REMNANTS]]
    if not smallest > 0:
        return f"the smallest collision's closing speed must be > 0 (inf: none yet), got {smallest}"
    if not (math.isfinite(largest) and largest >= 0):
        return f"the largest remnant's closing speed must be finite and >= 0 (0: none), got {largest}"
    if not (np.isfinite(near).all() and (near >= 0).all() and (near == np.floor(near)).all()):
        return f"the counts near the threshold must be whole numbers >= 0, got {near.tolist()}"
    if math.isinf(smallest) and near[0] > 0:
        return f"counts {near[0]:.0f} collisions near the threshold but no collision"
    return None


def mass_array(masses, n_balls: int) -> np.ndarray:
    """``(n_balls,)`` masses from None (all 1), one number, or an array; each finite and > 0."""
    if masses is None:
        return np.ones(n_balls)
    try:
        m = np.array(masses, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("masses", f"must be an array of numbers ({exc})") from None
    if m.ndim == 0:
        m = np.full(n_balls, float(m))
    if m.shape != (n_balls,):
        raise FieldError("masses", f"must have shape (n_balls,) = ({n_balls},), got {m.shape}")
    if not (np.isfinite(m).all() and (m > 0).all()):
        raise FieldError("masses", "must all be finite and > 0")
    return m
