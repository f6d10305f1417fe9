"""The hyperbolic study: one rim ball of the {3,7} disk moving inward, the frozen energy by rings from
the rim, for each number of rings."""

from __future__ import annotations

from pathlib import Path

from .common import _frozen_row, _inward_spec, _levels_figure, _observing, _profile, level_row
from .plan import Ensemble, ExtendedPlan


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
