"""Users' collision rules, written as docs/extending.md shows: whole, or by their impulse; and two that a GPU
cannot run with the CPU's bits (test_gpu.py)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

import pinnedballs as pb
from pinnedballs.rules import CollisionRule, closing_speed, impulse_rule, remnant_threshold


@njit(inline="always")
def collide_sticky(v, units, i, j, a, b, masses, params, dim, flat, write):
    """Equal masses; keeps a fraction params[0] of the closing speed (docs/extending.md's, written whole)."""
    keep, tau = params[0], remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    c = w * (1.0 + keep) / 2.0
    changed = False
    for k in range(dim):
        tj = -units[a, k] if flat else units[b, k]
        new_i, new_j = v[i, k] - c * units[a, k], v[j, k] - c * tj
        changed |= (new_i != v[i, k]) | (new_j != v[j, k])
        if write:
            v[i, k], v[j, k] = new_i, new_j
    return changed


class Sticky(CollisionRule):
    def __init__(self, keep: float):
        self.keep = keep

    def kernel(self, equal_masses: bool):
        return collide_sticky, np.array([self.keep])


@njit(inline="always")
def spring_impulse(w, i, j, masses, params):
    """Any masses; the lighter ball takes the larger share, softened by params[0]."""
    mi, mj = masses[i], masses[j]
    s = w * (2.0 - params[0]) / (mi + mj)
    return s * mj, s * mi


collide_spring = impulse_rule(spring_impulse)


class Spring(CollisionRule):
    """A rule given by its impulse: the engine adds the threshold and the kick, and its branch-free form."""

    def __init__(self, soft: float):
        self.soft = soft

    def kernel(self, equal_masses: bool):
        return collide_spring, np.array([self.soft])


@njit(inline="always")
def exponential_impulse(w, i, j, masses, params):
    c = w * math.exp(-params[0] * w)
    return c, c


class Exponential(CollisionRule):
    """Damped by exp: libdevice's exp is not libm's, so a GPU would not give the CPU's bits."""

    def kernel(self, equal_masses: bool):
        return impulse_rule(exponential_impulse), np.array([0.1])


@njit(inline="always")
def allocating_impulse(w, i, j, masses, params):
    d = np.linalg.norm(masses[: i + 1])
    return w / d, w / d


class Allocating(CollisionRule):
    """Calls numpy's linear algebra, which numba-cuda cannot compile."""

    def kernel(self, equal_masses: bool):
        return impulse_rule(allocating_impulse), np.array([0.0])


__all__ = ["Sticky", "Spring", "Exponential", "Allocating", "collide_sticky", "collide_spring", "pb"]
