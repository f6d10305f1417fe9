"""Which limit ends a run: steps, a collision total, or the freeze."""

import numpy as np
import pytest

import pinnedballs as pb


def _half_plane(seed=0):
    half = pb.HalfPlane(rows=6, cols=9)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.0, np.sqrt(200.0)]
    return pb.Simulation(half, v, seed=seed)


@pytest.fixture(scope="module")
def frozen_at():
    """(steps, collisions) of the exact freeze of the reference run."""
    sim = _half_plane()
    assert sim.run_until_frozen(max_steps=10**7)
    return sim.steps, sim.collisions, sim.velocities.copy()


def test_until_frozen_stops_at_the_same_step_as_run_until_frozen(frozen_at):
    steps, collisions, velocities = frozen_at
    sim = _half_plane()
    sim.run(steps=10 * steps, collisions=collisions + 1000, until_frozen=True)
    assert (sim.steps, sim.collisions) == (steps, collisions)
    np.testing.assert_array_equal(sim.velocities, velocities)


def test_collisions_alone_stop_at_the_freeze_when_the_target_is_out_of_reach(frozen_at):
    steps, collisions, _ = frozen_at
    sim = _half_plane()
    sim.run(collisions=collisions + 1)
    assert (sim.steps, sim.collisions) == (steps, collisions)
    assert sim.is_frozen()


def test_a_collision_target_stops_on_the_collision_itself(frozen_at):
    _, collisions, _ = frozen_at
    sim = _half_plane()
    sim.run(steps=10**7, collisions=collisions // 2)
    assert sim.collisions == collisions // 2
    one_short = _half_plane()
    one_short.run(steps=sim.steps - 1)  # the last step taken was the target collision
    assert one_short.collisions == collisions // 2 - 1


def test_steps_bound_a_frozen_system_that_keeps_picking(frozen_at):
    steps, collisions, velocities = frozen_at
    sim = _half_plane()
    sim.run_until_frozen(max_steps=10**7)
    sim.run(steps=12345)
    assert (sim.steps, sim.collisions) == (steps + 12345, collisions)
    np.testing.assert_array_equal(sim.velocities, velocities)


@pytest.mark.parametrize("kwargs, message", [
    ({}, "run: give steps= or collisions="),
    ({"steps": -1}, r"steps: must be an integer >= 0 and < 2\*\*63, got -1"),
    ({"collisions": -5}, r"collisions: must be an integer >= 0 and < 2\*\*63, got -5"),
    ({"steps": 2**63}, r"steps: must be an integer >= 0 and < 2\*\*63, got 9223372036854775808"),
    ({"steps": 2**64 + 5}, r"steps: must be an integer >= 0 and < 2\*\*63, got 18446744073709551621"),
])
def test_bad_limits(kwargs, message):
    with pytest.raises(ValueError, match=message):
        _half_plane().run(**kwargs)


def test_steps_must_be_an_integer():
    with pytest.raises(TypeError, match="steps: must be an integer, got 1.5"):
        _half_plane().run(steps=1.5)


def test_a_step_cap_near_the_int64_limit_never_wraps_the_counter(frozen_at):
    steps, collisions, _ = frozen_at
    sim = _half_plane()
    sim.run_until_frozen(max_steps=2**63 - 1)
    assert (sim.steps, sim.collisions) == (steps, collisions)
    sim.set_state(sim.get_state().replace(steps=2**63 - 10))
    sim.run(steps=2**63 - 1)  # only 9 steps are left before the counter would wrap
    assert sim.steps == 2**63 - 1
