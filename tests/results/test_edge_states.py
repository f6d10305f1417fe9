"""Every run the engine completes loads: states at the edges of the floats (every velocity 0, subnormal,
tiny, huge), no contact approaching from the start, written by a run and read back whole."""

import numpy as np
import pytest

import pinnedballs as pb

HALF = pb.HalfPlane.from_size(20, 10)
PAIR = pb.GraphGeometry.from_positions(np.array([[0.0, 0.0], [2.0, 0.0]]))


@pytest.mark.parametrize("geometry, velocities", [
    (HALF, np.zeros((HALF.n_balls, 2))),                                           # nothing moves: threshold 0
    (HALF, np.full((HALF.n_balls, 2), 5e-324)),                                    # subnormal
    (HALF, np.random.default_rng(1).normal(size=(HALF.n_balls, 2)) * 1e-300),     # tiny: the threshold underflows
    (HALF, np.random.default_rng(2).normal(size=(HALF.n_balls, 2)) * 1e150),      # huge
    (PAIR, np.array([[-1.0, 0.0], [1.0, 0.0]])),                                   # receding: frozen from the start
], ids=["zero", "subnormal", "tiny", "huge", "receding pair"])
@pytest.mark.parametrize("scheduler", [pb.UniformRandomPair(), pb.RejectionFree()], ids=["uniform", "rejection-free"])
def test_an_edge_state_is_written_and_read_back(tmp_path, geometry, velocities, scheduler):
    sim = pb.Simulation(geometry, velocities, scheduler=scheduler, seed=3)
    writer = pb.ResultsWriter(tmp_path / "run", snapshots={"every_steps": 50})
    frozen = sim.run_until_frozen(max_steps=20_000, writers=[writer], progress=False)
    res = pb.load(tmp_path / "run")
    assert (res.steps, res.collisions, res.frozen) == (sim.steps, sim.collisions, frozen)
    np.testing.assert_array_equal(res.velocities, sim.velocities)
    assert res.closing_margin.threshold == sim.threshold >= 0.0
    again = res.simulation()
    np.testing.assert_array_equal(again.velocities, sim.velocities)
