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

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
