"""The closing margin (`engine.margin`): how near the criterion ``w > resolution * V`` a run's picks
came, kept by every loop, and the resolution as a parameter of the model."""

import math
import warnings

import numpy as np
import pytest
from helpers import thin_torus
from numba import njit

import pinnedballs as pb
from pinnedballs.engine.margin import (
    NEAR,
    MarginWarning,
    collided_speed,
    near_collision,
    near_remnant,
    remnant_speed,
    track,
)
from pinnedballs.rules import DEFAULT_RESOLUTION, collide_elastic
from pinnedballs.simulation import FreezeWarning


def _pair(v):
    """Two balls on a line (dim 1): contact 0 is (0, 1), t_0 = +1, t_1 = -1; closing speed v0 - v1."""
    return pb.Simulation(pb.GraphGeometry.from_positions([0.0, 2.0]), np.array(v, dtype=float)[:, None], seed=0)


def test_a_collision_is_measured_in_thresholds():
    sim = _pair([1.0, 0.0])  # E = 1/2, V = 1, threshold 4 * 2^-53
    sim.run(steps=3)
    m = sim.closing_margin()
    assert sim.collisions == 1
    assert m.threshold == 4 * 2.0**-53 and m.resolution == DEFAULT_RESOLUTION
    assert m.smallest_collision == 2.0**51  # w = 1 exactly
    assert (m.largest_remnant, m.near_collisions, m.near_remnants) == (None, 0, 0)
    assert not m.thin


def test_a_positive_closing_speed_below_the_threshold_is_a_remnant():
    sim = _pair([1.0, 1.0 - 2.0**-53])  # w = 2^-53, below 4 * 2^-53 * V (V about sqrt 2)
    sim.run(steps=1)
    m = sim.closing_margin()
    assert sim.collisions == 0
    assert m.smallest_collision is None and m.near_collisions == 0
    assert m.largest_remnant == pytest.approx(2.0**-53 / m.threshold, rel=1e-15)
    assert 1e-4 < m.largest_remnant < 1 and m.near_remnants == 1


def test_a_thin_run_says_so_once_where_it_ends_frozen():
    """The count until frozen is the observable: a run that ends frozen after a collision near the threshold
    says so once, in one line; the same pick run for its steps says nothing (`closing_margin` tells it)."""
    v = [1.0, 1.0 - 64 * 2.0**-53]  # w = 64 * 2^-53: about 11 thresholds
    for_steps = _pair(v)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for_steps.run(steps=1)
    m = for_steps.closing_margin()
    assert m.thin and m.near_collisions == 1 and m.smallest_collision == pytest.approx(64 / (4 * math.sqrt(2)))
    sim = _pair(v)
    with pytest.warns(MarginWarning, match=r"^the closing margin is thin \(smallest collision 11\.3 thresholds.*"
                                           r"arithmetic=\"exact\"") as said:
        assert sim.run_until_frozen(max_steps=10)
    assert len(said) == 1 and "\n" not in str(said[0].message) and sim.closing_margin() == m
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.run_until_frozen(max_steps=5)  # said once


def test_a_torus_says_nothing_of_its_thin_margin():
    """A torus never freezes, and every long run of one comes near the threshold: a run for its steps says
    nothing, and a run until frozen only that it never freezes (one line, the `FreezeWarning`)."""
    g, v = thin_torus()
    sim = pb.Simulation(g, v, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.run(steps=1000)
    assert sim.collisions > 0 and sim.closing_margin().thin
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert not pb.Simulation(g, v, seed=0).run_until_frozen(max_steps=1000)
    assert [w.category for w in caught] == [FreezeWarning]


def test_the_margin_of_the_paper_run():
    """The paper's 100x50 half-plane (seed 0): genuine collisions 10^7 thresholds above the criterion,
    remnants below a tenth of it: a wide margin, so the float count is the exact one (docs/collisions.md)."""
    half = pb.HalfPlane.from_size(100, 50)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.0, np.sqrt(200.0)]
    sim = pb.Simulation(half, v, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.run_until_frozen(max_steps=10**7)
    m = sim.closing_margin()
    assert m.smallest_collision > NEAR * 1000 and m.near_collisions == 0
    assert 0 < m.largest_remnant < 0.5 and m.near_remnants > 0


@pytest.mark.parametrize("value, message", [
    (0, "resolution: must be a number in (0, 1): a pick collides when its closing speed exceeds resolution * V "
        "(V the system's speed scale), got 0"),
    (1.0, "got 1.0"), (-1e-9, "got -1e-09"),
    (float("nan"), "resolution: must be a finite number, got nan"),
    ("1e-9", "resolution: must be a number, got '1e-9'"),
])
def test_bad_resolutions_are_refused_naming_the_field(value, message):
    with pytest.raises(ValueError, match="^" + message.replace("(", r"\(").replace(")", r"\)").replace("*", r"\*")
                       .replace(".", r"\.") if message.startswith("resolution") else message):
        pb.Simulation(pb.FlatTorus(4, 3), np.ones((12, 2)), resolution=value)


def _half_plane(**kwargs):
    half = pb.HalfPlane.from_size(60, 30)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.3, np.sqrt(200.0)]
    sim = pb.Simulation(half, v, seed=4, **kwargs)
    sim.run_until_frozen(max_steps=10**7)
    return sim


def test_the_default_resolution_is_four_units_in_the_last_place_of_the_speed_scale():
    default, explicit = _half_plane(), _half_plane(resolution=4 * 2.0**-53)
    assert (default.steps, default.collisions) == (explicit.steps, explicit.collisions)
    np.testing.assert_array_equal(default.velocities, explicit.velocities)
    assert default.threshold == pytest.approx(4 * 2.0**-53 * math.sqrt(200.09), rel=1e-15)  # V = sqrt(2E/m)


def test_a_coarser_resolution_is_a_model_of_its_own():
    """N_e with e = 1e-6: picks closing below 1e-6 V are set aside; a chosen resolution is the model,
    so its run does not warn that its count depends on it."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        coarse = _half_plane(resolution=1e-6)
    m = coarse.closing_margin()
    assert coarse.resolution == 1e-6 and coarse.threshold == pytest.approx(1e-6 * math.sqrt(200.09), rel=1e-15)
    assert m.smallest_collision > 1
    assert coarse.is_frozen()  # frozen for this criterion: no pick closes faster than 1e-6 V


def test_the_parallel_sweep_keeps_the_margin_of_the_sequential_loop():
    """ColoredSweep's plain steps (its own parallel loop) and its limited loop (sequential) try the same
    contacts: the same margin."""
    torus = pb.FlatTorus(10, 10)
    v = np.random.default_rng(1).normal(size=(torus.n_balls, 2))
    a = pb.Simulation(torus, v, scheduler=pb.ColoredSweep(), seed=1)
    b = pb.Simulation(torus, v, scheduler=pb.ColoredSweep(), seed=1)
    a.run(steps=20_000)
    b.run(steps=20_000, collisions=10**9)
    assert a.collisions == b.collisions
    assert a.closing_margin() == b.closing_margin()


def test_a_tracking_scheduler_keeps_the_margin():
    torus = pb.FlatTorus(10, 10)
    v = np.random.default_rng(2).normal(size=(torus.n_balls, 2))
    sim = pb.Simulation(torus, v, scheduler=pb.RejectionFree(), seed=1)
    sim.run(steps=5000)
    m = sim.closing_margin()
    assert sim.collisions > 0 and m.smallest_collision > 1


def test_the_margin_ends_with_the_run_however_it_is_split():
    """A run until frozen ends right after its last collision, and so does its margin: picks the loop
    tried past that collision before it found the freeze (and rewound) are not part of it, so a run
    split into calls at any steps has the margin of one call."""
    whole = _half_plane()
    half = pb.HalfPlane.from_size(60, 30)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.3, np.sqrt(200.0)]
    split = pb.Simulation(half, v, seed=4)
    for steps in (1, 999, 7777, 20000, 3):
        split.run(steps=steps)
    split.run_until_frozen(max_steps=10**7)
    assert (split.steps, split.collisions) == (whole.steps, whole.collisions)
    np.testing.assert_array_equal(split.engine.state.margin, whole.engine.state.margin)


def test_picks_tried_past_the_last_collision_are_not_in_the_margin():
    """Four balls on a line: the first two close at 2^-55 (a sixteenth of the threshold: a remnant for
    good), the last two collide once. The loop tries thousands of picks past that collision before its
    scan finds the freeze; the run, and its margin, end at the collision: no pick past it is counted."""
    line = pb.GraphGeometry.from_positions([0.0, 2.0, 4.0, 6.0])
    v = np.array([[2.0**-55], [0.0], [1.0], [0.0]])
    whole = pb.Simulation(line, v, seed=3)
    assert whole.run_until_frozen(max_steps=10**6)
    m = whole.closing_margin()
    assert (whole.steps, whole.collisions) == (9, 1)  # contact 2 first picked at step 9
    assert m.largest_remnant == pytest.approx(1 / 16) and m.near_remnants == 5  # contact 0 among the first 8
    split = pb.Simulation(line, v, seed=3)
    split.run(steps=4)
    split.run_until_frozen(max_steps=10**6)
    assert (split.steps, split.collisions) == (whole.steps, whole.collisions)
    np.testing.assert_array_equal(split.engine.state.margin, whole.engine.state.margin)


@njit
def collide_mine(v, units, i, j, a, b, masses, params, dim, flat, write):
    """A user's rule: the paper's exchange, which exact arithmetic does not know as the user's."""
    return collide_elastic(v, units, i, j, a, b, masses, params, dim, flat, write)


class MyRule(pb.CollisionRule):
    def kernel(self, equal_masses: bool):
        return collide_mine, np.ones(1)


def test_the_warning_is_about_the_callers_line_and_its_advice_applies():
    """The line that ran the simulation is where the warning points (not the run driver inside the package),
    and a rule without an exact form is not told to count exactly (it cannot: arithmetic="exact" refuses it)."""
    v = [1.0, 1.0 - 64 * 2.0**-53]
    with pytest.warns(MarginWarning) as built_in:
        _pair(v).run_until_frozen(max_steps=10)
    with pytest.warns(MarginWarning) as mine:
        pb.Simulation(pb.GraphGeometry.from_positions([0.0, 2.0]), np.array(v)[:, None], rule=MyRule(),
                      seed=0).run(collisions=5)  # until frozen, which comes first
    for record in (built_in, mine):
        assert len(record) == 1 and record[0].filename == __file__
    assert 'arithmetic="exact"' in str(built_in[0].message)
    said = str(mine[0].message)
    assert 'arithmetic="exact"' not in said and "give resolution= to make the criterion part of the model" in said


def test_the_reductions_are_track_one_number_at_a_time():
    """The parallel sweep keeps the margin as four reductions (`collided_speed`, `remnant_speed`, `near_collision`,
    `near_remnant`); over every kind of pick (a collision far from the threshold and near it, a remnant near it
    and far below it, a separating pair, an exact zero) in any order they give `track`'s four numbers."""
    tau = 1e-15
    picks = [(True, 3.0), (True, 5e-12), (False, 0.9e-15), (False, 1e-20), (False, -2.0), (False, 0.0),
             (True, 7e-16 * 1e4), (False, 3e-21)]
    for order in (picks, picks[::-1], picks[3:] + picks[:3]):
        m = (np.inf, 0.0, 0.0, 0.0)
        r = [np.inf, 0.0, 0.0, 0.0]
        for hit, w in order:
            m = track(hit, w, tau, *m)
            r[0] = min(r[0], collided_speed(hit, w))
            r[1] = max(r[1], remnant_speed(hit, w))
            r[2] += near_collision(hit, w, tau)
            r[3] += near_remnant(hit, w, tau)
        assert tuple(m) == tuple(r) and r[2] == 2 and r[3] == 1, (m, r)
