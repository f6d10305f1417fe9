"""The states `explore_orders` walks through, in float64 or in exact arithmetic, and what each costs.

A state is a `Node`: its velocities ``v``, a 128-bit ``key``, its live contacts ``ks`` in contact
order and, when a sampled order asks for them, their closing speeds ``ws``. A system makes the root
node of the velocities given and the child a collision of contact ``k`` leads to.

A collision here is exactly the engine's: in float64 the rule's own jitted ``collide`` with the same
compile-time ``dim`` and ``flat`` (a contact is live when colliding it would change a bit of a
velocity); in exact arithmetic the collision of `pinnedballs.engine.field.rational` in the number field of
the contact normals (a contact is live when its exact closing speed is positive). So every order
replays through `Simulation` with the `Replay` scheduler to the same count.

Keys (Zobrist hashing): the sum modulo 2^128 of a BLAKE2b-128 digest of each ball's index and
velocity bits (float) or exact coefficients. A child's key is its parent's with the two collided
balls' terms replaced: O(1) per state, not O(balls). Two of a million distinct states share a key
with probability below 1e-26. Float states of at most `WHOLE_BYTES` are keyed from all their bits at
once (the bits themselves up to `SMALL_BYTES`), which is faster for so few balls.

Cost of a state: in float64, a copy of the velocities and the live contacts found again by a compiled
kernel over all contacts (a few ns a contact: `benchmarks/results/measurements.md`); in exact arithmetic
only the contacts at the two collided balls are tested again, each by a float filter first
(`pinnedballs.engine.field.rational.FILTER`), the others keeping their parent's answer, so a state costs about
as much on 10,000 balls as on 10, but more as its numbers grow: with restitution r < 1 they grow along an order
(on a 4x4 torus with r = 1/2 two balls' numbers take 0.6 kB at first, 26 kB after 20,000 collisions), so such a
state counts as several (`Node.cost`, `COST_BYTES`).
"""

from __future__ import annotations

import bisect
import functools
import hashlib
import itertools
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from gmpy2 import to_binary
from numba import njit

from ..engine.chain import incidence
from ..engine.field.chain import filtered_sign
from ..engine.jit.cache import jit_cached_if_possible
from ..rules import closing_speed

__all__ = ["Node", "FloatSystem", "ExactSystem", "OrderKernels", "order_kernels", "NODE_BYTES", "COST_BYTES"]

#: bytes a known state holds in the search's memo (its key, its figures, the dict's slot): an upper estimate of the
#: size measured (`benchmarks/results/measurements.md`)
NODE_BYTES = 320
#: an exact state whose two collided balls' numbers take ``b`` bytes costs ``1 + b // COST_BYTES`` states:
#: its time grows with them (`benchmarks/results/measurements.md`), and restitution r < 1
#: makes them grow along an order without end, so the bounds count work, not states alone
COST_BYTES = 2048
#: float states of at most this many bytes are keyed by their bits themselves (exact) ...
SMALL_BYTES = 64
#: ... and up to this many by a BLAKE2b-128 digest of all their bits (faster than Zobrist's four digests)
WHOLE_BYTES = 4096
_MOD = 1 << 128


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
    D, FLAT = dim, flat  # compile-time constants, as in engine.sequential.loops.chain_kernel

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


# ---------------------------------------------------------------- states


class Node:
    """A state: velocities ``v``, their ``key``, the live contacts ``ks`` in contact order (an ``(L,) int64``
    array in float64, a list in exact arithmetic), their closing speeds ``ws`` (None until asked for),
    ``nbytes``, what it holds on the search path, ``cost``, what making it took in states (`COST_BYTES`),
    and in exact arithmetic the velocities' float roundings ``floats`` and each ball's term of the key, ``terms``."""

    __slots__ = ("v", "key", "ks", "ws", "nbytes", "floats", "terms", "cost")

    def __init__(self, v, key, ks, ws=None, nbytes: int = 0, floats=None, terms=None, cost: int = 1):
        self.v, self.key, self.ks, self.ws, self.nbytes = v, key, ks, ws, nbytes
        self.floats, self.terms, self.cost = floats, terms, cost


def _term(ball: int, data: bytes) -> int:
    """Ball ``ball``'s term of a key: a BLAKE2b-128 digest of its index and its velocity's ``data``."""
    return int.from_bytes(hashlib.blake2b(data, digest_size=16, salt=ball.to_bytes(8, "little")).digest(), "little")


class FloatSystem:
    """States in float64: ``v`` an ``(n_balls, dim)`` array, collided by the engine's compiled ``collide``."""

    arithmetic = "float"

    def __init__(self, sim, min_closing_speed: float = 0.0):
        c = sim.geometry.contacts
        self.min_w = float(min_closing_speed)
        self.pairs = c.pairs.tolist()
        model = sim.engine.model
        self.tables = (c.pairs, c.ends, c.units, model.masses, model.params)  # the rule's params and the threshold
        self.kernels = order_kernels(model.collide, sim.geometry.dim, c.flat)
        self.start = np.ascontiguousarray(sim.velocities)
        self.whole = self.start.nbytes <= WHOLE_BYTES  # keyed from all their bits at once

    def _node(self, v: np.ndarray, key: int) -> Node:
        ks, ws = self.kernels.live(v, *self.tables, self.min_w)
        return Node(v, key, ks, ws, v.nbytes + 16 * len(ks))

    def root(self) -> Node:
        v = self.start
        return self._node(v, self._whole(v) if self.whole
                          else sum(_term(b, row.tobytes()) for b, row in enumerate(v)) % _MOD)

    def child(self, node: Node, k: int, speeds: bool = False) -> Node:
        """The state after colliding contact ``k`` of ``node`` (its closing speeds always come along)."""
        v = self.kernels.child(node.v, *self.tables, k)
        if self.whole:
            return self._node(v, self._whole(v))
        key = node.key
        for b in self.pairs[k]:
            key += _term(b, v[b].tobytes()) - _term(b, node.v[b].tobytes())
        return self._node(v, key % _MOD)

    @staticmethod
    def _whole(v: np.ndarray):
        """The key of a small state from all its bits: the bits themselves, or their BLAKE2b-128 digest."""
        data = v.tobytes()
        return data if len(data) <= SMALL_BYTES else hashlib.blake2b(data, digest_size=16).digest()

    @staticmethod
    def speeds(node: Node) -> tuple[np.ndarray, np.ndarray]:
        """``(contacts (L,), closing speeds (L,))`` of the live contacts of ``node``."""
        return node.ks, node.ws


class ExactSystem:
    """States in exact arithmetic (`pinnedballs.engine.field.rational`): ``v`` a tuple of rows, each a tuple of
    field elements, with their float roundings beside them (``floats``) for the filter."""

    arithmetic = "exact"

    def __init__(self, sim, min_closing_speed: float = 0.0):
        self.chain, self.min_w = sim.engine.state.field_chain, float(min_closing_speed)
        self.field = self.chain.field
        g = sim.geometry
        ptr, inc = incidence(g.contacts.pairs, g.n_balls)
        self.around = [tuple(inc[ptr[b]:ptr[b + 1]].tolist()) for b in range(g.n_balls)]
        self.pairs, self.ends = g.contacts.pairs.tolist(), g.contacts.ends.tolist()
        self.units_f = g.contacts.units.tolist()
        self.dim, self.n_balls = g.dim, g.n_balls
        self.near: dict[int, tuple[list[int], frozenset]] = {}
        self.start = tuple(tuple(row) for row in self.chain.v)

    # ------------------------------------------------------------ one contact
    def _approaching(self, v, floats, k: int) -> bool:
        """True when contact ``k``'s exact closing speed is positive: the float filter, then exactly."""
        i, j = self.pairs[k]
        a, b = self.ends[k]
        sign, size = filtered_sign(self.units_f[a], self.units_f[b], floats[i], floats[j], self.dim)
        if sign:
            return sign > 0
        if size == 0 and not any(map(any, v[i])) and not any(map(any, v[j])):  # both at rest
            return False
        return self.field.sign(self.chain.closing_of(v[i], v[j], k)) > 0

    def _speed(self, v, k: int) -> float:
        i, j = self.pairs[k]
        return self.field.to_float(self.chain.closing_of(v[i], v[j], k))

    def _live(self, v, floats, k: int) -> bool:
        return self._approaching(v, floats, k) and (not self.min_w or self._speed(v, k) > self.min_w)

    # ------------------------------------------------------------ states
    def _row(self, row) -> tuple[tuple, bytes]:
        """A row's float roundings, and its exact coefficients as bytes (each length-prefixed: one row,
        one string), linear in their size (``repr`` is not)."""
        data = b"".join(len(b).to_bytes(4, "little") + b for b in map(to_binary, itertools.chain.from_iterable(row)))
        return tuple(self.field.to_float(x) for x in row), data

    def root(self) -> Node:
        v = self.start
        rows = [self._row(row) for row in v]
        floats = tuple(f for f, _ in rows)
        terms = tuple(_term(b, data) for b, (_, data) in enumerate(rows))
        ks = [k for k in range(len(self.pairs)) if self._live(v, floats, k)]
        return Node(v, sum(terms) % _MOD, ks, None, 8 * self.n_balls + sum(len(d) for _, d in rows), floats, terms)

    def child(self, node: Node, k: int, speeds: bool = False) -> Node:
        """The state after colliding contact ``k`` of ``node``; its live contacts found again only at the
        two balls that collided; ``speeds``: with their closing speeds (``node``'s must be known)."""
        chain, (i, j), (a, b) = self.chain, self.pairs[k], self.ends[k]
        v, floats, terms = list(node.v), list(node.floats), list(node.terms)
        key, nbytes, size = node.key, 8 * self.n_balls, 0
        ci, cj = chain.kicks(chain.closing_of(v[i], v[j], k), k)
        for ball, c, t in ((i, ci, chain.units[a]), (j, cj, chain.units[b])):
            v[ball] = tuple(chain.kicked(v[ball], c, t))
            floats[ball], data = self._row(v[ball])
            key -= terms[ball]
            terms[ball] = _term(ball, data)
            key += terms[ball]
            size += len(data)
        v, floats = tuple(v), tuple(floats)
        near, around = self._near(k)
        fresh = [c for c in near if self._live(v, floats, c)]
        ks = [c for c in node.ks if c not in around]
        for c in fresh:
            bisect.insort(ks, c)
        ws = None
        if speeds:
            ws = {c: w for c, w in node.ws.items() if c not in around}
            ws.update((c, self._speed(v, c)) for c in fresh)
        return Node(v, key % _MOD, ks, ws, nbytes + size + 16 * len(ks), floats, tuple(terms), 1 + size // COST_BYTES)

    def _near(self, k: int) -> tuple[list[int], frozenset]:
        """The contacts at either ball of contact ``k``, in order, and as a set."""
        near = self.near.get(k)
        if near is None:
            i, j = self.pairs[k]
            around = frozenset(self.around[i]) | frozenset(self.around[j])
            near = self.near[k] = (sorted(around), around)
        return near

    def speeds(self, node: Node) -> tuple[np.ndarray, np.ndarray]:
        """``(contacts (L,), closing speeds (L,))`` of the live contacts of ``node`` (kept in ``node.ws``)."""
        if node.ws is None:
            node.ws = {c: self._speed(node.v, c) for c in node.ks}
        return np.array(node.ks, dtype=np.int64), np.array([node.ws[c] for c in node.ks], dtype=np.float64)
