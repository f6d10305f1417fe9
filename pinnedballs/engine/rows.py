"""Contacts read from their index: the row pattern of a lattice.

The triangular lattices (`FlatTorus`, `HalfPlane`) number their balls row by row and their
contacts ball by ball, so every row but the last repeats one of two patterns (even and odd rows),
shifted by the row's first ball. `row_pattern` finds such a pattern in any contact tables, checks
it against every contact, and packs it into a few kilobytes; `decode` then gives contact ``k``'s
``(i, j, a, b)`` with a division and one load from that small table, instead of two loads from the
``(E, 2)`` tables that, on a large lattice, miss every cache. The numbers are the tables' own, so a
loop reading the pattern makes the same picks and the same bits.

The pattern is ``(table, per_row, rows, cols, inverse)``: ``table (3 * per_row,) int64`` holds, for
contact ``o`` of an even row, an odd row and the last row (``table[2 * per_row:]``), its first
ball's offset in the row (bits 0-23), ``j - i + 2^23`` (bits 24-47), ``a`` (48-55) and ``b``
(56-62); ``per_row`` contacts in each row but the last; ``inverse = 1 / per_row``.
"""

from __future__ import annotations

import numpy as np

from .jit.cache import njit_cached

__all__ = ["row_pattern", "decode", "MIN_BALLS"]

#: a pattern is looked for only on lattices at least this large (smaller tables stay in cache)
MIN_BALLS = 1 << 14
_FIELD = (1 << 24) - 1
_SHIFT = 1 << 23


@njit_cached(inline="always")
def decode(pattern, k):
    """``(i, j, a, b)`` of contact ``k`` (int64) from its row pattern."""
    table, per_row, rows, cols, inverse = pattern
    r = np.int64(np.float64(k) * inverse)
    if r * per_row > k:  # the float quotient is off by at most one
        r -= 1
    elif (r + 1) * per_row <= k:
        r += 1
    last = r >= rows - 1
    if last:
        r = rows - 1
    e = table[k - r * per_row + (2 * per_row if last else (r & 1) * per_row)]
    i = r * cols + (e & _FIELD)
    return i, i + ((e >> 24) & _FIELD) - _SHIFT, (e >> 48) & 0xFF, e >> 56


@njit_cached
def _matches(pattern, pairs, ends):
    """True when `decode` gives every contact of the tables."""
    for k in range(pairs.shape[0]):
        i, j, a, b = decode(pattern, np.int64(k))
        if i != pairs[k, 0] or j != pairs[k, 1] or a != ends[k, 0] or b != ends[k, 1]:
            return False
    return True


def _pack(pairs: np.ndarray, ends: np.ndarray, first: int) -> np.ndarray:
    i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
    return ((i - first) | ((j - i + _SHIFT) << 24) | (ends[:, 0].astype(np.int64) << 48)
            | (ends[:, 1].astype(np.int64) << 56))


def row_pattern(pairs: np.ndarray, ends: np.ndarray, rows: int, cols: int, min_balls: int = MIN_BALLS) -> tuple | None:
    """The row pattern of contacts ``pairs, ends (E, 2)`` on ``rows x cols`` balls numbered row by row,
    or None when they have none (checked contact by contact) or fewer than ``min_balls`` balls."""
    n_contacts = len(pairs)
    if rows < 3 or rows * cols < min_balls or cols >= _SHIFT or n_contacts == 0:
        return None
    row_of = pairs[:, 0].astype(np.int64) // cols
    per_row = int(np.searchsorted(row_of, 1))
    if per_row == 0 or n_contacts < (rows - 1) * per_row or per_row >= 1 << 31:
        return None
    last = (rows - 1) * per_row
    dj = pairs[:, 1].astype(np.int64) - pairs[:, 0].astype(np.int64)
    if np.abs(dj).max() >= _SHIFT or ends.max() >= 128:
        return None
    table = np.zeros(3 * per_row, dtype=np.int64)
    table[:per_row] = _pack(pairs[:per_row], ends[:per_row], 0)
    table[per_row:2 * per_row] = _pack(pairs[per_row:2 * per_row], ends[per_row:2 * per_row], cols)
    tail = _pack(pairs[last:], ends[last:], (rows - 1) * cols)
    if len(tail) > per_row:
        return None
    table[2 * per_row:2 * per_row + len(tail)] = tail
    pattern = (table, np.int64(per_row), np.int64(rows), np.int64(cols), 1.0 / per_row)
    if not _matches(pattern, pairs, ends):
        return None
    return pattern
