"""The torus's stationary law: excess kurtosis, approaching fraction and line-of-centres correlation on
the flat torus against time (steps per ball) and size, mean ± standard error over replicas, and the
verdict at the largest torus and the last time. The sphere study (`sphere_study`) reuses its specs,
rows and figure."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ....specs.run import RunSpec, parse_spec
from ....specs.study import StudySpec, parse_study
from ... import ensemble as ens
from ..plan import torus_row
from .common import _observing, _stats
from .plan import Ensemble, ExtendedPlan

LAW = (("kurtosis", "excess kurtosis of a component"), ("approaching_fraction", "approaching fraction"),
       ("line_of_centres_correlation", "line-of-centres correlation"))


def _law_spec(geometry: dict, balls: int, plan: ExtendedPlan, what: str) -> RunSpec:
    """Ball 0 moving with ``plan.energy``, `UniformRandomPair`, snapshots at ``plan.torus_times`` steps per ball."""
    return parse_spec(_law_dict(geometry, balls, plan, what))


def _law_dict(geometry: dict, balls: int, plan: ExtendedPlan, what: str) -> dict:
    """`_law_spec`, as JSON."""
    steps = _law_steps(balls, plan)
    return {"description": f"{what}: ball 0 moving, all others at rest", "geometry": geometry,
            "initial": {"kind": "single_ball", "ball": 0, "direction": [1.0, 0.0], "energy": float(plan.energy)},
            "stop": {"steps": steps[-1]}, "snapshots": {"at_steps": steps[:-1]} if len(steps) > 1 else None,
            "seed": plan.seed}


def _law_steps(balls: int, plan: ExtendedPlan) -> list[int]:
    """The steps of ``plan.torus_times`` (steps per ball) on ``balls`` balls."""
    return [t * balls for t in plan.torus_times]


def torus_law_study_spec(plan: ExtendedPlan) -> StudySpec:
    """The torus-law study as a study (`specs.study`; the full plan's is ``examples/studies/extended_torus_law.json``):
    the square tori of ``plan.torus_sides`` zipped with their stops and snapshots at ``plan.torus_times`` steps per
    ball, every torus on the plan's seed (seeds "as_spec")."""
    sides = plan.torus_sides
    base = _law_dict({"kind": "flat_torus", "rows": sides[0], "cols": sides[0]}, sides[0] ** 2, plan, "torus law")
    zipped = {"geometry.rows": list(sides), "geometry.cols": list(sides),
              "stop.steps": [_law_steps(s * s, plan)[-1] for s in sides]}
    if len(plan.torus_times) > 1:
        zipped["snapshots.at_steps"] = [_law_steps(s * s, plan)[:-1] for s in sides]
    return parse_study({"description": "the extended reproduction's torus law: its observables against time and size",
                        "base": base, "zip": zipped, "replicas": plan.torus_replicas, "seeds": "as_spec"})


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
    for side, point in zip(plan.torus_sides, torus_law_study_spec(plan).expand()):
        res = ensemble(f"torus_law_{side}x{side}", point.spec, point.replicas, task=_observing(torus_row))
        rows += _law_rows(res, side * side, plan, {"side": side})
    series = {f"torus {s}x{s}": [r for r in rows if r["side"] == s] for s in plan.torus_sides}
    return {"rows": rows, "verdicts": law_verdicts(rows, plan),
            "figures": [_law_figure(series, "flat torus: the long-run law against time and size",
                                    out / "extended_torus_law.png")]}




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
    from ....plot import base as plots

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
