"""The most collisions until frozen over initial velocities and orders: `search_max_collisions`.

The theory (Athreya-Burdzy-Duarte 2018, Burdzy-Duarte 2022) bounds the number of collisions over
every order *and* every initial velocity. `explore_orders` gives the most over orders for given
velocities; this module searches the velocities, for equal masses and elastic collisions.

Only a direction matters: a collision is linear in the velocities and a contact is live by the
sign of its closing speed, so velocities ``c v`` (``c > 0``) have the same orders and counts as
``v``. The search draws velocities as ``n_balls * dim`` independent standard normal components (a
uniform direction) and scales them by a power of two, which is exact in floats and so changes no
count, until the largest component lies in [1/2, 1).

The search is hill climbing with restarts, one evaluation (a *trial*) at a time:

* a *climb* starts from ``start`` (the first climb, if given) or fresh random velocities;
* each next trial makes one move (`moved`): with probability `SWAP` two balls, chosen uniformly,
  exchange their velocities (on a chain this undoes an inversion at once); otherwise one ball's
  velocity gains ``s * r * g``, with ``g`` standard normal, ``r`` the root mean square speed of a
  ball and ``s`` log-uniform in [`STEP_MIN`, `STEP_MAX`] (fine and coarse moves alike), and the
  whole is normalised again;
* a move is kept when the most collisions over orders does not decrease (equal counts are kept
  too, so the climb drifts along plateaus of the integer count);
* after ``patience`` trials in a row without raising the climb's best, a new climb starts.

A trial's most over orders is `explore_orders` in float arithmetic (the engine's compiled loop,
about 20 times faster than exact arithmetic here; rounding remnants below its threshold are left
out, so it agrees with exact arithmetic collision for collision): every order when the velocities
have at most ``max_states`` distinct states; otherwise only a *lower bound*, the most of the orders
tried: those through the part searched, two greedy orders (largest, then smallest closing speed
first) and `SAMPLED_ORDERS` orders picking a live contact uniformly at random.

The best velocities are then searched again over orders in the result's arithmetic (exact where the
contact normals lie in a known number field) with ``final_states`` states. The result's order is
that search's most order, or the trial's own if it is longer and replays in that arithmetic, and it
is replayed (`Replay`) in that arithmetic before returning: it must collide at every pick and end
frozen.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.base import Geometry
from ..schedulers.replay import Replay
from ..simulation import Simulation
from ..util import checks
from ..util.errors import FieldError, FieldTypeError
from ..util.progress import Progress
from ..util.sigint import deferred
from .orders import OrdersResult, explore_orders

__all__ = ["search_max_collisions", "MaxCollisionsResult", "random_velocities", "normalised", "moved", "perturbed"]

#: relative sizes of a move: log-uniform between these, times a ball's root mean square speed
STEP_MIN, STEP_MAX = 1e-2, 3.0
#: the probability that a move exchanges two balls' velocities rather than perturbing one
SWAP = 0.25
#: uniformly random orders `explore_orders` adds when ``max_states`` stops its search
SAMPLED_ORDERS = 20


@dataclass(frozen=True, eq=False)
class MaxCollisionsResult:
    """The most collisions until frozen found over initial velocities and orders (`search_max_collisions`).

    The most over velocities is the best found, not proven, unless a known answer applies.

    Parameters
    ----------
    collisions : int
        The most found.
    velocities : numpy.ndarray
        ``(n_balls, dim) float64`` reaching it (take them exactly: a float is a rational).
    order : tuple of int
        Contact indices of an order reaching it, every pick a collision, ending frozen (verified by a
        replay in ``arithmetic`` before returning).
    exhaustive_orders : bool
        True when ``collisions`` is the most over *every* order for these velocities (else a lower bound).
    min_collisions : int
        The fewest over orders for them (an upper bound when not exhaustive).
    states : int
        Distinct states of that search over orders.
    trials : int
        Velocities evaluated.
    climbs : int
        Of which random restarts (or ``start``).
    found_at : int
        The trial (from 1) that found them.
    arithmetic : {"exact", "float"}
        Of the final search and the replay.
    """

    collisions: int
    velocities: np.ndarray
    order: tuple[int, ...]
    exhaustive_orders: bool
    min_collisions: int
    states: int
    trials: int
    climbs: int
    found_at: int
    arithmetic: str

    def __str__(self) -> str:
        if self.exhaustive_orders:
            orders = f"{self.min_collisions} to {self.collisions} over every order"
        else:
            orders = f"at most {self.min_collisions} to at least {self.collisions} over orders (a partial search)"
        return (f"Most collisions found: {self.collisions} (best of {self.trials} trials in {self.climbs} climbs, "
                f"found at trial {self.found_at}); its velocities give {orders}, {self.arithmetic} arithmetic.")

    def __repr__(self) -> str:
        return (f"MaxCollisionsResult(collisions={self.collisions}, min_collisions={self.min_collisions}, "
                f"exhaustive_orders={self.exhaustive_orders}, trials={self.trials}, arithmetic={self.arithmetic!r})")


# ---------------------------------------------------------------- velocities and moves


def normalised(v: np.ndarray) -> np.ndarray:
    """``v (n_balls, dim)`` times the power of two that puts its largest component in [1/2, 1): exact."""
    exponent = math.frexp(float(np.max(np.abs(v))))[1]
    return np.ldexp(v, -exponent)


def random_velocities(rng: np.random.Generator, n_balls: int, dim: int) -> np.ndarray:
    """``(n_balls, dim)`` velocities in a uniformly random direction, `normalised`."""
    while True:
        v = rng.standard_normal((n_balls, dim))
        if v.any():
            return normalised(v)


def moved(v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``v (n_balls, dim)`` after one move: two balls' velocities exchanged (probability `SWAP`) or one's perturbed."""
    if rng.uniform() < SWAP:
        i, j = rng.choice(len(v), size=2, replace=False)
        out = v.copy()
        out[[i, j]] = v[[j, i]]
        return out
    return perturbed(v, rng)


def perturbed(v: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``v (n_balls, dim)`` with one ball's velocity moved (see the module docstring), `normalised`."""
    ball = int(rng.integers(len(v)))
    step = math.exp(rng.uniform(math.log(STEP_MIN), math.log(STEP_MAX)))
    rms = math.sqrt(float(np.sum(v * v)) / len(v))
    out = v.copy()
    out[ball] += step * rms * rng.standard_normal(v.shape[1])
    return normalised(out) if out.any() else v


# ---------------------------------------------------------------- one trial


def _most(geometry: Geometry, v: np.ndarray, max_states: int, max_collisions: int, seed: int,
          arithmetic: str, progress: bool | None = False) -> OrdersResult:
    """`explore_orders` of ``v`` for the search; a system that never freezes is refused on ``geometry``."""
    try:
        return explore_orders(geometry, v, max_states=max_states, restarts=SAMPLED_ORDERS, seed=seed,
                              max_collisions=max_collisions, arithmetic=arithmetic, progress=progress)
    except FieldError:
        raise
    except ValueError as exc:  # explore_orders: an order came back to a state, or ran on unfrozen
        raise FieldError("geometry", f"{type(geometry).__name__} has no most collisions until frozen: {exc}") from None


class _Climbs:
    """Hill climbing with restarts over velocities (module docstring); `step` runs one trial."""

    def __init__(self, geometry: Geometry, start, patience: int, max_states: int, max_collisions: int,
                 rng: np.random.Generator):
        self.geometry, self.start, self.patience, self.rng = geometry, start, patience, rng
        self.max_states, self.max_collisions = max_states, max_collisions
        self.trials = self.climbs = self.stale = 0
        self.current: tuple[int, np.ndarray] | None = None  # the climb's (count, velocities)
        self.best: tuple[int, np.ndarray, int, tuple] | None = None  # (count, velocities, trial, its most order)

    def _next(self) -> np.ndarray:
        if self.current is not None and self.stale < self.patience:
            return moved(self.current[1], self.rng)
        self.current, self.stale = None, 0
        self.climbs += 1
        if self.climbs == 1 and self.start is not None:
            return self.start
        return random_velocities(self.rng, self.geometry.n_balls, self.geometry.dim)

    def step(self) -> None:
        v = self._next()
        seed = int(self.rng.integers(2**63))
        most = _most(self.geometry, v, self.max_states, self.max_collisions, seed, "float")
        count = most.max_collisions
        self.trials += 1
        if self.current is None or count > self.current[0]:
            self.current, self.stale = (count, v), 0
        else:
            self.stale += 1
            if count == self.current[0]:
                self.current = (count, v)
        if self.best is None or count > self.best[0]:
            self.best = (count, v, self.trials, most.max_order)


# ---------------------------------------------------------------- checks and the replay


def _start(geometry: Geometry, start) -> np.ndarray | None:
    if start is None:
        return None
    try:
        v = np.array(start, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("start", f"must be an array of numbers ({exc})") from None
    shape = (geometry.n_balls, geometry.dim)
    if v.shape != shape:
        raise FieldError("start", f"must have shape (n_balls, dim) = {shape}, got {v.shape}")
    if not np.isfinite(v).all():
        raise FieldError("start", "has a NaN or infinite component")
    if not v.any():
        raise FieldError("start", "is all zero: no direction to start from")
    return normalised(v)


def _arithmetic(geometry: Geometry, arithmetic: str) -> str:
    """``"exact"`` or ``"float"``: the result's arithmetic (``"auto"``: exact where the geometry has it)."""
    checks.choice("arithmetic", arithmetic, ("auto", "exact", "float"))
    if arithmetic == "float":
        return "float"
    try:
        Simulation(geometry, np.zeros((geometry.n_balls, geometry.dim)), arithmetic="exact")
    except FieldError as exc:
        if arithmetic == "exact" or exc.field != "arithmetic":
            raise
        return "float"
    return "exact"


def _replays(geometry: Geometry, v: np.ndarray, order: tuple[int, ...], arithmetic: str) -> bool:
    """Whether `Replay` of ``order`` in ``arithmetic`` collides at every pick and is frozen after the last."""
    sim = Simulation(geometry, v, scheduler=Replay(order), arithmetic=arithmetic)
    if order:
        sim.run_until_frozen(max_steps=len(order))
    return sim.is_frozen() and sim.steps == sim.collisions == len(order)


def _verified(geometry: Geometry, v: np.ndarray, final: OrdersResult, found: tuple[int, ...]) -> tuple[int, ...]:
    """The longer of ``final``'s most order and the search's order ``found`` (float arithmetic) that
    replays in ``final``'s arithmetic; RuntimeError if ``final``'s own does not."""
    if len(found) > len(final.max_order) and _replays(geometry, v, found, final.arithmetic):
        return found
    if not _replays(geometry, v, final.max_order, final.arithmetic):
        raise RuntimeError(f"search_max_collisions: the order of {final.max_collisions} collisions does not replay "
                           f"in {final.arithmetic} arithmetic to as many collisions, frozen")
    return final.max_order


# ---------------------------------------------------------------- the public function


def search_max_collisions(geometry: Geometry, trials: int = 1000, seed=0, *, start=None, patience: int = 50,
                          max_states: int = 20_000, final_states: int = 200_000, max_collisions: int = 10**5,
                          arithmetic: str = "auto", progress: bool | None = None) -> MaxCollisionsResult:
    """The most collisions until frozen found over initial velocities and orders of collisions.

    Equal masses, elastic collisions. ``trials`` velocities are evaluated, each by its most
    collisions over orders (`explore_orders` in float arithmetic, every order when they have at
    most ``max_states`` distinct states, else a lower bound), by hill climbing from random
    directions: one move at a time (one ball's velocity perturbed, or two balls' exchanged), kept
    when the count does not decrease, a new climb after ``patience`` trials without a rise (module
    docstring). The best velocities are searched again over orders with ``final_states`` states in
    ``arithmetic``; their most order is replayed in it (`Replay`) to its count, frozen, before returning.
    Same inputs give the same result. The bounds bound the call: ``trials`` searches of at most
    ``max_states`` states each and one of ``final_states`` (`explore_orders` says what a state costs).

    Parameters
    ----------
    geometry : Geometry
        The balls.
    trials : int
        Velocities evaluated.
    seed : int or numpy.random.SeedSequence
        Seeds the search.
    start : array_like, optional
        ``(n_balls, dim)``: where the first climb starts.
    patience : int
        Trials without a rise before a new climb.
    max_states : int
        States of each trial's search over orders.
    final_states : int
        States of the final search over orders.
    max_collisions : int
        The most collisions of one order.
    arithmetic : {"auto", "exact", "float"}
        Of the final search and the replay: ``"auto"`` (exact where the contact normals lie in a known
        number field, float elsewhere), ``"exact"`` or ``"float"``.
    progress : bool or None
        A bar over the trials, the most found so far beside it, then the final search's (True, False, or
        None: in a terminal or a notebook, once the call has taken 2 s).

    Returns
    -------
    MaxCollisionsResult

    Raises
    ------
    FieldError
        On ``geometry`` for a system that never freezes (a torus, a sphere): an order came back to a state
        it passed, or one of ``max_collisions`` collisions had not frozen; on ``start`` (a bad shape, NaN,
        all zero) or another argument.
    KeyboardInterrupt
        On Ctrl-C, the search so far discarded.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> m = pb.search_max_collisions(pb.HalfPlane(rows=2, cols=2), trials=20, seed=0)
    >>> m.collisions, len(m.order), m.exhaustive_orders, m.arithmetic
    (7, 7, True, 'exact')
    """
    if not isinstance(geometry, Geometry):
        raise FieldTypeError("geometry", f"must be a pinnedballs Geometry, got {type(geometry).__name__}")
    trials = checks.integer("trials", trials, 1)
    seed = checks.seed("seed", seed)
    patience = checks.integer("patience", patience, 1)
    max_states = checks.integer("max_states", max_states, 1)
    final_states = checks.integer("final_states", final_states, 1)
    max_collisions = checks.integer("max_collisions", max_collisions, 1)
    with deferred() as held:  # Ctrl-C between trials, states and collisions, never inside numba (compiling or running)
        start = _start(geometry, start)
        arithmetic = _arithmetic(geometry, arithmetic)
        rng = np.random.default_rng(seed)
        climbs = _Climbs(geometry, start, patience, max_states, max_collisions, rng)
        with Progress(progress, trials, "trials", "most collisions", scale=False) as bar:
            for trial in range(1, trials + 1):
                held.deliver()
                climbs.step()
                bar.update(trial, f"best={climbs.best[0]}")
        _, v, found_at, found = climbs.best
        final = _most(geometry, v, final_states, max_collisions, int(rng.integers(2**63)), arithmetic, progress)
        order = _verified(geometry, v, final, found)
    v.setflags(write=False)
    return MaxCollisionsResult(len(order), v, order, final.exhaustive, final.min_collisions,
                               final.states, climbs.trials, climbs.climbs, found_at, final.arithmetic)
