"""`RejectionFree`: the paper's chain without its rejected picks (the n-fold way).

Bortz, Kalos and Lebowitz, J. Comput. Phys. 17 (1975). With ``L`` live contacts
of ``M``, the paper's scheduler picks ``G`` contacts up to and including the next
live one, ``G`` geometric with ``p = L / M``, and that live one is uniform among
the ``L`` and independent of ``G``. So the loop draws ``G``, adds it to the steps
and collides a uniformly chosen live contact: ``steps``, ``collisions`` and the
velocities have the joint law of `UniformRandomPair`'s (not its bits).

**The draw.** ``G = 1 + floor(ln U / ln(1 - p))`` with ``U = 1 - u`` in ``(0, 1]``
and ``u`` the stream's 53-bit uniform (`engine.streams.xoshiro.random_float`): then
``P(G > g) = P(U <= (1 - p)^g) = (1 - p)^g`` exactly up to the 2^-53 grid of
``U``. ``ln(1 - p)`` is ``log1p(-p)``, accurate for tiny ``p``. ``p = 1`` gives
``G = 1`` without a draw; ``L = 0`` never collides (the paper's chain would pick
forever). ``G`` is at most ``1 + 37 / p`` (about ``37 M``); it becomes an integer
capped at 2^62, far beyond any ``M`` numba can index, so it never overflows.

**A run ends at exactly ``max_steps``.** A ``G`` beyond the steps left ends the
run there without that collision and keeps the rest, ``G - left``, as the picks
still to come before the next live one. Given ``G > left`` that rest is again
geometric with the same ``p`` (the law is memoryless) and the live set has not
changed, so keeping it gives the same law as drawing afresh, and it makes a run
split into calls (chunks, checkpoints, resume) bit-identical to one call.

**The live set** is an array ``live[:L]`` plus a position map ``pos (M,) int64``
(``-1``: not live). The engine's tracked loop (`engine.sequential.loops`) re-tests the contacts of the two
balls of each collision and tells `changed` of each contact that became live or not: an append,
or a swap with the last entry to remove.

**The checkpoint** is the live array in its current order and the picks still to
come, ``state = [L, rest, live[0], ..., live[L-1], -1, ...]`` (``(M + 2,) int64``;
``rest = 0``: draw afresh). The set follows from
the velocities, but its order follows from the history of swaps, and the pick
``live[r]`` depends on that order: a set rebuilt in contact order would continue
the same law but not the same bits. ``state[0] = -1`` (a fresh run) means
"build from the velocities, in contact order" (and then ``rest = 0``). The position map is rebuilt
from the array at each call (`begin`, O(M), like the live flags).
"""

from __future__ import annotations

import numpy as np

from ..engine.jit.cache import njit_cached
from ..engine.sequential.loops import Selector
from ..engine.streams.xoshiro import bounded, random_float
from ..util.errors import FieldError
from .base import Scheduler

__all__ = ["RejectionFree", "picks_until_live"]

_CAP = float(2**62)  #: picks beyond this are as good as never


@njit_cached(inline="always")
def picks_until_live(rng, n_live, n_contacts):
    """``(G, rng)``: the paper's picks up to and including the next live one, as a float64
    (an integer >= 1); geometric with ``p = n_live / n_contacts``, ``1 <= n_live <= n_contacts``."""
    if n_live == n_contacts:
        return 1.0, rng
    return _picks(rng, np.log1p(-(n_live / n_contacts)))


@njit_cached(inline="always")
def _picks(rng, log_q):
    """``(G, rng)``: ``1 + floor(ln(1 - u) / log_q)``, with ``log_q = ln(1 - p) < 0``."""
    u, rng = random_float(rng)
    return 1.0 + np.floor(np.log(1.0 - u) / log_q), rng


@njit_cached(inline="always")
def select(state, aux, rng, n, left):
    """The next live contact and the picks up to it (at most ``left``; ``k = -1`` beyond them, the
    rest kept in ``state[1]``). ``aux = (pos (M,), log_q (M + 1,))``: ``log_q[L]`` caches
    ``log1p(-L / M)`` (0.0: not yet)."""
    n_live = state[0]
    if n_live == 0:  # frozen: the paper's chain picks on without ever colliding
        return np.int64(-1), left, rng
    if state[1] > 0:  # picks left over from an earlier call
        g = state[1]
        state[1] = 0
    else:
        if n_live == n:
            x = 1.0
        else:
            log_q = aux[1]
            if log_q[n_live] == 0.0:
                log_q[n_live] = np.log1p(-(n_live / n))
            x, rng = _picks(rng, log_q[n_live])  # as picks_until_live, bit for bit
        g = np.int64(min(x, _CAP))
    if g > left:  # the next live pick lies beyond the run
        state[1] = g - left
        return np.int64(-1), left, rng
    r, rng = bounded(rng, n_live)
    return state[2 + np.int64(r)], g, rng


@njit_cached(inline="always")
def changed(state, aux, c, live):
    """Contact ``c`` became live (``live = 1``: appended) or not (swapped with the last entry)."""
    pos, n_live = aux[0], state[0]
    if live:
        state[2 + n_live] = c
        pos[c] = n_live
        state[0] = n_live + 1
    else:
        at = pos[c]
        n_live -= 1
        last = state[2 + n_live]
        state[2 + at] = last
        pos[last] = at
        state[2 + n_live] = -1
        pos[c] = -1
        state[0] = n_live


@njit_cached
def begin(state, aux, flags):
    """Fill the position map from ``state``'s live array, or rebuild both from ``flags`` (in contact
    order, the rest reset) when the array does not hold exactly the live contacts of ``flags``."""
    pos, n_live = aux[0], state[0]
    pos[:] = -1
    ok = n_live >= 0 and n_live == np.count_nonzero(flags)
    if ok:
        for m in range(n_live):
            c = state[2 + m]
            if flags[c] == 0 or pos[c] >= 0:
                ok = False
                break
            pos[c] = m
    if not ok:
        pos[:] = -1
        state[2:] = -1
        state[1] = 0  # picks drawn for another live set
        n_live = 0
        for k in range(flags.shape[0]):
            if flags[k] != 0:
                state[2 + n_live] = k
                pos[k] = n_live
                n_live += 1
        state[0] = n_live


class RejectionFree(Scheduler):
    """The paper's chain without its rejected picks: each step of the loop jumps over the
    picks of non-live contacts (a geometric number, counted in ``steps``) and collides a live
    contact chosen uniformly. Same joint law of steps, collisions and velocities as
    `UniformRandomPair` (not its bits); far faster when few contacts are live (a half-plane near its
    freeze). The module's docstring gives the draw, the live set and the checkpoint.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, scheduler=pb.RejectionFree(), seed=1)
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 593, 52)
    """

    law = "uniform_chain"  #: `Scheduler.law`

    def selector(self, geometry) -> Selector:
        """The live set's selector (`Scheduler.selector`): it jumps over the picks of non-live contacts.

        Parameters
        ----------
        geometry : Geometry
            The geometry the simulation is built on.

        Returns
        -------
        pinnedballs.engine.selector.Selector
            One that tracks the live contacts and skips picks.
        """
        n = geometry.n_contacts
        aux = (np.full(n, -1, dtype=np.int64), np.zeros(n + 1))
        return Selector(select, begin, changed, aux, tracks=True, skips=True)

    def to_spec(self) -> dict:
        """The scheduler as a run spec's ``"scheduler"`` (`Scheduler.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "rejection_free"}``.
        """
        return {"kind": "rejection_free"}

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """A live set still to be built from the velocities (`Scheduler.initial_state`).

        Parameters
        ----------
        n_contacts : int
            The geometry's contacts.

        Returns
        -------
        numpy.ndarray
            ``(n_contacts + 2,) int64``: ``[-1, 0, -1, -1, ...]``.
        """
        state = np.full(n_contacts + 2, -1, dtype=np.int64)
        state[1] = 0
        return state

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """`Scheduler.check_state`: the live set's size, the picks still to come and the live contacts.

        Parameters
        ----------
        state : numpy.ndarray
            ``(n_contacts + 2,) int64``: ``[L, rest, live[0], ..., live[L-1], -1, ...]``.
        n_contacts : int
            The geometry's contacts.

        Raises
        ------
        FieldError
            On ``scheduler_state``, for another shape, ``L`` outside ``[-1, n_contacts]``, ``rest`` outside
            ``[0, 2**62]`` (or not 0 with no live contact), live contacts not distinct indices, or entries
            after them other than -1.
        """
        super().check_state(state, n_contacts)
        n_live = state[0]
        if not -1 <= n_live <= n_contacts:
            raise FieldError("scheduler_state", f"the number of live contacts must be in [-1, {n_contacts}], "
                             f"got {n_live}")
        if not 0 <= state[1] <= 2**62 or (n_live <= 0 and state[1] != 0):
            raise FieldError("scheduler_state", f"the picks still to come must be in [0, 2**62] (0 unless a "
                             f"contact is live), got {state[1]}")
        live, rest = state[2:2 + max(n_live, 0)], state[2 + max(n_live, 0):]
        if len(live) and (live.min() < 0 or live.max() >= n_contacts or len(np.unique(live)) != len(live)):
            raise FieldError("scheduler_state", f"the live contacts must be distinct indices in [0, {n_contacts})")
        if (rest != -1).any():
            raise FieldError("scheduler_state", "entries after the live contacts must be -1")

    def check_resume(self, state: np.ndarray, selector: Selector, flags: np.ndarray | None) -> None:
        """`Scheduler.check_resume`: the live contacts saved are those of the velocities.

        Parameters
        ----------
        state : numpy.ndarray
            The state, through `check_state`.
        selector : pinnedballs.engine.selector.Selector
            The selector it resumes with.
        flags : numpy.ndarray
            ``(E,) bool``: the live contacts of the velocities restored.

        Raises
        ------
        FieldError
            On ``scheduler_state``, where its live contacts are not those of the velocities.
        """
        n_live = state[0]
        if n_live >= 0 and not np.array_equal(np.sort(state[2:2 + n_live]), np.flatnonzero(flags)):
            raise FieldError("scheduler_state", f"its {n_live} live contacts are not those of the velocities "
                             f"({np.count_nonzero(flags)} live)")
