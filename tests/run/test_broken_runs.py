"""A run stopped between two states (issue 42, item 9): a user's pick out of range raises from inside the compiled
loop, after the chunk's earlier picks moved the velocities and before its counters were counted. Such a state
cannot go on: the simulation says so, and the run directory keeps the last state it recorded whole, marked
failed with the error's words, which `--resume` and `Results` read as a failure, never as an interruption."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

import pinnedballs as pb
from pinnedballs.engine.streams.xoshiro import bounded


@njit(inline="always")
def pick_then_beyond(state, rng, n_contacts):
    """The paper's picks for 300 steps, then a contact that does not exist."""
    state[0] += 1
    if state[0] > 300:
        return np.uint64(n_contacts + 2), rng
    return bounded(rng, n_contacts)


class LateBeyond(pb.Scheduler):
    def kernel(self):
        return pick_then_beyond


def simulation() -> pb.Simulation:
    g = pb.HalfPlane.from_size(20, 10)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, 10.0]
    return pb.Simulation(g, v, scheduler=LateBeyond(), seed=3)


def test_a_pick_out_of_range_mid_chunk_leaves_a_failed_run_and_a_simulation_that_cannot_go_on(tmp_path):
    sound = simulation()
    sound.run(steps=300)  # the last snapshot (every 100 steps) before the pick out of range, at step 301
    sim = simulation()
    with pytest.raises(pb.FieldError, match=r"^scheduler: LateBeyond.kernel\(\)'s pick 'pick_then_beyond' picked "
                                            r"contact \d+, but there are \d+ contacts"):
        sim.run(steps=5000, writers=[pb.ResultsWriter(tmp_path / "r", snapshots={"every_steps": 100})])
    with pytest.raises(pb.FieldError, match=r"^simulation: cannot go on: it stopped between two states on "
                                            r"PickOutOfRange: scheduler: "):
        sim.run(steps=1)
    res = pb.load(tmp_path / "r")
    assert res.status == "failed" and "picked contact" in res.failure["message"]
    assert res.state().identical(sound.get_state())  # the last state recorded whole
    with pytest.raises(pb.InputError, match=r"^resume: the run in .* failed at step 300: scheduler: LateBeyond"):
        pb.ResultsWriter(tmp_path / "r", resume=True).attach(simulation())
