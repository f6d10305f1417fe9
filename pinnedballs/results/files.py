"""Results files written so that a kill, a Ctrl-C or a full disk never leaves half of one: HDF5 files
built in memory first (`h5_image`), then written whole (`util.atomic.write_bytes_atomic`); their
rows gathered from segments (`virtual_rows`); signals held while a checkpoint is written (`held_signals`); an
attribute read as a plain number (`scalar`)."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

import h5py
import numpy as np

__all__ = ["h5_image", "virtual_rows", "held_signals", "scalar"]


def h5_image(fill: Callable[[h5py.File], None]) -> bytes:
    """The bytes of an HDF5 file built in memory by ``fill(f)``, to be written with `write_bytes_atomic`.

    HDF5 never writes to disk itself: a full disk is a plain OSError from our own write,
    never a file HDF5 cannot close (h5py issue 2160: a native crash on closing a file
    whose write failed), and no partial file is left behind.
    """
    f = h5py.File(f"image.{threading.get_ident()}.{id(fill)}", "w", driver="core", backing_store=False)
    try:
        fill(f)
        f.flush()
        return f.id.get_file_image()
    finally:
        f.close()


@contextlib.contextmanager
def held_signals() -> Iterator[None]:
    """Hold SIGINT and SIGTERM until the block ends, then deliver them to the handlers they would have
    reached: a Ctrl-C lands right after a checkpoint, never in the middle of one. Only the main
    thread receives signals, so elsewhere this does nothing; a handler not set from Python is left alone."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []
    held = [s for s in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(s) is not None]
    old = {s: signal.signal(s, lambda signum, frame: got.append(signum)) for s in held}
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        for s in got:  # each, in order (a second Ctrl-C may mean "now")
            signal.raise_signal(s)


def virtual_rows(f: h5py.File, where: str, source: str, dtype: np.dtype, shape: tuple, segments: list,
                 rel: str) -> None:
    """``where`` in ``f``: the rows ``source`` of every segment ``[file, first, count]`` (files named
    relative to ``rel``), one after another, as one virtual dataset of rows ``shape`` and ``dtype``."""
    total = sum(s[2] for s in segments)
    if total == 0:
        f.create_dataset(where, shape=(0, *shape), dtype=dtype)
        return
    layout = h5py.VirtualLayout(shape=(total, *shape), dtype=dtype)
    for name, first, count in segments:
        layout[first:first + count] = h5py.VirtualSource(rel + name, source, shape=(count, *shape), dtype=dtype)
    f.create_virtual_dataset(where, layout)


def scalar(value):
    """An HDF5 attribute as a plain Python number."""
    return value.item() if isinstance(value, np.generic) else value
