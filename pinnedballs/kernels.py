"""The compiled loop (numba) and its helpers for tracking frozen states.

`run_chain` is the one hot loop: pick a contact, try to collide it, count.
The rule's ``collide`` and the scheduler's ``pick`` are passed in as jitted
functions, so each combination is compiled (and cached on disk) once and runs
without Python in the loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .rules import closing_speed

__all__ = ["run_chain", "approaching_flags", "incidence"]

#: indices into the ``counters`` array shared by Python and the loop
STEPS, COLLISIONS, APPROACHING = 0, 1, 2


@njit(cache=True)
def approaching_flags(v, table, units, flags):
    """Set ``flags[k] = 1`` where contact ``k`` approaches; return how many do."""
    count = 0
    for k in range(table.shape[0]):
        w = closing_speed(v, units, table[k, 0], table[k, 1], table[k, 2], table[k, 3])
        flags[k] = 1 if w > 0.0 else 0
        count += flags[k]
    return count


def incidence(table: np.ndarray, n_balls: int) -> tuple[np.ndarray, np.ndarray]:
    """Contacts of each ball in CSR form: ``(ptr (n_balls+1,) int64, contacts (2E,) int32)``."""
    ends = table[:, :2].ravel()
    order = np.argsort(ends, kind="stable").astype(np.int32) // 2
    ptr = np.zeros(n_balls + 1, dtype=np.int64)
    np.cumsum(np.bincount(ends, minlength=n_balls), out=ptr[1:])
    return ptr, order.astype(np.int32)


@njit(cache=True, inline="always")
def _refresh(v, table, units, ptr, inc, flags, ball):
    """Re-test the contacts of ``ball``; return the change in the number approaching."""
    delta = 0
    for m in range(ptr[ball], ptr[ball + 1]):
        c = inc[m]
        w = closing_speed(v, units, table[c, 0], table[c, 1], table[c, 2], table[c, 3])
        new = 1 if w > 0.0 else 0
        delta += new - flags[c]
        flags[c] = new
    return delta


@njit(cache=True)
def run_chain(v, table, units, masses, params, collide, pick, sched_state, rng, counters,
              max_steps, max_collisions, track, ptr, inc, flags):
    """Run the chain in place; stop after ``max_steps`` picks, at ``max_collisions`` in total,
    or (when ``track``) as soon as no contact approaches.

    v: ``(n_balls, dim)`` velocities; table: ``(E, 4) int32``; units: ``(K, dim)``;
    counters: ``(3,) int64`` totals ``[steps, collisions, approaching]`` (approaching is
    kept up to date only when ``track``, from ``flags (E,) uint8`` and the incidence
    ``ptr, inc``). Returns the number of steps taken.
    """
    n = table.shape[0]
    collisions = counters[COLLISIONS]
    approaching = counters[APPROACHING]
    steps = 0
    while steps < max_steps and collisions < max_collisions:
        if track and approaching == 0:
            break
        k = pick(sched_state, rng, n)
        steps += 1
        i = table[k, 0]
        j = table[k, 1]
        if collide(v, units, i, j, table[k, 2], table[k, 3], masses, params):
            collisions += 1
            if track:
                approaching += _refresh(v, table, units, ptr, inc, flags, i)
                approaching += _refresh(v, table, units, ptr, inc, flags, j)
    counters[STEPS] += steps
    counters[COLLISIONS] = collisions
    counters[APPROACHING] = approaching
    return steps
