"""Studies beyond the paper (``pinnedballs reproduce --extended``): one function per study.

Each study takes the `ExtendedPlan`, the output directory and an ``ensemble(name, spec,
replicas, task=...)`` callable (`reproduce`'s, which records the replicas' tables and
failures), and returns plain numbers: ``{"rows": [...], ..., "figures": [PNG names]}``.

* `scaling`: collisions and steps until frozen against the number of balls, half-plane,
  one boundary ball moving inward, `UniformRandomPair`; fitted exponents (`fit.fit_exponent`);
* `torus_law`: excess kurtosis, approaching fraction and line-of-centres correlation on the
  torus against time (steps per ball) and size, mean ± standard error over replicas;
* `sphere`: the same observables for one moving ball on a geodesic sphere, against the torus;
* `hyperbolic`: one rim ball moving inward on the {3,7} disk, energy by rings from the rim;
* `fcc_half_space`: the half-space experiment on an open FCC block (boundary z = 0);
* `orders`: fewest and most collisions over every order against the random order.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..run import ensemble as ens
from ..engine.errors import InputError
from ..specs.run import RunSpec, parse_spec
from .fit import fit_exponent
from .plan import torus_row

#: the studies in the order they run; keys of ``results.json["extended"]``
STUDIES = ("scaling", "torus_law", "sphere", "hyperbolic", "fcc_half_space", "orders")
DECILES = 10


@dataclass(frozen=True)
class ExtendedPlan:
    """What the extended studies run. Sizes are chosen for the time budget (2 cores)."""

    #: half-plane ``(length, depth, replicas)``, by size
    scaling: tuple[tuple[float, float, int], ...] = (
        (10, 5, 16), (30, 15, 16), (60, 30, 16), (100, 50, 16), (200, 100, 8), (300, 150, 8), (500, 250, 8),
        (1000, 500, 8), (2000, 1000, 8))
    torus_sides: tuple[int, ...] = (16, 38, 76, 128)   #: square tori ``side x side``
    torus_times: tuple[int, ...] = (100, 300, 1000, 3000, 10000, 30000)   #: steps per ball
    torus_replicas: int = 24
    sphere_frequency: int = 12   #: 10 f^2 + 2 balls (12: 1,442, next to the 38x38 torus's 1,444)
    hyperbolic_layers: tuple[int, ...] = (2, 3, 4, 5, 6)
    hyperbolic_replicas: int = 16
    fcc: tuple[tuple[int, int, int], ...] = ((6, 6, 3), (10, 10, 5), (14, 14, 7))   #: open FCC blocks
    fcc_replicas: int = 8
    orders_replicas: int = 1000   #: random orders per configuration
    orders_max_states: int = 10**6
    energy: float = 100.0
    seed: int = 0
    max_steps: int = 10**11


EXTENDED_FULL = ExtendedPlan()
EXTENDED_QUICK = ExtendedPlan(
    scaling=((10, 5, 8), (20, 10, 8), (30, 15, 8), (60, 30, 8), (100, 50, 8), (200, 100, 8), (300, 150, 4)),
    torus_sides=(16, 38, 76), torus_times=(100, 300, 1000, 3000, 10000), torus_replicas=16,
    hyperbolic_layers=(2, 3, 4, 5, 6), hyperbolic_replicas=8, fcc=((6, 6, 3), (8, 8, 4), (10, 10, 5)),
    fcc_replicas=4, orders_replicas=400, orders_max_states=10**5)

Ensemble = Callable[..., ens.EnsembleResult]


def check_extended_plan(plan: ExtendedPlan) -> None:
    """`InputError` naming the field of a plan that cannot run."""
    for name in ("torus_replicas", "hyperbolic_replicas", "fcc_replicas", "orders_replicas", "orders_max_states"):
        ens._check_count(name, getattr(plan, name))
    if len(plan.scaling) < 2 or any(len(s) != 3 or s[2] < 2 for s in plan.scaling):
        raise InputError(f"scaling: give at least two (length, depth, replicas >= 2), got {plan.scaling}")
    if not plan.torus_sides or not plan.torus_times or list(plan.torus_times) != sorted(set(plan.torus_times)):
        raise InputError(f"torus_times: must be increasing steps per ball, got {plan.torus_times}")
    for name in ("hyperbolic_layers", "fcc"):
        if not getattr(plan, name):
            raise InputError(f"{name}: give at least one size")


# ---------------------------------------------------------------- observables of one state (module level: pickled)


def decile_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` and ``decile_k``: the energy share at distance in ``[k, k+1) / 10`` of the largest."""
    from ..analysis import observables as obs

    row = ens.state_row(geometry, velocities, masses)
    d = geometry.boundary.distance
    e = obs.energy_per_ball(velocities, masses)
    k = np.minimum((DECILES * d / d.max()).astype(np.int64), DECILES - 1)
    shares = np.bincount(k, weights=e, minlength=DECILES) / e.sum()
    row.update({f"decile_{j}": float(s) for j, s in enumerate(shares)})
    return row


def level_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` and ``level_k``: the energy share of the ``k``-th row from the boundary."""
    from ..analysis import observables as obs

    row = ens.state_row(geometry, velocities, masses)
    _, fraction = obs.energy_profile(geometry.boundary.distance, velocities, masses)
    row.update({f"level_{j}": float(s) for j, s in enumerate(fraction)})
    return row


def _observing(observe) -> Callable:
    """An ensemble task: `ensemble.run_replica` recording ``observe`` (picklable)."""
    import functools

    return functools.partial(ens.run_replica, observe=observe)


def _stats(x: np.ndarray) -> tuple[float, float, float]:
    """Mean, sample sd and standard error of ``x`` (NaN where undefined)."""
    x = x[np.isfinite(x)]
    if not len(x):
        return math.nan, math.nan, math.nan
    sd = float(x.std(ddof=1)) if len(x) > 1 else math.nan
    return float(x.mean()), sd, sd / math.sqrt(len(x))


def _profile(res: ens.EnsembleResult, prefix: str) -> list[float]:
    """Mean over replicas of the columns ``prefix0, prefix1, ...`` (final state)."""
    out, j = [], 0
    while len(res.column(f"{prefix}{j}")):
        out.append(_stats(res.column(f"{prefix}{j}"))[0])
        j += 1
    return out


def _frozen_row(res: ens.EnsembleResult) -> dict:
    """Replicas, frozen count, and mean ± sd of collisions and steps, and of the boundary and far shares."""
    row = {"replicas": int(len(res.column("collisions"))), "frozen": int(res.column("frozen").sum())}
    for name in ("collisions", "steps", "boundary_share", "far_half_share", "far_row_share"):
        mean, sd, _ = _stats(res.column(name))
        row[f"{name}_mean"], row[f"{name}_sd"] = mean, sd
    return row


# ---------------------------------------------------------------- scaling


def scaling_spec(length: float, depth: float, plan: ExtendedPlan) -> RunSpec:
    """Half-plane ``length x depth``: the boundary-centre ball moving inward, the paper's chain
    (`UniformRandomPair`: until frozen it runs untracked, 4-5x faster than `RejectionFree` on these
    half-planes, docs/performance.md), until frozen."""
    return _inward_spec({"kind": "half_plane", "length": float(length), "depth": float(depth)}, plan,
                        f"scaling: half-plane {length:g}x{depth:g}", "uniform_random_pair")


def scaling(plan: ExtendedPlan, out: Path, ensemble: Ensemble) -> dict:
    """Collisions and steps until frozen against balls; exponents; the energy profile by decile of depth."""
    rows, profiles = [], {}
    for length, depth, replicas in plan.scaling:
        spec = scaling_spec(length, depth, plan)
        g = spec.build().geometry
        t0 = time.perf_counter()
        res = ensemble(f"scaling_{length:g}x{depth:g}", spec, replicas, task=_observing(decile_row))
        row = {"length": float(length), "depth": float(depth), "rows": g.rows, "cols": g.cols, "balls": g.n_balls,
               **_frozen_row(res), "seconds": time.perf_counter() - t0}
        row["collisions_se"] = row["collisions_sd"] / math.sqrt(row["replicas"])
        row["steps_se"] = row["steps_sd"] / math.sqrt(row["replicas"])
        rows.append(row)
        profiles[f"{length:g}x{depth:g}"] = _profile(res, "decile_")
    fits = {what: fit_exponent([r["balls"] for r in rows], [r[f"{what}_mean"] for r in rows],
                               [r[f"{what}_se"] for r in rows]) for what in ("collisions", "steps")}
    for what in ("collisions", "steps"):  # slopes between consecutive sizes: does one power law hold?
        fits[what].update(local_exponents(rows, what))
    figures = [_scaling_figure(rows, fits, out / "extended_scaling.png"),
               _profiles_figure(profiles, out / "extended_scaling_profiles.png")]
    return {"rows": rows, "fit": fits, "profiles": profiles, "figures": figures}


def local_exponents(rows: list[dict], what: str) -> dict[str, list[float]]:
    """The slope of ``log(mean of what)`` against ``log(balls)`` between consecutive sizes, each with its
    standard error from the replicas (``se/mean`` is the error of a log; the two sizes' errors add in
    quadrature), and ``local_z_2``: how many standard errors each lies below 2."""
    n = np.log([r["balls"] for r in rows])
    y = np.log([r[f"{what}_mean"] for r in rows])
    e = np.array([r[f"{what}_se"] / r[f"{what}_mean"] for r in rows])
    slope = np.diff(y) / np.diff(n)
    se = np.sqrt(e[1:] ** 2 + e[:-1] ** 2) / np.diff(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(se > 0, (2.0 - slope) / se, np.nan)
    return {"local_exponents": slope.tolist(), "local_exponents_se": se.tolist(), "local_z_2": z.tolist(),
            "local_at_balls": np.sqrt(np.exp(n[1:] + n[:-1])).tolist()}


def _scaling_figure(rows: list[dict], fits: dict, path: Path) -> str:
    """Left: collisions and steps until frozen against balls, with the fitted power laws. Right: the
    local exponents between consecutive sizes, ± their standard errors, against 2."""
    from ..plot import base as plots

    fig = plots.new_figure((12.0, 5.0))
    left, right = fig.subplots(1, 2)
    n = np.array([r["balls"] for r in rows], dtype=float)
    for what, colour in (("collisions", "tab:blue"), ("steps", "tab:orange")):
        mean = np.array([r[f"{what}_mean"] for r in rows])
        se = np.array([r[f"{what}_se"] for r in rows])
        f = fits[what]
        left.errorbar(n, mean, yerr=np.nan_to_num(se), fmt="o", color=colour, capsize=3,
                      label=f"{what} until frozen (mean ± se)")
        left.plot(n, f["prefactor"] * n ** f["exponent"], color=colour, linestyle="--",
                  label=f"one power law: {f['prefactor']:.3g} N^({f['exponent']:.3f} ± {f['exponent_se']:.3f})")
        right.errorbar(f["local_at_balls"], f["local_exponents"], yerr=np.nan_to_num(f["local_exponents_se"]),
                       fmt="o-", color=colour, capsize=3, label=f"{what}")
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("balls N")
    left.set_ylabel("count until frozen")
    left.set_title("until frozen against the number of balls")
    left.legend(fontsize="small")
    right.axhline(2.0, color="k", linestyle=":", linewidth=1, label="slope 2")
    right.set_xscale("log")
    right.set_xlabel("balls N (geometric mean of the two sizes)")
    right.set_ylabel("local exponent d log(count) / d log N")
    right.set_title("local exponents, consecutive sizes (± se, replicas)")
    right.legend(fontsize="small")
    fig.suptitle("half-plane, one boundary ball sent inward with energy 100, run until frozen")
    plots.save(fig, path)
    return path.name


def _profiles_figure(profiles: dict, path: Path) -> str:
    from ..plot import base as plots

    fig = plots.new_figure((8.0, 5.0))
    ax = fig.add_subplot()
    x = (np.arange(DECILES) + 0.5) / DECILES
    for label, shares in profiles.items():
        shares = np.asarray(shares, dtype=float)
        held = shares > 0  # a small rectangle has fewer rows than tenths: its empty tenths are left out
        ax.plot(x[held], shares[held], marker=".", label=label)
    ax.set_yscale("log")
    ax.set_xlabel("distance from the boundary / depth (tenths; empty tenths of small rectangles left out)")
    ax.set_ylabel("share of the energy (mean over replicas)")
    ax.set_title("frozen energy profile as the half-plane grows")
    ax.legend(title="length x depth", fontsize="small")
    plots.save(fig, path)
    return path.name


# ---------------------------------------------------------------- the torus's stationary law (and the sphere)

LAW = (("kurtosis", "excess kurtosis of a component"), ("approaching_fraction", "approaching fraction"),
       ("line_of_centres_correlation", "line-of-centres correlation"))


def _law_spec(geometry: dict, balls: int, plan: ExtendedPlan, what: str) -> RunSpec:
    """Ball 0 moving with ``plan.energy``, `UniformRandomPair`, snapshots at ``plan.torus_times`` steps per ball."""
    steps = [t * balls for t in plan.torus_times]
    return parse_spec({
        "description": f"{what}: ball 0 moving, all others at rest",
        "geometry": geometry,
        "initial": {"kind": "single_ball", "ball": 0, "direction": [1.0, 0.0], "energy": float(plan.energy)},
        "stop": {"steps": steps[-1]}, "snapshots": {"at_steps": steps[:-1]} if len(steps) > 1 else None,
        "seed": plan.seed})


def _law_rows(res: ens.EnsembleResult, balls: int, plan: ExtendedPlan, head: dict) -> list[dict]:
    rows = []
    for t in plan.torus_times:
        at = f"steps={t * balls}" if t != plan.torus_times[-1] else ens.FINAL
        row = {**head, "balls": balls, "steps_per_ball": t, "steps": t * balls,
               "replicas": int(len(res.column("approaching_fraction", at)))}
        kurt = (res.column("kurtosis_x", at) + res.column("kurtosis_y", at)) / 2
        for name, _ in LAW:
            x = kurt if name == "kurtosis" else res.column(name, at)
            row[f"{name}_mean"], row[f"{name}_sd"], row[f"{name}_se"] = _stats(x)
        row["kurtosis_normal"] = -6 / (balls + 1)   # a normal sample of N values
        rows.append(row)
    return rows


def torus_law(plan: ExtendedPlan, out: Path, ensemble: Ensemble) -> dict:
    """The three observables against steps per ball, for each torus ``side x side``."""
    rows = []
    for side in plan.torus_sides:
        spec = _law_spec({"kind": "flat_torus", "rows": side, "cols": side}, side * side, plan, f"torus {side}x{side}")
        res = ensemble(f"torus_law_{side}x{side}", spec, plan.torus_replicas, task=_observing(torus_row))
        rows += _law_rows(res, side * side, plan, {"side": side})
    series = {f"torus {s}x{s}": [r for r in rows if r["side"] == s] for s in plan.torus_sides}
    return {"rows": rows, "verdicts": law_verdicts(rows, plan),
            "figures": [_law_figure(series, "flat torus: the long-run law against time and size",
                                    out / "extended_torus_law.png")]}


def sphere(plan: ExtendedPlan, out: Path, ensemble: Ensemble, torus_rows: list[dict]) -> dict:
    """One moving ball on ``Sphere.geodesic(plan.sphere_frequency)``, against the torus of nearest size."""
    f = plan.sphere_frequency
    balls = 10 * f * f + 2
    spec = _law_spec({"kind": "sphere", "frequency": f}, balls, plan, f"sphere, frequency {f}")
    res = ensemble(f"sphere_{f}", spec, plan.torus_replicas, task=_observing(torus_row))
    rows = _law_rows(res, balls, plan, {"frequency": f})
    side = min(plan.torus_sides, key=lambda s: abs(s * s - balls))
    torus = [r for r in torus_rows if r["side"] == side]
    for row, t in zip(rows, torus):
        for name, _ in LAW:
            diff = row[f"{name}_mean"] - t[f"{name}_mean"]
            row[f"{name}_minus_torus"] = diff
            row[f"{name}_z"] = _z(diff, math.hypot(row[f"{name}_se"], t[f"{name}_se"]))
    series = {f"sphere, frequency {f} ({balls:,} balls)": rows, f"torus {side}x{side} ({side * side:,} balls)": torus}
    return {"rows": rows, "torus_side": side,
            "figures": [_law_figure(series, "one moving ball: the sphere against the flat torus",
                                    out / "extended_sphere_vs_torus.png")]}


def law_verdicts(rows: list[dict], plan: ExtendedPlan) -> dict[str, dict]:
    """Per observable, at the largest torus and the last time: the value ± se against its reference
    (0; 1/2 for the approaching fraction; -6/(N+1) for the kurtosis of a normal sample), its change
    from the time before and from the smallest torus (± se), with the z-score of each."""
    sides = sorted({r["side"] for r in rows})
    last = {s: [r for r in rows if r["side"] == s] for s in sides}
    big, small = last[sides[-1]], last[sides[0]]
    out = {}
    for name, _ in LAW:
        m, se = big[-1][f"{name}_mean"], big[-1][f"{name}_se"]
        ref = {"kurtosis": big[-1]["kurtosis_normal"], "approaching_fraction": 0.5}.get(name, 0.0)
        v = {"side": sides[-1], "steps_per_ball": big[-1]["steps_per_ball"], "mean": m, "se": se,
             "reference": ref, "z": _z(m - ref, se)}
        if len(big) > 1:
            d, dse = m - big[-2][f"{name}_mean"], math.hypot(se, big[-2][f"{name}_se"])
            v.update(time_change=d, time_change_se=dse, time_z=_z(d, dse))
        if len(sides) > 1:
            d, dse = m - small[-1][f"{name}_mean"], math.hypot(se, small[-1][f"{name}_se"])
            v.update(size_change=d, size_change_se=dse, size_z=_z(d, dse))
        out[name] = v
    return out


def _z(difference: float, se: float) -> float:
    return difference / se if se > 0 else math.nan


def _law_figure(series: dict[str, list[dict]], title: str, path: Path) -> str:
    from ..plot import base as plots

    fig = plots.new_figure((13.0, 4.2))
    axes = fig.subplots(1, 3)
    for ax, (name, label) in zip(axes, LAW):
        for text, rows in series.items():
            t = [r["steps_per_ball"] for r in rows]
            ax.errorbar(t, [r[f"{name}_mean"] for r in rows], yerr=np.nan_to_num([r[f"{name}_se"] for r in rows]),
                        marker="o", capsize=3, label=text)
        ax.axhline(0.5 if name == "approaching_fraction" else 0.0, color="k", linewidth=0.8, linestyle=":")
        ax.set_xscale("log")
        if name != "approaching_fraction":  # early transients are 10-100 times the long-run values
            ax.set_yscale("symlog", linthresh=0.05)
        ax.set_xlabel("steps per ball")
        ax.set_title(label + ("" if name == "approaching_fraction" else " (linear below |0.05|)"), fontsize="medium")
    axes[0].set_ylabel("mean ± se over replicas")
    axes[0].legend(fontsize="x-small")
    fig.suptitle(title)
    plots.save(fig, path)
    return path.name


# ---------------------------------------------------------------- hyperbolic disk and FCC half-space


def _inward_spec(geometry: dict, plan: ExtendedPlan, what: str, scheduler: str = "rejection_free") -> RunSpec:
    """``geometry``'s boundary-centre ball moving inward with the plan's energy, ``scheduler``, until frozen."""
    return parse_spec({
        "description": f"{what}: the boundary-centre ball moving inward, until frozen",
        "geometry": geometry,
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": "inward",
                    "energy": float(plan.energy)},
        "scheduler": {"kind": scheduler},
        "stop": {"frozen": True, "max_steps": plan.max_steps}, "seed": plan.seed})


def hyperbolic(plan: ExtendedPlan, out: Path, ensemble: Ensemble) -> dict:
    """A rim ball of the {3,7} disk moving inward: the frozen energy by rings from the rim, per number of rings."""
    rows, profiles = [], {}
    for layers in plan.hyperbolic_layers:
        spec = _inward_spec({"kind": "hyperbolic_plane", "q": 7, "layers": layers}, plan,
                            f"{{3,7}} disk, {layers} rings")
        g = spec.build().geometry
        res = ensemble(f"hyperbolic_{layers}", spec, plan.hyperbolic_replicas, task=_observing(level_row))
        profile = _profile(res, "level_")
        rows.append({"layers": layers, "balls": g.n_balls, **_frozen_row(res), "centre_share_mean": profile[-1]})
        profiles[f"{layers} rings ({g.n_balls:,} balls)"] = profile
    figure = _levels_figure(profiles, "rings from the rim", "{3,7} disk, one rim ball moving inward: frozen energy",
                            out / "extended_hyperbolic.png")
    return {"rows": rows, "profiles": profiles, "figures": [figure]}


def fcc_half_space(plan: ExtendedPlan, out: Path, ensemble: Ensemble) -> dict:
    """The half-space experiment on open FCC blocks (``periodic=False``; boundary z = 0): a finite
    block freezes, where one periodic in x and y is infinite in those directions and never does."""
    rows, profiles = [], {}
    for nx, ny, nz in plan.fcc:
        spec = _inward_spec({"kind": "fcc", "nx": nx, "ny": ny, "nz": nz, "periodic": False}, plan,
                            f"open FCC block {nx}x{ny}x{nz}")
        g = spec.build().geometry
        res = ensemble(f"fcc_{nx}x{ny}x{nz}", spec, plan.fcc_replicas, task=_observing(level_row))
        outward = _stats(res.column("boundary_outward_fraction"))[0]
        rows.append({"nx": nx, "ny": ny, "nz": nz, "balls": g.n_balls, **_frozen_row(res),
                     "boundary_outward_fraction_mean": outward})
        profiles[f"{nx}x{ny}x{nz} ({g.n_balls:,} balls)"] = _profile(res, "level_")
    figure = _levels_figure(profiles, "layer from the boundary z = 0", "open FCC block, one boundary ball moving "
                            "inward: frozen energy by layer", out / "extended_fcc_half_space.png")
    return {"rows": rows, "profiles": profiles, "figures": [figure]}


def _levels_figure(profiles: dict, xlabel: str, title: str, path: Path) -> str:
    from ..plot import base as plots

    fig = plots.new_figure((8.0, 5.0))
    ax = fig.add_subplot()
    for label, shares in profiles.items():
        ax.plot(np.arange(len(shares)), shares, marker="o", label=label)
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("share of the energy (mean over replicas)")
    ax.set_title(title, fontsize="medium")
    ax.legend(fontsize="small")
    plots.save(fig, path)
    return path.name


# ---------------------------------------------------------------- every order against the random one


def order_configurations():
    """``{name: (geometry, velocities (n_balls, dim))}``: small systems, one boundary ball moving inward
    with unit energy, and the rhombus of ``docs/orders.md``."""
    from ..geometry import FCC, GraphGeometry, HalfPlane, HyperbolicPlane

    def inward(g):
        b = g.boundary_center()
        v = np.zeros((g.n_balls, g.dim))
        v[b] = -math.sqrt(2.0) * g.boundary.outward[b]
        return g, v

    rhombus = GraphGeometry.from_positions([[0, 0], [2, 0], [1, 3**0.5], [3, 3**0.5]])
    return {"rhombus (4 balls)": (rhombus, np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, 0.0], [0.0, 0.0]])),
            "half-plane 2x3": inward(HalfPlane(rows=2, cols=3)),
            "open FCC 1x1x2": inward(FCC(1, 1, 2, periodic=False)),
            "{3,7} disk, 1 ring": inward(HyperbolicPlane(7, 1)),
            "half-plane 3x3": inward(HalfPlane(rows=3, cols=3)),
            "half-plane 3x4": inward(HalfPlane(rows=3, cols=4))}


def orders(plan: ExtendedPlan, out: Path, ensemble: Ensemble | None = None) -> dict:
    """`orders.orders_against_random` on each of `order_configurations`."""
    from ..analysis.orders import orders_against_random

    rows = []
    for name, (g, v) in order_configurations().items():
        r = orders_against_random(g, v, replicas=plan.orders_replicas, seed=plan.seed,
                                  max_states=plan.orders_max_states)
        # every random order is an order: the fewest is at most, the most at least, what they reached
        rows.append({"name": name, **r, "fewest_known": min(r["min_collisions"], r["random_min"]),
                     "most_known": max(r["max_collisions"], r["random_max"])})
    return {"rows": rows, "figures": [_orders_figure(rows, out / "extended_orders.png")]}


def _orders_figure(rows: list[dict], path: Path) -> str:
    from ..plot import base as plots

    cols = 3
    fig = plots.new_figure((12.0, 3.4 * math.ceil(len(rows) / cols)))
    axes = fig.subplots(math.ceil(len(rows) / cols), cols, squeeze=False).ravel()
    for ax, r in zip(axes, rows):
        n, runs = np.array(r["random_histogram"]).T
        ax.bar(n, runs / runs.sum(), width=0.8, color="tab:blue", label="random order")
        bound = "" if r["exhaustive"] else " (bound)"
        ax.axvline(r["fewest_known"], color="tab:green", linestyle="--", label=f"fewest{bound}: {r['fewest_known']}")
        ax.axvline(r["most_known"], color="tab:red", linestyle="--", label=f"most{bound}: {r['most_known']}")
        ax.set_title(f"{r['name']}", fontsize="medium")
        ax.set_xlabel("collisions until frozen")
        ax.legend(fontsize="x-small")
    for ax in axes[len(rows):]:
        ax.set_visible(False)
    axes[0].set_ylabel("share of random orders")
    fig.suptitle("collisions until frozen: every order against the paper's random order")
    plots.save(fig, path)
    return path.name


# ---------------------------------------------------------------- all of them


def run_extended(plan: ExtendedPlan, out: Path, ensemble: Ensemble, say: Callable[[str], None]) -> dict:
    """Every study in `STUDIES` order, flat for ``results.json["extended"]``: ``{study: rows,
    "<study>_<key>": its other numbers, "figures": {study: [PNG names]}, "seconds": {study: wall seconds}}``."""
    results: dict = {"plan": _plan_dict(plan), "figures": {}, "seconds": {}}
    for name in STUDIES:
        say(f"extended: {name}")
        t0 = time.perf_counter()
        if name == "sphere":
            study = sphere(plan, out, ensemble, results["torus_law"])
        else:
            study = globals()[name](plan, out, ensemble)
        results["seconds"][name] = time.perf_counter() - t0
        results[name] = study.pop("rows")
        results["figures"][name] = study.pop("figures")
        results.update({f"{name}_{key}": value for key, value in study.items()})
        say(f"extended: {name} took {results['seconds'][name]:.1f} s")
    return results


def expected_extended_figures() -> list[str]:
    """The PNG names the extended studies write."""
    return ["extended_scaling.png", "extended_scaling_profiles.png", "extended_torus_law.png",
            "extended_sphere_vs_torus.png", "extended_hyperbolic.png", "extended_fcc_half_space.png",
            "extended_orders.png"]


def _plan_dict(plan: ExtendedPlan) -> dict:
    import dataclasses

    return dataclasses.asdict(plan)
