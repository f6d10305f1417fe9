"""A user's own components, named by specs in test_user_components.py."""

from __future__ import annotations

import numpy as np

import pinnedballs as pb


def chain(n: int, spacing: float = 2.0) -> pb.GraphGeometry:
    """``n`` balls in a row, each touching the next."""
    return pb.GraphGeometry.from_positions(np.column_stack([spacing * np.arange(n), np.zeros(n)]))


def reversed_speeds(geometry: pb.Geometry, speed: float = 1.0) -> np.ndarray:
    """Ball k moves along x with speed ``speed * (n - k)``: every pair of balls is an inversion."""
    n = geometry.n_balls
    return np.column_stack([speed * (n - np.arange(n)), np.zeros(n)])


def half_elastic() -> pb.Restitution:
    return pb.Restitution(0.5)


def sweep() -> pb.Sweep:
    return pb.Sweep()


def not_a_rule() -> int:
    return 3
