"""`run_extended`: every study in `STUDIES` order, their numbers gathered for ``results.json``."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from .fcc_study import fcc_half_space
from .hyperbolic_study import hyperbolic
from .orders_study import orders
from .plan import STUDIES, Ensemble, ExtendedPlan, _plan_dict
from .scaling_study import scaling
from .sphere_study import sphere
from .torus_law_study import torus_law

#: the study function of each name in `STUDIES` but the sphere's (which also takes the torus's rows)
_STUDY = {"scaling": scaling, "torus_law": torus_law, "hyperbolic": hyperbolic, "fcc_half_space": fcc_half_space,
          "orders": orders}


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
            study = _STUDY[name](plan, out, ensemble)
        results["seconds"][name] = time.perf_counter() - t0
        results[name] = study.pop("rows")
        results["figures"][name] = study.pop("figures")
        results.update({f"{name}_{key}": value for key, value in study.items()})
        say(f"extended: {name} took {results['seconds'][name]:.1f} s")
    return results
