"""RejectionFree: the paper's chain without its rejected picks has the paper's law.

Bit-level agreement with its plain-Python twin is in `test_kernel_vs_reference.py`; here
are the facts of the law: the geometric number of picks, and two-sample tests against
`UniformRandomPair` on steps, collisions and the final energy profile until frozen.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import HALF_PLANE, spec
from numba import njit
from scipy import stats

import pinnedballs as pb
from pinnedballs.engine.streams.xoshiro import load, seed_state, store
from pinnedballs.schedulers.rejection_free import picks_until_live
from pinnedballs.specs import parse_spec

P_MIN = 1e-3  # fixed seeds, so deterministic; the threshold only says "not absurd"


@njit
def _draws(words, n_live, n_contacts, count):
    rng, out = load(words), np.empty(count)
    for m in range(count):
        out[m], rng = picks_until_live(rng, n_live, n_contacts)
    store(words, rng)
    return out


def draws(n_live: int, n_contacts: int, count: int, seed: int = 1) -> np.ndarray:
    """``count`` draws of the engine's geometric number of picks."""
    return _draws(seed_state(seed), n_live, n_contacts, count)


def test_picks_until_live_is_geometric():
    """20,000 draws with p = 3/10: chi-square against P(G = g) = (1 - p)^(g-1) p, g = 1..15 and a tail."""
    g = draws(3, 10, 20_000)
    assert (g >= 1).all() and np.array_equal(g, np.floor(g))
    p, top = 0.3, 16
    expected = np.array([(1 - p) ** (k - 1) * p for k in range(1, top)] + [(1 - p) ** (top - 1)]) * len(g)
    observed = np.bincount(np.minimum(g, top).astype(int), minlength=top + 1)[1:]
    assert stats.chisquare(observed, expected).pvalue > P_MIN


def test_picks_until_live_with_every_contact_live_is_one_and_draws_nothing():
    words = seed_state(4)
    before = words.copy()
    assert np.array_equal(_draws(words, 7, 7, 100), np.ones(100))
    assert np.array_equal(words, before)


def test_picks_until_live_with_one_live_contact_in_a_huge_system():
    """p = 1e-15: the mean of 4,000 draws is 1e15 (within 4 standard errors), every draw a finite
    integer, none overflowing int64 (at most ln(2^53) / p = 3.7e16)."""
    g = draws(1, 10**15, 4000, seed=9)
    assert np.isfinite(g).all() and g.max() < 3.7e16 and (g >= 1).all()
    assert abs(g.mean() - 1e15) < 4 * 1e15 / np.sqrt(len(g))


def small_half_plane():
    geom = pb.HalfPlane(rows=3, cols=4)
    v = np.zeros((geom.n_balls, 2))
    v[1] = [0.3, 1.0]  # a boundary ball moving into the others
    return geom, v


def until_frozen(scheduler, seeds):
    geom, v = small_half_plane()
    rows = np.round(geom.boundary_distance(), 9)
    steps, collisions, boundary_share = [], [], []
    for seed in seeds:
        sim = pb.Simulation(geom, v, scheduler=scheduler, seed=seed)
        assert sim.run_until_frozen(max_steps=10**7)
        e = 0.5 * np.einsum("ij,ij->i", sim.velocities, sim.velocities)
        steps.append(sim.steps)
        collisions.append(sim.collisions)
        boundary_share.append(e[rows == rows.min()].sum() / e.sum())
    return np.array(steps), np.array(collisions), np.array(boundary_share)


def test_same_law_as_the_papers_chain_until_frozen():
    """600 runs each on a 12-ball half-plane: two-sample Kolmogorov-Smirnov tests find no
    difference in steps, collisions or the boundary row's final share of the energy; and the
    runs are not trivial (steps vary over a wide range)."""
    a = until_frozen(pb.UniformRandomPair(), range(600))
    b = until_frozen(pb.RejectionFree(), range(1000, 1600))
    for name, x, y in zip(["steps", "collisions", "boundary share"], a, b):
        assert stats.ks_2samp(x, y).pvalue > P_MIN, name
    assert a[0].std() > 10 and len(np.unique(a[1])) > 5


def test_a_shifted_law_would_be_caught():
    """The test above has power: counting only collisions as steps is rejected at once."""
    a_steps, a_coll, _ = until_frozen(pb.UniformRandomPair(), range(200))
    assert stats.ks_2samp(a_steps, a_coll).pvalue < 1e-6


def test_run_ends_at_exactly_the_steps_asked_and_frozen_systems_take_them_all():
    geom, v = small_half_plane()
    sim = pb.Simulation(geom, v, scheduler=pb.RejectionFree(), seed=3)
    for n in [1, 2, 5, 1000, 10**6]:
        before = sim.steps
        assert sim.run(steps=n) == n and sim.steps == before + n
    assert sim.is_frozen()
    rng = sim.get_state().rng_state
    assert sim.run(steps=10**15) == 10**15  # no live contact: the chain picks on, drawing nothing
    assert np.array_equal(sim.get_state().rng_state, rng)
    assert sim.run_until_frozen(max_steps=0)  # already frozen: True without a step


def test_energy_conserved_and_momentum_kept_on_a_torus():
    torus = pb.FlatTorus(rows=20, cols=20)
    v = np.random.default_rng(2).normal(size=(torus.n_balls, 2))
    sim = pb.Simulation(torus, v, scheduler=pb.RejectionFree(), seed=2)
    e0, p0 = sim.energy(), sim.momentum()
    sim.run(steps=200_000)
    assert sim.collisions > 40_000
    assert abs(sim.energy() - e0) < 1e-12 * e0
    np.testing.assert_allclose(sim.momentum(), p0, atol=1e-11 * np.sqrt(e0 * torus.n_balls))


def test_state_holds_the_live_array_and_is_checked():
    geom, v = small_half_plane()
    sim = pb.Simulation(geom, v, scheduler=pb.RejectionFree(), seed=3)
    sim.run(steps=20)
    state = sim.get_state()
    s = state.scheduler_state
    assert s.shape == (geom.n_contacts + 2,)
    assert sorted(s[2:2 + s[0]]) == list(np.flatnonzero(_live(sim)))
    other = pb.Simulation(geom, v, scheduler=pb.RejectionFree(), seed=99)
    other.set_state(state)
    sim.run(steps=500)
    other.run(steps=500)
    assert np.array_equal(sim.velocities, other.velocities) and sim.collisions == other.collisions

    bad = state.replace(scheduler_state=s.copy())
    bad.scheduler_state[2:2 + s[0]] = np.roll(np.arange(geom.n_contacts), 1)[:s[0]]
    with pytest.raises(ValueError, match=r"scheduler_state: its \d+ live contacts are not those of the velocities"):
        other.set_state(bad)
    bad = state.replace(scheduler_state=np.full(geom.n_contacts + 2, -1, dtype=np.int64))
    bad.scheduler_state[1] = 5
    with pytest.raises(ValueError, match=r"scheduler_state: the picks still to come must be in \[0, 2\*\*62\]"):
        other.set_state(bad)
    bad = state.replace(scheduler_state=np.zeros(3, dtype=np.int64))
    with pytest.raises(ValueError, match=r"scheduler_state: must have shape \(\d+,\) for RejectionFree\(\)"):
        other.set_state(bad)


def _live(sim) -> np.ndarray:
    """``(E,) bool``: contacts whose pick would change velocities (the twin's definition)."""
    from reference import ReferenceSimulation

    twin = ReferenceSimulation.from_geometry(sim.geometry, sim.velocities)
    return np.array([twin.live(k) for k in range(sim.geometry.n_contacts)])


def test_spec_kind_builds_it():
    sim = parse_spec(spec(HALF_PLANE, scheduler={"kind": "rejection_free"})).build()
    assert sim.scheduler == pb.RejectionFree()
