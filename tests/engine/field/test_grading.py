"""The grading of a state in Q(sqrt 3): the coefficients that stay 0, and the tables without their terms giving the
same run, bit for bit, as the full tables."""

from __future__ import annotations

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.field import fixed
from pinnedballs.engine.field.fixed import lines_of
from pinnedballs.engine.field.fixed_kernels import refresh_shadows
from pinnedballs.engine.field.grading import graded, parities


def half_plane(length: int = 60, depth: int = 30, velocity=(0.0, 1.0)):
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = velocity
    return g, v


def chain_after(g, v, steps: int, arithmetic: str = "certified", seed: int = 3):
    sim = pb.Simulation(g, v, seed=seed, arithmetic=arithmetic)
    sim.run(steps)
    return sim, sim.engine.state.field_chain


@pytest.mark.parametrize("velocity, parity", [((0.0, 1.0), [1, 0]), ((1.0, 0.0), [0, 1])])
def test_one_ball_moving_along_an_axis_of_the_triangular_lattice_grades_the_state(velocity, parity):
    """x in sqrt(3) Q and y in Q from (0, 1) (the reverse from (1, 0)), and a run keeps it: the other coefficient
    of every component is 0 after thousands of collisions; the closing speeds are of one kind on every line."""
    g, v = half_plane(velocity=velocity)
    sim, chain = chain_after(g, v, 20_000)
    assert sim.collisions > 1_000
    assert chain.tables.parity.tolist() == parity
    for d, p in enumerate(parity):
        assert not chain.X[:, d, 1 - p].any() and chain.X[:, d, p].any()
    t = chain.tables
    assert (t.wcount.min(axis=1) == 0).all()  # one coefficient of each line's closing speed dropped
    assert t.kcount.sum() * 2 == lines_of(g).tables.kcount.sum()  # half the exchange's coefficients


@pytest.mark.parametrize("arithmetic", ["certified", "exact"])
def test_the_graded_tables_run_the_chain_to_the_same_bits_as_the_full_ones(arithmetic, monkeypatch):
    """The terms dropped are exactly 0: the limbs, bounds, shadows, counts and margin are those of the full tables."""
    g, v = half_plane()
    sim, graded_chain = chain_after(g, v, 30_000, arithmetic)
    assert graded_chain.tables.parity.min() >= 0
    monkeypatch.setattr(fixed, "tables_for", lambda tables, X: tables)
    other, full = chain_after(g, v, 30_000, arithmetic)
    assert full.tables.parity.tolist() == [-1, -1]
    assert (sim.collisions, sim.steps) == (other.collisions, other.steps) and sim.collisions > 1_000
    for a, b in [(graded_chain.X, full.X), (graded_chain.rows, full.rows), (graded_chain.B, full.B),
                 (graded_chain.Pp, full.Pp), (graded_chain.margin, full.margin)]:
        assert np.array_equal(a, b)


def test_the_shadows_read_from_one_coefficient_are_those_read_from_both():
    g, v = half_plane()
    _, chain = chain_after(g, v, 20_000)
    rows = np.empty_like(chain.rows)
    refresh_shadows(chain.X, chain.T, chain.tables.root, rows, chain.B, chain.S, chain.tables.parity)
    full = np.empty_like(rows)
    refresh_shadows(chain.X, chain.T, chain.tables.root, full, chain.B, chain.S, np.full(2, -1, dtype=np.int64))
    assert np.array_equal(rows.view(np.uint64), full.view(np.uint64))


def _set_mixed_and_run(arithmetic: str):
    """A graded run whose velocities are then set to mix the kinds (three balls at rest given (0.25, 0.5)), run on."""
    g, v = half_plane()
    sim, chain = chain_after(g, v, 5_000, arithmetic)
    graded_before = chain.tables.parity.min() >= 0
    mixed = sim.velocities.copy()
    mixed[np.flatnonzero(np.abs(mixed).sum(axis=1) == 0)[:3]] = (0.25, 0.5)
    sim.velocities = mixed
    sim.run(10_000)
    chain = sim.engine.state.field_chain
    return sim, graded_before, chain.tables is chain._ungraded


def test_a_state_that_is_not_graded_keeps_the_full_tables_and_a_new_one_is_graded_anew(monkeypatch):
    """A ball moving off the axes mixes the kinds (no grading); velocities set on a graded chain that break its
    grading give the full tables back (else a dropped term would be a lost one): the run goes on as the full
    tables' and exact arithmetic's, collision for collision."""
    g, v = half_plane(velocity=(0.6, 0.8))
    _, chain = chain_after(g, v, 5_000)
    assert chain.tables.parity.tolist() == [-1, -1] and chain.tables is chain._ungraded
    sim, graded_before, ungraded_after = _set_mixed_and_run("certified")
    assert graded_before and ungraded_after
    exact, _, _ = _set_mixed_and_run("exact")
    monkeypatch.setattr(fixed, "tables_for", lambda tables, X: tables)
    full, _, _ = _set_mixed_and_run("certified")
    assert sim.collisions == full.collisions == exact.collisions and sim.collisions > 1_000
    assert np.array_equal(sim.velocities, full.velocities) and np.array_equal(sim.velocities, exact.velocities)


def test_the_square_lattice_and_a_line_of_both_kinds_have_no_grading():
    square = lines_of(pb.FlatTorus(4, 4)).tables
    assert parities(square, np.zeros((16, 2, 1, 2), dtype=np.uint64)) is None
    t = lines_of(pb.HalfPlane.from_size(10, 5)).tables
    X = np.zeros((t.pairs.max() + 1, 2, 2, 2), dtype=np.uint64)
    assert parities(t, X).tolist() == [0, 1]  # all at rest: the first parity that fits the lines
    X[0, 0, 0], X[0, 0, 1] = 1, 1  # a component with both kinds
    assert parities(t, X) is None
    g = graded(t, np.array([1, 0]))
    assert g.parity.tolist() == [1, 0] and t.parity.tolist() == [-1, -1]
    assert g.wcount.sum() * 2 == t.wcount.sum()  # half of each closing speed's terms read zeros
