"""The field backend's door: velocities set on an exact or certified simulation are the ones it runs from."""

from __future__ import annotations

import numpy as np
import pytest
from gmpy2 import mpq

import pinnedballs as pb


@pytest.mark.parametrize("arithmetic", ["exact", "certified"])
def test_velocities_set_on_an_exact_simulation_are_the_ones_it_runs_from(arithmetic):
    """Set mid-run, they read back exactly, the run goes on from them with the energy they carry (to the last
    bit in exact arithmetic, the floats read back within 1e-12). Before, the setting was dropped: the chain ran on
    from its own velocities, and those read back were its."""
    g = pb.HalfPlane.from_size(40, 20)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = (0.0, 1.0)
    sim = pb.Simulation(g, v, seed=3, arithmetic=arithmetic)
    sim.run(3_000)
    new = sim.velocities.copy()
    new[:3] = (0.25, 0.5)  # three balls at rest set moving (in Q, where x had been in sqrt(3) Q)
    energy = float(np.sum(new**2))
    sim.velocities = new
    assert np.array_equal(sim.velocities, new)
    before = sim.collisions
    sim.run(2_000)
    assert sim.collisions > before
    assert abs(float(np.sum(sim.velocities**2)) - energy) <= 1e-12 * energy
    assert sim.engine.state.field_chain.X[:3].any()


def test_velocities_that_the_energy_cannot_hold_are_refused_by_a_certified_simulation():
    g = pb.HalfPlane.from_size(20, 10)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = (0.0, 1.0)
    sim = pb.Simulation(g, v, seed=1, arithmetic="certified")
    with pytest.raises(ValueError, match="larger than the energy"):
        sim.velocities = v * 1e6


def test_the_velocities_read_back_set_again_leave_the_exact_ones_as_they_are():
    """Reading the velocities and setting them again (the floats they round to) does not round the exact state:
    a ball at 1 + 2^-80, which no float holds, stays there."""
    g = pb.HalfPlane.from_size(20, 10)
    sim = pb.Simulation(g, np.zeros((g.n_balls, 2)), seed=3, arithmetic="exact")
    chain = sim.engine.state.field_chain
    fine = mpq(2**80 + 1, 2**80)
    chain.set_velocities([[(fine, mpq(0)), (mpq(0), mpq(0))]] + [[(mpq(0), mpq(0))] * 2] * (g.n_balls - 1))
    exact = chain.coefficients().copy()
    assert sim.velocities[0, 0] == 1.0
    sim.velocities = sim.velocities
    assert np.array_equal(chain.coefficients(), exact) and mpq(exact[0, 0, 0]) == fine
