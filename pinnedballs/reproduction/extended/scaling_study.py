"""The scaling study: collisions and steps until frozen against the number of balls on half-planes,
one boundary ball moving inward, `UniformRandomPair`; fitted exponents (`fit.fit_exponent`), local
exponents between consecutive sizes, the frozen energy profile by decile of depth, and the closing
margin of each size's counts (`engine.margin`: how near the float criterion their picks came)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from ...specs.run import RunSpec
from ..fit import fit_exponent
from .common import DECILES, _frozen_row, _inward_spec, _margin_row, _observing, _profile, decile_row
from .plan import Ensemble, ExtendedPlan


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
               **_frozen_row(res), **_margin_row(res), "seconds": time.perf_counter() - t0}
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
    from ...plot import base as plots

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
    from ...plot import base as plots

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
