"""The schedulers that answer "which contact next" one pick at a time: the paper's uniform
random pair, and every contact once per sweep in a fixed or a fresh random order."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..engine.jit.cache import njit_cached
from ..engine.sequential.loops import Selector, no_begin, no_change, pick_selector
from ..engine.streams.philox import CACHE_WORDS, pick_counter, select_counter
from ..engine.streams.xoshiro import bounded
from ..engine.threads.tuning import check_threads
from ..util import checks
from ..util.errors import FieldError
from .base import Scheduler

__all__ = ["UniformRandomPair", "Sweep", "RandomSweep", "pick_uniform", "pick_sweep", "pick_random_sweep"]


@njit_cached(inline="always")
def pick_uniform(state, rng, n_contacts):
    """The paper's Algorithm 2: a contact uniformly at random."""
    return bounded(rng, n_contacts)


@njit_cached(inline="always")
def pick_sweep(state, rng, n_contacts):
    """Contacts ``0, 1, ..., n-1, 0, 1, ...``; ``state[0]`` is the next one."""
    k = state[0]
    state[0] = k + 1 if k + 1 < n_contacts else 0
    return np.uint64(k), rng


@njit_cached(inline="always")
def pick_random_sweep(state, rng, n_contacts):
    """Every contact once per sweep in a fresh random order (Fisher-Yates).

    ``state[0]`` is the position in the sweep, ``state[1:]`` the current order.
    """
    order = state[1:]
    if state[0] >= n_contacts:
        for m in range(n_contacts - 1, 0, -1):
            r, rng = bounded(rng, m + 1)
            order[m], order[r] = order[r], order[m]
        state[0] = 0
    k = order[state[0]]
    state[0] += 1
    return np.uint64(k), rng


class UniformRandomPair(Scheduler):
    """Each step tries one contact chosen uniformly at random (the paper's scheduler, Algorithm 2).

    The default scheduler of a `Simulation`. The bits never depend on ``threads``.

    Parameters
    ----------
    threads : int or None
        How many of numba's threads a run may use; None (the default) lets long runs on large
        systems use every core, each stretch on the count a `ThreadTuner` finds faster (never slower than
        one thread on a busy machine); 1 runs the sequential loop only. On
        the xoshiro stream the lattice is cut into regions (`engine.threads.regions`); a system runs on one thread
        where regions do not pay: fewer than 65,536 contacts, many contacts joining the regions, or
        contacts joining balls far apart in index (a torus's wrap-around). On the counter stream batches
        of picks run by deterministic reservations (`engine.threads.reservations`), on any geometry.
    stream : {"xoshiro", "counter"}
        Where the picks come from. ``"xoshiro"`` (the default, every published seed's bits):
        xoshiro256** words drawn in order. ``"counter"``: Philox4x64-10 keyed by the seed
        (`engine.streams.philox`), the pick of step ``s`` a function of ``(seed, s)`` alone, so any thread or a
        GPU computes any step's pick; the same law, other picks, and the stream that runs on every core
        (`engine.threads.reservations`) and on a GPU (``Simulation(..., device="cuda")``) with the bits of one
        core.

    Raises
    ------
    FieldError
        On ``threads`` below 1 or ``stream`` not one of `STREAMS`.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, scheduler=pb.UniformRandomPair(), seed=1)
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 556, 50)
    >>> sim = pb.Simulation(g, v, scheduler=pb.UniformRandomPair(stream="counter"), seed=1)
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 602, 61)
    """

    #: the streams a `UniformRandomPair` draws from
    STREAMS = ("xoshiro", "counter")

    def __init__(self, threads: int | None = None, stream: str = "xoshiro"):
        self.threads = None if threads is None else checks.integer("threads", threads, minimum=1)
        self.stream = checks.choice("stream", stream, self.STREAMS)

    law = "uniform"  #: `Scheduler.law`

    def kernel(self) -> Callable:
        """The stream's pick (`Scheduler.kernel`).

        Returns
        -------
        callable
            `pick_uniform`, or the counter stream's ``pick_counter``.
        """
        return pick_counter if self.stream == "counter" else pick_uniform

    def selector(self, geometry) -> Selector:
        """The stream's selector (`Scheduler.selector`): the counter stream keeps its last Philox block.

        Parameters
        ----------
        geometry : Geometry
            The geometry the simulation is built on.

        Returns
        -------
        pinnedballs.engine.selector.Selector

        Raises
        ------
        FieldError
            On ``threads`` beyond numba's ``NUMBA_NUM_THREADS``.
        """
        check_threads(self.threads)
        if self.stream == "counter":  # its own cache of the last Philox block: four steps' words
            return Selector(select_counter, no_begin, no_change, np.zeros(CACHE_WORDS, dtype=np.uint64), counter=True)
        return pick_selector(pick_uniform)._replace(uniform=True)

    def to_spec(self) -> dict:
        """The scheduler as a run spec's ``"scheduler"`` (`Scheduler.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "uniform_random_pair"}``, with ``"threads"`` and ``"stream"`` where not the defaults.
        """
        return {"kind": "uniform_random_pair", **({} if self.threads is None else {"threads": self.threads}),
                **({} if self.stream == "xoshiro" else {"stream": self.stream})}

    def __repr__(self) -> str:
        args = [f"threads={self.threads}"] * (self.threads is not None) + [f"stream={self.stream!r}"] * (
            self.stream != "xoshiro")
        return f"UniformRandomPair({', '.join(args)})"

    def __hash__(self) -> int:
        return hash((type(self), self.threads, self.stream))


class Sweep(Scheduler):
    """Tries every contact once per sweep, in the geometry's fixed contact order.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, scheduler=pb.Sweep())
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 179, 54)
    """

    law = "sweep"  #: `Scheduler.law`

    def kernel(self) -> Callable:
        """The sweep's pick (`Scheduler.kernel`).

        Returns
        -------
        callable
            `pick_sweep`: ``state[0]`` is the next contact.
        """
        return pick_sweep

    def to_spec(self) -> dict:
        """The scheduler as a run spec's ``"scheduler"`` (`Scheduler.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "sweep"}``.
        """
        return {"kind": "sweep"}

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """`Scheduler.check_state`: the next contact in range.

        Parameters
        ----------
        state : numpy.ndarray
            ``(1,) int64``: the next contact.
        n_contacts : int
            The geometry's contacts.

        Raises
        ------
        FieldError
            On ``scheduler_state``, for another shape or a contact outside ``[0, n_contacts)``.
        """
        super().check_state(state, n_contacts)
        if not 0 <= state[0] < n_contacts:
            raise FieldError("scheduler_state", f"the next contact must be in [0, {n_contacts}), got {state[0]}")


class RandomSweep(Scheduler):
    """Tries every contact once per sweep, in a fresh uniformly random order each sweep (Fisher-Yates).

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, scheduler=pb.RandomSweep(), seed=1)
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 251, 46)
    """

    law = "sweep"  #: `Scheduler.law`

    def kernel(self) -> Callable:
        """The random sweep's pick (`Scheduler.kernel`).

        Returns
        -------
        callable
            `pick_random_sweep`.
        """
        return pick_random_sweep

    def to_spec(self) -> dict:
        """The scheduler as a run spec's ``"scheduler"`` (`Scheduler.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "random_sweep"}``.
        """
        return {"kind": "random_sweep"}

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """`Scheduler.check_state`: the position in the sweep in range, the order a permutation.

        Parameters
        ----------
        state : numpy.ndarray
            ``(n_contacts + 1,) int64``: the position in the sweep, then the sweep's order.
        n_contacts : int
            The geometry's contacts.

        Raises
        ------
        FieldError
            On ``scheduler_state``, for another shape, a position outside ``[0, n_contacts]`` or an order
            that is not a permutation of the contacts.
        """
        super().check_state(state, n_contacts)
        if not 0 <= state[0] <= n_contacts:
            raise FieldError("scheduler_state",
                             f"the position in the sweep must be in [0, {n_contacts}], got {state[0]}")
        if not np.array_equal(np.sort(state[1:]), np.arange(n_contacts)):
            raise FieldError("scheduler_state", f"the sweep order must be a permutation of 0..{n_contacts - 1}")

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """A sweep about to be shuffled (`Scheduler.initial_state`).

        Parameters
        ----------
        n_contacts : int
            The geometry's contacts.

        Returns
        -------
        numpy.ndarray
            ``(n_contacts + 1,) int64``: ``[n_contacts, 0, 1, ..., n_contacts - 1]``.
        """
        state = np.empty(n_contacts + 1, dtype=np.int64)
        state[0] = n_contacts  # shuffle before the first pick
        state[1:] = np.arange(n_contacts)
        return state
