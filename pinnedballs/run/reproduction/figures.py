"""The reproduction's figures: the paper's (Figures 1-8) and our own."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.ticker import MaxNLocator

from .. import ensemble as ens
from .plan import PAPER_FROZEN_COLLISIONS, Plan, _label, _Run

# ---------------------------------------------------------------- figures of our own


def _frozen_collisions_figure(ours: np.ndarray, paper_lattice: np.ndarray, labels: tuple[str, str], path: Path):
    from ...plot import base as plots

    fig = plots.new_figure((8.0, 4.0))
    ax = fig.add_subplot()
    data = [x for x in (ours, paper_lattice) if len(x)]
    lo = min(x.min() for x in data) if data else 0
    hi = max(x.max() for x in data) if data else 1
    bins = np.linspace(min(lo, PAPER_FROZEN_COLLISIONS) * 0.98, max(hi, PAPER_FROZEN_COLLISIONS) * 1.02, 41)
    for x, label, colour in zip((ours, paper_lattice), labels, ("tab:blue", "tab:green")):
        if len(x):
            ax.hist(x, bins=bins, alpha=0.6, color=colour, label=f"{label}: mean {x.mean():,.0f}, {len(x)} runs")
    ax.axvline(PAPER_FROZEN_COLLISIONS, color="k", linestyle="--", label=f"paper: {PAPER_FROZEN_COLLISIONS:,}")
    ax.set_xlabel("collisions until frozen")
    ax.set_ylabel("runs")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title("collisions until frozen, 100x50 half-plane, over seeds")
    ax.legend(fontsize="small")
    plots.save(fig, path)
    return path


def _far_share_figure(rows: list[tuple[str, int, np.ndarray, np.ndarray]], path: Path):
    from ...plot import base as plots

    fig = plots.new_figure((8.0, 4.0))
    ax = fig.add_subplot()
    n = np.array([r[1] for r in rows], dtype=float)
    for k, (name, marker) in enumerate((("far half (distance > depth / 2)", "o"), ("farthest row", "s"))):
        values = [r[2 + k] for r in rows]
        ax.errorbar(n, [v.mean() if len(v) else np.nan for v in values],
                    yerr=[v.std(ddof=1) if len(v) > 1 else 0 for v in values], marker=marker, capsize=3, label=name)
    for label, balls, far_half, _ in rows:
        if len(far_half):
            ax.annotate(label, (balls, far_half.mean()), textcoords="offset points", xytext=(0, 10), ha="center",
                        rotation=45, fontsize="x-small")
    ax.set_xscale("log")
    ax.set_ylim(bottom=0)
    ax.set_xlabel("balls")
    ax.set_ylabel("share of the energy (mean ± sd over runs)")
    ax.set_title("energy far from the boundary in the frozen state")
    ax.legend(fontsize="small")
    plots.save(fig, path)
    return path


# ---------------------------------------------------------------- figures of the paper


def _figures_half_plane(out: Path, plan: Plan, geom, by_steps: _Run, by_collisions: _Run) -> None:
    from ...plot.figures import energy_by_distance
    from ...plot.states import quiver

    sim = by_steps.sim
    name = f"half-plane {_label(plan.detail)} ({geom.rows}x{geom.cols}, {geom.n_balls:,} balls)"
    quiver(geom.positions, by_steps.initial, title=f"{name}: initial state",
           path=out / "fig1_half_plane_initial.png")
    for s in plan.steps:
        snap = by_steps.snapshots.get(s)
        if snap is not None:
            title = f"{name}: after {s:,} steps ({snap.state.collisions:,} collisions)"
            v = snap.state.velocities
        else:
            title = (f"{name}: frozen at step {sim.steps:,} ({sim.collisions:,} collisions),\n"
                     f"before {s:,} steps: this is also the state at step {s:,}")
            v = sim.velocities
        quiver(geom.positions, v, title=title, path=out / f"fig2_half_plane_step_{s}.png")
    dist = geom.boundary_distance()
    snap = by_collisions.snapshots.get(plan.collisions)
    if snap is not None:
        v = snap.state.velocities
        title = f"{name}: after {plan.collisions:,} collisions ({snap.state.steps:,} steps)"
    else:
        v, title = sim.velocities, f"{name}: frozen after {sim.collisions:,} collisions, before {plan.collisions:,}"
    energy_by_distance(dist, v, title=title, path=out / f"fig3_energy_by_distance_collisions_{plan.collisions}.png",
                       radius=geom.radius)
    state = "frozen" if sim.is_frozen() else "not frozen"
    energy_by_distance(dist, sim.velocities, path=out / "fig3_energy_by_distance_final.png", radius=geom.radius,
                       title=f"{name}: final state, {state} after {sim.collisions:,} collisions ({sim.steps:,} steps)")


def _figure_sizes(out: Path, profiles: dict) -> None:
    from ...plot import base as plots
    from ...plot.figures import energy_profiles

    fig = plots.new_figure((9.0, 7.5))
    top, bottom = fig.subplots(2, 1)
    energy_profiles(profiles, ax=top, title="energy against distance from the boundary, frozen state (seed 0)")
    energy_profiles(profiles, ax=bottom, logy=True)
    bottom.get_legend().remove()
    plots.save(fig, out / "fig4_energy_by_distance_sizes.png")


def _figure_paper_lattice(out: Path, run: _Run) -> None:
    from ...plot.figures import energy_by_distance

    g = run.sim.geometry
    energy_by_distance(g.boundary.distance, run.sim.velocities, path=out / "extra_paper_lattice_energy_by_distance.png",
                       radius=g.radius,
                       title=f"paper orientation ({g.n_balls:,} balls, rows perpendicular to the boundary): "
                             f"frozen after {run.sim.collisions:,} collisions")


def _figures_torus(out: Path, plan: Plan, run: _Run) -> None:
    from ...plot.figures import component_histograms
    from ...plot.states import quiver

    g = run.sim.geometry
    name = f"flat torus {g.rows}x{g.cols} ({g.n_balls:,} balls)"
    quiver(g.positions, run.initial, title=f"{name}: initial state", path=out / "fig5_torus_initial.png")
    for s in plan.steps:
        snap = run.snapshots.get(s)
        v = snap.state.velocities if snap is not None else run.sim.velocities
        collisions = snap.state.collisions if snap is not None else run.sim.collisions
        title = f"{name}: after {s:,} steps ({collisions:,} collisions)"
        quiver(g.positions, v, title=title, path=out / f"fig5_torus_step_{s}.png")
        component_histograms(v, title=f"{name}: velocity components after {s:,} steps",
                             path=out / f"fig6_torus_components_step_{s}.png")


def _figures_correlations(out: Path, plan: Plan, res: ens.EnsembleResult, at: str) -> None:
    from ...plot.figures import correlation_histogram

    n = len(res.column("line_of_centres_correlation", at))
    correlation_histogram(res.column("line_of_centres_correlation", at), 0.02, xlabel="correlation of u and u'",
                          title=f"line-of-centres components of touching balls: {n} runs, {plan.steps[-1]:,} steps",
                          path=out / "fig7_correlation_line_of_centres.png")
    correlation_histogram(res.column("xy_correlation", at), 0.02, xlabel="correlation of x- and y-components",
                          title=f"x- and y-components: {n} runs, {plan.steps[-1]:,} steps",
                          path=out / "fig8_correlation_xy.png")
