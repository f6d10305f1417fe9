"""The sphere study: the torus's three observables for one moving ball on a geodesic sphere, against
the torus of nearest size (`torus_law_study`)."""

from __future__ import annotations

import math
from pathlib import Path

from ..plan import torus_row
from .common import _observing
from .plan import Ensemble, ExtendedPlan
from .torus_law_study import LAW, _law_figure, _law_rows, _law_spec, _z


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
