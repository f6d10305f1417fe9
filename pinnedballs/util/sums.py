"""Sums over the balls whose bits do not depend on the machine: the kinetic energy, the momentum, a dot product.

numpy's ``@`` and ``np.dot`` call the BLAS (OpenBLAS here), which splits a long sum among its threads and picks
its kernel by the CPU: the same arrays give other last bits on a machine with other cores (``OPENBLAS_NUM_THREADS``
1 and 2 differ on 2 million balls), and its threads spin for a while after each call, taking cores from the
engine's threads (a 2-thread chain run just after one is a fifth slower: `benchmarks/results/measurements.md`).
These use numpy's own reductions instead, whose order is fixed (pairwise sums), on one thread.
"""

from __future__ import annotations

import numpy as np

__all__ = ["kinetic_energy", "momentum", "dot"]


def kinetic_energy(masses: np.ndarray, velocities: np.ndarray) -> float:
    """``sum m |v|^2 / 2`` for ``masses (n,)`` and ``velocities (n, dim)``: each ``|v|^2`` first, then the sum."""
    v = np.asarray(velocities, dtype=np.float64)
    return 0.5 * float(np.sum(np.asarray(masses, dtype=np.float64) * np.sum(v * v, axis=1)))


def momentum(masses: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """``(dim,)`` ``sum m v``, a component at a time."""
    mv = np.asarray(masses, dtype=np.float64)[:, None] * np.asarray(velocities, dtype=np.float64)
    return np.array([np.sum(mv[:, k]) for k in range(mv.shape[1])])


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``sum a b`` of two ``(n,)`` arrays."""
    return float(np.sum(np.asarray(a, dtype=np.float64) * np.asarray(b, dtype=np.float64)))
