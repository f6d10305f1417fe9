"""GSD trajectories: a run's states as frames of HOOMD-blue's schema, for OVITO, freud and MDAnalysis.

Written by `pinnedballs.run.gsd_writer.GSDWriter` during a run, by ``pinnedballs run`` when its
spec asks for a ``"trajectory"``, and by `export` (``pinnedballs export DIR OUT.gsd``) from the
snapshots of a results directory. Each frame, ``N`` balls, in the schema's single precision
(the results file keeps float64)::

    configuration/step        the steps of the state
    configuration/dimensions  2 (balls on a line or in a plane) or 3
    configuration/box         [Lx, Ly, Lz, 0, 0, 0]: the period along a periodic axis (torus,
                              periodic packings), else the balls' extent plus a diameter; Lz = 0 in 2-D
    particles/position        (N, 3) the centres the figures use (z = 0 in 2-D; on a sphere and the
                              hyperboloid their embedding, the hyperboloid's x0 first), less
                              ``log/pinnedballs/origin``: GSD boxes are centred on 0
    particles/velocity        (N, 3) in the same coordinates (carried from each ball's frame with
                              `Geometry.frames` on a curved surface)
    particles/diameter        (N,) 2 radius; on a curved surface each ball's mean chord to the balls it touches
    particles/types, typeid   "bulk" (0) and "boundary" (1): the balls nearest the boundary
    particles/mass            (N,) when the run has masses
    log/<name>                each recorded observable (steps, collisions, energy, momentum, ...)
    log/pinnedballs/origin    (3,) in frame 0: position + origin = the figures' coordinates

What does not change (positions, box, types, diameters) is stored once, in frame 0: ``gsd.hoomd``
leaves out what equals frame 0 and reads it back from there. Appending is safe against kills: GSD
ignores a frame that was not flushed, and a resumed run skips the frames already on disk.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..analysis.observables import boundary_rows
from ..geometry.base import Geometry
from ..util.atomic import written_atomically
from ..util.errors import FieldError, InputError
from ..util.extras import need
from ..util.sums import kinetic_energy
from .tables import rows

__all__ = ["TRAJECTORY_NAME", "TYPES", "ORIGIN_LOG", "Layout", "Trajectory", "export", "gsd_hoomd"]

#: the trajectory's name in a run directory
TRAJECTORY_NAME = "trajectory.gsd"
#: particle types, by typeid
TYPES = ("bulk", "boundary")
#: the log entry (frame 0) to add to ``position`` for the figures' coordinates
ORIGIN_LOG = "pinnedballs/origin"


@dataclass(frozen=True, eq=False)
class Layout:
    """What every frame of one run shares, in GSD's terms (see the module's docstring).

    position ``(n, 3) float32``; origin ``(3,)``; box ``(6,) float32``; dimensions 2 or 3;
    diameter ``(n,) float32``; typeid ``(n,) uint32``; mass ``(n,) float32`` or None;
    frames ``(n, dim, k)`` on a curved surface, else None; k the number of coordinates.
    """

    position: np.ndarray
    origin: np.ndarray
    box: np.ndarray
    dimensions: int
    diameter: np.ndarray
    typeid: np.ndarray
    mass: np.ndarray | None
    frames: np.ndarray | None
    k: int

    @classmethod
    def of(cls, geometry: Geometry, masses=None) -> Layout:
        """The layout of a run on ``geometry`` with ``masses`` (None, a number or ``(n,)``)."""
        p = np.asarray(geometry.positions, dtype=np.float64)
        n, k = p.shape
        if k > 3:
            raise FieldError("geometry", f"a GSD frame holds at most 3 coordinates; these balls have {k}")
        frames = np.asarray(geometry.frames(), dtype=np.float64) if geometry.curved else None
        if frames is None and geometry.dim != k:
            raise FieldError("geometry", f"velocities of {geometry.dim} components cannot be drawn at positions of "
                                         f"{k} coordinates (a geometry with no frames)")
        diameter = _diameters(geometry, p)
        dimensions = 3 if k == 3 else 2
        lengths, origin = _box(geometry, p, dimensions, float(diameter.max()) if n else 0.0)
        centred = np.zeros((n, 3))
        centred[:, :k] = p - origin[:k]
        _fits_float32(max(float(np.abs(centred).max(initial=0.0)), float(lengths.max())),
                      float(diameter.min(initial=np.inf)))
        mass = None if masses is None else np.broadcast_to(np.asarray(masses, dtype=np.float32), (n,)).copy()
        return cls(centred.astype(np.float32), origin, np.concatenate([lengths, np.zeros(3)]).astype(np.float32),
                   dimensions, diameter.astype(np.float32), _typeid(geometry), mass, frames, k)

    @property
    def n_balls(self) -> int:
        return len(self.position)

    def velocity(self, velocities: np.ndarray) -> np.ndarray:
        """``(n, 3) float32``: ``velocities (n, dim)`` in the coordinates of `position`."""
        v = np.asarray(velocities, dtype=np.float64)
        if self.frames is not None:
            v = np.einsum("nd,ndk->nk", v, self.frames)
        out = np.zeros((len(v), 3))
        out[:, :self.k] = v
        return out.astype(np.float32)

    def frame(self, steps: int, velocities: np.ndarray, log: dict, first: bool):
        """A `gsd.hoomd.Frame` of the state after ``steps`` with ``velocities (n, dim)`` and the
        observables ``log`` (name -> value); ``first``: frame 0, which also carries the origin."""
        f = gsd_hoomd().Frame()
        f.configuration.step = int(steps)
        f.configuration.dimensions = self.dimensions
        f.configuration.box = self.box
        p = f.particles
        p.N = self.n_balls
        p.types = list(TYPES)
        p.typeid, p.position, p.diameter = self.typeid, self.position, self.diameter
        p.velocity = self.velocity(velocities)
        if self.mass is not None:
            p.mass = self.mass
        f.log = {name: _log_value(value) for name, value in log.items()}
        if first:
            f.log[ORIGIN_LOG] = self.origin.astype(np.float64)
        return f


#: what a GSD frame's 32-bit floats hold with all their digits: sizes from FLOAT32[0] to FLOAT32[1]
FLOAT32 = (1e-30, 1e38)


def _fits_float32(largest: float, diameter: float) -> None:
    """A `FieldError` on ``trajectory`` unless lengths up to ``largest`` and balls of ``diameter`` fit
    GSD's 32-bit floats (whose range float64 runs far exceed: their frames would hold inf or 0)."""
    low, high = FLOAT32
    if largest > high or diameter < low:
        raise FieldError("trajectory", f"a GSD trajectory holds 32-bit floats, which cannot hold this geometry "
                                       f"(balls {diameter:.3g} across, coordinates up to {largest:.3g}; they hold "
                                       f"{low:g} to {high:g})")


def check_speeds_fit(velocities: np.ndarray, masses=None) -> None:
    """A `FieldError` on ``trajectory`` unless every speed a run from ``velocities (n, dim)`` can reach
    (all its energy in the lightest ball) fits GSD's 32-bit floats."""
    v = np.asarray(velocities, dtype=np.float64)
    m = np.ones(len(v)) if masses is None else np.broadcast_to(np.asarray(masses, dtype=np.float64), (len(v),))
    energy = kinetic_energy(m, v) if len(v) else 0.0
    fastest = float(np.sqrt(2.0 * energy / m.min())) if len(v) else 0.0
    if fastest > FLOAT32[1]:
        raise FieldError("trajectory", f"a GSD trajectory holds 32-bit floats, which cannot hold the speeds of this "
                                       f"run (up to {fastest:.3g}; they hold at most {FLOAT32[1]:g})")


def _diameters(geometry: Geometry, p: np.ndarray) -> np.ndarray:
    """``(n,)``: ``2 radius`` in flat space; on a curved surface each ball's mean chord (in the
    embedding) to the balls it touches (the mean over all contacts for a ball that touches none)."""
    n = len(p)
    if not geometry.curved:
        return np.full(n, 2.0 * float(geometry.radius))
    pairs = np.asarray(geometry.contacts.pairs, dtype=np.int64)
    if len(pairs) == 0:
        return np.full(n, 2.0 * float(geometry.radius))
    chords = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1)
    total = np.bincount(pairs.ravel(), weights=np.repeat(chords, 2), minlength=n)
    count = np.bincount(pairs.ravel(), minlength=n)
    return np.where(count > 0, total / np.maximum(count, 1), chords.mean())


def _box(geometry: Geometry, p: np.ndarray, dimensions: int, diameter: float) -> tuple[np.ndarray, np.ndarray]:
    """``(lengths (3,), origin (3,))``: along each axis the period if it is periodic, else the
    extent of the centres plus a ``diameter``; the origin is the box's centre in the geometry's
    coordinates. Lz = 0 and origin z = 0 in 2-D."""
    k = p.shape[1]
    lo, hi = p.min(axis=0), p.max(axis=0)
    lengths, origin = np.zeros(3), np.zeros(3)
    lengths[:k], origin[:k] = hi - lo + diameter, (lo + hi) / 2.0
    period = getattr(geometry, "period", None)
    if period is not None:
        period = np.asarray(period, dtype=np.float64)
        periodic = getattr(geometry, "periodic", (True,) * len(period))
        for axis, (length, wraps) in enumerate(zip(period, periodic)):
            if wraps and axis < k:
                lengths[axis], origin[axis] = length, lo[axis] + length / 2.0
    if dimensions == 2:
        lengths[2] = origin[2] = 0.0
    return lengths, origin


def _typeid(geometry: Geometry) -> np.ndarray:
    """``(n,) uint32``: 1 for the balls of the row nearest the boundary, 0 for the others."""
    typeid = np.zeros(geometry.n_balls, dtype=np.uint32)
    boundary = geometry.boundary
    if boundary is not None:
        row, _ = boundary_rows(boundary.distance)
        typeid[row == 0] = 1
    return typeid


def _log_value(value) -> np.ndarray:
    """An observable as a GSD log chunk: a 1-D or 2-D array (a number becomes ``(1,)``)."""
    a = np.atleast_1d(np.asarray(value))
    if a.dtype == bool:
        a = a.astype(np.uint8)
    return a.reshape(len(a), -1) if a.ndim > 2 else a


# ---------------------------------------------------------------- files


def gsd_hoomd():
    """The module ``gsd.hoomd``; a `MissingExtra` naming the ``gsd`` extra without it."""
    return need("gsd.hoomd", "a GSD trajectory", "gsd")


def _open_gsd(path: Path, mode: str):
    """``gsd.hoomd.open(path, mode)``; an `InputError` naming ``path`` if it is not a readable GSD file."""
    hoomd = gsd_hoomd()
    try:
        return hoomd.open(str(path), mode)
    except (RuntimeError, OSError) as exc:
        raise InputError(f"{path}: not a readable GSD trajectory ({' '.join(str(exc).split())})") from None


def check_output(path: str | os.PathLike, *, force: bool, hint: str) -> Path:
    """``path`` as a Path if a GSD file may be written there; else an `InputError` naming it."""
    path = Path(path)
    if path.suffix.lower() != ".gsd":
        raise InputError(f"{path}: a GSD trajectory's name must end in .gsd")
    if path.is_dir():
        raise InputError(f"{path}: is a directory")
    if path.exists() and not force:
        raise InputError(f"{path}: exists; {hint}")
    parent = path.parent
    if not parent.is_dir():
        raise InputError(f"{path}: {parent} is not a directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{path}: {parent} is not writable")
    return path


class Trajectory:
    """A GSD file of one run's frames, open for appending. `open` starts or continues one;
    `append` adds a frame (skipping one the file already holds); `close` ends it."""

    def __init__(self, path: Path, handle, layout: Layout, last_steps: int | None):
        self.path, self.handle, self.layout = path, handle, layout
        self.last_steps = last_steps  #: the steps of the last frame on disk, or None

    @classmethod
    def open(cls, path: str | os.PathLike, layout: Layout, *, force: bool = False, resume: bool = False,
             hint: str = "pass force=True to replace it or resume=True to append to it") -> Trajectory:
        """Start ``path`` afresh, or with ``resume`` continue it (its frames must be of the same
        balls); an existing file is refused unless ``force`` or ``resume``."""
        path = Path(path)
        if resume and path.exists():
            handle = _open_gsd(path, "a")
            try:
                last = _check_same_balls(handle, layout, path)
            except BaseException:
                handle.close()
                raise
            return cls(path, handle, layout, last)
        check_output(path, force=force, hint=hint)
        return cls(path, _open_gsd(path, "w"), layout, None)

    def __len__(self) -> int:
        return len(self.handle)

    def append(self, steps: int, velocities: np.ndarray, log: dict) -> bool:
        """Write and flush the frame of the state after ``steps``; False (nothing written) if the
        file already holds a frame at or after ``steps`` (a resumed run going over them again)."""
        if self.last_steps is not None and steps <= self.last_steps:
            return False
        self.handle.append(self.layout.frame(steps, velocities, log, first=len(self.handle) == 0))
        self.handle.flush()
        self.last_steps = int(steps)
        return True

    def close(self) -> None:
        self.handle.close()


def _check_same_balls(handle, layout: Layout, path: Path) -> int | None:
    """The steps of the last frame of the open trajectory ``handle`` (None if it has none); an
    `InputError` naming ``path`` unless its frames are of the balls of ``layout``."""
    if len(handle) == 0:
        return None
    first = handle[0]
    if int(first.particles.N) != layout.n_balls or not np.array_equal(first.particles.position, layout.position):
        raise InputError(f"{path}: holds frames of another run ({int(first.particles.N)} balls, this run has "
                         f"{layout.n_balls}); choose another file or replace it")
    return int(handle[-1].configuration.step)


def export(res, out: str | os.PathLike, *, force: bool = False,
           hint: str = "pass force=True to replace it") -> Path:
    """Write every snapshot of the run ``res`` (its `pinnedballs.results.load.Results`) as one frame of
    the GSD file ``out`` (written whole to a temporary file, then renamed), then the state the run
    stopped in, unless the last snapshot is that state; returns its path. The final frame logs the
    observables the results file holds for it (a user's observable is NaN there).

    An `InputError` naming the file or run if ``out`` cannot be written (an existing file needs
    ``force``) or the run has no snapshots; nothing is written then.
    """
    out = check_output(out, force=force, hint=hint)
    if not res.snapshots:
        raise InputError(f"{res.run_dir}: the run has no snapshots to export (give its spec \"snapshots\", "
                         f"or a \"trajectory\" to write {TRAJECTORY_NAME} while it runs)")
    try:
        layout = Layout.of(res.geometry, res.masses)
    except FieldError as exc:
        raise InputError(f"{out}: {exc.problem}") from None
    columns, final = rows(res)
    with written_atomically(out) as tmp:  # a refusal below leaves nothing written
        handle = _open_gsd(tmp, "w")
        try:
            for i in range(len(final)):
                log = {name: column[i] for name, column in columns.items()}
                velocities = res.velocities if i == len(res.snapshots) else res.snapshots.velocities(i)
                try:
                    check_speeds_fit(velocities, res.masses)
                except FieldError as exc:
                    raise InputError(f"{out}: {exc.problem}") from None
                handle.append(layout.frame(int(columns["steps"][i]), velocities, log, first=i == 0))
        finally:
            handle.close()
    return out
