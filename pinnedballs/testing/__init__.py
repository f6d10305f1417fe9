"""Testing your own components: the checks the project runs on its own geometries, rules and schedulers.

``check_geometry(g)``, ``check_rule(rule)`` and ``check_scheduler(s)`` run every check that applies and
raise an `AssertionError` naming the broken property and a small example; each check is also a public
function of its own (``check_momentum_conserved(rule)``, ...), and ``parametrize_with_checks([...])``
makes one pytest test per (component, check). ``strategies`` holds hypothesis strategies for the
project's types (``from pinnedballs.testing import strategies``). docs/testing.md shows them at work.

Only `parametrize_with_checks` needs pytest and only `strategies` needs hypothesis; both are imported
where they are used. One module per idea: `geometry_checks`, `rule_checks`, `scheduler_checks`,
`roundtrips` (specs and pickles), `battery` (which checks apply, running them, pytest), `samples`
(what the checks run on) and `strategies`.
"""

from .battery import (
                      GEOMETRY_CHECKS,
                      RULE_CHECKS,
                      SCHEDULER_CHECKS,
                      check_geometry,
                      check_rule,
                      check_scheduler,
                      checks_for,
                      parametrize_with_checks,
)
from .geometry_checks import (
                      check_boundary,
                      check_contact_graph_round_trip,
                      check_contact_tables,
                      check_contacts_are_touching_pairs,
                      check_frames,
)
from .roundtrips import (
                      check_geometry_pickles,
                      check_geometry_spec_round_trip,
                      check_rule_pickles,
                      check_rule_spec_round_trip,
                      check_scheduler_pickles,
                      check_scheduler_spec_round_trip,
)
from .rule_checks import (
                      check_energy_conserved_if_elastic,
                      check_energy_never_created,
                      check_exact_agrees,
                      check_momentum_conserved,
                      check_restitution_law,
                      check_separating_untouched,
                      check_swap_symmetric,
)
from .scheduler_checks import (
                      check_scheduler_law,
                      check_scheduler_picks_in_range,
                      check_scheduler_same_seed_same_run,
                      check_scheduler_split_run,
                      check_scheduler_state_round_trip,
)

__all__ = ["check_geometry", "check_rule", "check_scheduler", "parametrize_with_checks", "checks_for",
           "GEOMETRY_CHECKS", "RULE_CHECKS", "SCHEDULER_CHECKS",
           "check_contact_tables", "check_contacts_are_touching_pairs", "check_contact_graph_round_trip",
           "check_frames", "check_boundary", "check_geometry_spec_round_trip", "check_geometry_pickles",
           "check_separating_untouched", "check_energy_never_created", "check_energy_conserved_if_elastic",
           "check_momentum_conserved", "check_swap_symmetric", "check_restitution_law", "check_exact_agrees",
           "check_rule_spec_round_trip", "check_rule_pickles",
           "check_scheduler_picks_in_range", "check_scheduler_same_seed_same_run", "check_scheduler_split_run",
           "check_scheduler_state_round_trip", "check_scheduler_law", "check_scheduler_spec_round_trip",
           "check_scheduler_pickles"]
