"""The closing margin of a run: how far from the collision criterion its picks came.

A float run counts a pick as a collision when its closing speed ``w`` exceeds the threshold
``tau = resolution * V`` (`pinnedballs.rules`). The count is a clean fact only where no pick came
near ``tau``: a genuine approach closing below it is left out, a rounding remnant above it
would be counted. Every loop therefore keeps four numbers of every pick it tries, in a
``(4,) float64`` array, ``margin``:

* ``margin[SMALLEST]``: the smallest ``w`` of a collision (``inf`` before the first);
* ``margin[LARGEST]``: the largest positive ``w`` set aside (0 before the first);
* ``margin[NEAR_COLLISIONS]``: collisions with ``w <= NEAR * tau``;
* ``margin[NEAR_REMNANTS]``: picks set aside with ``tau / NEAR < w``.

`ClosingMargin` says them in units of ``tau``. A run is *thin* when a collision closed within
a factor `NEAR` of ``tau``: its genuine closing speeds reach down towards the criterion, so some
may lie below it. (Picks set aside close below ``tau`` by definition; rounding remnants reach
about half of it, measured against exact arithmetic, so they say nothing of the genuine ones.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..util.notes import Note
from .jit.cache import njit_cached

__all__ = ["ClosingMargin", "MarginWarning", "new_margin", "merge_margin", "track", "collided_speed", "remnant_speed",
           "near_collision", "near_remnant", "SMALLEST", "LARGEST", "NEAR_COLLISIONS", "NEAR_REMNANTS", "NEAR"]

SMALLEST, LARGEST, NEAR_COLLISIONS, NEAR_REMNANTS = 0, 1, 2, 3
#: a pick within this factor of the threshold, on either side, is *near* it
NEAR = 1e4


class MarginWarning(Note):
    """A float run's count depends on its collision criterion: picks came near the threshold.

    Said once, in one line about the caller's line, by a float run at the default resolution that ends frozen
    with a thin closing margin (`Simulation.warn_if_thin`; the module's docstring says what thin is), where the
    count is the observable. A run for its steps says nothing (on a torus, which never freezes, picks come near
    the threshold in every long run); `Simulation.closing_margin` tells it when asked. The line
    says what to do: count exactly with ``arithmetic="exact"`` (or ``"certified"``) on the same seed, or give
    ``resolution=`` to make the criterion part of the model (docs/collisions.md).
    """


def new_margin() -> np.ndarray:
    """``(4,) float64``: the margin of a run that has tried nothing yet."""
    return np.array([np.inf, 0.0, 0.0, 0.0])


def merge_margin(into: np.ndarray, other: np.ndarray) -> None:
    """Fold the margin ``other`` (of later picks) into ``into``, in place."""
    into[SMALLEST] = min(into[SMALLEST], other[SMALLEST])
    into[LARGEST] = max(into[LARGEST], other[LARGEST])
    into[NEAR_COLLISIONS] += other[NEAR_COLLISIONS]
    into[NEAR_REMNANTS] += other[NEAR_REMNANTS]


@njit_cached(inline="always")
def track(hit, w, tau, smallest, largest, near_hits, near_rest):
    """One pick's closing speed ``w`` (collided when ``hit``) folded into the running margin:
    ``(smallest, largest, near_hits, near_rest)`` updated. A collision costs a ``min`` and a compare;
    the other branches (a collision near the threshold, a positive ``w`` set aside) are rare."""
    if hit:
        smallest = min(smallest, w)
        if w <= NEAR * tau:
            near_hits += 1.0
    elif w > 0.0:
        largest = max(largest, w)
        if w * NEAR > tau:
            near_rest += 1.0
    return smallest, largest, near_hits, near_rest


# the four numbers one by one, for a loop that keeps them as reductions over a parallel loop (`ColoredSweep`):
# ``smallest = min(smallest, collided_speed(...))``, ``largest = max(largest, remnant_speed(...))``, and the
# two counts summed; `track` is their sequential form (tests/engine/test_margin.py holds them equal)


@njit_cached(inline="always")
def collided_speed(hit, w):
    """``w`` where the pick collided (it may be the smallest), else ``inf``."""
    return w if hit else np.inf


@njit_cached(inline="always")
def remnant_speed(hit, w):
    """``w`` where the pick was set aside closing (it may be the largest remnant), else 0."""
    return w if (not hit) and w > 0.0 else 0.0


@njit_cached(inline="always")
def near_collision(hit, w, tau):
    """1 where the pick collided within a factor `NEAR` of ``tau``, else 0."""
    return 1.0 if hit and w <= NEAR * tau else 0.0


@njit_cached(inline="always")
def near_remnant(hit, w, tau):
    """1 where the pick was set aside closing above ``tau / NEAR``, else 0."""
    return 1.0 if (not hit) and w > 0.0 and w * NEAR > tau else 0.0


@dataclass(frozen=True)
class ClosingMargin:
    """How close a run's picks came to its collision criterion, in units of its threshold ``tau``.

    smallest_collision: the smallest closing speed counted as a collision (None: no collision yet).
    largest_remnant: the largest positive closing speed set aside (None: none).
    near_collisions, near_remnants: collisions closing at most `NEAR` ``tau``, and picks set aside
    closing above ``tau / NEAR``.
    threshold: ``tau`` itself; resolution: ``tau / V`` (the criterion as a model parameter).
    """

    smallest_collision: float | None
    largest_remnant: float | None
    near_collisions: int
    near_remnants: int
    threshold: float
    resolution: float

    @classmethod
    def of(cls, margin: np.ndarray, threshold: float, resolution: float) -> ClosingMargin:
        """From a loop's ``margin (4,)`` array and the run's threshold."""
        def ratio(w):
            return float(w / threshold) if threshold > 0 else math.inf
        smallest = None if not np.isfinite(margin[SMALLEST]) else ratio(margin[SMALLEST])
        largest = None if margin[LARGEST] <= 0 else ratio(margin[LARGEST])
        return cls(smallest, largest, int(margin[NEAR_COLLISIONS]), int(margin[NEAR_REMNANTS]), float(threshold),
                   float(resolution))

    @property
    def thin(self) -> bool:
        """True when the count may depend on the criterion: a collision closed within `NEAR` thresholds."""
        return self.near_collisions > 0

    def describe(self) -> str:
        """One line: the margin on both sides and the counts near the threshold."""
        low = "no collision yet" if self.smallest_collision is None else \
            f"smallest collision {self.smallest_collision:.3g} thresholds"
        high = "no remnant set aside" if self.largest_remnant is None else \
            f"largest remnant {self.largest_remnant:.3g} thresholds"
        return (f"{low}, {high}; {_counted(self.near_collisions, 'collision')} and "
                f"{_counted(self.near_remnants, 'remnant')} within a factor {NEAR:.0e} of it")

    def warning(self, exact: bool = True) -> str:
        """The one line a thin float run says; ``exact``: the run could be counted exactly (a built-in rule
        and a scheduler that picks without a live set), so the line says how."""
        advice = ("; count it exactly with arithmetic=\"exact\" (or \"certified\") on the same seed" if exact else
                  "; give resolution= to make the criterion part of the model (its counts N_e)")
        return (f"the closing margin is thin ({self.describe()}): the collision count depends on the float "
                f"criterion (resolution {self.resolution:.3g}){advice}")

    def to_dict(self) -> dict:
        """The fields as plain numbers (None where there is none)."""
        return {"smallest_collision": self.smallest_collision, "largest_remnant": self.largest_remnant,
                "near_collisions": self.near_collisions, "near_remnants": self.near_remnants,
                "threshold": self.threshold, "resolution": self.resolution}


def _counted(n: int, noun: str) -> str:
    """``n noun(s)``: "1 collision", "12 collisions"."""
    return f"{n:,} {noun}{'' if n == 1 else 's'}"
