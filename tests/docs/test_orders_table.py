"""docs/orders.md's most collisions over velocities and orders: its example prints what the page says,
and its table of small configurations is what docs/orders_table.py makes (but the times)."""

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb

DOCS = Path(__file__).resolve().parents[2] / "docs"
PAGE = DOCS / "orders.md"

#: the configurations whose rows the test makes again (the hexagon and the tripod take minutes)
FAST = ("triangle", "4-ball star", "4-ball rhombus", "5-ball diamond", "5-ball bent chain", "5-ball chain")


@pytest.fixture(scope="module")
def table():
    spec = importlib.util.spec_from_file_location("orders_table", DOCS / "orders_table.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def page_rows(names) -> dict[str, str]:
    """The table's row on the page of each configuration in ``names``, without its time."""
    lines = PAGE.read_text().splitlines()
    return {name: line.rsplit(" | ", 1)[0] for name in names for line in lines if line.startswith(f"| {name} |")}


def test_configurations_are_the_named_ones_in_exact_arithmetic(table):
    """Balls and contacts as named (the hexagon: 6 spokes and 6 rim contacts; the tripod a tree), each
    with exact normals, and every configuration a row of the page's table."""
    expected = {"triangle": (3, 3), "4-ball star": (4, 3), "4-ball rhombus": (4, 5), "5-ball diamond": (5, 4),
                "5-ball bent chain": (5, 4), "7-ball hexagon": (7, 12), "7-ball tripod": (7, 6),
                "5-ball chain": (5, 4)}
    rows = page_rows(table.CONFIGURATIONS)
    text = PAGE.read_text()
    assert len(rows) == len(table.CONFIGURATIONS) and table.HEADER in text
    below = text.split(table.HEADER)[1].lstrip("\n").split("\n\n")[0].splitlines()
    assert len(below) == len(rows)  # no other row in the table
    for name in table.CONFIGURATIONS:
        g = table.geometry(name)
        (key,) = [k for k in expected if name.startswith(k)]
        assert (g.n_balls, g.n_contacts) == expected[key], name
        assert pb.Simulation(g, np.zeros((g.n_balls, 2)), arithmetic="exact").arithmetic == "exact"
        assert f"| {g.n_balls} | {g.n_contacts} |" in rows[name]


@pytest.mark.slow
def test_fast_rows_are_what_the_script_makes(table):
    """The page's rows for the small configurations, made again with the page's trials and seed."""
    rows = page_rows(table.CONFIGURATIONS)
    assert "`trials=2000, seed=0`" in PAGE.read_text()
    for name in table.CONFIGURATIONS:
        if name.startswith(FAST):
            assert table.row(name, 2000, 0).rsplit(" | ", 1)[0] == rows[name]


def test_example_prints_what_the_page_says():
    """The page's python blocks in turn: the search from the rhombus's velocities finds 7, replayed exactly."""
    ns: dict = {}
    for block in re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S):
        exec(compile(block, str(PAGE), "exec"), ns)
    m = ns["m"]
    assert str(m) in PAGE.read_text()
    assert m.collisions == len(m.order) == 7 and m.exhaustive_orders and m.arithmetic == "exact"
    sim = pb.Simulation(ns["rhombus"], m.velocities, scheduler=pb.Replay(m.order), arithmetic="exact")
    assert sim.run_until_frozen(max_steps=7) and sim.collisions == 7
