"""Every order of collisions: the fewest and the most collisions until frozen.

The paper's scheduler follows one random order; the theory (Athreya-Burdzy-Duarte
2018, Burdzy-Duarte 2022) bounds the number of collisions over *every* order.
`explore_orders` searches them: depth first over the live contacts of each state,
with states merged by their velocities (two commuting collisions reach the same
state), so the search is over states, not sequences. Each state's fewest and most
collisions until frozen are kept once known. The states, their keys and what each
costs are those of `order_systems` (float64 or exact arithmetic); every returned order
replays through `Simulation` with the `Replay` scheduler to the reported count, ending frozen.

When ``max_states`` stops the search, the figures become bounds reached by real
orders (fewest: at most; most: at least), improved by greedy orders (largest or
smallest closing speed first) and seeded random orders, which together take at most
``max(max_states, 10,000)`` more collisions: the bounds bound the whole call's time and
memory (memory beyond what the machine has is refused at once), a state on exact numbers grown
large counting as several (`Node.cost`). A system no order can freeze (a torus) is refused at once.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..geometry.base import Geometry
from ..schedulers.simple import UniformRandomPair
from ..simulation import Simulation
from ..util import checks
from ..util.errors import FieldError
from ..util.limits import check_memory
from ..util.progress import Progress
from ..util.sigint import Deferred, deferred
from .order_systems import NODE_BYTES, ExactSystem, FloatSystem, Node, order_kernels

__all__ = ["explore_orders", "OrdersResult", "order_kernels", "orders_against_random"]

#: the search path keeps each open state's velocities: it stops before they take more than this
PATH_BYTES = 512 << 20
#: the default bound on the states searched, in float64 and in exact arithmetic (a minute or two each)
MAX_STATES, MAX_EXACT_STATES = 10**6, 10**5
#: the sampled orders may take at least this many collisions in all, whatever ``max_states``
WALK_FLOOR = 10_000
#: states between two updates of the progress bar
_SHOW_EVERY = 64


# ---------------------------------------------------------------- the result


@dataclass(frozen=True)
class OrdersResult:
    """Fewest and most collisions until frozen over orders of collisions (what `explore_orders` returns).

    When not ``exhaustive`` the figures are bounds reached by real orders: the fewest is *at most*
    ``min_collisions``, the most *at least* ``max_collisions``.

    Parameters
    ----------
    min_collisions, max_collisions : int
        The fewest and the most collisions until frozen.
    min_order, max_order : tuple of int
        Contact indices reaching ``min_collisions`` and ``max_collisions`` (every pick a collision;
        replay them with `Replay`).
    states : int
        Distinct states the depth-first search visited.
    exhaustive : bool
        Every order was searched (False: ``max_states`` stopped it, or the search path's velocities
        reached `PATH_BYTES`).
    sampled : int
        Orders sampled (greedy, random) that helped find the bounds.
    arithmetic : {"exact", "float"}
        The arithmetic of the search.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=2, cols=3)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[1] = [0.0, 1.0]
    >>> print(pb.explore_orders(g, v))
    Collisions until frozen over every order (32 distinct states): fewest 4, most 6.
    """

    min_collisions: int
    max_collisions: int
    min_order: tuple[int, ...]
    max_order: tuple[int, ...]
    states: int
    exhaustive: bool
    sampled: int = 0
    arithmetic: str = "exact"

    def _figures(self) -> tuple[str, str]:
        if self.exhaustive:
            return f"{self.min_collisions}", f"{self.max_collisions}"
        return f"at most {self.min_collisions}", f"at least {self.max_collisions}"

    def __str__(self) -> str:
        fewest, most = self._figures()
        if self.exhaustive:
            how = f"every order ({self.states:,} distinct states)"
        else:
            how = (f"a partial search ({self.states:,} states) and {self.sampled} sampled orders "
                   "(bounds, not exact)")
        return f"Collisions until frozen over {how}: fewest {fewest}, most {most}."

    def __repr__(self) -> str:
        fewest, most = self._figures()
        return (f"OrdersResult(min_collisions={fewest}, max_collisions={most}, states={self.states}, "
                f"exhaustive={self.exhaustive})")


# ---------------------------------------------------------------- the exhaustive search


class _Frame:
    """A state on the search path: its node, the next live contact to try, the best so far."""

    __slots__ = ("node", "next", "lo", "hi", "k_lo", "k_hi")

    def __init__(self, node: Node):
        self.node, self.next = node, 0
        self.lo, self.hi, self.k_lo, self.k_hi = -1, -1, -1, -1

    def take(self, k: int, lo: int, hi: int) -> None:
        """Fold in the child reached by contact ``k``, whose fewest and most are ``lo, hi``."""
        if self.lo < 0 or lo + 1 < self.lo:
            self.lo, self.k_lo = lo + 1, k
        if hi + 1 > self.hi:
            self.hi, self.k_hi = hi + 1, k

    def result(self) -> tuple[int, int, int, int]:
        """``(fewest, most, contact to the fewest, contact to the most)``; -1 contacts when frozen."""
        return (0, 0, -1, -1) if len(self.node.ks) == 0 else (self.lo, self.hi, self.k_lo, self.k_hi)


def _never_freezes(limit: int) -> ValueError:
    return ValueError(f"max_collisions: an order of {limit:,} collisions has not frozen; raise max_collisions, "
                      "unless this system can collide forever (a torus or a sphere can)")


def _search(system, root: Node, max_states: int, max_collisions: int, bar: Progress,
            held: Deferred) -> tuple[dict, list[_Frame], int]:
    """Depth-first search from ``root`` over at most ``max_states`` distinct states, each counting its
    `Node.cost` (and a path of at most `PATH_BYTES` of velocities).

    Returns ``(memo, path, states)``: ``memo[key] = (fewest, most, k_fewest, k_most)`` for
    every state fully explored, and the path of frames still open (empty when exhaustive).
    An explicit stack: orders can be longer than Python's recursion limit.
    """
    memo: dict[int, tuple[int, int, int, int]] = {}
    path, on_path, states, path_bytes = [_Frame(root)], {root.key}, 1, root.nbytes
    work = root.cost  # states, a state on large exact numbers counting as several (`Node.cost`)
    while path:
        held.deliver()  # Ctrl-C between states (never inside a compiled kernel: `util.sigint`)
        f = path[-1]
        if f.next == len(f.node.ks):
            memo[f.node.key] = f.result()
            on_path.discard(f.node.key)
            path_bytes -= f.node.nbytes
            path.pop()
            if path:
                parent = path[-1]
                r = memo[f.node.key]
                parent.take(int(parent.node.ks[parent.next]), r[0], r[1])
                parent.next += 1
            continue
        k = int(f.node.ks[f.next])
        child = system.child(f.node, k)
        known = memo.get(child.key)
        if known is not None:
            f.take(k, known[0], known[1])
            f.next += 1
        elif child.key in on_path:
            raise ValueError(f"velocities: an order returns to a state it passed (by contact {k}), so this "
                             "system can collide forever (a torus or a sphere can): nothing freezes it")
        elif work + child.cost > max_states or path_bytes + child.nbytes > PATH_BYTES:
            bar.update(work)
            return memo, path, states
        elif len(path) >= max_collisions and len(child.ks):
            raise _never_freezes(max_collisions)
        else:
            states += 1
            work += child.cost
            path.append(_Frame(child))
            on_path.add(child.key)
            path_bytes += child.nbytes
            if states % _SHOW_EVERY == 0:
                bar.update(work)
    bar.update(work)
    return memo, [], states


def _follow(system, node: Node, memo: dict, which: int) -> list[int]:
    """The order the memo records from the fully explored state ``node``: ``which`` 2 for the fewest, 3 the most."""
    order = []
    k = memo[node.key][which]
    while k >= 0:
        order.append(k)
        node = system.child(node, k)
        k = memo[node.key][which]
    return order


# ---------------------------------------------------------------- bounds when the search stops


class _Best:
    """The fewest and the most collisions of the complete orders seen so far."""

    def __init__(self):
        self.lo = self.hi = None  # (count, order)

    def offer(self, count_lo: int, order_lo: list[int], count_hi: int, order_hi: list[int]) -> None:
        if self.lo is None or count_lo < self.lo[0]:
            self.lo = (count_lo, order_lo)
        if self.hi is None or count_hi > self.hi[0]:
            self.hi = (count_hi, order_hi)


def _from_path(system, memo: dict, path: list[_Frame], best: _Best) -> None:
    """Complete orders through the open frames' explored children."""
    prefix: list[int] = []
    for f in path:
        if f.hi >= 0:
            lo = prefix + [f.k_lo] + _follow(system, system.child(f.node, f.k_lo), memo, 2)
            hi = prefix + [f.k_hi] + _follow(system, system.child(f.node, f.k_hi), memo, 3)
            best.offer(len(lo), lo, len(hi), hi)
        if f.next < len(f.node.ks):
            prefix = prefix + [int(f.node.ks[f.next])]


class _Budget:
    """The collisions orders may still take, all together (`explore_orders`' bound), one on large exact
    numbers counting as several (`Node.cost`); ``tally()`` is told of each one (the progress)."""

    def __init__(self, collisions: int, tally: Callable[[], None]):
        self.left, self.tally, self.heavy = collisions, tally, False

    def spend(self, cost: int) -> bool:
        """One collision more, costing ``cost`` (that of the state it leaves), if that much is left."""
        if self.left < cost:
            return False
        self.left -= cost
        self.heavy |= cost > 1
        self.tally()
        return True


class _Tally:
    """Collisions counted on ``bar`` (call it for each one; `shown` when done)."""

    def __init__(self, bar: Progress, held: Deferred):
        self.bar, self.count, self.held = bar, 0, held

    def __call__(self) -> None:
        self.held.deliver()  # Ctrl-C between collisions
        self.count += 1
        if self.count % _SHOW_EVERY == 0:
            self.bar.update(self.count)

    def shown(self) -> None:
        self.bar.update(self.count)


def _walk(system, node: Node, memo: dict, choose: Callable, best: _Best, limit: int, budget: _Budget) -> bool:
    """One order from ``node`` to frozen, each contact chosen by ``choose(contacts, closing speeds)``;
    it ends early at a fully explored state, whose fewest and most complete it both ways. False when
    it was given up because the ``budget`` ran out. Raises ValueError after ``limit`` collisions
    without freezing."""
    order: list[int] = []
    while len(order) < limit:
        known = memo.get(node.key)
        if known is not None:
            best.offer(len(order) + known[0], order + _follow(system, node, memo, 2),
                       len(order) + known[1], order + _follow(system, node, memo, 3))
            return True
        ks, ws = system.speeds(node)
        if len(ks) == 0:
            best.offer(len(order), order, len(order), order)
            return True
        if not budget.spend(node.cost):
            return False
        k = int(ks[choose(ks, ws)])
        order.append(k)
        node = system.child(node, k, speeds=True)
    raise _never_freezes(limit)


def check_count(name: str, value, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name}: must be an integer, got {value!r}")
    if value < minimum:
        raise ValueError(f"{name}: must be >= {minimum}, got {value}")
    return int(value)


def _check_seed(seed) -> None:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer, np.random.SeedSequence)):
        raise TypeError(f"seed: must be a non-negative int or numpy SeedSequence, got {type(seed).__name__}")
    if not isinstance(seed, np.random.SeedSequence) and seed < 0:
        raise ValueError(f"seed: must be a non-negative integer, got {seed}")


def _check_speed(speed) -> None:
    if isinstance(speed, bool) or not isinstance(speed, (int, float, np.number)):
        raise TypeError(f"min_closing_speed: must be a number, got {speed!r}")
    if not (np.isfinite(speed) and speed >= 0):
        raise ValueError(f"min_closing_speed: must be finite and >= 0, got {speed}")


# ---------------------------------------------------------------- the public function


def explore_orders(geometry: Geometry, velocities, masses=None, rule=None, max_states: int | None = None,
                   *, restarts: int = 100, seed=0, min_closing_speed: float = 0.0,
                   max_collisions: int = 10**6, arithmetic: str = "auto", progress: bool | None = None) -> OrdersResult:
    """Fewest and most collisions until frozen over every order of collisions.

    Searches every order when the system has at most ``max_states`` distinct states; otherwise returns
    bounds (``exhaustive=False``) from the part searched, two greedy orders (largest, then smallest closing
    speed first) and up to ``restarts`` orders choosing a live contact uniformly at random. Same inputs give
    the same result. States are told apart by a 128-bit key of their velocities (`order_systems`): two of a
    million distinct states share one with probability below 1e-26.

    Parameters
    ----------
    geometry : Geometry
        As for `Simulation`.
    velocities : array_like
        ``(n_balls, dim)``, as for `Simulation`.
    masses : array_like, optional
        ``(n_balls,)``, or None (all equal).
    rule : CollisionRule, optional
        Default `Elastic()`.
    max_states : int, optional
        Bounds the call: at most ``max_states`` states are searched and ``max(max_states, 10,000)`` more
        made along the sampled orders (`WALK_FLOOR`), each in about 2-30 us (float64, ten to a thousand
        balls) or 0.04-1 ms (exact arithmetic, any size), a state whose exact numbers have grown large
        counting as several (`order_systems.COST_BYTES`: restitution r < 1 makes them grow along an order);
        the search keeps about 300 bytes per state. None, the default: `MAX_STATES` in float64 (10^6),
        `MAX_EXACT_STATES` in exact arithmetic (10^5), a minute or two either way.
    restarts : int
        Orders choosing a live contact uniformly at random, these sampled orders taking at most
        ``max(max_states, 10,000)`` collisions in all.
    seed : int or numpy.random.SeedSequence
        Seeds the sampled orders.
    min_closing_speed : float
        > 0 also leaves out contacts closing at or below it, in velocity units; the orders still replay
        collision for collision, but end with only such slow contacts live.
    max_collisions : int
        The most collisions of one sampled order.
    arithmetic : {"auto", "exact", "float"}
        ``"exact"`` searches in exact arithmetic (`pinnedballs.engine.field.rational`): states
        are merged by their exact values and a contact is live when its exact closing speed is positive,
        so the fewest and the most are exact; ``"float"`` uses the engine's float64 loop (states merged
        by their bits, rounding remnants below the engine's threshold left out); ``"auto"`` (default):
        exact where the geometry's normals lie in a known number field, float elsewhere. The result
        says which (``arithmetic``).
    progress : bool or None
        A bar over the states, then a count of the sampled orders' collisions (True, False, or None: in
        a terminal or a notebook, once the call has taken 2 s).

    Returns
    -------
    OrdersResult

    Raises
    ------
    FieldError
        On ``max_states`` for a bound needing more memory than the machine has (at once), or on the
        system as `Simulation` checks it.
    ValueError
        Naming the argument: at once on ``velocities`` where no order can freeze (a torus not frozen at the
        start, ``min_closing_speed`` 0, with any r > 0 in exact arithmetic or, on a `Geometry.rigid` one,
        elastic collisions: `docs/model.md`), and on a count or speed out of range (a TypeError for one that
        is no number); when no order reaches frozen within the bound (raise ``max_states``), when an order
        returns to a state it passed, or when an order of ``max_collisions`` collisions has not frozen: a
        torus or a sphere can collide forever.
    KeyboardInterrupt
        On Ctrl-C, the partial search discarded.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=2, cols=3)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[1] = [0.0, 1.0]
    >>> r = pb.explore_orders(g, v)
    >>> r.min_collisions, r.max_collisions, r.exhaustive, r.arithmetic
    (4, 6, True, 'exact')
    >>> r.max_order
    (3, 2, 4, 0, 8, 6)
    """
    with deferred() as held:  # Ctrl-C at the next state or collision, never inside numba (compiling or running)
        sim = _simulation(geometry, velocities, masses, rule, checks.choice("arithmetic", arithmetic,
                                                                             ("auto", "exact", "float")))
        if max_states is None:
            max_states = MAX_EXACT_STATES if sim.arithmetic == "exact" else MAX_STATES
        max_states = check_count("max_states", max_states, 1)
        restarts = check_count("restarts", restarts, 0)
        max_collisions = check_count("max_collisions", max_collisions, 1)
        _check_seed(seed)
        _check_speed(min_closing_speed)
        check_memory(max_states * NODE_BYTES + min(PATH_BYTES, max_states * sim.velocities.nbytes), "max_states",
                     f"a search of {max_states:,} states of {geometry.n_balls:,} balls")
        system = (ExactSystem if sim.arithmetic == "exact" else FloatSystem)(sim, min_closing_speed)
        never = None if min_closing_speed else sim.never_freezes()
        return _explore(system, max_states, max_collisions, seed, restarts, progress, held, never)


def _explore(system, max_states: int, max_collisions: int, seed, restarts: int, progress, held: Deferred,
             never: str | None = None) -> OrdersResult:
    """`explore_orders` once its arguments are checked: the search over states, then sampled orders.
    ``never``: why this system, unless it starts frozen, never freezes (`Simulation.never_freezes`)."""
    root = system.root()
    if never and len(root.ks):
        raise ValueError(f"velocities: no order of this system ever freezes: {never}")
    with Progress(progress, max_states, "states", "orders", scale=False) as bar:
        memo, path, states = _search(system, root, max_states, max_collisions, bar, held)
    if not path:
        return OrdersResult(*_root_result(system, root, memo), states=states, exhaustive=True,
                            arithmetic=system.arithmetic)
    best = _Best()
    _from_path(system, memo, path, best)
    rng = np.random.default_rng(seed)
    chosen = [lambda ks, ws: int(np.argmax(ws)), lambda ks, ws: int(np.argmin(ws))]
    chosen += [lambda ks, ws: int(rng.integers(len(ks)))] * restarts
    sampled = 0
    with Progress(progress, None, "collisions", "sampled orders", scale=False) as bar:
        tally = _Tally(bar, held)
        budget = _Budget(max(max_states, WALK_FLOOR), tally)
        for choose in chosen:
            if not _walk(system, root, memo, choose, best, max_collisions, budget):
                break
            sampled += 1
        tally.shown()
    if best.lo is None:
        heavy = " (on numbers grown large, one counting as several)" if budget.heavy else ""
        raise ValueError(f"max_states: no order reached frozen within the bound: the search of {states:,} states, "
                         f"then {max(max_states, WALK_FLOOR):,} collisions along sampled orders{heavy}; this system's "
                         f"orders are longer (raise max_states), or never end (on a torus or a sphere they can)")
    return OrdersResult(best.lo[0], best.hi[0], tuple(best.lo[1]), tuple(best.hi[1]),
                        states=states, exhaustive=False, sampled=sampled, arithmetic=system.arithmetic)


def _simulation(geometry, velocities, masses, rule, arithmetic: str) -> Simulation:
    """The system as a `Simulation` (which checks every input as the engine does), in exact
    arithmetic when asked for or, with ``"auto"``, when the geometry and rule allow it."""
    if arithmetic != "float":
        try:
            return Simulation(geometry, velocities, rule=rule, masses=masses, arithmetic="exact")
        except FieldError as exc:
            if arithmetic == "exact" or exc.field != "arithmetic":
                raise
    return Simulation(geometry, velocities, rule=rule, masses=masses)


def _root_result(system, root: Node, memo: dict) -> tuple:
    lo, hi = memo[root.key][:2]
    return lo, hi, tuple(_follow(system, root, memo, 2)), tuple(_follow(system, root, memo, 3))


# ---------------------------------------------------------------- against the random order


def orders_against_random(geometry: Geometry, velocities, replicas: int = 200, seed=0, masses=None, rule=None,
                          max_states: int = 10**6, max_steps: int = 10**9) -> dict:
    """Fewest and most collisions over all orders against the paper's random order (plain numbers).

    Runs ``replicas`` simulations with `UniformRandomPair` until frozen, replica ``k`` seeded
    with ``SeedSequence(seed, spawn_key=(k,))``, and `explore_orders` on the same system.
    Returns a dict: ``balls``, ``contacts``, ``min_collisions``, ``max_collisions``,
    ``exhaustive``, ``states``, ``replicas``, ``random_mean``, ``random_sd`` (sample),
    ``random_min``, ``random_max``, ``random_at_min`` and ``random_at_max`` (fractions of
    replicas reaching the fewest and the most) and ``random_histogram``, ``[[collisions, replicas], ...]``
    in increasing collisions.
    """
    replicas = check_count("replicas", replicas, 1)
    check_count("seed", seed, 0)
    orders = explore_orders(geometry, velocities, masses=masses, rule=rule, max_states=max_states, seed=seed,
                            progress=False)
    counts = np.empty(replicas, dtype=np.int64)
    for k in range(replicas):
        sim = Simulation(geometry, velocities, rule=rule, scheduler=UniformRandomPair(), masses=masses,
                         seed=np.random.SeedSequence(seed, spawn_key=(k,)))
        if not sim.run_until_frozen(max_steps=max_steps):
            raise RuntimeError(f"orders_against_random: replica {k} not frozen after max_steps = {max_steps}")
        counts[k] = sim.collisions
    return {
        "balls": geometry.n_balls, "contacts": geometry.n_contacts,
        "min_collisions": orders.min_collisions, "max_collisions": orders.max_collisions,
        "exhaustive": orders.exhaustive, "states": orders.states, "replicas": replicas,
        "random_mean": float(counts.mean()), "random_sd": float(counts.std(ddof=1)) if replicas > 1 else 0.0,
        "random_min": int(counts.min()), "random_max": int(counts.max()),
        "random_at_min": float(np.mean(counts == orders.min_collisions)),
        "random_at_max": float(np.mean(counts == orders.max_collisions)),
        "random_histogram": [[int(n), int(runs)] for n, runs in zip(*np.unique(counts, return_counts=True))],
    }
