"""A run directory's data files (`format`): ``static.h5``, written once with what never changes (the geometry, the
initial state), and one segment ``frames_<first>.h5`` per checkpoint that had new snapshots; each built in memory
and written whole (`files.h5_image`), returning its digest for the index."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from ..geometry.base import Geometry
from ..util.atomic import write_bytes_atomic
from .digest import bytes_digest
from .files import h5_image
from .format import Record

__all__ = ["write_static", "write_segment"]


def write_static(path: Path, geometry: Geometry, masses, initial: Record) -> str:
    """The geometry (with its boundary, frames and view: all that reading the run needs) and the
    initial state; the digest of the file."""
    n = geometry.n_balls

    def fill(f: h5py.File) -> None:
        g = f.create_group("geometry")
        c = geometry.contacts
        g["positions"] = geometry.positions
        g["pairs"] = np.ascontiguousarray(c.pairs)
        g["t_i"], g["t_j"] = c.t_i, c.t_j
        g.attrs["radius"] = float(getattr(geometry, "radius", 1.0))
        g.attrs["view"] = geometry.view
        g.attrs["rigid"] = bool(geometry.rigid)  # `Geometry.rigid`: a torus's, when the file stands in for it
        boundary = geometry.boundary
        if boundary is not None:
            g["boundary_distance"], g["boundary_outward"] = boundary.distance, boundary.outward
        if geometry.curved:
            g["frames"] = np.ascontiguousarray(geometry.frames())
        if masses is not None:
            g["masses"] = np.broadcast_to(np.asarray(masses, dtype=np.float64), (n,))
        i = f.create_group("initial")
        i["velocities"] = initial.state.velocities
        i["momentum"] = initial.momentum
        i.attrs.update(energy=initial.energy, approaching=initial.approaching)

    return _write(path, h5_image(fill))


def write_segment(path: Path, frames: list[Record], names: list[str]) -> str:
    """``frames`` as one segment: velocities ``(F, n, d)`` and each observable of ``names``; the digest of
    the file."""
    def fill(f: h5py.File) -> None:
        f["velocities"] = np.stack([r.state.velocities for r in frames])
        for name in names:
            f[f"observables/{name}"] = np.stack([np.asarray(r.values[name]) for r in frames])

    return _write(path, h5_image(fill))


def _write(path: Path, image: bytes) -> str:
    write_bytes_atomic(path, image)
    return bytes_digest(image)
