"""What the studies share: the rows each replica records (module level: pickled to workers), their
summaries over replicas, the spec of one boundary ball sent inward, and the figure of a profile by level."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from ....specs.run import RunSpec, parse_spec
from ... import ensemble as ens
from .plan import ExtendedPlan

DECILES = 10


def decile_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` and ``decile_k``: the energy share at distance in ``[k, k+1) / 10`` of the largest."""
    from ....analysis import observables as obs

    row = ens.state_row(geometry, velocities, masses)
    d = geometry.boundary.distance
    e = obs.energy_per_ball(velocities, masses)
    k = np.minimum((DECILES * d / d.max()).astype(np.int64), DECILES - 1)
    shares = np.bincount(k, weights=e, minlength=DECILES) / e.sum()
    row.update({f"decile_{j}": float(s) for j, s in enumerate(shares)})
    return row


def level_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` and ``level_k``: the energy share of the ``k``-th row from the boundary."""
    from ....analysis import observables as obs

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


def _margin_row(res: ens.EnsembleResult) -> dict:
    """The replicas' closing margins (`engine.margin`, final states): how many are thin, the smallest
    collision and the largest remnant over them (in thresholds; NaN where there is none), and the mean
    counts of collisions and remnants near the threshold."""
    def over(name: str, pick) -> float:
        x = res.column(name)
        return float(pick(x)) if len(x) else math.nan

    return {"thin": len(res.thin()), "smallest_collision_min": over("smallest_collision", np.min),
            "largest_remnant_max": over("largest_remnant", np.max),
            "near_collisions_mean": over("near_collisions", np.mean),
            "near_remnants_mean": over("near_remnants", np.mean)}


def _inward_spec(geometry: dict, plan: ExtendedPlan, what: str, scheduler: str = "rejection_free") -> RunSpec:
    """``geometry``'s boundary-centre ball moving inward with the plan's energy, ``scheduler``, until frozen."""
    return parse_spec({
        "description": f"{what}: the boundary-centre ball moving inward, until frozen",
        "geometry": geometry,
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": "inward",
                    "energy": float(plan.energy)},
        "scheduler": {"kind": scheduler},
        "stop": {"frozen": True, "max_steps": plan.max_steps}, "seed": plan.seed})


def _levels_figure(profiles: dict, xlabel: str, title: str, path: Path) -> str:
    from ....plot import base as plots

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
