"""The chain as plain data: what it is (`Model`, fixed for its life), what changes as it runs (`ChainState`),
the arrays every compiled loop reads (`Chain`), the counters, the live-contact set and the incidence that
says which contacts to re-test after a collision.

A `Simulation` builds a `Model` and a `ChainState` and hands both to the backend that runs its chain
(`engine.backends`); every engine takes them and hands them back, and nothing below the simulation reads
anything else of it (JAX-MD's state records, HOOMD-blue's ``Simulation.state``)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

__all__ = ["Model", "ChainState", "Chain", "LiveSet", "incidence", "STEPS", "COLLISIONS", "LIVE", "LAST", "COUNTERS",
           "NO_LIMIT"]

#: indices into the ``counters (COUNTERS,) int64`` array shared by Python and the loops: steps and
#: collisions so far, live contacts (-1: unknown), and the step count right after the last collision a
#: call made (left as it was by a call that made none)
STEPS, COLLISIONS, LIVE, LAST = 0, 1, 2, 3
COUNTERS = 4

NO_LIMIT = np.iinfo(np.int64).max  #: "no limit" for max_steps or max_collisions


@dataclass(frozen=True, eq=False)
class Model:
    """What a chain is, fixed for its life: the engine's view of a `Simulation`'s geometry, masses, rule and
    scheduler, as plain data.

    geometry: the `Geometry` (its ``contacts``, ``n_balls``, ``dim``, ``row_pattern``); masses ``(n_balls,)``;
    collide: the rule's jitted ``collide`` (`pinnedballs.rules`); params: the rule's params with the collision
    threshold last (``params[-1]``); selector: the scheduler's `Selector`; threads: the threads the scheduler
    asks for (None: as many as pay); rule and scheduler: the components themselves, which an engine names in a
    refusal, compiles for itself (a GPU compiles the rule's functions) or runs in exact form (exact and certified
    arithmetic: the rule's `pinnedballs.rules.CollisionRule.exact_kick`).
    """

    geometry: object
    masses: np.ndarray
    collide: Callable
    params: np.ndarray
    selector: object
    threads: int | None = None
    rule: object = None
    scheduler: object = None

    @property
    def threshold(self) -> float:
        """The collision threshold: a pick collides only when its closing speed exceeds it."""
        return float(self.params[-1])

    def chain(self, velocities: np.ndarray) -> Chain:
        """The arrays a compiled loop reads, for ``velocities``."""
        c = self.geometry.contacts
        return Chain(velocities, c.pairs, c.ends, c.units, self.masses, self.params)


@dataclass(eq=False)
class ChainState:
    """What changes as a chain runs, as plain data the engines read and write in place.

    velocities ``(n_balls, dim) float64`` (on a GPU, the host's copy as last set); counters ``(COUNTERS,)
    int64`` (`STEPS`, `COLLISIONS`, `LIVE`, `LAST`); rng ``(4,) uint64``, the random stream's words;
    scheduler ``(L,) int64``, the scheduler's own state; margin ``(4,) float64``, the closing margin
    (`engine.margin`); field_chain: in exact or certified arithmetic, the chain holding the velocities in
    the number field (`engine.field.rational.FieldChain`: its own state, the certified bounds too), else None.
    """

    velocities: np.ndarray
    counters: np.ndarray
    rng: np.ndarray
    scheduler: np.ndarray
    margin: np.ndarray
    field_chain: object = None
    broken: str = ""

    @property
    def steps(self) -> int:
        return int(self.counters[STEPS])

    @property
    def collisions(self) -> int:
        return int(self.counters[COLLISIONS])


def incidence(pairs: np.ndarray, n_balls: int) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of each ball in CSR form: ``(ptr (n_balls+1,) int64, contacts (2E,) uint32)``."""
    balls = pairs.ravel()
    contacts = (np.argsort(balls, kind="stable") // 2).astype(np.uint32)
    ptr = np.zeros(n_balls + 1, dtype=np.int64)
    np.cumsum(np.bincount(balls.astype(np.intp), minlength=n_balls), out=ptr[1:])
    return ptr, contacts


class Chain(NamedTuple):
    """The plain data every loop reads: velocities ``v (n_balls, dim)`` (written in place),
    ``pairs, ends (E, 2)``, ``units (K, dim)``, ``masses (n_balls,)`` and the rule's ``params``."""

    v: np.ndarray
    pairs: np.ndarray
    ends: np.ndarray
    units: np.ndarray
    masses: np.ndarray
    params: np.ndarray


class LiveSet(NamedTuple):
    """The live contacts as plain data, owned by the `Simulation`: ``flags (E,) uint8``
    (1 where picking the contact would change velocities) and the incidence ``ptr, inc``
    (see `incidence`) that says which contacts to re-test after a collision. Their number
    is ``counters[LIVE]``."""

    ptr: np.ndarray
    inc: np.ndarray
    flags: np.ndarray
