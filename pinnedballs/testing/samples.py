"""What the checks run on, and how they fail: small geometries given as tables (`TableGeometry`,
`pair_geometry`: separate touching pairs, each contact on its own), a simulation whose refusal is a
failed check, and `fail`, the one way a check reports what broke.

Everything is seeded: a check gives the same verdict on every run.
"""

from __future__ import annotations

from typing import NoReturn

import numpy as np

from ..geometry.base import Contacts, Geometry
from ..simulation import Simulation

__all__ = ["fail", "vector", "TableGeometry", "pair_geometry", "simulation", "SEED"]

#: the seed of every sample the checks draw
SEED = 20250
#: distance between the pairs of `pair_geometry` (in radii): far from touching each other
_PAIR_SPACING = 10.0


def fail(prop: str, detail: str) -> NoReturn:
    """Raise the `AssertionError` of a check: ``"<property>: <what broke, with a small example>"``."""
    raise AssertionError(f"{prop}: {detail}")


def vector(x) -> str:
    """A short picture of a vector (or a number) for a message."""
    return "(" + ", ".join(f"{float(c):.6g}" for c in np.atleast_1d(np.asarray(x, dtype=float))) + ")"


class TableGeometry(Geometry):
    """Balls at ``positions (n, k)`` and the contacts ``pairs (E, 2)``, ``ends (E, 2)``, ``units (K, dim)``.

    ``curved``: the velocities live in tangent planes whose frames are the identity and whose
    metric is not stated (so ``t_j`` need not be ``-t_i``, and the contact checks leave directions
    alone): what a rule meets on a curved surface, in a few numbers."""

    def __init__(self, positions, pairs, ends, units, curved: bool = False):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.tables = (np.asarray(pairs), np.asarray(ends), np.asarray(units, dtype=np.float64))
        self.curved = curved

    def _build_contacts(self) -> Contacts:
        return Contacts.build(*self.tables)

    def frames(self) -> np.ndarray:
        if not self.curved:
            return super().frames()
        k = self.positions.shape[1]
        return np.broadcast_to(np.eye(k), (self.n_balls, k, k))


def pair_geometry(t_i: np.ndarray, t_j: np.ndarray | None = None, swapped: bool = False) -> TableGeometry:
    """``P`` separate pairs of touching balls, contact ``p`` joining balls ``2p`` and ``2p + 1`` with unit
    vectors ``t_i[p]`` and ``t_j[p]`` (``(P, d)``; None: ``-t_i``, flat space; else as on a curved
    surface). ``swapped``: each contact listed the other way round, ``(2p + 1, 2p)`` with ``t_j, t_i``."""
    t_i = np.asarray(t_i, dtype=np.float64)
    n_pairs, d = t_i.shape
    t_j = -t_i if t_j is None else np.asarray(t_j, dtype=np.float64)
    positions = np.zeros((2 * n_pairs, d))
    positions[0::2, 0] = _PAIR_SPACING * np.arange(n_pairs)
    positions[1::2] = positions[0::2] + 2.0 * t_i
    units = np.empty((2 * n_pairs, d))
    units[0::2], units[1::2] = t_i, t_j
    pairs = np.arange(2 * n_pairs).reshape(n_pairs, 2)
    if swapped:
        pairs = pairs[:, ::-1]
    return TableGeometry(positions, pairs, pairs.copy(), units, curved=not np.array_equal(t_j, -t_i))


def simulation(prop: str, geometry, velocities, **options) -> Simulation:
    """A `Simulation`; its refusal (a component the engine cannot run) fails the check ``prop``."""
    try:
        return Simulation(geometry, velocities, **options)
    except (ValueError, TypeError) as error:
        fail(prop, f"the simulation refused it: {type(error).__name__}: {error}")
