"""The paper's statements against our measurements: one `Check` per row of the report."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import ensemble as ens
from .plan import (
    CORRELATION_TOLERANCE,
    PAPER_BOUNDARY_SHARE,
    PAPER_FROZEN_COLLISIONS,
    Plan,
    _label,
    _Run,
    paper_lattice_row,
)


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



# ---------------------------------------------------------------- the checks


def _half_plane_checks(plan: Plan, detail: dict, size_results: dict, lattice_res, lattice_run) -> list[Check]:
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
    from ...analysis import observables as obs

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
            v = snap.state.velocities if snap is not None else run.sim.velocities
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
