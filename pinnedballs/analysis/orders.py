"""Every order of collisions: the fewest and the most collisions until frozen.

The paper's scheduler follows one random order; the theory (Athreya-Burdzy-Duarte
2018, Burdzy-Duarte 2022) bounds the number of collisions over *every* order.
`explore_orders` searches them: depth first over the live contacts of each state,
with states merged by the exact bits of their velocities (two commuting
collisions reach the same state), so the search is over states, not sequences.
Each state's fewest and most collisions until frozen are kept once known.

A collision here is exactly the engine's: the rule's own jitted ``collide``, with
the same compile-time ``dim`` and ``flat``, and a contact is *live* when colliding
it would change a bit of a velocity. So every returned order replays through
`Simulation` with the `Replay` scheduler to the reported count, ending frozen.

When ``max_states`` stops the search, the figures become bounds reached by real
orders (fewest: at most; most: at least), improved by greedy orders (largest or
smallest closing speed first) and seeded random orders.
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
from numba import njit

from ..engine import checks
from ..engine.errors import FieldError
from ..engine.jitcache import jit_cached_if_possible
from ..geometry.base import Geometry
from ..rules import closing_speed
from ..schedulers.simple import UniformRandomPair
from ..simulation import Simulation

__all__ = ["explore_orders", "OrdersResult", "order_kernels", "orders_against_random"]


# ---------------------------------------------------------------- kernels


class OrderKernels(NamedTuple):
    """Compiled helpers of the search, for one rule's ``collide``, ``dim`` and ``flat``.

    live(v, pairs, ends, units, masses, params, min_w) -> (contacts (L,) int64, closing speeds (L,))
        the live contacts (colliding would change a bit of a velocity) closing faster than
        ``min_w`` (0: every live contact), in contact order;
    child(v, pairs, ends, units, masses, params, k) -> (n_balls, dim)
        a copy of ``v`` after colliding contact ``k``;
    collide_at(v, pairs, ends, units, masses, params, k) -> bool
        collides contact ``k`` in place; True if a velocity changed.

    ``v`` is ``(n_balls, dim)``; the tables are those of `pinnedballs.geometry.Contacts`.
    """

    live: Callable
    child: Callable
    collide_at: Callable


@functools.cache
def order_kernels(collide: Callable, dim: int, flat: bool) -> OrderKernels:
    """`OrderKernels` calling ``collide`` exactly as the engine's loop does."""
    D, FLAT = dim, flat  # compile-time constants, as in engine.loops.chain_kernel

    @njit(inline="always")
    def attempt(v, pairs, ends, units, masses, params, k, write):
        return collide(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], masses, params, D, FLAT, write)

    @jit_cached_if_possible
    def live(v, pairs, ends, units, masses, params, min_w):
        ks = np.empty(pairs.shape[0], dtype=np.int64)
        ws = np.empty(pairs.shape[0], dtype=np.float64)
        n = 0
        for k in range(pairs.shape[0]):
            if attempt(v, pairs, ends, units, masses, params, k, False):
                w = closing_speed(v, units, pairs[k, 0], pairs[k, 1], ends[k, 0], ends[k, 1], D, FLAT)
                if w > min_w:
                    ks[n], ws[n] = k, w
                    n += 1
        return ks[:n], ws[:n]

    @jit_cached_if_possible
    def child(v, pairs, ends, units, masses, params, k):
        out = v.copy()
        attempt(out, pairs, ends, units, masses, params, k, True)
        return out

    @jit_cached_if_possible
    def collide_at(v, pairs, ends, units, masses, params, k):
        return attempt(v, pairs, ends, units, masses, params, k, True)

    return OrderKernels(live, child, collide_at)


class _FloatSystem:
    """A float64 system: the engine's compiled ``collide`` on velocity arrays, states keyed by their bits."""

    arithmetic = "float"

    def __init__(self, sim: Simulation, min_closing_speed: float = 0.0):
        c, masses = sim.geometry.contacts, sim._mass_array
        self.min_w = float(min_closing_speed)
        self.tables = (c.pairs, c.ends, c.units, masses, sim._params)  # the rule's params and the threshold
        self.kernels = order_kernels(sim._collide, sim.geometry.dim, c.flat)
        self.start = np.ascontiguousarray(sim.velocities)

    def live(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.kernels.live(v, *self.tables, self.min_w)

    def child(self, v: np.ndarray, k: int) -> np.ndarray:
        return self.kernels.child(v, *self.tables, k)

    @staticmethod
    def key(v: np.ndarray) -> bytes:
        return _key(v)

    @staticmethod
    def size(v: np.ndarray) -> int:
        return v.nbytes


class _ExactSystem:
    """An exact system (`pinnedballs.engine.exact`): states are the exact velocities, tuples of field
    elements, merged by exact equality; a contact is live when its exact closing speed is positive."""

    arithmetic = "exact"

    def __init__(self, sim: Simulation, min_closing_speed: float = 0.0):
        self.chain, self.min_w = sim._exact, float(min_closing_speed)
        self.start = tuple(tuple(row) for row in self.chain.v)

    def live(self, v: tuple) -> tuple[np.ndarray, np.ndarray]:
        chain, F = self.chain, self.chain.field
        ks, ws = [], []
        for k, (i, j) in enumerate(chain.pairs):
            w = chain.closing_of(v[i], v[j], k)
            if F.sign(w) > 0 and (not self.min_w or F.to_float(w) > self.min_w):
                ks.append(k)
                ws.append(F.to_float(w))
        return np.array(ks, dtype=np.int64), np.array(ws, dtype=np.float64)

    def child(self, v: tuple, k: int) -> tuple:
        chain, (i, j), (a, b) = self.chain, self.chain.pairs[k], self.chain.ends[k]
        ci, cj = chain.kicks(chain.closing_of(v[i], v[j], k), k)
        out = list(v)
        out[i] = tuple(chain.kicked(v[i], ci, chain.units[a]))
        out[j] = tuple(chain.kicked(v[j], cj, chain.units[b]))
        return tuple(out)

    @staticmethod
    def key(v: tuple) -> tuple:
        return v

    def size(self, v: tuple) -> int:
        """About the bytes a state holds (its rationals grow with the collisions behind it)."""
        return sum(len(str(c)) + 64 for row in v for x in row for c in x)


#: states up to this many bytes are keyed by their bits; larger ones by a 128-bit digest of them
_EXACT_KEY_BYTES = 64

#: the search path keeps each open state's velocities: it stops before they take more than this
PATH_BYTES = 512 << 20


def _key(v: np.ndarray) -> bytes:
    """A state's identity: the bits of its velocities, or above `_EXACT_KEY_BYTES` their
    BLAKE2b-128 digest (two of a million states share one with probability below 1e-26),
    so that a million states of a thousand balls take 16 MB of keys, not 16 GB."""
    if v.nbytes <= _EXACT_KEY_BYTES:
        return v.tobytes()
    return hashlib.blake2b(v, digest_size=16).digest()


# ---------------------------------------------------------------- the result


@dataclass(frozen=True)
class OrdersResult:
    """Fewest and most collisions until frozen over orders of collisions.

    min_order, max_order: contact indices reaching ``min_collisions`` and ``max_collisions``
    (every pick a collision; replay them with `Replay`). ``states``: distinct states the
    depth-first search visited. When not ``exhaustive`` (``max_states`` stopped it, or the
    search path's velocities reached `PATH_BYTES`) the
    figures are bounds reached by real orders: the fewest is *at most* ``min_collisions``,
    the most *at least* ``max_collisions``; ``sampled`` orders (greedy, random) helped find them.
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
    """A state on the search path: its live contacts, the next to try, the best so far."""

    __slots__ = ("v", "key", "ks", "next", "lo", "hi", "k_lo", "k_hi")

    def __init__(self, v: np.ndarray, key: bytes, ks: np.ndarray):
        self.v, self.key, self.ks, self.next = v, key, ks.tolist(), 0
        self.lo, self.hi, self.k_lo, self.k_hi = -1, -1, -1, -1

    def take(self, k: int, lo: int, hi: int) -> None:
        """Fold in the child reached by contact ``k``, whose fewest and most are ``lo, hi``."""
        if self.lo < 0 or lo + 1 < self.lo:
            self.lo, self.k_lo = lo + 1, k
        if hi + 1 > self.hi:
            self.hi, self.k_hi = hi + 1, k

    def result(self) -> tuple[int, int, int, int]:
        """``(fewest, most, contact to the fewest, contact to the most)``; -1 contacts when frozen."""
        return (0, 0, -1, -1) if not self.ks else (self.lo, self.hi, self.k_lo, self.k_hi)


def _search(system, v0, max_states: int) -> tuple[dict, list[_Frame], int]:
    """Depth-first search from ``v0`` over at most ``max_states`` distinct states (and a path
    of at most `PATH_BYTES` of velocities).

    Returns ``(memo, path, states)``: ``memo[key] = (fewest, most, k_fewest, k_most)`` for
    every state fully explored, and the path of frames still open (empty when exhaustive).
    An explicit stack: orders can be longer than Python's recursion limit.
    """
    memo: dict[bytes, tuple[int, int, int, int]] = {}
    root = _Frame(v0, system.key(v0), system.live(v0)[0])
    path, on_path, states = [root], {root.key}, 1
    while path:
        f = path[-1]
        if f.next == len(f.ks):
            memo[f.key] = f.result()
            on_path.discard(f.key)
            path.pop()
            if path:
                parent = path[-1]
                r = memo[f.key]
                parent.take(parent.ks[parent.next], r[0], r[1])
                parent.next += 1
            continue
        k = f.ks[f.next]
        v = system.child(f.v, k)
        key = system.key(v)
        known = memo.get(key)
        if known is not None:
            f.take(k, known[0], known[1])
            f.next += 1
        elif key in on_path:
            raise ValueError(f"velocities: an order returns to a state it passed (by contact {k}), so this "
                             "system can collide forever (a torus or a sphere can): nothing freezes it")
        elif states >= max_states or (len(path) + 1) * system.size(v) > PATH_BYTES:
            return memo, path, states
        else:
            states += 1
            path.append(_Frame(v, key, system.live(v)[0]))
            on_path.add(key)
    return memo, [], states


def _follow(system, v, memo: dict, which: int) -> list[int]:
    """The order the memo records from the fully explored state ``v``: ``which`` 2 for the fewest, 3 the most."""
    order = []
    k = memo[system.key(v)][which]
    while k >= 0:
        order.append(k)
        v = system.child(v, k)
        k = memo[system.key(v)][which]
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
            lo = prefix + [f.k_lo] + _follow(system, system.child(f.v, f.k_lo), memo, 2)
            hi = prefix + [f.k_hi] + _follow(system, system.child(f.v, f.k_hi), memo, 3)
            best.offer(len(lo), lo, len(hi), hi)
        if f.next < len(f.ks):
            prefix = prefix + [f.ks[f.next]]


def _walk(system, v, memo: dict, choose: Callable, best: _Best, limit: int) -> None:
    """One order from ``v`` to frozen, each contact chosen by ``choose(contacts, closing speeds)``;
    it ends early at a fully explored state, whose fewest and most complete it both ways.
    Raises ValueError after ``limit`` collisions without freezing."""
    order: list[int] = []
    while len(order) < limit:
        known = memo.get(system.key(v))
        if known is not None:
            best.offer(len(order) + known[0], order + _follow(system, v, memo, 2),
                       len(order) + known[1], order + _follow(system, v, memo, 3))
            return
        ks, ws = system.live(v)
        if len(ks) == 0:
            best.offer(len(order), order, len(order), order)
            return
        k = int(ks[choose(ks, ws)])
        order.append(k)
        v = system.child(v, k)
    raise ValueError(f"max_collisions: an order of {limit:,} collisions has not frozen; raise max_collisions, "
                     "unless this system can collide forever (a torus or a sphere can)")


def _check_count(name: str, value, minimum: int) -> int:
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


def explore_orders(geometry: Geometry, velocities, masses=None, rule=None, max_states: int = 10**6,
                   *, restarts: int = 100, seed=0, min_closing_speed: float = 0.0,
                   max_collisions: int = 10**6, arithmetic: str = "auto") -> OrdersResult:
    """Fewest and most collisions until frozen over every order of collisions.

    geometry, velocities ``(n_balls, dim)``, masses ``(n_balls,)`` or None, rule (default
    `Elastic()`): as for `Simulation`. Searches every order when the system has at most
    ``max_states`` distinct states; otherwise returns bounds (``exhaustive=False``) from the
    part searched, two greedy orders (largest, then smallest closing speed first) and
    ``restarts`` orders choosing a live contact uniformly at random (``seed``: int or
    ``numpy.random.SeedSequence``). Same inputs give the same result.

    ``arithmetic``: ``"exact"`` searches in exact arithmetic (`pinnedballs.engine.exact`): states
    are merged by exact equality and a contact is live when its exact closing speed is positive,
    so the fewest and the most are exact; ``"float"`` uses the engine's float64 loop (states merged
    by their bits, rounding remnants below the engine's threshold left out); ``"auto"`` (default):
    exact where the geometry's normals lie in a known number field, float elsewhere. The result
    says which (``arithmetic``).

    ``min_closing_speed`` > 0 also leaves out contacts closing at or below it, in velocity units;
    the orders still replay collision for collision, but end with only such slow contacts live.

    Raises ValueError when an order returns to a state it passed, or when a sampled order of
    ``max_collisions`` collisions has not frozen: a torus or a sphere can collide forever.
    """
    sim = _simulation(geometry, velocities, masses, rule, checks.choice("arithmetic", arithmetic,
                                                                         ("auto", "exact", "float")))
    max_states = _check_count("max_states", max_states, 1)
    restarts = _check_count("restarts", restarts, 0)
    max_collisions = _check_count("max_collisions", max_collisions, 1)
    _check_seed(seed)
    _check_speed(min_closing_speed)
    system = (_ExactSystem if sim.arithmetic == "exact" else _FloatSystem)(sim, min_closing_speed)
    v0 = system.start
    memo, path, states = _search(system, v0, max_states)
    if not path:
        return OrdersResult(*_root_result(system, v0, memo), states=states, exhaustive=True,
                            arithmetic=system.arithmetic)
    best = _Best()
    _from_path(system, memo, path, best)
    _walk(system, v0, memo, lambda ks, ws: int(np.argmax(ws)), best, max_collisions)
    _walk(system, v0, memo, lambda ks, ws: int(np.argmin(ws)), best, max_collisions)
    rng = np.random.default_rng(seed)
    for _ in range(restarts):
        _walk(system, v0, memo, lambda ks, ws: int(rng.integers(len(ks))), best, max_collisions)
    return OrdersResult(best.lo[0], best.hi[0], tuple(best.lo[1]), tuple(best.hi[1]),
                        states=states, exhaustive=False, sampled=restarts + 2, arithmetic=system.arithmetic)


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


def _root_result(system, v0, memo: dict) -> tuple:
    lo, hi = memo[system.key(v0)][:2]
    return lo, hi, tuple(_follow(system, v0, memo, 2)), tuple(_follow(system, v0, memo, 3))


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
    replicas = _check_count("replicas", replicas, 1)
    _check_count("seed", seed, 0)
    orders = explore_orders(geometry, velocities, masses=masses, rule=rule, max_states=max_states, seed=seed)
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
