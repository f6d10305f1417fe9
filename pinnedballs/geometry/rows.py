"""Rows of balls at equal distance from a boundary (or layers at equal height): `boundary_rows`,
which the energy profiles, the GSD types and the pictures of 3-D layers group balls by."""

from __future__ import annotations

import numpy as np

__all__ = ["boundary_rows"]


def boundary_rows(distances, tol: float = 1e-6) -> tuple[np.ndarray, np.ndarray]:
    """Group balls into rows of equal distance from the boundary.

    distances: ``(n_balls,)``. Sorted distances closer than ``tol`` (relative to
    the largest distance, at least 1) to the previous one join its row.
    Returns ``row (n_balls,) int`` (0 = nearest the boundary) and ``centres
    (n_rows,)`` the mean distance of each row.
    """
    try:
        d = np.asarray(distances, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"distances: must be an array of numbers ({exc})") from None
    if d.ndim != 1:
        raise ValueError(f"distances: must have shape (n,), got {d.shape}")
    if len(d) == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0)
    order = np.argsort(d, kind="stable")
    scale = max(1.0, float(np.abs(d).max()))
    starts = np.diff(d[order]) > tol * scale
    row = np.empty(len(d), dtype=np.int64)
    row[order] = np.concatenate([[0], np.cumsum(starts)])
    centres = np.bincount(row, weights=d) / np.bincount(row)
    return row, centres
