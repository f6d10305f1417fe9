# The public names of `pinnedballs.testing`, each imported from its module when first used
# (`lazy_loader.attach_stub` reads this file), so that `from pinnedballs.testing import strategies` loads
# no checks and `check_rule` no hypothesis.
from .battery import GEOMETRY_CHECKS as GEOMETRY_CHECKS
from .battery import RULE_CHECKS as RULE_CHECKS
from .battery import SCHEDULER_CHECKS as SCHEDULER_CHECKS
from .battery import check_geometry as check_geometry
from .battery import check_rule as check_rule
from .battery import check_scheduler as check_scheduler
from .battery import checks_for as checks_for
from .battery import parametrize_with_checks as parametrize_with_checks
from .geometry_checks import check_boundary as check_boundary
from .geometry_checks import check_contact_graph_round_trip as check_contact_graph_round_trip
from .geometry_checks import check_contact_tables as check_contact_tables
from .geometry_checks import check_contacts_are_touching_pairs as check_contacts_are_touching_pairs
from .geometry_checks import check_frames as check_frames
from .roundtrips import check_geometry_pickles as check_geometry_pickles
from .roundtrips import check_geometry_spec_round_trip as check_geometry_spec_round_trip
from .roundtrips import check_rule_pickles as check_rule_pickles
from .roundtrips import check_rule_spec_round_trip as check_rule_spec_round_trip
from .roundtrips import check_scheduler_pickles as check_scheduler_pickles
from .roundtrips import check_scheduler_spec_round_trip as check_scheduler_spec_round_trip
from .rule_checks import check_energy_conserved_if_elastic as check_energy_conserved_if_elastic
from .rule_checks import check_energy_never_created as check_energy_never_created
from .rule_checks import check_exact_agrees as check_exact_agrees
from .rule_checks import check_momentum_conserved as check_momentum_conserved
from .rule_checks import check_restitution_law as check_restitution_law
from .rule_checks import check_separating_untouched as check_separating_untouched
from .rule_checks import check_swap_symmetric as check_swap_symmetric
from .scheduler_checks import check_scheduler_law as check_scheduler_law
from .scheduler_checks import check_scheduler_picks_in_range as check_scheduler_picks_in_range
from .scheduler_checks import check_scheduler_same_seed_same_run as check_scheduler_same_seed_same_run
from .scheduler_checks import check_scheduler_split_run as check_scheduler_split_run
from .scheduler_checks import check_scheduler_state_round_trip as check_scheduler_state_round_trip
