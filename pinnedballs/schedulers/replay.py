"""`Replay`: a given order of contacts, one per step (the orders `pinnedballs.explore_orders`
finds, a collision log), then a refusal to go on."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..engine.jit.cache import njit_cached
from .base import Scheduler

__all__ = ["Replay", "pick_replay"]


@njit_cached(inline="always")
def pick_replay(state, rng, n_contacts):
    """Contacts ``state[1], state[2], ...`` in turn; ``state[0]`` counts the picks made."""
    p = state[0]
    if p >= state.shape[0] - 1:
        raise ValueError("Replay: every contact of its order has been picked; a run may take only len(order) steps")
    state[0] = p + 1
    return np.uint64(state[p + 1]), rng


class Replay(Scheduler):
    """Tries the contacts of ``order`` in turn, then refuses to go on.

    Replays an order from `explore_orders`: ``Simulation(geom, v, scheduler=Replay(r.max_order))``
    then ``run_until_frozen(max_steps=len(r.max_order))``, or a collision log's. A run that asks for
    more steps than the order holds raises ValueError; that simulation's counters then miss the steps
    of that call (its velocities do not), so start a new one.

    Parameters
    ----------
    order : sequence of int
        Contact indices (>= 0), one per step.

    Attributes
    ----------
    order : numpy.ndarray
        ``(len(order),) int64``.

    Raises
    ------
    TypeError
        If ``order`` is not a sequence of integers.
    ValueError
        If ``order`` is not 1-D or holds a negative index (and when a run is built on a geometry
        without one of its contacts).

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=2, cols=3)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[1] = [0.0, 1.0]
    >>> r = pb.explore_orders(g, v)
    >>> r.max_order
    (3, 2, 4, 0, 8, 6)
    >>> sim = pb.Simulation(g, v, scheduler=pb.Replay(r.max_order))
    >>> sim.run_until_frozen(max_steps=len(r.max_order)), sim.collisions
    (True, 6)
    """

    def __init__(self, order):
        try:
            a = np.asarray(order)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"order: must be a sequence of contact indices ({exc})") from None
        if a.ndim != 1:
            raise ValueError(f"order: must be a 1-D sequence of contact indices, got shape {a.shape}")
        if a.size and (a.dtype == bool or not np.issubdtype(a.dtype, np.integer)):
            raise TypeError(f"order: contact indices must be integers, got {a.dtype}")
        if a.size and (a.min() < 0 or a.max() > np.iinfo(np.int64).max):
            raise ValueError(f"order: contact indices must be >= 0, got {a.min()}")
        self.order = a.astype(np.int64)

    def kernel(self) -> Callable:
        """The replay's pick (`Scheduler.kernel`).

        Returns
        -------
        callable
            `pick_replay`.
        """
        return pick_replay

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """No pick made yet, then the order (`Scheduler.initial_state`).

        Parameters
        ----------
        n_contacts : int
            The geometry's contacts.

        Returns
        -------
        numpy.ndarray
            ``(len(order) + 1,) int64``: ``[0, order[0], order[1], ...]``.

        Raises
        ------
        ValueError
            If the order names a contact the geometry does not have.
        """
        if self.order.size and self.order.max() >= n_contacts:
            raise ValueError(f"order: contact {self.order.max()} does not exist; "
                             f"the geometry has {n_contacts} contacts")
        return np.concatenate([[0], self.order]).astype(np.int64)

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """`Scheduler.check_state`: the picks made in range, and this replay's order.

        Parameters
        ----------
        state : numpy.ndarray
            ``(len(order) + 1,) int64``: the picks made, then the order.
        n_contacts : int
            The geometry's contacts.

        Raises
        ------
        ValueError
            For another shape (a `FieldError`), picks made outside ``[0, len(order)]``, or another order.
        """
        super().check_state(state, n_contacts)
        if not 0 <= state[0] <= len(self.order):
            raise ValueError(f"scheduler_state: the picks made must be in [0, {len(self.order)}], got {state[0]}")
        if not np.array_equal(state[1:], self.order):
            raise ValueError("scheduler_state: holds a different order from this Replay's")

    def __repr__(self) -> str:
        if len(self.order) <= 12:
            return f"Replay({self.order.tolist()})"
        return f"Replay(<order of {len(self.order)} contacts>)"
