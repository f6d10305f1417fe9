"""The figures of one run, written beside its results (``pinnedballs run`` and ``plot``)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from .base import length_label, length_unit, save
from .figures import component_histograms, energy_by_distance
from .names import FIGURE_PATTERNS, figure_files
from .sheet import contact_sheet
from .states import state_picture

#: the velocity histograms' range: this quantile of the absolute components (one outlier does not set it)
ROBUST_RANGE = 0.99

__all__ = ["write_figures", "figures", "plot_results", "plot_simulation", "PLOTS", "LIVE_PLOTS", "figure_files",
           "snapshot_name", "snapshot_counter", "FIGURE_PATTERNS"]


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
    written: list[Path] = []
    for name, make in _figures(res, every_snapshot):
        path = out / name
        save(make(None), path)  # one figure at a time: a run of many snapshots holds one
        written.append(path)
    return written


def figures(res, every_snapshot: bool = False) -> dict[str, Figure]:
    """The figures `write_figures` writes, as ``{file name without .png: Figure}``."""
    return {name.removesuffix(".png"): make(None) for name, make in _figures(res, every_snapshot)}


def _figures(res, every_snapshot: bool = False) -> Iterator[tuple[str, Callable]]:
    """``(file name, make(ax) -> Figure)`` of each figure of ``res``, in the order `write_figures` writes them."""
    positions = np.asarray(res.positions, dtype=np.float64)
    final = np.asarray(res.velocities, dtype=np.float64)
    geometry = res.geometry
    draw = state_picture(geometry)
    snapshots = () if res.snapshots is None else res.snapshots
    steps = [int(s) for s in _steps(snapshots)]
    start = [k for k, s in enumerate(steps) if s == 0]
    later = [k for k, s in enumerate(steps) if s != 0]
    initial = getattr(res, "initial_velocities", None)
    if start or initial is not None:
        yield "state_initial.png", lambda ax: draw(_velocities(snapshots, start[0]) if start else
                                                   np.asarray(initial, dtype=np.float64), "initial state", ax=ax)
    counter = snapshot_counter(res)
    if len(later) > 1:
        def sheet(ax):
            tiles = [(snapshot_name(snapshots[k], counter)[1].removeprefix("after "), _velocities(snapshots, k))
                     for k in later]
            return contact_sheet(draw, tiles, title=f"the {len(later)} snapshots after the start", ax=ax)
        yield "state_snapshots.png", sheet
    if every_snapshot or len(later) == 1:  # a sheet of one would be a small copy of its picture
        for k in later:
            snap = snapshots[k]
            name, title = snapshot_name(snap, counter)
            v = np.asarray(snap.velocities, dtype=np.float64)
            yield name, lambda ax, v=v, t=title: draw(v, t, ax=ax)
    yield "state_final.png", lambda ax: draw(final, "final state", ax=ax)
    yield from _observed(geometry, positions, final, res.masses, "final state")


def _observed(geometry, positions: np.ndarray, v: np.ndarray, masses, when: str) -> Iterator[tuple[str, Callable]]:
    """``(file name, make(ax, title=None) -> Figure)`` of the figures of the state ``v (n_balls, dim)`` beyond its
    picture, as a run's figures draw them (``when``, e.g. "final state", ends their default titles): the energy
    by distance on a geometry with a boundary, by height in flat 3-D, the velocity components' histograms."""
    if geometry.boundary is not None:
        unit = "lengths on the surface" if geometry.curved else length_unit(geometry.radius)
        yield "energy_by_distance.png", lambda ax, title=None: energy_by_distance(
            geometry.boundary.distance, v, masses, ax=ax,
            title=title or f"energy by distance from the boundary, {when}",
            xlabel=f"distance from the boundary ({unit})")
    if geometry.dim == 3 and positions.shape[1] == 3 and not geometry.curved:
        yield "energy_by_height.png", lambda ax, title=None: energy_by_distance(
            positions[:, 2] - positions[:, 2].min(), v, masses, ax=ax, title=title or f"energy by height (z), {when}",
            xlabel=length_label("height z above the lowest layer", geometry.radius), first="lowest layer")
    if v.ndim == 2 and 1 <= v.shape[1] <= 3:
        yield "velocity_histograms.png", lambda ax, title=None: component_histograms(
            v, title=title or f"velocity components, {when}", quantile=ROBUST_RANGE, ax=ax)


def _steps(snapshots) -> list[int]:
    """The steps of each snapshot, without reading their velocities when the run was loaded lazily."""
    steps = getattr(snapshots, "steps", None)
    return list(steps) if steps is not None else [s.steps for s in snapshots]


def _velocities(snapshots, k: int) -> np.ndarray:
    return np.asarray(snapshots[k].velocities, dtype=np.float64)


#: what `plot_results` draws: ``what`` -> the figure of `write_figures` it is
PLOTS = {"final": "state_final", "initial": "state_initial", "snapshots": "state_snapshots",
         "energy": "energy_by_distance", "height": "energy_by_height", "histograms": "velocity_histograms"}


def plot_results(res, what: str = "final", *, snapshot: int | None = None, ax=None):
    """A figure of the run ``res`` (`pinnedballs.Results.plot`), as `write_figures` draws it: ``what`` is
    ``"final"`` (the final state), ``"initial"``, ``"snapshot"`` (snapshot number ``snapshot``, e.g. -1),
    ``"snapshots"`` (the contact sheet), ``"energy"`` (energy by distance from the boundary), ``"height"``
    (energy by height, flat 3-D), ``"histograms"`` (the velocity components), or ``"all"``:
    ``{name: Figure}`` of every figure ``pinnedballs plot`` writes. ``ax``: draw into these axes (a
    drawing of several panels takes their place); else a new figure. Returns the `Figure` (a dict for
    ``"all"``); a ValueError names what this run has when ``what`` does not fit it."""
    if what == "all":
        return figures(res)
    if what == "snapshot":
        if snapshot is None:
            raise ValueError("snapshot: give the number of the snapshot to draw (0 the first, -1 the last)")
        snap = res.snapshots[snapshot]
        title = snapshot_name(snap, snapshot_counter(res))[1]
        return state_picture(res.geometry)(np.asarray(snap.velocities, dtype=np.float64), title, ax=ax)
    makers = {name.removesuffix(".png"): make for name, make in _figures(res)}
    if what not in PLOTS or PLOTS[what] not in makers:
        known = [w for w, name in PLOTS.items() if name in makers] + ["snapshot", "all"]
        raise ValueError(f"what: {what!r} is not a figure of this run; it has: {', '.join(known)}")
    return makers[PLOTS[what]](ax)


#: what `plot_simulation` draws of a simulation's current state: ``what`` -> the figure of a run it is drawn as
LIVE_PLOTS = {"state": "state_final", "energy": "energy_by_distance", "height": "energy_by_height",
              "histograms": "velocity_histograms"}


def plot_simulation(sim, what: str = "state", *, ax=None, title: str | None = None):
    """A figure of ``sim``'s current state (`pinnedballs.Simulation.plot`), as a run's figures draw it
    (`Results.plot`): ``what`` is ``"state"`` (its picture in the geometry's view), ``"energy"`` (energy by
    distance from the boundary), ``"height"`` (energy by height, flat 3-D) or ``"histograms"`` (the velocity
    components); into ``ax`` or a new figure, titled ``title`` (by default, the counts it is after). A
    simulation keeps no snapshots (a `ResultsWriter` does): a ValueError names the figures it has when
    ``what`` does not fit it."""
    g, v = sim.geometry, np.asarray(sim.velocities, dtype=np.float64)
    when = f"after {sim.steps:,} steps, {sim.collisions:,} collisions"
    makers = {"state_final": lambda ax, title=None: state_picture(g)(v, title or when, ax=ax)}
    makers.update((name.removesuffix(".png"), make) for name, make in _observed(g, g.positions, v, sim.masses, when))
    known = [w for w, name in LIVE_PLOTS.items() if name in makers]
    if not isinstance(what, str):
        raise TypeError(f"what: must name a figure of this simulation ({', '.join(known)}), got {what!r}")
    if what not in LIVE_PLOTS or LIVE_PLOTS[what] not in makers:
        hint = {"final": "; its current state is 'state'"}.get(what, "; a simulation keeps no snapshots: record it "
                                                                     "with a ResultsWriter, then pb.load(DIR).plot()"
                                                            if what in ("initial", "snapshot", "snapshots", "all")
                                                            else "")
        raise ValueError(f"what: {what!r} is not a figure of this simulation; it has: {', '.join(known)}{hint}")
    return makers[LIVE_PLOTS[what]](ax, title)
