"""The contact sheet of a run's snapshots: one tile per snapshot, titled with its counts, in order,
on the arrow scale of all of them."""

from __future__ import annotations

import numpy as np

import pinnedballs as pb
from pinnedballs.plot import sheet, states


def states_of(geom, n: int) -> list[tuple[str, np.ndarray]]:
    rng = np.random.default_rng(0)
    return [(f"{100 * (k + 1):,} collisions", rng.standard_normal((geom.n_balls, 2)) * (k + 1)) for k in range(n)]


def tiles(fig) -> list:
    return [ax for ax in fig.axes if ax.images]


def test_one_tile_per_snapshot_in_order_on_one_scale(monkeypatch):
    half = pb.HalfPlane(rows=3, cols=4)
    scales = []
    quiver = states.quiver
    monkeypatch.setitem(states.DRAWINGS, "plane", lambda p, v, **kw: scales.append(kw["shared"]) or quiver(p, v, **kw))
    given = states_of(half, 5)
    fig = sheet.contact_sheet(states.state_picture(half), given, title="the 5 snapshots after the start")
    assert [ax.get_title() for ax in tiles(fig)] == [label for label, _ in given]
    assert all(s is scales[0] and len(s) == 5 for s in scales)         # every tile drawn with all states' scale
    assert fig.get_suptitle() == "the 5 snapshots after the start"


def test_many_snapshots_get_evenly_spaced_tiles_with_the_first_and_the_last(monkeypatch):
    monkeypatch.setattr(sheet, "MAX_TILES", 4)
    half = pb.HalfPlane(rows=3, cols=4)
    given = states_of(half, 10)
    fig = sheet.contact_sheet(states.state_picture(half), given)
    assert [ax.get_title() for ax in tiles(fig)] == ["100 collisions", "400 collisions", "700 collisions",
                                                      "1,000 collisions"]
    assert fig.get_suptitle() == "snapshots (4 of 10, evenly spaced)"
