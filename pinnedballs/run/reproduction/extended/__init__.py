"""Studies beyond the paper (``pinnedballs reproduce --extended``): one module per study.

Each study takes the `ExtendedPlan`, the output directory and an ``ensemble(name, spec,
replicas, task=...)`` callable (`reproduce`'s, which records the replicas' tables and
failures), and returns plain numbers: ``{"rows": [...], ..., "figures": [PNG names]}``.

The scaling and torus-law studies are study specs (`scaling_study_spec`, `torus_law_study_spec`; the full plan's
in ``examples/studies/``), their points expanded by `pinnedballs.specs.study` as ``pinnedballs study`` expands a
user's, each point's ensemble run through `reproduce`'s ``ensemble``.

* `scaling_study`: collisions and steps until frozen against the number of balls, half-plane,
  one boundary ball moving inward, `UniformRandomPair` on `ExtendedPlan.stream` (the counter stream on a
  GPU: `EXTENDED_GPU`); fitted exponents (`fit.fit_exponent`); up to `ExtendedPlan.exact_max_balls` the exact
  count (certified arithmetic) and up to `ExtendedPlan.resolution_limit` N_e beside the float one;
* `torus_law_study`: excess kurtosis, approaching fraction and line-of-centres correlation on the
  torus against time (steps per ball) and size, mean ± standard error over replicas;
* `sphere_study`: the same observables for one moving ball on a geodesic sphere, against the torus;
* `hyperbolic_study`: one rim ball moving inward on the {3,7} disk, energy by rings from the rim;
* `fcc_study`: the half-space experiment on an open FCC block (boundary z = 0);
* `orders_study`: fewest and most collisions over every order against the random order.

`plan` holds what they run, `common` what they share, `run` runs them all in order and `report`
writes their section of ``report.md``.
"""

from .common import DECILES, decile_row, level_row
from .fcc_study import fcc_half_space
from .hyperbolic_study import hyperbolic
from .orders_study import order_configurations, orders
from .plan import (
                   EXTENDED_FULL,
                   EXTENDED_GPU,
                   EXTENDED_QUICK,
                   STUDIES,
                   ExtendedPlan,
                   check_extended_plan,
                   expected_extended_figures,
)
from .run import run_extended
from .scaling_study import count_name, exact_verdict, local_exponents, scaling, scaling_spec, scaling_study_spec
from .sphere_study import sphere
from .torus_law_study import LAW, law_verdicts, torus_law, torus_law_study_spec

__all__ = ["STUDIES", "DECILES", "LAW", "ExtendedPlan", "EXTENDED_FULL", "EXTENDED_QUICK", "EXTENDED_GPU",
           "check_extended_plan",
           "expected_extended_figures", "run_extended", "decile_row", "level_row", "scaling", "scaling_spec",
           "scaling_study_spec", "torus_law_study_spec",
           "count_name", "exact_verdict",
           "local_exponents", "torus_law", "law_verdicts", "sphere", "hyperbolic", "fcc_half_space", "orders",
           "order_configurations"]
