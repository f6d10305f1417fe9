"""The paper's reproduction: every figure of the paper, and ``report.md`` comparing its numbers with ours.

The paper's set-ups (``docs/reproduce.md`` explains them and our choices):

* half-plane: ``HalfPlane.from_size(L, D)`` for the paper's seven rectangles, one
  boundary ball (``boundary_center``) sent into the bulk (direction ``(0, 1)``) with
  energy 100, unit masses, run until frozen. As a cross-check, the 100 x 50 rectangle
  also in the orientation the paper's ball count implies (``HalfPlane`` ``orientation="across"``);
* flat torus: ``FlatTorus(38, 38)`` (1,444 balls; the paper gives no size), ball 0
  moving with energy 100, snapshots at 211,417 and 422,834 steps.

Single runs (the pictures) use ``seed`` itself; ensembles use replicas ``0..N-1`` of
``seed`` (`pinnedballs.run.ensemble`). Everything is seeded, so the report is reproducible.
`FULL` is the paper's scale; `QUICK` a smaller one for a first look.

One module per idea: `plan` (what is run: the plan and the paper's set-ups), `run`
(running it: `reproduce`), `checks` (the paper's statements against our numbers),
`figures` and `report`; beyond the paper, `extended` (the studies of ``--extended``, a module each,
and their report) and `fit`. The command ``pinnedballs reproduce`` lives in `pinnedballs.run.cli`.
"""

from .checks import Check
from .extended.plan import EXTENDED_FULL, EXTENDED_GPU, EXTENDED_QUICK, ExtendedPlan, expected_extended_figures
from .fit import fit_exponent
from .plan import (
                   FULL,
                   PAPER_SIZES,
                   QUICK,
                   Plan,
                   expected_figures,
                   half_plane_spec,
                   paper_lattice_row,
                   paper_lattice_spec,
                   torus_row,
                   torus_spec,
)
from .run import reproduce

__all__ = ["Plan", "FULL", "QUICK", "PAPER_SIZES", "Check", "reproduce", "expected_figures",
           "half_plane_spec", "torus_spec", "paper_lattice_spec", "paper_lattice_row", "torus_row",
           "ExtendedPlan", "EXTENDED_FULL", "EXTENDED_QUICK", "EXTENDED_GPU", "expected_extended_figures",
           "fit_exponent"]
