"""The colour `explore_orders`' notebook bar ends in (issue 42): a search that ends below ``max_states``
ends normally (it searched every state), so its widget ends in the normal colour, not tqdm's failure red,
which is kept for an error or an interruption."""

from __future__ import annotations

import pytest
from helpers import RHOMBUS_V, rhombus

import pinnedballs as pb
from pinnedballs.analysis import orders
from pinnedballs.util import progress

pytest.importorskip("ipywidgets")


@pytest.fixture
def widgets(monkeypatch) -> list:
    """The notebook widgets the calls open (as in a Jupyter kernel), in order."""
    opened = []

    def recorded(**kwargs):
        bar = open_bar(**kwargs)
        opened.append(bar)
        return bar

    open_bar = progress.open_bar
    monkeypatch.setattr(progress, "_in_notebook", lambda: True)
    monkeypatch.setattr(progress, "open_bar", recorded)
    return opened


def final(bar) -> tuple[str, int, int | None]:
    """``(colour, count, total)`` a closed widget shows."""
    return bar.container.children[1].bar_style, bar.n, bar.total


def test_a_search_that_ends_below_its_bound_ends_in_the_normal_colour(widgets):
    result = pb.explore_orders(rhombus(), RHOMBUS_V, max_states=1000, progress=True)
    assert result.exhaustive and result.states < 1000
    (bar,) = widgets
    assert final(bar) == ("success", result.states, 1000)


def test_an_interrupted_search_ends_red(widgets, monkeypatch):
    search = orders._search

    def interrupted(system, root, max_states, max_collisions, bar, held):
        search(system, root, max_states, max_collisions, bar, held)
        raise KeyboardInterrupt

    monkeypatch.setattr(orders, "_search", interrupted)
    with pytest.raises(KeyboardInterrupt):
        pb.explore_orders(rhombus(), RHOMBUS_V, max_states=1000, progress=True)
    (bar,) = widgets
    assert final(bar)[0] == "danger"


def test_a_bar_without_an_end_is_red_only_after_an_error(widgets):
    with progress.Progress(True, None, "collisions", "sampled orders") as bar:
        bar.update(12)
    with pytest.raises(ValueError), progress.Progress(True, None, "collisions", "sampled orders") as bar:
        bar.update(12)
        raise ValueError("no order reached frozen")
    assert [final(bar) for bar in widgets] == [("success", 12, None), ("danger", 12, None)]
