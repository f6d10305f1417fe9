"""The examples of docs/testing.md run, and do what the page says."""

import re
import sys
import types
from pathlib import Path

import pytest

import pinnedballs as pb

DOC = Path(__file__).resolve().parents[2] / "docs" / "testing.md"


@pytest.fixture(scope="module")
def doc():
    """The namespace after running every python block of the page, in order: a module of its own, as
    the reader's would be (its classes pickle)."""
    page = types.ModuleType("testing_page")
    sys.modules[page.__name__] = page
    try:
        for block in re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S):
            exec(compile(block, str(DOC), "exec"), page.__dict__)
        yield page.__dict__
    finally:
        del sys.modules[page.__name__]


def test_the_greedy_rule_gets_the_message_the_page_quotes(doc):
    quoted = re.search(r"`message` reads `(.*?)`: the property", DOC.read_text(), flags=re.S).group(1)
    assert doc["message"] == " ".join(quoted.split())


def test_the_ring_passes_every_geometry_check(doc):
    from pinnedballs.testing import checks_for

    ring = doc["Ring"](12)
    assert [c.__name__ for c in checks_for(ring)][:2] == ["check_contact_tables", "check_contacts_are_touching_pairs"]
    for check in checks_for(ring):
        check(ring)


def test_the_decorated_test_has_a_case_per_check_and_declares_the_greedy_ones(doc):
    from pinnedballs.testing import checks_for

    mark = next(m for m in doc["test_my_components"].pytestmark if m.name == "parametrize")
    names, cases = mark.args
    assert names == "component, check"
    components = [doc["Ring"](12), pb.Elastic(), pb.Sweep(), doc["Greedy"]()]
    assert len(cases) == sum(len(checks_for(c)) for c in components)
    xfails = sorted(p.id for p in cases if p.marks)
    assert [x.split("-", 1)[1] for x in xfails] == ["check_energy_conserved_if_elastic", "check_energy_never_created"]
    for case in cases:  # every case runs as the page says: the greedy ones fail, the rest pass
        component, check = case.values
        if case.marks:
            with pytest.raises(AssertionError):
                check(component)
        else:
            check(component)


def test_the_property_based_example_runs(doc):
    doc["test_a_sweep_never_gains_energy"]()


def test_every_check_of_the_kit_is_in_the_page_table():
    from pinnedballs import testing

    table = DOC.read_text().split("## The checks", 1)[1].split("## In your", 1)[0]
    named = set(re.findall(r"`(check_[a-z_]+)`", table))
    assert named == {c.__name__ for c in (*testing.GEOMETRY_CHECKS, *testing.RULE_CHECKS, *testing.SCHEDULER_CHECKS)}
