"""The FCC half-space study: one boundary ball moving inward on open FCC blocks (boundary z = 0), the
frozen energy by layer and the share of the boundary's energy pointing outward."""

from __future__ import annotations

from pathlib import Path

from .common import _frozen_row, _inward_spec, _levels_figure, _observing, _profile, _stats, level_row
from .plan import Ensemble, ExtendedPlan


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
