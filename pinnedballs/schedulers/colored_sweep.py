"""`ColoredSweep`: colour classes of contacts that share no ball, each class in parallel.

The contacts are split into colour classes, each a matching (a proper edge
colouring): no two contacts of a class share a ball, so the collisions of a class
commute and may run at once. A sweep runs the classes in turn, each on all numba
threads (``prange``); the result does not depend on the number of threads, nor on
the order within a class, so the sequential loop used for collision targets and
the freeze gives the same bits.

**The colouring** is greedy (each contact takes the smallest colour free at both
its balls) over the contacts ordered by direction (their ``t_i`` row), then by
ball: on a lattice each direction's lines alternate two colours, which gives the
lower bound, the maximum degree, on the triangular lattice (6) and FCC (12).
Short of that, the contact order is tried too and the fewer classes kept. Greedy never needs
more than ``2 * degree - 1``. Each class is sorted by its smaller ball, for
memory locality.

**The state** is ``(6,) int64``: ``[slot, offset, w0, w1, w2, w3]``: the position
of the current class in the sweep (``-1``: start a new sweep before the next
contact), the contacts of that class already tried, and (with ``shuffle``) the
random stream's words as the sweep began, from which the sweep's order of classes
is replayed (a Fisher-Yates shuffle of ``0..C-1``, as `RandomSweep` does).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import njit, prange

from ..engine.chain import COLLISIONS, LIVE, STEPS
from ..engine.closing import closing_speed
from ..engine.jit.cache import jit_cached_if_possible, njit_cached
from ..engine.margin import (
    LARGEST,
    NEAR_COLLISIONS,
    NEAR_REMNANTS,
    SMALLEST,
    collided_speed,
    near_collision,
    near_remnant,
    remnant_speed,
)
from ..engine.sequential.loops import Selector, contact_kernels, copy_into, no_change
from ..engine.streams.xoshiro import bounded, load, store
from ..engine.threads.tuning import TUNED_SEGMENT, ThreadTuner, check_threads, using
from ..util import checks
from ..util.errors import FieldError
from .base import Scheduler

__all__ = ["ColoredSweep", "colour_classes", "sweep_selector", "sweep_steps"]

_STATE = 6  #: length of the state array


@njit_cached
def _greedy_colours(pairs, order, n_balls, max_colours):
    """``(E,) int64`` colours: contacts in ``order`` take the smallest colour free at both balls."""
    used = np.zeros((n_balls, max_colours), dtype=np.uint8)
    colour = np.empty(pairs.shape[0], dtype=np.int64)
    for k in order:
        i, j = pairs[k, 0], pairs[k, 1]
        c = 0
        while used[i, c] or used[j, c]:
            c += 1
        colour[k] = c
        used[i, c] = 1
        used[j, c] = 1
    return colour


def colour_classes(pairs: np.ndarray, ends: np.ndarray, n_balls: int) -> list[np.ndarray]:
    """The colour classes of contacts ``pairs (E, 2)`` (``ends (E, 2)`` gives their directions):
    a list of ``int64`` arrays of contact indices, each a matching, each sorted by its smaller ball."""
    pairs = np.asarray(pairs).astype(np.int64)
    if len(pairs) == 0:
        return []
    low = pairs.min(axis=1)
    degree = int(np.bincount(pairs.ravel(), minlength=n_balls).max())
    colour = _greedy_colours(pairs, np.lexsort((pairs.max(axis=1), low, np.asarray(ends)[:, 0])), n_balls, 2 * degree)
    if colour.max() + 1 > degree:  # not yet the fewest possible: try the contact order too
        other = _greedy_colours(pairs, np.arange(len(pairs)), n_balls, 2 * degree)
        colour = other if other.max() < colour.max() else colour
    by_class = np.lexsort((np.arange(len(pairs)), low, colour))
    bounds = np.searchsorted(colour[by_class], np.arange(colour.max() + 2))
    return [by_class[bounds[c]:bounds[c + 1]] for c in range(colour.max() + 1)]


@njit_cached
def class_order(state, n_classes, shuffle):
    """``(C,) int64``: the order of classes in the sweep under way, replayed from ``state``."""
    order = np.arange(n_classes)
    if shuffle and state[0] >= 0:
        _shuffle(order, load(state[2:_STATE].view(np.uint64)))
    return order


@njit_cached(inline="always")
def _shuffle(order, rng):
    """Fisher-Yates on ``order`` in place, as `simple.pick_random_sweep`; the advanced stream."""
    for m in range(order.shape[0] - 1, 0, -1):
        r, rng = bounded(rng, m + 1)
        order[m], order[r] = order[r], order[m]
    return rng


@njit_cached
def start_sweep(state, order, rng, shuffle):
    """Begin a sweep: the order of classes (with ``shuffle`` drawn, and the stream as it began
    remembered in ``state[2:6]``); returns the advanced stream. Not inlined: ``view`` defeats
    numba's analysis of the parallel loop."""
    for m in range(order.shape[0]):
        order[m] = m
    if shuffle:
        store(state[2:_STATE].view(np.uint64), rng)
        rng = _shuffle(order, rng)
    state[0], state[1] = 0, 0
    return rng


@njit_cached(inline="always")
def _move_on(state, starts, order, tried):
    """``tried`` more contacts of the current class; to the next class at its end."""
    c = order[state[0]]
    state[1] += tried
    if starts[c] + state[1] == starts[c + 1]:
        state[0] = state[0] + 1 if state[0] + 1 < order.shape[0] else -1
        state[1] = 0


@functools.cache
def sweep_selector(shuffle: bool) -> tuple[Callable, Callable]:
    """``(select, begin)`` of the sweep one contact at a time (what the engine's limited loops run):
    ``aux = (classes (E,), starts (C + 1,), order (C,))``, class ``c`` at ``classes[starts[c]:starts[c + 1]]``."""
    SHUFFLE = shuffle

    @njit(inline="always")
    def select(state, aux, rng, n, left):
        classes, starts, order = aux
        if state[0] < 0:
            rng = start_sweep(state, order, rng, SHUFFLE)
        k = classes[starts[order[state[0]]] + state[1]]
        _move_on(state, starts, order, 1)
        return k, 1, rng

    @njit(inline="always")
    def begin(state, aux, flags):
        order = aux[2]
        copy_into(order, class_order(state, order.shape[0], SHUFFLE))

    return select, begin


@functools.cache
def sweep_steps(collide: Callable, dim: int, flat: bool, shuffle: bool) -> Callable:
    """The parallel loop of plain steps for one rule's ``collide``, ``dim``, ``flat`` and ``shuffle``:
    ``steps(v, pairs, ends, units, masses, params, state, aux, rng_words, counters, margin, max_steps)`` tries
    ``max_steps`` contacts, each class (or the part of it within the limit) on all numba threads."""
    attempt, _ = contact_kernels(collide, dim, flat)
    SHUFFLE, D, FLAT = shuffle, dim, flat

    @jit_cached_if_possible(parallel=True)
    def steps(v, pairs, ends, units, masses, params, state, aux, rng_words, counters, margin, max_steps):
        classes, starts, order = aux
        copy_into(order, class_order(state, order.shape[0], SHUFFLE))
        taken, made, rng = 0, 0, load(rng_words)
        tau = params[params.shape[0] - 1]
        smallest, largest = margin[SMALLEST], margin[LARGEST]
        near_hits, near_rest = 0.0, 0.0
        while taken < max_steps:
            if state[0] < 0:
                rng = start_sweep(state, order, rng, SHUFFLE)
            c = order[state[0]]
            lo = starts[c] + state[1]
            hi = min(starts[c + 1], lo + (max_steps - taken))
            part = 0
            for m in prange(lo, hi):  # a matching: no two iterations touch the same ball
                k = classes[m]
                w = closing_speed(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], D, FLAT)
                hit = attempt(v, pairs, ends, units, masses, params, k, True)
                part += 1 if hit else 0
                smallest = min(smallest, collided_speed(hit, w))  # the margin (engine.margin), as reductions
                largest = max(largest, remnant_speed(hit, w))
                near_hits += near_collision(hit, w, tau)
                near_rest += near_remnant(hit, w, tau)
            made += part
            taken += hi - lo
            _move_on(state, starts, order, hi - lo)
        store(rng_words, rng)
        margin[SMALLEST], margin[LARGEST] = smallest, largest
        margin[NEAR_COLLISIONS] += near_hits
        margin[NEAR_REMNANTS] += near_rest
        counters[STEPS] += max_steps
        counters[COLLISIONS] += made
        counters[LIVE] = -1
        return max_steps

    return steps


class ColoredSweep(Scheduler):
    """Every contact once per sweep, colour class by colour class (`classes`); each class runs in
    parallel, with the same bits on any number of threads.

    The module's docstring gives the colouring and the state.

    Parameters
    ----------
    shuffle : bool
        A fresh random order of the classes each sweep (the order within a class does not matter).
    threads : int or None
        How many of numba's threads a run uses; None (the default) uses as many as numba
        is set to (``NUMBA_NUM_THREADS``, every core unless set; see `pinnedballs.engine.threads`).

    Raises
    ------
    FieldError
        On ``shuffle`` not a bool or ``threads`` below 1.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> [len(c) for c in pb.ColoredSweep.classes(g)]
    [12, 12, 9, 6, 10, 4]
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, scheduler=pb.ColoredSweep(shuffle=True), seed=1)
    >>> sim.run_until_frozen(100_000), sim.steps, sim.collisions
    (True, 198, 45)
    """

    law = "sweep"  #: `Scheduler.law`

    def __init__(self, shuffle: bool = False, threads: int | None = None):
        self.shuffle = checks.flag("shuffle", shuffle)
        self.threads = None if threads is None else checks.integer("threads", threads, minimum=1)

    @staticmethod
    def classes(geometry) -> list[np.ndarray]:
        """The colour classes of ``geometry``'s contacts, in the order a sweep runs them (without shuffle).

        Parameters
        ----------
        geometry : Geometry
            Any geometry.

        Returns
        -------
        list of numpy.ndarray
            ``int64`` arrays of contact indices, each a matching (no two of its contacts share a ball).
        """
        c = geometry.contacts
        return colour_classes(c.pairs, c.ends, geometry.n_balls)

    def selector(self, geometry) -> Selector:
        """The sweep one contact at a time (`sweep_selector`) and its parallel loop of plain steps
        (`sweep_steps`): `Scheduler.selector`.

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
        classes = self.classes(geometry)
        starts = np.zeros(len(classes) + 1, dtype=np.int64)
        np.cumsum([len(c) for c in classes], out=starts[1:])
        aux = (np.concatenate(classes), starts, np.arange(len(classes), dtype=np.int64))
        select, begin = sweep_selector(self.shuffle)
        check_threads(self.threads)
        return Selector(select, begin, no_change, aux,
                        steps=functools.partial(_threaded_steps, shuffle=self.shuffle, threads=self.threads))

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """A sweep about to start (`Scheduler.initial_state`).

        Parameters
        ----------
        n_contacts : int
            The geometry's contacts.

        Returns
        -------
        numpy.ndarray
            ``(6,) int64``: ``[-1, 0, 0, 0, 0, 0]``, start a sweep before the first contact.
        """
        state = np.zeros(_STATE, dtype=np.int64)
        state[0] = -1
        return state

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """`Scheduler.check_state`: the position in the sweep, and the words of a shuffled one.

        Parameters
        ----------
        state : numpy.ndarray
            ``(6,) int64``: ``[slot, offset, w0, w1, w2, w3]``.
        n_contacts : int
            The geometry's contacts.

        Raises
        ------
        FieldError
            On ``scheduler_state``, for another shape, a slot below -1, a negative offset (or one not 0
            between sweeps), or a shuffled sweep under way whose random words are all zero.
        """
        super().check_state(state, n_contacts)
        if state[0] < -1 or state[1] < 0 or (state[0] == -1 and state[1] != 0):
            raise FieldError("scheduler_state", f"the position in the sweep must be a class slot >= -1 and an offset "
                             f">= 0 (0 between sweeps), got {state[0]}, {state[1]}")
        if self.shuffle and state[0] >= 0 and not state[2:].any():
            raise FieldError("scheduler_state", "the random words of the sweep under way must not all be zero")

    def check_resume(self, state: np.ndarray, selector: Selector, flags) -> None:
        """`Scheduler.check_resume`: the slot and offset within the classes of the selector's geometry.

        Parameters
        ----------
        state : numpy.ndarray
            The state, through `check_state`.
        selector : pinnedballs.engine.selector.Selector
            The selector it resumes with (its classes).
        flags : numpy.ndarray or None
            Unused: the sweep tracks no live contacts.

        Raises
        ------
        FieldError
            On ``scheduler_state``, for a slot beyond the classes or an offset beyond its class.
        """
        starts = selector.aux[1]
        n_classes = len(starts) - 1
        if state[0] >= n_classes:
            raise FieldError("scheduler_state", f"class slot {state[0]} is beyond the {n_classes} classes")
        if state[0] >= 0:
            c = class_order(state, n_classes, self.shuffle)[state[0]]
            size = starts[c + 1] - starts[c]
            if state[1] >= size:
                raise FieldError("scheduler_state", f"offset {state[1]} is beyond the {size} contacts of its class")

    def to_spec(self) -> dict:
        """The scheduler as a run spec's ``"scheduler"`` (`Scheduler.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "colored_sweep", "shuffle": ...}``, with ``"threads"`` where given.
        """
        return {"kind": "colored_sweep", "shuffle": self.shuffle,
                **({} if self.threads is None else {"threads": self.threads})}

    def __repr__(self) -> str:
        return f"ColoredSweep(shuffle={self.shuffle}{'' if self.threads is None else f', threads={self.threads}'})"

    def __hash__(self) -> int:
        return hash((type(self), self.shuffle, self.threads))


def _threaded_steps(collide: Callable, dim: int, flat: bool, shuffle: bool, threads: int | None) -> Callable:
    """`sweep_steps` on ``threads`` of numba's threads; None: in segments of at most `TUNED_SEGMENT` steps, each
    on the count a `ThreadTuner` chooses (the same bits), the tuner kept from call to call (a run's calls are
    short: on a busy machine, untuned, they ran on every thread)."""
    loop = sweep_steps(collide, dim, flat, shuffle)
    tuner = ThreadTuner() if threads is None else None

    def steps(*args):
        *chain, max_steps = args
        if tuner is None or len(tuner.candidates) == 1 or max_steps <= 0:  # no steps: compiles, on any count
            with using(threads):
                return loop(*args)
        done = 0
        while done < max_steps:
            done += tuner.run(lambda n: loop(*chain, n), min(TUNED_SEGMENT, max_steps - done))
        return max_steps

    steps.loop = loop  # the compiled loop (its cache statistics, its signatures)
    steps.tuner = tuner  # what it chose (a run's provenance: `engine.backends.LoopBackend.resources`)
    return steps
