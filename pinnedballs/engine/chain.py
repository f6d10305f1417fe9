"""The plain data every compiled loop reads and writes: the chain's arrays, the counters, the
live-contact set and the incidence that says which contacts to re-test after a collision."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Chain", "LiveSet", "incidence", "STEPS", "COLLISIONS", "LIVE", "LAST", "COUNTERS", "NO_LIMIT"]

#: indices into the ``counters (COUNTERS,) int64`` array shared by Python and the loops: steps and
#: collisions so far, live contacts (-1: unknown), and the step count right after the last collision a
#: call made (left as it was by a call that made none)
STEPS, COLLISIONS, LIVE, LAST = 0, 1, 2, 3
COUNTERS = 4

NO_LIMIT = np.iinfo(np.int64).max  #: "no limit" for max_steps or max_collisions


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
