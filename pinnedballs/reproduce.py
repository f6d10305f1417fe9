"""``pinnedballs reproduce``: every figure of the paper, and ``report.md`` comparing its numbers with ours.

The paper's set-ups (``docs/reproduce.md`` explains them and our choices):

* half-plane: ``HalfPlane.from_size(L, D)`` for the paper's seven rectangles, one
  boundary ball (``boundary_center``) sent into the bulk (direction ``(0, 1)``) with
  energy 100, unit masses, run until frozen. As a cross-check, the 100 x 50 rectangle
  also in the orientation the paper's ball count implies (``HalfPlane`` ``orientation="across"``);
* flat torus: ``FlatTorus(38, 38)`` (1,444 balls; the paper gives no size), ball 0
  moving with energy 100, snapshots at 211,417 and 422,834 steps.

Single runs (the pictures) use ``seed`` itself; ensembles use replicas ``0..N-1`` of
``seed`` (`pinnedballs.ensemble`). Everything is seeded, so the report is reproducible.
`FULL` is the paper's scale; `QUICK` a smaller one for a first look.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from . import ensemble as ens
from .cli import arg, subcommand
from .io import check_out_dir
from .spec import InputError, RunSpec, parse_spec

__all__ = ["Plan", "FULL", "QUICK", "PAPER_SIZES", "Check", "reproduce", "expected_figures",
           "half_plane_spec", "torus_spec", "paper_lattice_spec", "paper_lattice_row", "torus_row"]

PAPER_SIZES = ((10, 5), (60, 30), (100, 50), (200, 100), (300, 150), (400, 200), (500, 250))
#: the paper's numbers
PAPER_BOUNDARY_SHARE = 0.30
PAPER_FROZEN_COLLISIONS = 45_158
#: "near 0" for a mean correlation over runs
CORRELATION_TOLERANCE = 0.05
REPORT_NAME = "report.md"


@dataclass(frozen=True)
class Plan:
    """What `reproduce` runs. Sizes are ``(length, depth)`` in radii."""

    sizes: tuple[tuple[float, float], ...] = PAPER_SIZES  #: half-plane rectangles (Figure 4)
    detail: tuple[float, float] = (100, 50)   #: the rectangle of Figures 1-3
    torus: tuple[int, int] = (38, 38)         #: rows, cols of the flat torus
    steps: tuple[int, int] = (211_417, 422_834)  #: snapshots (Figures 2, 5, 6, 7, 8)
    long_steps: int = 4_228_340               #: the torus ensemble runs on to here (is it still changing?)
    collisions: int = 22_579                  #: Figure 3's first bar plot
    energy: float = 100.0
    replicas: int = 240       #: torus runs (Figures 7, 8) and replicas of the detail rectangle
    size_replicas: int = 24   #: replicas of each other rectangle
    seed: int = 0
    max_steps: int = 10**11   #: a half-plane that is not frozen by then is reported so


FULL = Plan()
QUICK = dataclasses.replace(FULL, sizes=PAPER_SIZES[:4], replicas=24, size_replicas=8)


@dataclass(frozen=True)
class Check:
    """One row of the report: a statement of the paper, its figure, ours, the criterion, the verdict."""

    statement: str
    paper: str
    ours: str
    criterion: str
    agrees: bool | None  #: None: nothing to compare (a remark of ours, or a figure without a number)

    def __post_init__(self):
        if self.agrees is not None:  # numpy booleans become plain ones (``is True`` and JSON need them)
            object.__setattr__(self, "agrees", bool(self.agrees))


# ---------------------------------------------------------------- set-ups


def _label(size) -> str:
    return f"{size[0]:g}x{size[1]:g}"


def half_plane_spec(size, plan: Plan, snapshots: dict | None = None) -> RunSpec:
    """The paper's half-plane ``size = (length, depth)``: boundary-centre ball into the bulk, run until frozen."""
    return parse_spec({
        "description": f"half-plane {_label(size)}: one boundary ball sent into the bulk, run until frozen",
        "geometry": {"kind": "half_plane", "length": float(size[0]), "depth": float(size[1])},
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0],
                    "energy": float(plan.energy)},
        "stop": {"frozen": True, "max_steps": plan.max_steps},
        "snapshots": snapshots, "seed": plan.seed})


def torus_spec(plan: Plan, stop: int | None = None) -> RunSpec:
    """The flat torus: ball 0 moving along x; stop at ``stop`` (default ``plan.steps[-1]``), snapshots
    at the earlier ``plan.steps``."""
    rows, cols = plan.torus
    stop = plan.steps[-1] if stop is None else stop
    earlier = [s for s in plan.steps if s < stop]
    return parse_spec({
        "description": f"flat torus {rows}x{cols}: ball 0 moving, all others at rest",
        "geometry": {"kind": "flat_torus", "rows": rows, "cols": cols},
        "initial": {"kind": "single_ball", "ball": 0, "direction": [1.0, 0.0], "energy": float(plan.energy)},
        "stop": {"steps": stop},
        "snapshots": {"at_steps": earlier} if earlier else None,
        "seed": plan.seed})


def paper_lattice_spec(plan: Plan) -> RunSpec:
    """The paper's orientation of the ``plan.detail`` rectangle: ``HalfPlane.from_size(..., orientation="across")``,
    lattice rows perpendicular to the boundary (``(100, 50)``: 57 rows of 25 = 1,425 balls)."""
    length, depth = plan.detail
    return parse_spec({
        "description": "the paper's orientation: lattice rows perpendicular to the boundary y = 0",
        "geometry": {"kind": "half_plane", "length": float(length), "depth": float(depth), "orientation": "across"},
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0],
                    "energy": float(plan.energy)},
        "stop": {"frozen": True, "max_steps": plan.max_steps}, "seed": plan.seed})


def paper_lattice_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` (``boundary_share`` is the share at distance 0) and ``next_share`` (distance 1)."""
    from . import observables as obs

    row = ens.state_row(geometry, velocities, masses)
    _, fraction = obs.energy_profile(geometry.boundary.distance, velocities, masses)
    row["next_share"] = float(fraction[1])
    return row


def torus_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` and, per component, the variance (``ddof=0``), the excess kurtosis,
    the KS p-value and the Anderson–Darling statistic against a fitted normal (NaN where undefined)."""
    from scipy import stats

    from . import observables as obs

    row = ens.state_row(geometry, velocities, masses)
    for k, name in enumerate("xy"[:velocities.shape[1]]):
        row[f"variance_{name}"] = float(velocities[:, k].var())
        row[f"kurtosis_{name}"] = float(stats.kurtosis(velocities[:, k])) if velocities[:, k].std() > 0 else math.nan
        try:
            t = obs.normality_tests(velocities[:, k])
        except ValueError:
            t = {"ks_pvalue": math.nan, "ad_statistic": math.nan}
        row[f"ks_pvalue_{name}"], row[f"ad_statistic_{name}"] = t["ks_pvalue"], t["ad_statistic"]
    return row


# ---------------------------------------------------------------- runs


@dataclass
class _Run:
    """A single run: the simulation after its stop, the initial velocities, the snapshots by label."""

    sim: object
    initial: np.ndarray
    snapshots: dict[int, object]
    reason: str


def _single(spec: RunSpec) -> _Run:
    from .runner import run_to_stop

    sim = spec.build()
    initial = sim.velocities.copy()
    counter = spec.snapshots.counter if spec.snapshots else ""
    snaps: dict[int, object] = {}
    reason = run_to_stop(spec, sim, on_snapshot=lambda record: snaps.__setitem__(record.state[counter], record))
    return _Run(sim, initial, snaps, reason)


def expected_figures(plan: Plan) -> list[str]:
    """The PNG names `reproduce` writes for ``plan``."""
    return ["fig1_half_plane_initial.png",
            *[f"fig2_half_plane_step_{s}.png" for s in plan.steps],
            f"fig3_energy_by_distance_collisions_{plan.collisions}.png", "fig3_energy_by_distance_final.png",
            "fig4_energy_by_distance_sizes.png",
            "fig5_torus_initial.png", *[f"fig5_torus_step_{s}.png" for s in plan.steps],
            *[f"fig6_torus_components_step_{s}.png" for s in plan.steps],
            "fig7_correlation_line_of_centres.png", "fig8_correlation_xy.png",
            "extra_collisions_until_frozen.png", "extra_far_share_by_size.png",
            "extra_paper_lattice_energy_by_distance.png"]


# ---------------------------------------------------------------- formatting


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %" if math.isfinite(x) else "n/a"


def _mean_sd(x: np.ndarray, fmt: Callable[[float], str]) -> str:
    if not len(x):
        return "n/a"
    sd = float(x.std(ddof=1)) if len(x) > 1 else math.nan
    return f"{fmt(float(x.mean()))} ± {fmt(sd).lstrip('+')}" if math.isfinite(sd) else fmt(float(x.mean()))


def _int(x: float) -> str:
    return f"{x:,.0f}" if math.isfinite(x) else "n/a"


def _yes(flag: bool | None) -> str:
    return {True: "**yes**", False: "**no**", None: "—"}[flag]


# ---------------------------------------------------------------- figures of our own


def _frozen_collisions_figure(ours: np.ndarray, paper_lattice: np.ndarray, labels: tuple[str, str], path: Path):
    from . import plots

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
    ax.set_title("collisions until frozen, 100x50 half-plane, over seeds")
    ax.legend(fontsize="small")
    plots.save(fig, path)
    return path


def _far_share_figure(rows: list[tuple[str, int, np.ndarray, np.ndarray]], path: Path):
    from . import plots

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


# ---------------------------------------------------------------- the whole reproduction


def reproduce(out, plan: Plan | None = None, *, quick: bool = False, force: bool = False, workers: int | None = None,
              progress: bool | None = False, log: Callable[[str], None] | None = None, **overrides) -> Path:
    """Run ``plan`` (default `QUICK` if ``quick`` else `FULL`, with ``overrides`` of its fields) into ``out``.

    Writes the PNGs of `expected_figures`, ``report.md``, ``results.json``, the specs
    (``specs/``) and every ensemble's table (``ensembles/<name>/``). Returns the report's path.
    ``workers``: local processes for the ensembles (default all cores). Refuses a
    non-empty ``out`` without ``force`` (`InputError`).
    """
    from . import observables as obs

    t0 = time.perf_counter()
    plan = dataclasses.replace(plan or (QUICK if quick else FULL), **overrides)
    _check_plan(plan)
    out = check_out_dir(out, force)
    say = log or (lambda message: None)
    say_t = lambda message: say(f"[{time.perf_counter() - t0:6.1f} s] {message}")  # noqa: E731
    # every spec is built (and so validated) before anything is written
    detail_steps = half_plane_spec(plan.detail, plan, {"at_steps": list(plan.steps)})
    detail_collisions = half_plane_spec(plan.detail, plan, {"at_collisions": [plan.collisions]})
    size_specs = {size: half_plane_spec(size, plan) for size in _sizes(plan)}
    torus = torus_spec(plan)
    torus_long = torus_spec(plan, max(plan.long_steps, plan.steps[-1]))
    for spec in (detail_steps, *size_specs.values(), torus, torus_long):
        spec.build()
    out.mkdir(parents=True, exist_ok=True)
    for sub in ("specs", "data", "ensembles"):
        (out / sub).mkdir(exist_ok=True)
    lattice = paper_lattice_spec(plan)
    specs = {"half_plane_detail_steps": detail_steps, "half_plane_detail_collisions": detail_collisions,
             "torus": torus, "torus_ensemble": torus_long, "paper_lattice": lattice,
             **{f"half_plane_{_label(s)}": spec for s, spec in size_specs.items()}}
    for name, spec in specs.items():
        (out / "specs" / f"{name}.json").write_text(spec.to_json() + "\n", encoding="utf-8")

    checks: list[Check] = []
    results: dict = {"plan": dataclasses.asdict(plan)}
    failures: list[dict] = []
    run_ensemble = functools.partial(ens.run_ensemble, workers=workers, progress=progress)

    def ensemble(name: str, spec: RunSpec, replicas: int, **kwargs) -> ens.EnsembleResult:
        say_t(f"ensemble {name}: {replicas} replicas")
        result = run_ensemble(spec, replicas, **kwargs)
        ens.write_outputs(result, out / "ensembles" / name, figures=False)
        failures.extend({"ensemble": name, **row} for row in result.failures)
        return result

    # ---------------------------------------------------------- half-plane: Figures 1-3
    say_t(f"half-plane {_label(plan.detail)}: single runs (seed {plan.seed})")
    by_steps, by_collisions = _single(detail_steps), _single(detail_collisions)
    if not np.array_equal(by_steps.sim.velocities, by_collisions.sim.velocities):
        raise RuntimeError("the same half-plane spec and seed gave two different final states")
    sim = by_steps.sim
    geom = sim.geometry
    dist = geom.boundary_distance()
    _figures_half_plane(out, plan, geom, by_steps, by_collisions)
    final_row = ens.state_row(geom, sim.velocities)
    at_c = by_collisions.snapshots.get(plan.collisions)
    results["detail"] = {"rows": geom.rows, "cols": geom.cols, "balls": geom.n_balls, "steps": sim.steps,
                         "collisions": sim.collisions, "frozen": sim.is_frozen(), "final": final_row,
                         "boundary_share_at_collisions": (obs.boundary_share(dist, at_c.state["velocities"])
                                                          if at_c is not None else None)}

    # ---------------------------------------------------------- half-plane: sizes (Figure 4) and ensembles
    profiles, size_rows, size_results = {}, [], {}
    for size, spec in size_specs.items():
        say_t(f"half-plane {_label(size)}: single run")
        run = by_steps if size == tuple(plan.detail) else _single(spec)
        g = run.sim.geometry
        profiles[f"{_label(size)} ({g.rows}x{g.cols}, {g.n_balls:,} balls)"] = obs.energy_profile(
            g.boundary_distance(), run.sim.velocities)
        replicas = plan.replicas if size == tuple(plan.detail) else plan.size_replicas
        res = ensemble(f"half_plane_{_label(size)}", spec, replicas)
        size_results[size] = (g, res)
        size_rows.append((_label(size), g.n_balls, res.column("far_half_share"), res.column("far_row_share")))
    _figure_sizes(out, profiles)
    _far_share_figure(size_rows, out / "extra_far_share_by_size.png")
    lattice_res = ensemble("paper_lattice", lattice, plan.replicas,
                           task=functools.partial(ens.run_replica, observe=paper_lattice_row))
    say_t("paper-orientation lattice: single run")
    lattice_run = _single(lattice)
    _figure_paper_lattice(out, lattice_run)
    detail_geom, detail_res = size_results[tuple(plan.detail)]
    _frozen_collisions_figure(detail_res.column("collisions"), lattice_res.column("collisions"),
                              (f"HalfPlane {detail_geom.rows}x{detail_geom.cols}",
                               f"paper orientation ({lattice_run.sim.geometry.n_balls:,} balls)"),
                              out / "extra_collisions_until_frozen.png")
    checks += _half_plane_checks(plan, results["detail"], size_results, lattice_res, lattice_run)

    # ---------------------------------------------------------- torus: Figures 5-8
    say_t(f"torus {plan.torus[0]}x{plan.torus[1]}: single run (seed {plan.seed})")
    trun = _single(torus)
    _figures_torus(out, plan, trun)
    tres = ensemble("torus", torus_long, plan.replicas, task=functools.partial(ens.run_replica, observe=torus_row))
    _figures_correlations(out, plan, tres, _torus_stage(plan, plan.steps[-1]))
    checks += _torus_checks(plan, trun, tres, results)

    wall = time.perf_counter() - t0
    results["wall_seconds"] = wall
    results["failures"] = failures
    results["checks"] = [dataclasses.asdict(c) for c in checks]
    (out / "results.json").write_text(json.dumps(ens._json_safe(_plain(results)), indent=2) + "\n", encoding="utf-8")
    report = out / REPORT_NAME
    report.write_text(_report(plan, quick, checks, results, geom, trun.sim.geometry, lattice_run.sim.geometry,
                              failures, wall), encoding="utf-8")
    say_t(f"wrote {report}")
    return report


def _check_plan(plan: Plan) -> None:
    for name in ("replicas", "size_replicas"):
        ens._check_count(name, getattr(plan, name))
    if not plan.sizes:
        raise InputError("sizes: give at least one rectangle")
    if len(plan.steps) < 1 or any(s <= 0 for s in plan.steps) or list(plan.steps) != sorted(set(plan.steps)):
        raise InputError(f"steps: must be increasing positive step counts, got {plan.steps}")


def _sizes(plan: Plan) -> list[tuple[float, float]]:
    """The rectangles of Figure 4, with the detail rectangle among them, by size."""
    sizes = dict.fromkeys(tuple(s) for s in plan.sizes)
    sizes[tuple(plan.detail)] = None
    return sorted(sizes, key=lambda s: s[0] * s[1])


def _plain(value):
    """``value`` with numpy scalars and arrays made JSON-friendly."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    return value


# ---------------------------------------------------------------- figures of the paper


def _figures_half_plane(out: Path, plan: Plan, geom, by_steps: _Run, by_collisions: _Run) -> None:
    from .plots import energy_by_distance, quiver

    sim = by_steps.sim
    name = f"half-plane {_label(plan.detail)} ({geom.rows}x{geom.cols}, {geom.n_balls:,} balls)"
    quiver(geom.positions, by_steps.initial, title=f"{name}: initial state",
           path=out / "fig1_half_plane_initial.png")
    for s in plan.steps:
        snap = by_steps.snapshots.get(s)
        if snap is not None:
            title = f"{name}: after {s:,} steps ({snap.state['collisions']:,} collisions)"
            v = snap.state["velocities"]
        else:
            title = (f"{name}: frozen at step {sim.steps:,} ({sim.collisions:,} collisions),\n"
                     f"before {s:,} steps: this is also the state at step {s:,}")
            v = sim.velocities
        quiver(geom.positions, v, title=title, path=out / f"fig2_half_plane_step_{s}.png")
    dist = geom.boundary_distance()
    snap = by_collisions.snapshots.get(plan.collisions)
    if snap is not None:
        v = snap.state["velocities"]
        title = f"{name}: after {plan.collisions:,} collisions ({snap.state['steps']:,} steps)"
    else:
        v, title = sim.velocities, f"{name}: frozen after {sim.collisions:,} collisions, before {plan.collisions:,}"
    energy_by_distance(dist, v, title=title, path=out / f"fig3_energy_by_distance_collisions_{plan.collisions}.png")
    state = "frozen" if sim.is_frozen() else "not frozen"
    energy_by_distance(dist, sim.velocities, path=out / "fig3_energy_by_distance_final.png",
                       title=f"{name}: final state, {state} after {sim.collisions:,} collisions ({sim.steps:,} steps)")


def _figure_sizes(out: Path, profiles: dict) -> None:
    from . import plots
    from .plots import energy_profiles

    fig = plots.new_figure((9.0, 7.5))
    top, bottom = fig.subplots(2, 1)
    energy_profiles(profiles, ax=top, title="energy against distance from the boundary, frozen state (seed 0)")
    energy_profiles(profiles, ax=bottom, logy=True)
    bottom.get_legend().remove()
    plots.save(fig, out / "fig4_energy_by_distance_sizes.png")


def _figure_paper_lattice(out: Path, run: _Run) -> None:
    from .plots import energy_by_distance

    g = run.sim.geometry
    energy_by_distance(g.positions[:, 1], run.sim.velocities, path=out / "extra_paper_lattice_energy_by_distance.png",
                       title=f"paper orientation ({g.n_balls:,} balls, rows perpendicular to the boundary): "
                             f"frozen after {run.sim.collisions:,} collisions")


def _figures_torus(out: Path, plan: Plan, run: _Run) -> None:
    from .plots import component_histograms, quiver

    g = run.sim.geometry
    name = f"flat torus {g.rows}x{g.cols} ({g.n_balls:,} balls)"
    quiver(g.positions, run.initial, title=f"{name}: initial state", path=out / "fig5_torus_initial.png")
    for s in plan.steps:
        snap = run.snapshots.get(s)
        v = snap.state["velocities"] if snap is not None else run.sim.velocities
        collisions = snap.state["collisions"] if snap is not None else run.sim.collisions
        title = f"{name}: after {s:,} steps ({collisions:,} collisions)"
        quiver(g.positions, v, title=title, path=out / f"fig5_torus_step_{s}.png")
        component_histograms(v, title=f"{name}: velocity components after {s:,} steps",
                             path=out / f"fig6_torus_components_step_{s}.png")


def _figures_correlations(out: Path, plan: Plan, res: ens.EnsembleResult, at: str) -> None:
    from .plots import correlation_histogram

    n = len(res.column("line_of_centres_correlation", at))
    correlation_histogram(res.column("line_of_centres_correlation", at), 0.02, xlabel="correlation of u and u'",
                          title=f"line-of-centres components of touching balls: {n} runs, {plan.steps[-1]:,} steps",
                          path=out / "fig7_correlation_line_of_centres.png")
    correlation_histogram(res.column("xy_correlation", at), 0.02, xlabel="correlation of x- and y-components",
                          title=f"x- and y-components: {n} runs, {plan.steps[-1]:,} steps",
                          path=out / "fig8_correlation_xy.png")


# ---------------------------------------------------------------- the checks


def _half_plane_checks(plan: Plan, detail: dict, size_results: dict, lattice_res, lattice_run) -> list[Check]:
    from . import observables as obs

    checks = []
    g, res = size_results[tuple(plan.detail)]
    n = res.replicas - len(res.failures)
    name = f"{_label(plan.detail)}: {g.rows}x{g.cols} = {g.n_balls:,} balls"
    f = detail["final"]
    share, lshare = res.column("boundary_share"), lattice_res.column("boundary_share")
    lat = lattice_run.sim.geometry
    lrow = paper_lattice_row(lat, lattice_run.sim.velocities)
    in_band = lambda x: bool(len(x)) and abs(float(x.mean()) - PAPER_BOUNDARY_SHARE) <= 0.10  # noqa: E731
    checks.append(Check(
        f"About 30 % of the energy ends in the boundary row ({name})", "≈ 30 %",
        f"seed {plan.seed}: {_pct(f['boundary_share'])}; {n} runs: {_mean_sd(share, _pct)}",
        "mean over runs within 30 ± 10 points", in_band(share)))
    checks.append(Check(
        f"… same, in the paper's orientation ({lat.n_balls:,} balls, rows perpendicular to the boundary; "
        "share at distance 0)", "≈ 30 %",
        f"seed {plan.seed}: {_pct(lrow['boundary_share'])}; {len(lshare)} runs: {_mean_sd(lshare, _pct)} "
        f"(distance 1: {_mean_sd(lattice_res.column('next_share'), _pct)})",
        "mean over runs within 30 ± 10 points", in_band(lshare)))
    out_frac = res.column("boundary_outward_fraction")
    checks.append(Check(
        "… pointing outward", "most of it",
        f"share of the boundary row's energy moving outward: seed {plan.seed}: {_pct(f['boundary_outward_fraction'])}; "
        f"{n} runs: mean {_pct(out_frac.mean()) if len(out_frac) else 'n/a'}, "
        f"min {_pct(out_frac.min()) if len(out_frac) else 'n/a'}",
        "mean over runs ≥ 90 %", bool(len(out_frac)) and float(out_frac.mean()) >= 0.9))
    far = res.column("far_row_share")
    checks.append(Check(
        "A little energy settles at the far side", "a little",
        f"farthest row: seed {plan.seed}: {_pct(f['far_row_share'])}; {n} runs: {_mean_sd(far, _pct)}",
        "mean over runs between 1 % and the boundary row's share",
        bool(len(far)) and 0.01 < float(far.mean()) < float(share.mean())))
    coll, lcoll = res.column("collisions"), lattice_res.column("collisions")

    def frozen_cell(x, seed_value):
        lo, hi = (np.percentile(x, [2.5, 97.5]) if len(x) else (math.nan, math.nan))
        return (f"seed {plan.seed}: {seed_value}; {len(x)} runs: {_mean_sd(x, _int)}, "
                f"95 % of runs in [{_int(lo)}, {_int(hi)}]")

    def within(x):
        return bool(len(x)) and bool(np.percentile(x, 2.5) <= PAPER_FROZEN_COLLISIONS <= np.percentile(x, 97.5))

    checks.append(Check(
        f"The stationary (frozen) state follows {PAPER_FROZEN_COLLISIONS:,} collisions ({name})",
        f"{PAPER_FROZEN_COLLISIONS:,}",
        frozen_cell(coll, f"{detail['collisions']:,} collisions ({detail['steps']:,} steps)"),
        "the paper's figure inside the central 95 % of our runs", within(coll)))
    checks.append(Check(
        f"… same, in the paper's orientation ({lat.n_balls:,} balls)", f"{PAPER_FROZEN_COLLISIONS:,}",
        frozen_cell(lcoll, f"{lattice_run.sim.collisions:,} collisions"),
        "the paper's figure inside the central 95 % of our runs", within(lcoll)))
    bs = detail.get("boundary_share_at_collisions")
    checks.append(Check(
        f"Figure 3 (top): the energy profile after {plan.collisions:,} collisions", "figure only",
        f"boundary row after {plan.collisions:,} collisions: {_pct(bs) if bs is not None else 'not reached (frozen)'}"
        f"; at the freeze: {_pct(f['boundary_share'])} (seed {plan.seed})", "—", None))
    sizes = sorted(size_results, key=lambda s: s[0] * s[1])
    means = [float(size_results[s][1].column("far_half_share").mean()) for s in sizes]
    cells = ", ".join(f"{_label(s)}: {_pct(m)}" for s, m in zip(sizes, means))
    checks.append(Check(
        "The bigger the system, the less energy far from the boundary", "decreasing with size",
        f"share beyond half the depth (mean over runs): {cells}",
        "means strictly decrease with size", all(a > b for a, b in zip(means, means[1:]))))
    frozen_all = [(s, size_results[s][1]) for s in sizes] + [("paper lattice", lattice_res)]
    total = sum(len(r.column("frozen")) for _, r in frozen_all)
    frozen = sum(int(r.column("frozen").sum()) for _, r in frozen_all)
    steps_max = max(float(r.column("steps").max()) for _, r in frozen_all if len(r.column("steps")))
    checks.append(Check(
        "Finite systems freeze: finitely many collisions (theory)", "all",
        f"{frozen:,} of {total:,} half-plane runs frozen (longest: {steps_max:,.0f} steps)",
        f"every run frozen within {plan.max_steps:,} steps", frozen == total))
    corr = res.column("line_of_centres_correlation")
    checks.append(Check(
        "(ours) A frozen state has u ≤ u' on every contact, so a strongly positive line-of-centres correlation",
        "—", f"{_label(plan.detail)} frozen: {n} runs: {_mean_sd(corr, lambda x: f'{x:+.3f}')}", "—", None))
    return checks


def _binomial_ok(k: int, n: int, p: float) -> bool:
    """True unless ``k`` rejections in ``n`` exceed the nominal rate ``p`` (one-sided binomial test at 1 %)."""
    from scipy import stats

    return n == 0 or stats.binomtest(k, n, p, alternative="greater").pvalue > 0.01


def _torus_stage(plan: Plan, steps: int) -> str:
    """The ``at`` of the torus ensemble's rows at ``steps``."""
    return ens.FINAL if steps == max(plan.long_steps, plan.steps[-1]) else f"steps={steps}"


def _stat(x: np.ndarray, fmt: str = "+.4f") -> str:
    """``mean ± standard error`` of ``x``."""
    if len(x) < 2:
        return format(float(x.mean()), fmt) if len(x) else "n/a"
    return f"{x.mean():{fmt}} ± {x.std(ddof=1) / math.sqrt(len(x)):.4f}"


def _torus_checks(plan: Plan, run: _Run, res: ens.EnsembleResult, results: dict) -> list[Check]:
    from . import observables as obs

    checks = []
    g = run.sim.geometry
    N, E = g.n_balls, plan.energy
    tol = 4 * math.sqrt(2 / N)
    long = max(plan.long_steps, plan.steps[-1])
    results["torus"] = {"rows": g.rows, "cols": g.cols, "balls": N, "single": {}, "ensemble": res.statistics()}
    both = lambda name, at: np.concatenate([res.column(f"{name}_x", at), res.column(f"{name}_y", at)])  # noqa: E731
    crit = obs.ad_critical_5pct(N)
    for s in dict.fromkeys([*plan.steps, long]):
        at = _torus_stage(plan, s)
        ks, ad, kurt = both("ks_pvalue", at), both("ad_statistic", at), both("kurtosis", at)
        ks_rej, ad_rej = int((ks < 0.01).sum()), int((ad > crit).sum())
        runs = f"{len(ks) // 2} runs: KS rejects at 1 % in {ks_rej}/{len(ks)} components, AD at 5 % in " \
               f"{ad_rej}/{len(ad)}; excess kurtosis {_stat(kurt, '+.3f')} (normal: {-6 / (N + 1):+.3f})"
        rates_ok = _binomial_ok(ks_rej, len(ks), 0.01) and _binomial_ok(ad_rej, len(ad), 0.05)
        if s in plan.steps:
            snap = run.snapshots.get(s)
            v = snap.state["velocities"] if snap is not None else run.sim.velocities
            tests = [obs.normality_tests(v[:, k]) for k in range(2)]
            results["torus"]["single"][str(s)] = {"tests": tests, "variance_over_E_per_N": v.var(axis=0) * N / E}
            checks.append(Check(
                f"Torus, {s:,} steps: x- and y-components look normal (Figure 6)", "normal",
                f"seed {plan.seed}: KS p = {tests[0]['ks_pvalue']:.3f} / {tests[1]['ks_pvalue']:.3f}, "
                f"AD = {tests[0]['ad_statistic']:.3f} / {tests[1]['ad_statistic']:.3f} (5 % critical {crit:.3f}); "
                + runs,
                "seed's KS p > 0.01 for x and y; the runs' KS (1 %) and AD (5 %) rejection rates not above "
                "nominal (one-sided binomial test at 1 %)",
                all(t["ks_pvalue"] > 0.01 for t in tests) and rates_ok))
        else:
            checks.append(Check(
                f"(ours) Torus, {s:,} steps ({s / plan.steps[-1]:.0f} times longer): components normal?", "—", runs,
                "the runs' KS (1 %) and AD (5 %) rejection rates not above nominal (one-sided binomial test at 1 %)",
                rates_ok))
    s = plan.steps[-1]
    at = _torus_stage(plan, s)
    var = results["torus"]["single"][str(s)]["variance_over_E_per_N"]
    vx, vy = res.column("variance_x", at) * N / E, res.column("variance_y", at) * N / E
    ok = bool(np.all(np.abs(var - 1) <= tol)) and len(vx) > 0 and abs(float(vx.mean()) - 1) <= 0.02 \
        and abs(float(vy.mean()) - 1) <= 0.02
    checks.append(Check(
        f"Torus, {s:,} steps: equipartition, each component has variance E/N (N = {N:,})", "implied (i.i.d. normal)",
        f"variance × N/E: seed {plan.seed}: x {var[0]:.3f}, y {var[1]:.3f}; {len(vx)} runs: "
        f"x {_mean_sd(vx, lambda a: f'{a:.3f}')}, y {_mean_sd(vy, lambda a: f'{a:.3f}')} (mean ± sd)",
        f"seed within 4·sqrt(2/N) = {tol:.3f} of 1 for x and y; mean over runs within 0.02 of 1", ok))
    for column, what, fig in (("line_of_centres_correlation", "line-of-centres components of touching pairs", 7),
                              ("xy_correlation", "x- and y-components", 8)):
        x = res.column(column, at)
        others = "; ".join(f"at {t:,} steps: {_stat(res.column(column, _torus_stage(plan, t)))}"
                           for t in dict.fromkeys([*plan.steps, long]) if t != s)
        sd = float(x.std(ddof=1)) if len(x) > 1 else math.nan
        checks.append(Check(
            f"Torus: correlation of the {what} is near 0 (Figure {fig}, {len(x)} runs at {s:,} steps)", "≈ 0",
            f"mean ± standard error {_stat(x)} (sd over runs {sd:.4f}){'; ' + others if others else ''}",
            f"|mean| ≤ {CORRELATION_TOLERANCE}", bool(len(x)) and abs(float(x.mean())) <= CORRELATION_TOLERANCE))
    app = res.column("approaching_fraction", at)
    checks.append(Check(
        "A periodic system keeps colliding forever (theory)", "never frozen",
        f"{int((app > 0).sum())} of {len(app)} torus runs still colliding at {s:,} steps; "
        f"approaching contacts: {_stat(app, '.4f')} (mean ± standard error)", "every run has approaching contacts",
        bool(len(app)) and bool((app > 0).all())))
    return checks


# ---------------------------------------------------------------- the report


def _report(plan: Plan, quick: bool, checks: list[Check], results: dict, geom, torus, lattice,
            failures: list[dict], wall: float) -> str:
    agree = sum(c.agrees is True for c in checks)
    compared = sum(c.agrees is not None for c in checks)
    sizes = ", ".join(_label(s) for s in _sizes(plan))
    lines = [
        f"# Reproduction of *Pinned Billiard Balls Simulation* (WXML 2023){' — quick run' if quick else ''}",
        "",
        f"Wall time: **{wall:.1f} s** on {os.cpu_count()} core(s) for `pinnedballs reproduce"
        f"{' --quick' if quick else ''}` (Python start-up and imports, a few seconds, not included); "
        f"{agree} of {compared} comparisons agree.",
        "",
        "## Set-up",
        "",
        f"* Half-plane: `HalfPlane.from_size(L, D)` for {sizes}; the boundary ball nearest the middle "
        f"(`boundary_center()`) starts with velocity along (0, 1), into the bulk, energy {plan.energy:g}, masses 1; "
        f"run until frozen. Figures 1-3 use {_label(plan.detail)} = {geom.rows} rows of {geom.cols} = "
        f"{geom.n_balls:,} balls.",
        f"* Paper orientation (cross-check): the paper's 100x50 holds 1,425 = 57 x 25 balls, which fits lattice rows "
        f"*perpendicular* to the boundary (a zig-zag boundary of balls at distances 0 and 1); our `HalfPlane` has rows "
        f"parallel to it. We also ran that lattice ({lattice.n_balls:,} balls, "
        f"`HalfPlane.from_size(L, D, orientation=\"across\")`), same initial condition.",
        f"* Flat torus: the paper gives no size; we use `FlatTorus({torus.rows}, {torus.cols})` = {torus.n_balls:,} "
        f"balls, about the {_label(plan.detail)} half-plane's count. Ball 0 moves along (1, 0) with energy "
        f"{plan.energy:g}; snapshots at {', '.join(f'{s:,}' for s in plan.steps)} steps (a step is one pick of a "
        "contact; the paper's captions say collisions, but a 100x50 half-plane freezes after ~48,000 collisions, "
        "so these counts must be steps).",
        f"* Seeds: single runs (the pictures) use seed {plan.seed}; ensembles use replicas 0..N-1 of seed "
        f"{plan.seed} (`SeedSequence({plan.seed}).spawn(N)`): {plan.replicas} runs of the torus, of the "
        f"{_label(plan.detail)} half-plane and of the paper-orientation lattice, {plan.size_replicas} of each other "
        "rectangle. Every replica's row is in `ensembles/<name>/replicas.csv`; the specs are in `specs/`.",
        "",
        "## Statements of the paper against our measurements",
        "",
        "| # | Statement | Paper | Ours | Criterion | Agrees |",
        "|---|---|---|---|---|---|",
    ]
    cell = lambda text: text.replace("|", "\\|")  # noqa: E731 - a pipe would end the cell
    for k, c in enumerate(checks, 1):
        lines.append(f"| {k} | {cell(c.statement)} | {cell(c.paper)} | {cell(c.ours)} | {cell(c.criterion)} | "
                     f"{_yes(c.agrees)} |")
    torus_n, E = torus.n_balls, plan.energy
    lines += [
        "",
        "## Notes",
        "",
        f"* **Equilibrium in the torus.** Energy E = {E:g} and momentum P = (sqrt(2E), 0) are conserved (unit "
        f"masses). At equilibrium the internal energy E - |P|^2/(2N) is shared by 2(N - 1) degrees of freedom, so each "
        f"component has mean P/N ({math.sqrt(2 * E) / torus_n:.4f} for x, 0 for y: the paper's mean 0 is exact "
        f"only for y) and variance (2E - |P|^2/N) / (2(N - 1)) = E/N = {E / torus_n:.4f} exactly for this start. "
        "The sum of the two sample variances is fixed by the conservation laws, so what equilibrium adds is "
        "their equal split and the normal shape — which is what the rows above test.",
        "* **Frozen against running.** In a frozen state every contact has u ≤ u' (no contact approaches), so its "
        "line-of-centres correlation is strongly positive (the row above); the near-zero correlation of the paper "
        "is a statement about the running torus.",
        "* **The collision chain is not uniform on the energy sphere.** A contact collides only when it approaches, "
        "and a collision turns it receding, so receding contacts are over-represented: fewer than half of the "
        "torus's contacts approach at any time (last torus row), where the uniform law on the sphere would give "
        "one half.",
        "* **Orientation of the half-plane lattice.** Our `HalfPlane` boundary row holds a whole lattice row; the "
        "paper's count (1,425 balls) fits the other orientation, whose distance-0 share (about 30 %) and collisions "
        "until frozen are the paper's figures. See the rows marked 'paper's orientation'.",
        "* Criteria are stated before comparing and are deliberately simple: 'about 30 %' as 30 ± 10 points, "
        f"'near 0' as |mean| ≤ {CORRELATION_TOLERANCE}; a '**no**' marks a real difference, explained in "
        "`docs/reproduce.md`.",
    ]
    if failures:
        lines += ["", "## Failed replicas", ""]
        lines += [f"* {f['ensemble']}: replica {f['replica']} (seed entropy {f['seed_entropy']}, spawn key "
                  f"{f['spawn_key']}): {f[ens.ERROR_COLUMN]}" for f in failures]
    lines += ["", "## Figures", ""]
    lines += [f"* ![{name}]({name})" for name in expected_figures(plan)]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------- command line


@subcommand("reproduce", "every figure of the paper as PNG, and report.md comparing its numbers with ours",
            arg("--out", required=True, metavar="DIR", help="output directory (created)"),
            arg("--quick", action="store_true", help="smaller sizes and fewer replicas (about a minute)"),
            arg("--workers", type=int, metavar="K", help="local processes for the ensembles (default: all cores)"),
            arg("--force", action="store_true", help="write into a non-empty directory"),
            arg("--quiet", action="store_true", help="no progress messages"))
def reproduce_command(args) -> int:
    """``pinnedballs reproduce``: exit 0, 1 if a replica failed (the report is still written), 2 on bad input."""
    if args.workers is not None:
        ens._check_count("--workers", args.workers)
    check_out_dir(args.out, args.force)
    log = None if args.quiet else (lambda message: print(message, file=sys.stderr, flush=True))
    report = reproduce(args.out, quick=args.quick, force=args.force, workers=args.workers,
                       progress=False if args.quiet else None, log=log)
    results = json.loads((report.parent / "results.json").read_text(encoding="utf-8"))
    if not args.quiet:
        print(f"wrote {report} in {results['wall_seconds']:.1f} s")
    return 1 if results["failures"] else 0
