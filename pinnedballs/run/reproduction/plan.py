"""What the reproduction runs: the `Plan` (`FULL`, `QUICK`), the paper's set-ups as run specs,
and the table rows measured on their states."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ...specs.run import RunSpec, parse_spec
from ...util.errors import InputError
from .. import ensemble as ens

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
    from ...analysis import observables as obs

    row = ens.state_row(geometry, velocities, masses)
    _, fraction = obs.energy_profile(geometry.boundary.distance, velocities, masses)
    row["next_share"] = float(fraction[1])
    return row


def torus_row(geometry, velocities, masses=None) -> dict[str, float]:
    """`ensemble.state_row` and, per component, the variance (``ddof=0``), the excess kurtosis,
    the KS p-value and the Anderson–Darling statistic against a fitted normal (NaN where undefined)."""
    from scipy import stats

    from ...analysis import observables as obs

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



@dataclass
class _Run:
    """A single run: the simulation after its stop, the initial velocities, the snapshots by label."""

    sim: object
    initial: np.ndarray
    snapshots: dict[int, object]
    reason: str


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



def _check_plan(plan: Plan) -> None:
    for name in ("replicas", "size_replicas"):
        ens.check_count(name, getattr(plan, name))
    if not plan.sizes:
        raise InputError("sizes: give at least one rectangle")
    if len(plan.steps) < 1 or any(s <= 0 for s in plan.steps) or list(plan.steps) != sorted(set(plan.steps)):
        raise InputError(f"steps: must be increasing positive step counts, got {plan.steps}")


def _sizes(plan: Plan) -> list[tuple[float, float]]:
    """The rectangles of Figure 4, with the detail rectangle among them, by size."""
    sizes = dict.fromkeys(tuple(s) for s in plan.sizes)
    sizes[tuple(plan.detail)] = None
    return sorted(sizes, key=lambda s: s[0] * s[1])
