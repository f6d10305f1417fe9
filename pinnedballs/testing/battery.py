"""The battery: which checks apply to a component (`checks_for`), running them all (`check_geometry`,
`check_rule`, `check_scheduler`), and one pytest test per (component, check)
(`parametrize_with_checks`, the shape of scikit-learn's).

A check that does not apply to a component (a law it does not claim, an exact form it does not have,
a spec it has none of) is left out of `checks_for`; called directly, it returns without a word.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable, Mapping

from ..engine.protocol import Engine
from ..geometry.base import Geometry
from ..rules import CollisionRule
from ..schedulers.base import Scheduler
from . import geometry_checks as geometry
from . import roundtrips
from . import rule_checks as rule
from . import scheduler_checks as scheduler

__all__ = ["GEOMETRY_CHECKS", "RULE_CHECKS", "SCHEDULER_CHECKS", "checks_for", "check_geometry", "check_rule",
           "check_scheduler", "parametrize_with_checks"]

#: every geometry check, in the order they run (the contact tables first: the others read them)
GEOMETRY_CHECKS = (geometry.check_contact_tables, geometry.check_contacts_are_touching_pairs,
                   geometry.check_contact_graph_round_trip, geometry.check_frames, geometry.check_boundary,
                   roundtrips.check_geometry_spec_round_trip, roundtrips.check_geometry_pickles)
#: every rule check, in the order they run
RULE_CHECKS = (rule.check_separating_untouched, rule.check_energy_never_created,
               rule.check_energy_conserved_if_elastic, rule.check_momentum_conserved, rule.check_swap_symmetric,
               rule.check_restitution_law, rule.check_exact_agrees, roundtrips.check_rule_spec_round_trip,
               roundtrips.check_rule_pickles)
#: every scheduler check, in the order they run (picks in range first: the others run the picks)
SCHEDULER_CHECKS = (scheduler.check_scheduler_picks_in_range, scheduler.check_scheduler_same_seed_same_run,
                    scheduler.check_scheduler_split_run, scheduler.check_scheduler_state_round_trip,
                    scheduler.check_scheduler_law, roundtrips.check_scheduler_spec_round_trip,
                    roundtrips.check_scheduler_pickles)


def _applies(check: Callable, component) -> bool:
    """False for the checks that have nothing to look at in ``component`` (see the module's docstring)."""
    if check in (roundtrips.check_geometry_spec_round_trip, roundtrips.check_rule_spec_round_trip,
                 roundtrips.check_scheduler_spec_round_trip):
        return component.to_spec() is not None
    if check in (rule.check_restitution_law, rule.check_exact_agrees):
        return component.exact_restitution() is not None
    if check is rule.check_energy_conserved_if_elastic:
        return rule.claims_elastic(component)
    if check is scheduler.check_scheduler_law:
        return getattr(component, "law", None) is not None
    if check is geometry.check_contacts_are_touching_pairs:
        return not component.curved
    if check is geometry.check_boundary:
        return component.boundary is not None
    return True


def checks_for(component) -> list[Callable]:
    """The checks that apply to a component, in the order they run.

    Parameters
    ----------
    component : Geometry or CollisionRule or Scheduler or Engine
        A component (an engine: `engine_checks.engine_checks_for`).

    Returns
    -------
    list of callable
        Each ``check(component)``; those with nothing to look at in it left out (the module's docstring).

    Raises
    ------
    TypeError
        For anything else.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.testing import checks_for
    >>> [c.__name__ for c in checks_for(pb.Sweep())][:3]
    ['check_scheduler_picks_in_range', 'check_scheduler_same_seed_same_run', 'check_scheduler_split_run']
    """
    for base, battery in ((Geometry, GEOMETRY_CHECKS), (CollisionRule, RULE_CHECKS), (Scheduler, SCHEDULER_CHECKS)):
        if isinstance(component, base):
            return [c for c in battery if _applies(c, component)]
    if isinstance(component, Engine):
        from .engine_checks import engine_checks_for

        return engine_checks_for(component)
    raise TypeError(f"component: must be a Geometry, a CollisionRule, a Scheduler or an Engine, got "
                    f"{type(component).__name__}")


def _run_all(component, base: type, what: str) -> None:
    if not isinstance(component, base):
        raise TypeError(f"{what}: must be a {base.__name__}, got {type(component).__name__}")
    for check in checks_for(component):
        check(component)


def check_geometry(geometry: Geometry) -> None:
    """Run every geometry check on ``geometry`` (`GEOMETRY_CHECKS`, those that apply).

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        The first check that fails, naming the broken property and a small example.
    TypeError
        If ``geometry`` is not a `Geometry`.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.testing import check_geometry
    >>> check_geometry(pb.HalfPlane(rows=3, cols=4))
    """
    _run_all(geometry, Geometry, "geometry")


def check_rule(rule: CollisionRule) -> None:
    """Run every rule check on ``rule`` (`RULE_CHECKS`, those that apply).

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        The first check that fails, naming the broken property and a small example.
    TypeError
        If ``rule`` is not a `CollisionRule`.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.testing import check_rule
    >>> check_rule(pb.Restitution(0.5))
    """
    _run_all(rule, CollisionRule, "rule")


def check_scheduler(scheduler: Scheduler) -> None:
    """Run every scheduler check on ``scheduler`` (`SCHEDULER_CHECKS`, those that apply).

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        The first check that fails, naming the broken property and a small example.
    TypeError
        If ``scheduler`` is not a `Scheduler`.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.testing import check_scheduler
    >>> check_scheduler(pb.Sweep())
    """
    _run_all(scheduler, Scheduler, "scheduler")


def _label(component, position: int | None = None) -> str:
    """``repr(component)`` (cut at 60 characters), or, where that holds a memory address (``object``'s
    repr, which differs between processes: pytest-xdist's workers would collect different tests), the
    component's class and its ``position`` in the list: ``Greedy[0]``."""
    text = repr(component)
    if re.search(r"\bat 0x[0-9a-fA-F]+", text):
        text = type(component).__name__ + ("" if position is None else f"[{position}]")
    return text if len(text) <= 60 else text[:57] + "..."


def parametrize_with_checks(components: Iterable, *,
                            expected_failed_checks: Callable[[object], Mapping[str, str]] | Mapping[str, str]
                            | None = None):
    """A pytest decorator: one test per (component, check) that applies to it (engines too: their battery,
    `check_engine`'s checks). The test takes
    ``component, check`` and calls ``check(component)``; its id is ``<component>-<check name>``, the
    component's repr or, when that is ``object``'s (a memory address, different in every process), its
    class and place in ``components`` (``Greedy[0]``): the same ids in every pytest-xdist worker.

    Needs pytest (imported here only)::

        @parametrize_with_checks([MyGeometry(8), MyRule()])
        def test_my_components(component, check):
            check(component)

    Parameters
    ----------
    components : iterable
        Geometries, rules, schedulers and engines.
    expected_failed_checks : dict or callable, optional
        ``{check name: reason}`` for checks a component is known to fail, or a callable giving that dict for
        each component. Those are marked ``xfail`` (strict: one that passes fails the test run, so a
        declaration cannot outlive its reason).

    Returns
    -------
    pytest.MarkDecorator
        ``pytest.mark.parametrize("component, check", ...)``.

    Raises
    ------
    ValueError
        On ``expected_failed_checks`` naming what is no check of the component.
    TypeError
        For a component that is none of the four.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.testing import parametrize_with_checks
    >>> mark = parametrize_with_checks([pb.Sweep()])
    >>> [case.id for case in mark.args[1]][:2]
    ['Sweep()-check_scheduler_picks_in_range', 'Sweep()-check_scheduler_same_seed_same_run']
    """
    import pytest

    params = []
    for position, component in enumerate(components):
        expected = expected_failed_checks(component) if callable(expected_failed_checks) else \
            dict(expected_failed_checks or {})
        checks = checks_for(component)
        unknown = set(expected) - {c.__name__ for c in checks}
        if unknown:
            raise ValueError(f"expected_failed_checks: {sorted(unknown)} are no checks of {_label(component)} "
                             f"(its checks: {[c.__name__ for c in checks]})")
        for check in checks:
            marks = ([pytest.mark.xfail(reason=expected[check.__name__], strict=True, raises=AssertionError)]
                     if check.__name__ in expected else [])
            params.append(pytest.param(component, check, marks=marks,
                                       id=f"{_label(component, position)}-{check.__name__}"))
    return pytest.mark.parametrize("component, check", params)
