"""The snapshots of a run, read lazily: opening a run reads its index, not its frames.

`Snapshots` knows each snapshot's counters from the moment the run is loaded, and reads a
snapshot's velocities ``(n_balls, dim)`` from the file that holds them (a segment, or a format-1
file itself) only when it is asked for. So a run of 250,000 balls and 120 snapshots (480 MB of
velocities) opens in about a second with a few tens of MB, and any snapshot is read in
milliseconds (``benchmarks/bench_load.py``).

A damaged file is still refused with one line naming it: the digests of format 3 are verified
when the run is loaded (`check.check_results`), and each read checks that the file is the one
that was verified (same inode, size and modification time) and that the frame is finite; a file
removed or rewritten since (``pinnedballs run --force`` into the same directory) is a
`ResultsError` too.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from .format import ResultsError, Snapshot

__all__ = ["FrameFile", "Snapshots"]


def _signature(path: Path) -> tuple[int, int, int, int]:
    st = os.stat(path)
    return st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns


@dataclass(frozen=True)
class FrameFile:
    """Rows ``[first, first + count)`` of the snapshots, in the dataset ``dataset`` of the file ``path``
    (a segment's ``velocities``, or a format-1 file's ``snapshots/velocities``); ``signature``: its
    ``(device, inode, size, mtime_ns)`` when the run was loaded."""

    path: Path
    dataset: str
    first: int
    count: int
    signature: tuple[int, int, int, int]

    @classmethod
    def at(cls, path: Path, dataset: str, first: int, count: int) -> FrameFile:
        return cls(path, dataset, first, count, _signature(path))


class Snapshots(Sequence):
    """The snapshots of a run as a sequence of `Snapshot` ``(steps, collisions, velocities)``,
    the velocities ``(n_balls, dim)`` read from disk each time an item is taken.

    ``steps`` and ``collisions`` (``(F,) int64``) are in memory; ``velocities(k)`` reads one frame.
    Iterating reads one frame at a time, so a loop over a large run holds one frame at once.
    """

    def __init__(self, index: Path, steps: np.ndarray, collisions: np.ndarray, files: list[FrameFile],
                 shape: tuple[int, int]):
        self.index, self.files, self.shape = index, list(files), tuple(shape)
        self.steps = np.asarray(steps, dtype=np.int64)
        self.collisions = np.asarray(collisions, dtype=np.int64)
        self._starts = np.array([f.first for f in self.files], dtype=np.int64)

    def __len__(self) -> int:
        return len(self.steps)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        k = self._position(k)
        return Snapshot(int(self.steps[k]), int(self.collisions[k]), self.velocities(k))

    def __iter__(self):
        for k in range(len(self)):
            yield self[k]

    def __eq__(self, other) -> bool:
        if not isinstance(other, Sequence) or isinstance(other, (str, bytes)):
            return NotImplemented
        return len(self) == len(other) and all(_same(a, b) for a, b in zip(self, other))

    __hash__ = None  # equal to lists, which are unhashable

    def __repr__(self) -> str:
        steps = ", ".join(f"{s:,}" for s in self.steps[:4].tolist()) + (", ..." if len(self) > 4 else "")
        return f"<{len(self)} snapshots of {self.shape[0]:,} balls at steps [{steps}], read when asked>"

    def __dask_tokenize__(self):  # the same files read the same frames (dask's name for a lazy read)
        return str(self.index), [(str(f.path), f.signature) for f in self.files]

    def _position(self, k) -> int:
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
            raise TypeError(f"snapshot indices must be integers or slices, not {type(k).__name__}")
        if not -len(self) <= k < len(self):
            raise IndexError(f"snapshot {k} out of range: the run has {len(self)}")
        return int(k) % len(self)

    def velocities(self, k: int) -> np.ndarray:
        """``(n_balls, dim) float64``: the velocities of snapshot ``k``, read now; a `ResultsError`
        naming the run and the file if that file changed since the run was loaded or holds a damaged frame."""
        k = self._position(k)
        f = self.files[int(np.searchsorted(self._starts, k, side="right")) - 1]
        where = f"{self.index}: snapshot {k} ({f.path.name})"
        try:
            changed = _signature(f.path) != f.signature
        except FileNotFoundError:
            raise ResultsError(f"{where}: the file is gone since the run was loaded: load the run again") from None
        if changed:
            raise ResultsError(f"{where}: the file changed since the run was loaded (a run written there again?): "
                               f"load the run again")
        try:
            with h5py.File(f.path, "r") as h:
                v = h[f.dataset][k - f.first]
        except (OSError, KeyError, ValueError, TypeError) as exc:
            raise ResultsError(f"{where}: damaged results file ({' '.join(str(exc).split())})") from None
        if v.shape != self.shape or v.dtype.kind != "f":
            raise ResultsError(f"{where}: damaged results file: snapshots/velocities: must be floating point of "
                               f"shape {self.shape}, got {v.dtype} {v.shape}")
        if not np.isfinite(v).all():
            raise ResultsError(f"{where}: damaged results file: snapshots/velocities: holds non-finite values "
                               f"(NaN or inf)")
        return np.asarray(v, dtype=np.float64)


def _same(a, b) -> bool:
    """Two snapshots are equal: the same counters and the same velocities."""
    return tuple(a[:2]) == tuple(b[:2]) and np.array_equal(a[2], b[2])
