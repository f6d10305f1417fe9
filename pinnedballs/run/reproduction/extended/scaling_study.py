"""The scaling study: collisions and steps until frozen against the number of balls on half-planes,
one boundary ball moving inward, `UniformRandomPair`; fitted exponents (`fit.fit_exponent`), local
exponents between consecutive sizes, the frozen energy profile by decile of depth, and the closing
margin of each size's counts (`engine.margin`: how near the float criterion their picks came).

Up to `ExtendedPlan.exact_max_balls` each size is counted three ways on the same seeds: by the float
chain (the paper's criterion, 4 ulp), exactly (``arithmetic="certified"``: every decision proven,
docs/collisions.md), and by the float chain at each coarser criterion e of `ExtendedPlan.resolutions`
(the model N_e, up to `ExtendedPlan.resolution_limit`); each count has its local exponents. Every count
draws its picks from `ExtendedPlan.stream` (the counter stream: what a GPU runs)."""

from __future__ import annotations

import collections
import math
import time
from pathlib import Path

import numpy as np

from ....engine.field.fixed import UncertifiedDecision
from ....specs.run import RunSpec
from ....specs.study import StudySpec, parse_study
from ... import ensemble as ens
from .. import fit
from ..fit import fit_exponent
from .common import DECILES, _frozen_row, _margin_row, _observing, _profile, _stats, decile_row
from .plan import Ensemble, ExtendedPlan

#: the exact count's name in rows and fits (``exact_collisions_mean``, ...)
EXACT = "exact"


def count_name(resolution: float) -> str:
    """The name of the count N_e in rows and fits: ``N_1e-06`` for e = 1e-6."""
    return f"N_{resolution:.0e}"


def scaling_spec(length: float, depth: float, plan: ExtendedPlan, **counting) -> RunSpec:
    """Half-plane ``length x depth``: the boundary-centre ball moving inward, the paper's chain
    (`UniformRandomPair` on one thread, since the ensemble runs replicas side by side; until frozen it runs
    untracked, 4-5x faster than `RejectionFree` on these half-planes, docs/performance.md), until frozen.
    The picks come from ``plan.stream``. ``counting``: ``arithmetic=``, ``late_precision=`` and
    ``resolution=`` of the spec (default: float, the paper's criterion). Without them: the point of
    `scaling_study_spec` at that size."""
    spec = scaling_study_spec(plan).point_spec({"geometry.length": float(length), "geometry.depth": float(depth)})
    return spec.model_copy(update=counting)


def scaling_study_spec(plan: ExtendedPlan) -> StudySpec:
    """The scaling study's float count as a study (`specs.study`; the full plan's is
    ``examples/studies/extended_scaling.json``): the half-planes of ``plan.scaling`` zipped, each size's replicas
    by rule, every size on the plan's seed (seeds "as_spec": replica k of each size seeded alike)."""
    (length, depth, _), sizes = plan.scaling[0], plan.scaling
    base = {"description": "scaling: a half-plane, the boundary-centre ball moving inward, until frozen",
            "geometry": {"kind": "half_plane", "length": float(length), "depth": float(depth)},
            "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": "inward",
                        "energy": float(plan.energy)},
            "scheduler": {"kind": "uniform_random_pair", "threads": 1, "stream": plan.stream},
            "stop": {"frozen": True, "max_steps": plan.max_steps}, "seed": plan.seed}
    most = collections.Counter(r for *_, r in sizes).most_common(1)[0][0]  # the others by rule, this one for the rest
    replicas = [{"where": {"geometry.length": float(a), "geometry.depth": float(b)}, "replicas": r}
                for a, b, r in sizes if r != most] + [{"replicas": most}]
    return parse_study({"description": "the extended reproduction's scaling study: collisions and steps until "
                                       "frozen against the number of balls",
                        "base": base, "zip": {"geometry.length": [float(s[0]) for s in sizes],
                                              "geometry.depth": [float(s[1]) for s in sizes]},
                        "replicas": replicas if len(replicas) > 1 else most, "seeds": "as_spec"})


def scaling(plan: ExtendedPlan, out: Path, ensemble: Ensemble) -> dict:
    """Collisions and steps until frozen against balls; exponents; the energy profile by decile of depth;
    the exact count and N_e beside the float count up to `ExtendedPlan.exact_max_balls` (N_e up to
    `ExtendedPlan.resolution_limit`); the stream and where each count ran (``ran_on``: `EnsembleResult.where`)."""
    rows, profiles, ran_on = [], {}, {"float": [], EXACT: [], "N_e": []}
    for (length, depth, _), point in zip(plan.scaling, scaling_study_spec(plan).expand()):
        spec, replicas = point.spec, point.replicas
        g = spec.build().geometry
        t0 = time.perf_counter()
        name = f"scaling_{length:g}x{depth:g}"
        res = ensemble(name, spec, replicas, task=_observing(decile_row))
        row = {"length": float(length), "depth": float(depth), "rows": g.rows, "cols": g.cols, "balls": g.n_balls,
               **_frozen_row(res), **_margin_row(res), "seconds": time.perf_counter() - t0}
        row["collisions_se"] = row["collisions_sd"] / math.sqrt(row["replicas"])
        row["steps_se"] = row["steps_sd"] / math.sqrt(row["replicas"])
        _ran(ran_on, "float", res)
        row.update(_other_counts(plan, length, depth, replicas, name, res, ensemble, g.n_balls, ran_on))
        rows.append(row)
        profiles[f"{length:g}x{depth:g}"] = _profile(res, "decile_")
    fits = {what: fit_exponent([r["balls"] for r in rows], [r[f"{what}_mean"] for r in rows],
                               [r[f"{what}_se"] for r in rows]) for what in ("collisions", "steps")}
    for what in ("collisions", "steps"):  # slopes between consecutive sizes: does one power law hold?
        fits[what].update(local_exponents(rows, what))
    counted = {name: local_exponents([r for r in rows if f"{name}_collisions_mean" in r], f"{name}_collisions")
               for name in (EXACT, *map(count_name, plan.resolutions))}
    figures = [_scaling_figure(rows, fits, counted, out / "extended_scaling.png"),
               _profiles_figure(profiles, out / "extended_scaling_profiles.png")]
    return {"rows": rows, "fit": fits, "counts": counted, "verdict": exact_verdict(rows, fits),
            "profiles": profiles, "stream": plan.stream, "ran_on": ran_on, "figures": figures}


def _ran(ran_on: dict[str, list[str]], count: str, res: ens.EnsembleResult) -> None:
    """Add where ``res`` ran (`EnsembleResult.where`) to ``ran_on[count]``, once."""
    if res.where not in ran_on[count]:
        ran_on[count].append(res.where)


def _other_counts(plan: ExtendedPlan, length: float, depth: float, replicas: int, name: str,
                  floats: ens.EnsembleResult, ensemble: Ensemble, balls: int, ran_on: dict[str, list[str]]) -> dict:
    """The exact count (certified arithmetic; up to `ExtendedPlan.exact_max_balls`) and N_e (up to
    `ExtendedPlan.resolution_limit`) of one size of ``balls`` balls on the float ensemble's seeds: for each,
    mean, sd and se of the collisions, replicas counted, and the seconds it took; for the exact count also
    the float chain's misses per replica (``float_misses_*``: exact minus float, over the exact count) and
    the smallest genuine closing speed over the replicas, in thresholds of the float criterion."""
    out: dict = {}
    counts = []
    if balls <= plan.exact_max_balls:
        counts.append((EXACT, {"arithmetic": "certified", "late_precision": plan.exact_late_precision}))
    if balls <= plan.resolution_limit():
        counts += [(count_name(e), {"resolution": e}) for e in plan.resolutions]
    for count, counting in counts:
        t0 = time.perf_counter()
        task = {"task": certified_replica} if count == EXACT else {}
        res = ensemble(f"{name}_{count}", scaling_spec(length, depth, plan, **counting), replicas, **task)
        _ran(ran_on, EXACT if count == EXACT else "N_e", res)
        collisions = res.column("collisions")
        mean, sd, se = _stats(collisions)
        out.update({f"{count}_collisions_mean": mean, f"{count}_collisions_sd": sd, f"{count}_collisions_se": se,
                    f"{count}_replicas": int(len(collisions)), f"{count}_seconds": time.perf_counter() - t0})
        if count == EXACT:
            exact, floated = _by_replica(res, "collisions"), _by_replica(floats, "collisions")
            misses = np.array([(exact[k] - floated[k]) / exact[k] for k in exact if k in floated and exact[k] > 0])
            out["float_misses_mean"], _, out["float_misses_se"] = _stats(misses)
            out["float_misses_max"] = float(misses.max()) if len(misses) else math.nan
            smallest = res.column("smallest_collision")
            out["exact_smallest_collision_min"] = float(smallest.min()) if len(smallest) else math.nan
            out["exact_reruns"] = int(res.column(RERUN).sum())
    return out


#: the column of `certified_replica`'s rows: 1 when the replica ran again without narrowing
RERUN = "full_precision_rerun"


def certified_replica(spec: RunSpec, index: int, seed=None) -> list[dict]:
    """An ensemble task: `ensemble.run_replica`, run again at ``spec.precision`` throughout when a decision
    fails once its state was narrowed to ``spec.late_precision`` (the same exact counts, in more time);
    its rows say which (`RERUN`)."""
    try:
        rows, rerun = ens.run_replica(spec, index, seed), 0
    except UncertifiedDecision as exc:
        if not exc.narrowed:
            raise
        rows, rerun = ens.run_replica(spec.model_copy(update={"late_precision": None}), index, seed), 1
    return [{**row, RERUN: rerun} for row in rows]


def _by_replica(res: ens.EnsembleResult, column: str) -> dict[int, float]:
    """``{replica: value}`` of ``column`` in the final rows of the replicas that finished."""
    return {int(row["replica"]): float(row[column]) for row in res.rows
            if not row.get(ens.ERROR_COLUMN) and row["at"] == ens.FINAL and column in row}


def exact_verdict(rows: list[dict], fits: dict) -> dict:
    """Whether the float counts' rise of the local exponent past 2 survives in exact counts, between the two
    largest sizes counted exactly: the exact and the float local exponents there, each with its z from 2
    (``(slope - 2) / se``), and the float one between the two largest sizes of all. ``survives``: whether
    the exact slope lies more than 3 se above 2, when the float one does there; None when the float slope
    does not pass 2 between those sizes (nothing to survive) or fewer than two sizes were counted exactly."""
    exact_rows = [r for r in rows if f"{EXACT}_collisions_mean" in r]
    if len(exact_rows) < 2:
        return {"survives": None, "exact_sizes": len(exact_rows)}
    pair = exact_rows[-2:]
    exact, flt = local_exponents(pair, f"{EXACT}_collisions"), local_exponents(pair, "collisions")
    z = lambda a, e: (a - 2.0) / e if e > 0 else math.nan  # noqa: E731
    out = {"exact_sizes": len(exact_rows), "between": [pair[0]["balls"], pair[1]["balls"]],
           "exact": exact["local_exponents"][0], "exact_se": exact["local_exponents_se"][0],
           "float": flt["local_exponents"][0], "float_se": flt["local_exponents_se"][0],
           "float_last": fits["collisions"]["local_exponents"][-1],
           "float_last_se": fits["collisions"]["local_exponents_se"][-1],
           "float_last_between": [rows[-2]["balls"], rows[-1]["balls"]]}
    out["exact_z"], out["float_z"] = z(out["exact"], out["exact_se"]), z(out["float"], out["float_se"])
    out["survives"] = bool(out["exact_z"] > 3) if out["float_z"] > 3 else None
    return out


def local_exponents(rows: list[dict], what: str) -> dict[str, list[float]]:
    """The slope of ``log(mean of what)`` against ``log(balls)`` between consecutive sizes, each with its
    standard error from the replicas (``se/mean`` is the error of a log; the two sizes' errors add in
    quadrature), and ``local_z_2``: how many standard errors each lies below 2."""
    local = fit.local_exponents([r["balls"] for r in rows], [r[f"{what}_mean"] for r in rows],
                                [r[f"{what}_se"] for r in rows])
    slope, se = np.array(local["local_exponents"]), np.array(local["local_exponents_se"])
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(se > 0, (2.0 - slope) / se, np.nan)
    return {"local_exponents": local["local_exponents"], "local_exponents_se": local["local_exponents_se"],
            "local_z_2": z.tolist(), "local_at_balls": local["local_at"]}


def _scaling_figure(rows: list[dict], fits: dict, counted: dict, path: Path) -> str:
    """Left: collisions and steps until frozen against balls, with the fitted power laws, and the exact
    collisions where counted. Right: the local exponents between consecutive sizes, ± their standard
    errors, against 2: steps, float collisions, exact collisions and N_e."""
    from ....plot import base as plots

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
                       fmt="o-", color=colour, capsize=3,
                       label=f"{what}" + (", float count" if what == "collisions" else ""))
    exact = [r for r in rows if f"{EXACT}_collisions_mean" in r]
    if exact:
        left.errorbar([r["balls"] for r in exact], [r[f"{EXACT}_collisions_mean"] for r in exact],
                      yerr=np.nan_to_num([r[f"{EXACT}_collisions_se"] for r in exact]), fmt="s", mfc="none",
                      color="tab:green", capsize=3, label="collisions, exact count (certified arithmetic)")
    styles = {EXACT: ("tab:green", "s-", "collisions, exact")}
    for k, name in enumerate(n for n in counted if n != EXACT):
        styles[name] = (_grey(k), ".--", f"collisions, N_e with e = {name[2:]}")
    for name, f in counted.items():
        if f["local_exponents"]:
            colour, fmt, label = styles[name]
            right.errorbar(f["local_at_balls"], f["local_exponents"], yerr=np.nan_to_num(f["local_exponents_se"]),
                           fmt=fmt, color=colour, capsize=2, label=label, mfc="none")
    from matplotlib.ticker import NullFormatter

    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("balls N")
    left.set_ylabel("count until frozen")
    left.set_title("until frozen against the number of balls")
    left.legend(fontsize="small")
    right.axhline(2.0, color="k", linestyle=":", linewidth=1, label="slope 2")
    right.set_xscale("log")
    for ax in (left, right):
        ax.xaxis.set_minor_formatter(NullFormatter())  # minor ticks' labels overlap over 1-2 decades
    right.set_xlabel("balls N (geometric mean of the two sizes)")
    right.set_ylabel("local exponent d log(count) / d log N")
    right.set_title("local exponents, consecutive sizes (± se, replicas)")
    right.legend(fontsize="small")
    fig.suptitle("half-plane, one boundary ball sent inward with energy 100, run until frozen")
    plots.save(fig, path)
    return path.name


def _grey(k: int) -> str:
    """The k-th of the greys the N_e curves are drawn in (darker for finer criteria)."""
    return str(round(0.7 - 0.2 * (k % 3), 2))


def _profiles_figure(profiles: dict, path: Path) -> str:
    from ....plot import base as plots

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
