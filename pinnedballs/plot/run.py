"""The figures of one run, written beside its results (``pinnedballs run`` and ``plot``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .base import length_label, length_unit, save
from .names import FIGURE_PATTERNS, figure_files
from .figures import component_histograms, energy_by_distance
from .sheet import contact_sheet
from .states import state_picture

#: the velocity histograms' range: this quantile of the absolute components (one outlier does not set it)
ROBUST_RANGE = 0.99

__all__ = ["write_figures", "figure_files", "snapshot_name", "snapshot_counter", "FIGURE_PATTERNS"]


# ---------------------------------------------------------------- one run


def snapshot_counter(res) -> str:
    """``"collisions"`` if the run's spec placed its snapshots by collisions, else ``"steps"``."""
    snapshots = getattr(getattr(res, "spec", None), "snapshots", None)
    return getattr(snapshots, "counter", "steps")


def snapshot_name(snap, counter: str) -> tuple[str, str]:
    """``(file name, title)`` of the state picture of ``snap``, named after the count ``counter`` the
    spec asked for: ``state_collisions_22579.png``, "after 22,579 collisions (89,335 steps)"."""
    step, collisions = int(snap.steps), int(snap.collisions)
    if step == 0:
        return "state_initial.png", "initial state"
    if counter == "collisions":
        return f"state_collisions_{collisions}.png", f"after {collisions:,} collisions ({step:,} steps)"
    return f"state_step_{step}.png", f"after {step:,} steps ({collisions:,} collisions)"


def write_figures(res, out_dir, every_snapshot: bool = False) -> list[Path]:
    """Write the figures of one run's results into ``out_dir``; return their paths.

    res: what `pinnedballs.load` returns (``positions (n, k)``, final
    ``velocities (n, dim)``, ``snapshots`` with ``.steps``, ``.collisions``,
    ``.velocities``, ``geometry``, ``masses`` or None, and ``initial_velocities`` if it
    has them). Writes, in the geometry's view (see `state_picture`: the plane, both hemispheres of
    a sphere, the Poincare disk, the layers of a 3-D packing, a 1-D chain), ``state_initial.png``
    (the initial velocities, or a snapshot at step 0), ``state_snapshots.png`` (a contact sheet of
    the snapshots after the start, `sheet.contact_sheet`, when there are two or more) and
    ``state_final.png``; with ``every_snapshot`` (or a single snapshot after the start) also
    ``state_step_<N>.png`` or ``state_collisions_<C>.png`` for each of them (named after the counter
    the spec placed them by). Then ``energy_by_distance.png`` on any
    geometry with a ``boundary``; ``energy_by_height.png`` in flat 3-D; ``velocity_histograms.png``
    (one panel per component, up to 3).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    positions = np.asarray(res.positions, dtype=np.float64)
    final = np.asarray(res.velocities, dtype=np.float64)
    geometry = res.geometry
    written: list[Path] = []

    def emit(name: str, fig: Figure) -> None:
        path = out / name
        save(fig, path)
        written.append(path)

    draw = state_picture(geometry)
    snapshots = list(() if res.snapshots is None else res.snapshots)
    start = [s for s in snapshots if int(s.steps) == 0]
    later = [s for s in snapshots if int(s.steps) != 0]
    initial = start[0].velocities if start else getattr(res, "initial_velocities", None)
    if initial is not None:
        emit("state_initial.png", draw(np.asarray(initial, dtype=np.float64), "initial state"))
    counter = snapshot_counter(res)
    if len(later) > 1:
        tiles = [(snapshot_name(s, counter)[1].removeprefix("after "), np.asarray(s.velocities, dtype=np.float64))
                 for s in later]
        emit("state_snapshots.png", contact_sheet(draw, tiles, title=f"the {len(later)} snapshots after the start"))
    if every_snapshot or len(later) == 1:  # a sheet of one would be a small copy of its picture
        for snap in later:
            name, title = snapshot_name(snap, counter)
            emit(name, draw(np.asarray(snap.velocities, dtype=np.float64), title))
    emit("state_final.png", draw(final, "final state"))
    if geometry.boundary is not None:
        unit = "lengths on the surface" if geometry.curved else length_unit(geometry.radius)
        emit("energy_by_distance.png", energy_by_distance(geometry.boundary.distance, final, res.masses,
                                                          title="energy by distance from the boundary, final state",
                                                          xlabel=f"distance from the boundary ({unit})"))
    if geometry.dim == 3 and positions.shape[1] == 3 and not geometry.curved:
        emit("energy_by_height.png", energy_by_distance(
            positions[:, 2] - positions[:, 2].min(), final, res.masses, title="energy by height (z), final state",
            xlabel=length_label("height z above the lowest layer", geometry.radius), first="lowest layer"))
    if final.ndim == 2 and 1 <= final.shape[1] <= 3:
        emit("velocity_histograms.png", component_histograms(final, title="velocity components, final state",
                                                             quantile=ROBUST_RANGE))
    return written
