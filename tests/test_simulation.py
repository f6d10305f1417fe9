"""`Simulation`: conservation over long runs, termination of finite systems,
determinism, checkpoints, and refusal of bad input.

Tolerances are stated where used: energies relative to the total energy,
momenta relative to ``sqrt(2 E M)`` (the largest momentum the energy allows),
closing speeds relative to the largest speed.
"""

from __future__ import annotations

import math
import warnings

import networkx as nx
import numpy as np
import pytest
from helpers import (
    SLOWER,
    closing_speeds,
    energy,
    icosahedron_sphere,
    momentum,
    random_state,
    rule_kind,
    schedulers_for,
    stated_units,
    tangent_velocities,
)
from hypothesis import assume, given
from hypothesis import strategies as st
from reference import ReferenceSimulation
from scipy import stats

import pinnedballs as pb
from pinnedballs.simulation import FreezeWarning

SCHEDULERS = [pb.UniformRandomPair, pb.Sweep, pb.RandomSweep]


def paper_torus(rows=38, cols=38):
    """The paper's torus: one ball moving with energy 100, all others at rest."""
    g = pb.FlatTorus(rows=rows, cols=cols)
    v = np.zeros((g.n_balls, 2))
    v[0] = [math.sqrt(200.0), 0.0]
    return g, v


def paper_half_plane(length, depth):
    """The paper's half-plane: the middle boundary ball moves into the balls with energy 100."""
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, math.sqrt(200.0)]
    return g, v


def assert_frozen(geom, v):
    """No contact approaches, by numpy (a different summation order, hence a rounding tolerance)."""
    w = closing_speeds(geom, v)
    scale = float(np.max(np.abs(v))) if v.size else 0.0
    assert np.all(w <= 1e-12 * scale), f"approaching contacts: {np.flatnonzero(w > 1e-12 * scale)}"


# ---------------------------------------------------------------- long runs


def test_torus_long_elastic_run_conserves_energy_and_momentum():
    """38 x 38 torus, 5e6 steps (about 2.3e6 collisions): relative energy error < 1e-10,
    momentum error < 1e-9 sqrt(2 E M)."""
    g, v = paper_torus()
    sim = pb.Simulation(g, v, seed=1)
    e0, p0 = sim.energy(), sim.momentum()
    sim.run(steps=5_000_000)
    assert sim.steps == 5_000_000 and sim.collisions > 10**6
    assert abs(sim.energy() - e0) < 1e-10 * e0
    assert np.max(np.abs(sim.momentum() - p0)) < 1e-9 * math.sqrt(2 * e0 * g.n_balls)
    assert sim.energy() == pytest.approx(energy(sim.velocities), rel=1e-14)
    np.testing.assert_allclose(sim.momentum(), momentum(sim.velocities), atol=1e-12)


def test_torus_reaches_equipartition():
    """Paper figure 6: after many collisions the components look i.i.d. normal with variance E/N each."""
    g, v = paper_torus()
    sim = pb.Simulation(g, v, seed=2)
    sim.run(steps=5_000_000)
    u = sim.velocities - sim.momentum() / g.n_balls
    expected = 100.0 / g.n_balls  # E = (1/2) sum |v|^2 = N var_x (two components)
    assert u[:, 0].var() == pytest.approx(expected, rel=0.15)
    assert u[:, 1].var() == pytest.approx(expected, rel=0.15)
    assert stats.normaltest(u.ravel()).pvalue > 1e-3
    assert abs(np.corrcoef(u[:, 0], u[:, 1])[0, 1]) < 0.1


def test_torus_unequal_masses_conserve_energy_and_momentum():
    g = pb.FlatTorus(rows=20, cols=20)
    v, m = random_state(g, seed=8, unequal_masses=True)
    sim = pb.Simulation(g, v, masses=m, seed=8)
    e0, p0 = sim.energy(), sim.momentum()
    assert e0 == pytest.approx(energy(v, m), rel=1e-14)
    for _ in range(4):
        sim.run(steps=500_000)
        assert abs(sim.energy() - e0) < 1e-10 * e0
        assert np.max(np.abs(sim.momentum() - p0)) < 1e-9 * math.sqrt(2 * e0 * m.sum())


@pytest.mark.parametrize("scheduler", [cls() for cls in SCHEDULERS], ids=lambda s: type(s).__name__)
def test_restitution_loses_energy_keeps_momentum(scheduler):
    g = pb.FlatTorus(rows=10, cols=10)
    v, m = random_state(g, seed=9, unequal_masses=True)
    sim = pb.Simulation(g, v, rule=pb.Restitution(0.8), scheduler=scheduler, masses=m, seed=9)
    e, p0 = sim.energy(), sim.momentum()
    scale = math.sqrt(2 * e * m.sum())
    for _ in range(10):
        sim.run(steps=3000)
        assert sim.energy() <= e * (1 + 1e-12)
        e = sim.energy()
        assert np.max(np.abs(sim.momentum() - p0)) < 1e-10 * scale
    assert e < 0.5 * energy(v, m)  # it really dissipates


def test_sphere_conserves_energy_but_not_momentum():
    """Balls on a sphere (icosahedron, tangent velocities, unequal masses): t_j != -t_i, energy is
    still conserved to 1e-10 relative over 1e6 steps; the sum of momentum vectors is not."""
    g = icosahedron_sphere()
    v = tangent_velocities(g, seed=3)
    m = np.random.default_rng(3).uniform(0.5, 2.0, g.n_balls)
    sim = pb.Simulation(g, v, masses=m, seed=3)
    sim.run(steps=1_000_000)
    assert sim.collisions > 1000
    assert abs(sim.energy() - energy(v, m)) < 1e-10 * energy(v, m)
    assert np.max(np.abs(sim.momentum() - m @ v)) > 1e-3


def test_sweep_schedulers_also_conserve_energy():
    for cls in (pb.Sweep, pb.RandomSweep):
        g, v = paper_torus(rows=12, cols=12)
        sim = pb.Simulation(g, v, scheduler=cls(), seed=0)
        sim.run(steps=400_000)
        assert sim.collisions > 1000
        assert abs(sim.energy() - 100.0) < 1e-10 * 100.0


# ---------------------------------------------------------------- finite systems freeze


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_paper_half_plane_freezes_with_a_third_of_the_energy_on_the_boundary(seed):
    """Paper figure 3 (60 x 30): the run ends frozen, energy conserved; roughly 30 % of the energy
    ends in the boundary row, pointing outward (away from the balls)."""
    g, v = paper_half_plane(60, 30)
    sim = pb.Simulation(g, v, seed=seed)
    assert sim.run_until_frozen(max_steps=10**7)
    assert sim.is_frozen() and sim.approaching() == 0
    assert_frozen(g, sim.velocities)
    assert sim.energy() == pytest.approx(100.0, rel=1e-12)
    boundary = g.boundary_distance() == 0
    e = 0.5 * np.sum(sim.velocities**2, axis=1)
    assert 0.15 < e[boundary].sum() / 100.0 < 0.5
    outward = boundary & (sim.velocities[:, 1] < 0)
    assert e[outward].sum() >= 0.99 * e[boundary].sum()


@st.composite
def random_contact_graph(draw):
    """A random connected graph of 2..10 balls in R^d with random velocities (and maybe masses)."""
    n = draw(st.integers(2, 10))
    d = draw(st.sampled_from([1, 2, 3]))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-5, 5, (n, d))
    g = nx.Graph()
    for k in range(n):
        g.add_node(k, pos=tuple(pos[k]))
    for k in range(1, n):  # a random spanning tree keeps it connected
        g.add_edge(k, draw(st.integers(0, k - 1)))
    extra = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=2 * n))
    g.add_edges_from((a, b) for a, b in extra if a != b)
    geom = pb.GraphGeometry(stated_units(g))
    v = rng.standard_normal((n, d)) * draw(st.sampled_from([1e-3, 1.0, 1e3]))
    v[rng.random(n) < draw(st.floats(0, 0.8))] = 0.0  # some balls at rest
    masses = rng.uniform(0.1, 10, n) if draw(st.booleans()) else None
    r = draw(st.one_of(st.just(1.0), st.floats(0.1, 1.0)))
    scheduler = draw(st.sampled_from(schedulers_for(d, True, rule_kind(r, masses is not None), limited=True)))
    return geom, v, masses, r, scheduler, seed % 1000


@st.composite
def random_lattice_cluster(draw):
    """Random points of a triangular lattice (found by `from_positions`), random velocities."""
    k = draw(st.integers(2, 7))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    r, c = np.divmod(np.arange(k * k), k)
    p = np.column_stack([2.0 * c + (r % 2), math.sqrt(3) * r])[rng.random(k * k) < 0.7]
    assume(len(p) >= 2)
    geom = pb.GraphGeometry.from_positions(p)
    assume(geom.n_contacts > 0)
    v = rng.standard_normal((geom.n_balls, 2))
    scheduler = draw(st.sampled_from(schedulers_for(2, True, "exchange", limited=True)))
    return geom, v, None, 1.0, scheduler, seed % 1000


SCHEDULER_BY_NAME = {"uniform": pb.UniformRandomPair, "sweep": pb.Sweep, "random_sweep": pb.RandomSweep}


def check_run_until_frozen(case):
    geom, v, masses, r, sched, seed = case
    rule = pb.Elastic() if r == 1.0 else pb.Restitution(r)
    sim = pb.Simulation(geom, v, rule=rule, scheduler=SCHEDULER_BY_NAME[sched](), masses=masses, seed=seed)
    frozen = sim.run_until_frozen(max_steps=2_000_000)
    assert frozen
    assert_frozen(geom, sim.velocities)
    e0 = energy(v, masses)
    if r == 1.0:
        assert sim.energy() == pytest.approx(e0, rel=1e-10, abs=1e-300)
    else:
        assert sim.energy() <= e0 * (1 + 1e-12)
    # the twin stops at the same step: right after the last collision
    if sim.steps <= 50_000:
        twin = ReferenceSimulation.from_geometry(geom, v, r=r, masses=masses, scheduler=sched, seed=seed)
        assert twin.run_until_frozen(max_steps=2_000_000)
        assert (twin.steps, twin.collisions) == (sim.steps, sim.collisions)
        assert sim.steps == (twin.collision_steps[-1] if twin.collision_steps else 0)
        assert np.array_equal(twin.velocities, sim.velocities)
    # frozen is final: more steps change nothing
    before = sim.velocities.copy()
    sim.run(steps=1000)
    assert np.array_equal(sim.velocities, before) and sim.is_frozen()


@SLOWER
@given(random_contact_graph())
def test_random_graphs_freeze_and_stop_at_the_last_collision(case):
    check_run_until_frozen(case)


@SLOWER
@given(random_lattice_cluster())
def test_random_lattice_clusters_freeze_and_stop_at_the_last_collision(case):
    check_run_until_frozen(case)


def test_perfectly_inelastic_random_graph_freezes():
    """Restitution(0) is allowed (r in [0, 1]) and finite systems must freeze. After an r = 0
    collision the exact closing speed is 0, the computed one can be +1 ulp-ish; if the resulting
    correction is below an ulp of the velocities, nothing changes, the pair still "approaches",
    and every later pick of it counts a collision that changes no velocity: never frozen."""
    rng = np.random.default_rng(0)
    g = nx.connected_watts_strogatz_graph(12, 4, 0.5, seed=0)
    for u in g:
        g.nodes[u]["pos"] = tuple(rng.normal(size=2))
    geom = pb.GraphGeometry(stated_units(g))
    v = rng.normal(size=(geom.n_balls, 2))
    sim = pb.Simulation(geom, v, rule=pb.Restitution(0.0), scheduler=pb.RandomSweep(), seed=0)
    frozen = sim.run_until_frozen(max_steps=200_000)
    before = (sim.velocities.copy(), sim.collisions)
    sim.run(steps=5000)
    unchanged = np.array_equal(sim.velocities, before[0])
    assert not (unchanged and sim.collisions > before[1]), (
        f"{sim.collisions - before[1]} 'collisions' in 5000 steps changed no velocity")
    assert frozen, f"not frozen after {sim.steps} steps, {sim.collisions} collisions"


def test_run_until_frozen_returns_a_python_bool():
    g, v = paper_half_plane(10, 5)
    sim = pb.Simulation(g, v, seed=0)
    assert sim.run_until_frozen(max_steps=10**6) is True
    t = pb.Simulation(*paper_torus(rows=4, cols=3), seed=0)
    with pytest.warns(FreezeWarning):
        assert t.run_until_frozen(max_steps=100) is False  # a torus never freezes
    assert t.steps == 100


def freeze_notes(sim, max_steps: int) -> tuple[bool, list[str]]:
    """``sim.run_until_frozen(max_steps)`` and the `FreezeWarning` messages it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        frozen = sim.run_until_frozen(max_steps=max_steps, progress=False)
    return frozen, [str(w.message) for w in caught if issubclass(w.category, FreezeWarning)]


@pytest.mark.parametrize("rule, arithmetic, why", [
    (pb.Elastic(), "float", "only equal velocities are frozen, and elastic collisions keep the energy above theirs"),
    (pb.Elastic(), "exact", "in exact arithmetic each collision leaves its contact separating"),
    (pb.Restitution(0.5), "exact", "in exact arithmetic each collision leaves its contact separating")])
def test_a_torus_that_cannot_freeze_says_so_in_one_line(rule, arithmetic, why):
    """Issue 34, item 6: on a flat torus run_until_frozen ran its 10^8 steps and returned False, silently.
    Every contact lies on a closed row whose closing speeds sum to 0, so frozen means all 0: equal
    velocities. Elastic collisions keep the energy above theirs; in exact arithmetic any r > 0 leaves
    each collided contact separating. At its step cap it now says so, in one line. (A geometry of
    one's own with closed rows is not known to be rigid: in float64 it gives no note.)"""
    g = pb.FlatTorus(4, 4)
    sim = pb.Simulation(g, np.random.default_rng(0).normal(size=(16, 2)), rule=rule, arithmetic=arithmetic, seed=1)
    assert freeze_notes(sim, 0) == (False, [])  # a call of no steps (to compile) says nothing
    frozen, notes = freeze_notes(sim, 2000)
    assert not frozen and len(notes) == 1 and "\n" not in notes[0]
    assert notes[0].startswith("run_until_frozen: not frozen after 2,000 steps, and never will be: on a torus ")
    assert why in notes[0] and notes[0].endswith("; use run(steps=...)")


def test_systems_that_can_freeze_give_no_note():
    """A half-plane freezes (and says nothing at its step cap either); with r < 1 in float64 a torus
    freezes when rounding leaves its velocities equal; a torus started with one common velocity is
    frozen; a resolution of one's own, or in float64 a torus of one's own (not known to be rigid), is
    not certain never to freeze."""
    g, v = paper_half_plane(10, 5)
    assert freeze_notes(pb.Simulation(g, v, seed=0), 10**6) == (True, [])
    assert freeze_notes(pb.Simulation(g, v, seed=0), 3) == (False, [])
    t = pb.FlatTorus(4, 4)
    v = np.random.default_rng(0).normal(size=(16, 2))
    lossy = pb.Simulation(t, v, rule=pb.Restitution(0.5), seed=1)
    assert freeze_notes(lossy, 10) == (False, [])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its margin is thin: not this test's business
        assert lossy.run_until_frozen(max_steps=10**5, progress=False)
    assert np.ptp(lossy.velocities, axis=0).max() < 1e-12
    assert freeze_notes(pb.Simulation(t, np.tile([0.25, -1.0], (16, 1))), 10) == (True, [])
    assert freeze_notes(pb.Simulation(t, v, resolution=1e-3, seed=1), 10) == (False, [])
    own = pb.GraphGeometry(t.contact_graph())  # closed rows, but not known to be rigid
    assert own.contacts.closed_rows and freeze_notes(pb.Simulation(own, v, seed=1), 10) == (False, [])


def test_run_until_frozen_on_a_frozen_system_takes_no_step():
    g = pb.HalfPlane(rows=3, cols=3)
    sim = pb.Simulation(g, np.zeros((9, 2)), seed=0)
    assert sim.is_frozen()
    assert sim.run_until_frozen(max_steps=100)
    assert sim.steps == 0 and sim.collisions == 0


def test_run_until_frozen_respects_max_steps():
    g, v = paper_half_plane(60, 30)
    sim = pb.Simulation(g, v, seed=0)
    assert not sim.run_until_frozen(max_steps=1000)
    assert sim.steps == 1000
    assert sim.run_until_frozen(max_steps=10**7)  # and resumes


def test_run_to_a_collision_count_stops_exactly_there_or_when_frozen():
    g, v = paper_half_plane(10, 5)
    sim = pb.Simulation(g, v, seed=3)
    taken = sim.run(collisions=5)
    assert sim.collisions == 5 and taken == sim.steps
    sim.run(collisions=5)  # already there: nothing to do
    assert sim.collisions == 5 and sim.steps == taken
    sim.run(collisions=10**9)  # more than a finite system can make: stops when frozen
    assert sim.is_frozen() and sim.collisions < 10**9
    ref = pb.Simulation(g, v, seed=3)
    assert ref.run_until_frozen(max_steps=10**6)
    assert (ref.steps, ref.collisions) == (sim.steps, sim.collisions)


def test_run_returns_steps_taken_and_zero_steps_is_a_no_op():
    g, v = paper_torus(rows=6, cols=5)
    sim = pb.Simulation(g, v, seed=0)
    assert sim.run(steps=0) == 0 and sim.steps == 0
    assert sim.run(steps=123) == 123 and sim.steps == 123
    assert np.array_equal(pb.Simulation(g, v, seed=0).velocities, v)


# ---------------------------------------------------------------- determinism and checkpoints


@pytest.mark.parametrize("cls", SCHEDULERS)
def test_same_inputs_and_seed_are_bit_identical(cls):
    g = pb.FlatTorus(rows=8, cols=7)
    v, m = random_state(g, seed=1, unequal_masses=True)
    runs = []
    for _ in range(2):
        sim = pb.Simulation(g, v, scheduler=cls(), masses=m, seed=42)
        sim.run(steps=20_000)
        runs.append((sim.velocities, sim.steps, sim.collisions))
    assert np.array_equal(runs[0][0], runs[1][0]) and runs[0][1:] == runs[1][1:]


@pytest.mark.parametrize("cls", [pb.UniformRandomPair, pb.RandomSweep])
def test_different_seeds_differ(cls):
    g = pb.FlatTorus(rows=8, cols=7)
    v, _ = random_state(g, seed=1)
    a = pb.Simulation(g, v, scheduler=cls(), seed=1)
    b = pb.Simulation(g, v, scheduler=cls(), seed=2)
    a.run(steps=1000)
    b.run(steps=1000)
    assert not np.array_equal(a.velocities, b.velocities)


def test_sweep_does_not_depend_on_the_seed():
    g = pb.FlatTorus(rows=8, cols=7)
    v, _ = random_state(g, seed=1)
    a = pb.Simulation(g, v, scheduler=pb.Sweep(), seed=1)
    b = pb.Simulation(g, v, scheduler=pb.Sweep(), seed=2)
    a.run(steps=1000)
    b.run(steps=1000)
    assert np.array_equal(a.velocities, b.velocities)


def test_seed_sequence_and_int_seed_agree():
    g, v = paper_torus(rows=6, cols=5)
    a = pb.Simulation(g, v, seed=7)
    b = pb.Simulation(g, v, seed=np.random.SeedSequence(7))
    a.run(steps=3000)
    b.run(steps=3000)
    assert np.array_equal(a.velocities, b.velocities)


@pytest.mark.parametrize("cls", SCHEDULERS)
def test_get_state_set_state_continues_bit_identically(cls):
    g = pb.FlatTorus(rows=8, cols=7)
    v, m = random_state(g, seed=5, unequal_masses=True)
    a = pb.Simulation(g, v, rule=pb.Restitution(0.95), scheduler=cls(), masses=m, seed=5)
    a.run(steps=777)
    state = a.get_state()
    assert state.steps == 777 and state.collisions == a.collisions
    a.run(steps=1501)
    b = pb.Simulation(g, np.zeros_like(v), rule=pb.Restitution(0.95), scheduler=cls(), masses=m, seed=999)
    b.set_state(state)
    assert b.steps == 777
    b.run(steps=1501)
    assert np.array_equal(a.velocities, b.velocities)
    assert (a.steps, a.collisions) == (b.steps, b.collisions)
    assert np.array_equal(np.asarray(a.get_state().rng_state), np.asarray(b.get_state().rng_state))


def test_split_runs_equal_one_run():
    g, v = paper_torus(rows=10, cols=9)
    one = pb.Simulation(g, v, seed=3)
    one.run(steps=10_000)
    split = pb.Simulation(g, v, seed=3)
    for piece in [1, 2, 3, 4994, 5000]:
        split.run(steps=piece)
    assert np.array_equal(one.velocities, split.velocities) and one.collisions == split.collisions


def test_state_and_velocities_are_copies():
    g, v = paper_torus(rows=6, cols=5)
    given_v = v.copy()
    sim = pb.Simulation(g, given_v, seed=0)
    given_v[:] = 123.0  # the caller's array is not the simulation's
    assert sim.energy() == pytest.approx(100.0)
    state = sim.get_state()
    state.velocities[:] = 0.0
    assert sim.energy() == pytest.approx(100.0)
    sim.run(steps=100)
    assert state.steps == 0


def test_velocities_are_float64_of_shape_balls_by_dim():
    g = pb.HalfPlane(rows=3, cols=4)
    sim = pb.Simulation(g, np.ones((12, 2), dtype=np.int32), seed=0)
    assert sim.velocities.dtype == np.float64 and sim.velocities.shape == (12, 2)
    sim.run(steps=10)
    assert sim.velocities.dtype == np.float64


# ---------------------------------------------------------------- bad input


def small():
    g = pb.HalfPlane(rows=3, cols=4)
    return g, np.zeros((g.n_balls, 2))


@pytest.mark.parametrize(
    "velocities, match",
    [
        (np.zeros((12, 3)), r"^velocities: .*shape.*\(12, 2\)"),
        (np.zeros((11, 2)), r"^velocities: .*shape"),
        (np.zeros(24), r"^velocities: .*shape"),
        ([[0.0, 0.0]] * 3 + [[math.nan, 0.0]] + [[0.0, 0.0]] * 8, r"^velocities: ball 3 .*NaN or infinite"),
        ([[0.0, 0.0]] * 11 + [[0.0, -math.inf]], r"^velocities: ball 11 .*NaN or infinite"),
    ],
)
def test_bad_velocities_are_refused(velocities, match):
    g, _ = small()
    with pytest.raises(ValueError, match=match):
        pb.Simulation(g, velocities)


def test_non_numeric_velocities_are_refused():
    g, _ = small()
    with pytest.raises(TypeError, match=r"^velocities: "):
        pb.Simulation(g, [["a", "b"]] * 12)


@pytest.mark.parametrize(
    "masses, error, match",
    [
        (np.zeros(12), ValueError, r"^masses: .*> 0"),
        (-np.ones(12), ValueError, r"^masses: .*> 0"),
        (np.r_[np.ones(11), math.nan], ValueError, r"^masses: .*finite"),
        (np.r_[np.ones(11), math.inf], ValueError, r"^masses: .*finite"),
        (np.ones(11), ValueError, r"^masses: .*shape.*\(12,\)"),
        (np.ones((12, 1)), ValueError, r"^masses: .*shape"),
        (0.0, ValueError, r"^masses: .*> 0"),
        (["x"] * 12, TypeError, r"^masses: "),
    ],
)
def test_bad_masses_are_refused(masses, error, match):
    g, v = small()
    with pytest.raises(error, match=match):
        pb.Simulation(g, v, masses=masses)


def test_scalar_mass_means_all_equal():
    g, v = paper_torus(rows=6, cols=5)
    sim = pb.Simulation(g, v, masses=2.0, seed=0)
    assert sim.energy() == pytest.approx(200.0)


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"steps": -1}, ValueError, r"^steps: .*>= 0"),
        ({"steps": 1.5}, TypeError, r"^steps: .*integer"),
        ({"steps": 1e6}, TypeError, r"^steps: .*integer"),
        ({"steps": "10"}, TypeError, r"^steps: .*integer"),
        ({"steps": True}, TypeError, r"^steps: .*integer"),
        ({"collisions": -5}, ValueError, r"^collisions: .*>= 0"),
        ({"collisions": 2.0}, TypeError, r"^collisions: .*integer"),
        ({}, ValueError, r"^run: give steps= or collisions="),
    ],
)
def test_bad_run_limits_are_refused(kwargs, error, match):
    g, v = small()
    sim = pb.Simulation(g, v)
    with pytest.raises(error, match=match):
        sim.run(**kwargs)
    assert sim.steps == 0


def test_bad_max_steps_is_refused():
    g, v = small()
    sim = pb.Simulation(g, v)
    with pytest.raises(ValueError, match=r"^max_steps: .*>= 0"):
        sim.run_until_frozen(max_steps=-1)
    with pytest.raises(TypeError, match=r"^max_steps: .*integer"):
        sim.run_until_frozen(max_steps=1e9)


@pytest.mark.parametrize(
    "seed, error, match",
    [
        (-1, ValueError, r"^seed: .*non-negative"),
        (np.int64(-3), ValueError, r"^seed: .*non-negative"),
        (1.5, TypeError, r"^seed: "),
        ("0", TypeError, r"^seed: "),
        (True, TypeError, r"^seed: "),
    ],
)
def test_bad_seeds_are_refused(seed, error, match):
    g, v = small()
    with pytest.raises(error, match=match):
        pb.Simulation(g, v, seed=seed)


def test_bad_components_are_refused():
    g, v = small()
    with pytest.raises(TypeError, match=r"^geometry: "):
        pb.Simulation("torus", v)
    with pytest.raises(TypeError, match=r"^rule: "):
        pb.Simulation(g, v, rule="elastic")
    with pytest.raises(TypeError, match=r"^scheduler: "):
        pb.Simulation(g, v, scheduler=pb.Elastic())
    with pytest.raises(ValueError, match=r"^geometry: .*no contacts"):
        pb.Simulation(pb.HalfPlane(rows=1, cols=1), np.zeros((1, 2)))


def test_bad_states_are_refused():
    g, v = small()
    sim = pb.Simulation(g, v)
    good = sim.get_state()
    with pytest.raises(ValueError, match=r"^velocities: "):
        sim.set_state(good.replace(velocities=np.zeros((3, 2))))
    with pytest.raises(ValueError, match=r"^rng_state: "):
        sim.set_state(good.replace(rng_state=np.zeros(4, dtype=np.uint64)))
    with pytest.raises(ValueError, match=r"^steps: "):
        sim.set_state(good.replace(steps=-1))


def test_failed_set_state_leaves_the_simulation_unchanged():
    g, v = paper_torus(rows=6, cols=5)
    sim = pb.Simulation(g, v, seed=0)
    sim.run(steps=10)
    before = sim.get_state()
    bad = before.replace(velocities=np.ones_like(v), steps=-1)
    with pytest.raises(ValueError, match=r"^steps: "):
        sim.set_state(bad)
    after = sim.get_state()
    assert np.array_equal(after.velocities, before.velocities), "velocities were replaced by a refused state"
    assert after.steps == before.steps


@pytest.mark.parametrize(
    "cls, bad",
    [
        (pb.Sweep, lambda n: np.array([n + 10**6])),  # next contact beyond the last
        (pb.Sweep, lambda n: np.array([-1])),
        (pb.RandomSweep, lambda n: np.r_[0, np.arange(n)[::-1] + 10**6]),  # order not a permutation of contacts
    ],
    ids=["sweep-past-end", "sweep-negative", "random-sweep-bad-order"],
)
def test_set_state_refuses_scheduler_states_that_index_outside_the_contacts(cls, bad):
    """Such a state would make the compiled loop read and write outside its arrays (it segfaults
    on a 3 x 4 half-plane), so it must be refused here; nothing is run in this test."""
    g, v = small()
    sim = pb.Simulation(g, v, scheduler=cls())
    state = sim.get_state()
    with pytest.raises(ValueError, match=r"^scheduler_state: "):
        sim.set_state(state.replace(scheduler_state=bad(g.n_contacts)))


# ---------------------------------------------------------------- seeds (issue 26, item 4)


def test_without_a_seed_each_simulation_draws_its_own_and_records_it():
    """As numpy: no seed means fresh entropy, so replicas made in a loop are independent; `seed`
    records it, and passing it again repeats the run bit for bit."""
    g, v = paper_torus(rows=6, cols=5)
    a, b = pb.Simulation(g, v), pb.Simulation(g, v)
    assert isinstance(a.seed, int) and a.seed >= 2**64 and a.seed != b.seed  # 128 bits of entropy
    assert not np.array_equal(a.get_state().rng_state, b.get_state().rng_state)
    again = pb.Simulation(g, v, seed=a.seed)
    for sim in (a, b, again):
        sim.run(steps=2_000)
    assert again.get_state().identical(a.get_state()) and not b.get_state().identical(a.get_state())


def test_the_seed_recorded_is_what_repeats_the_run():
    g, v = paper_torus(rows=6, cols=5)
    assert pb.Simulation(g, v, seed=7).seed == 7
    assert pb.Simulation(g, v, seed=np.random.SeedSequence(7)).seed == 7  # its entropy alone repeats it
    child = np.random.SeedSequence(7).spawn(3)[2]  # an ensemble's replica: the spawn key matters
    sim = pb.Simulation(g, v, seed=child)
    assert sim.seed is child
    repeat = pb.Simulation(g, v, seed=sim.seed)
    sim.run(steps=500)
    repeat.run(steps=500)
    assert repeat.get_state().identical(sim.get_state())
    assert not pb.Simulation(g, v, seed=7).get_state().identical(pb.Simulation(g, v, seed=child).get_state())
