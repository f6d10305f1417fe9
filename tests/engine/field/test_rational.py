"""The chain in exact arithmetic: hand-computed collisions, exact counts, refusals, resume; and the
float engine counting exactly its collisions, collision for collision, on many runs."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import chain
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pinnedballs as pb


def exact_text(sim) -> list[list[str]]:
    return [[str(x) for x in row] for row in sim.exact_velocities]


def test_a_head_on_pair_exchanges_its_velocities_exactly():
    g = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0]])
    sim = pb.Simulation(g, [[0.1, 0.3], [-0.7, 0.0]], arithmetic="exact")
    sim.run(steps=1)
    assert sim.collisions == 1
    assert exact_text(sim) == [["-3152519739159347/4503599627370496", "5404319552844595/18014398509481984"],
                               ["3602879701896397/36028797018963968", "0"]]  # 0.1 and -0.7 swapped, exactly
    np.testing.assert_array_equal(sim.velocities, [[-0.7, 0.3], [0.1, 0.0]])


def test_a_slanted_contact_of_the_triangular_lattice_gives_roots_of_three():
    """Ball 0 at the origin moving (0, 1) and ball 2 above it to the right, normal (1/2, sqrt3/2):
    w = sqrt3/2, so ball 0 keeps (-sqrt3/4, 1/4) and ball 2 gets (sqrt3/4, 3/4)."""
    g = pb.HalfPlane(rows=2, cols=2)
    v = np.zeros((4, 2))
    v[0] = [0.0, 1.0]
    sim = pb.Simulation(g, v, scheduler=pb.Replay([g.contacts.pairs.tolist().index([0, 2])]), arithmetic="exact")
    assert sim.run_until_frozen(max_steps=1) is False or sim.collisions == 1
    assert exact_text(sim)[0] == ["-1/4*sqrt(3)", "1/4"] and exact_text(sim)[2] == ["1/4*sqrt(3)", "3/4"]
    x, y = sim.exact_velocities[0]
    assert x * x + y * y == 0.25


@pytest.mark.parametrize("scheduler", [pb.UniformRandomPair(), pb.Sweep(), pb.RandomSweep(), pb.ColoredSweep(),
                                       pb.ColoredSweep(shuffle=True)], ids=repr)
def test_a_chain_makes_exactly_its_inversions_and_velocities_stay_the_ones_it_started_with(scheduler):
    """On a collinear chain a collision swaps two velocities: the exact velocities end sorted, the
    same numbers exactly, after as many collisions as inversions, in every order."""
    g = chain(12)
    v = np.random.default_rng(4).normal(size=(12, 1))
    sim = pb.Simulation(g, v, scheduler=scheduler, seed=2, arithmetic="exact")
    assert sim.run_until_frozen(max_steps=10**6)
    x = v[:, 0]
    assert sim.collisions == sum(int(a > b) for k, a in enumerate(x) for b in x[k + 1:])
    final = sim.exact_velocities[:, 0]
    assert [float(a) for a in final] == sorted(x.tolist())
    assert all(str(a) == str(pb.Simulation(g, v, arithmetic="exact").exact_velocities[k, 0])
               for a, k in zip(final, np.argsort(x)))


@pytest.mark.parametrize("make, words", [
    (lambda: (pb.Sphere.geodesic(2), {}), "Sphere's are not: unit vector 0"),
    (lambda: (pb.HyperbolicPlane(7, 1), {}), "HyperbolicPlane's are not"),
    (lambda: (pb.HalfPlane(3, 3), {"scheduler": pb.RejectionFree()}),
     "RejectionFree() picks among live contacts in float arithmetic (UniformRandomPair has the same law)"),
])
def test_what_exact_arithmetic_cannot_run_is_refused_saying_why(make, words):
    g, kwargs = make()
    v = np.zeros((g.n_balls, g.dim))
    v[0, 0] = 1.0
    with pytest.raises(ValueError) as info:
        pb.Simulation(g, v, arithmetic="exact", **kwargs)
    assert str(info.value).startswith("arithmetic: ") and words in str(info.value)
    with pytest.raises(ValueError, match=r"^arithmetic: must be 'float' or 'exact' or 'certified', got 'rational'"):
        pb.Simulation(g, v, arithmetic="rational")


def test_a_rule_of_ones_own_has_no_exact_form():
    class Sticky(pb.Restitution):
        def exact_restitution(self):
            return None

    with pytest.raises(ValueError, match=r"^arithmetic: exact arithmetic runs the built-in rules"):
        pb.Simulation(chain(3), np.eye(3, 1), rule=Sticky(0.5), arithmetic="exact")


def test_an_exact_run_split_into_calls_and_resumed_from_its_results_ends_on_the_same_state(tmp_path):
    g = pb.HalfPlane(6, 8)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.3, 3.0]
    whole = pb.Simulation(g, v, seed=5, arithmetic="exact")
    assert whole.run_until_frozen(max_steps=10**6)
    split = pb.Simulation(g, v, seed=5, arithmetic="exact")
    split.run(steps=333, writers=[pb.ResultsWriter(tmp_path / "run", snapshots={"every_steps": 100})])
    resumed = pb.load(tmp_path / "run").simulation()
    assert resumed.arithmetic == "exact" and resumed.get_state().identical(split.get_state())
    for _ in range(5):
        resumed.run(steps=97, until_frozen=True)
    resumed.run_until_frozen(max_steps=10**6)
    assert resumed.get_state().identical(whole.get_state())


def test_an_exact_state_is_checked_before_it_is_taken():
    g = pb.HalfPlane(3, 4)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, 2.0]
    sim = pb.Simulation(g, v, arithmetic="exact")
    sim.run(steps=50)
    state = sim.get_state()
    with pytest.raises(ValueError, match=r"^exact: a simulation in exact arithmetic resumes only from an exact state"):
        sim.set_state(state.replace(exact=None))
    bad = state.exact.copy()
    bad[0, 0, 0] = "1/0"
    with pytest.raises(ValueError, match=r"^exact: a coefficient is not a rational number"):
        sim.set_state(state.replace(exact=bad))
    bad = state.exact.copy()
    bad[0, 0, 0] = "12345"
    with pytest.raises(ValueError, match=r"^exact: the exact velocities do not round to the state's velocities"):
        sim.set_state(state.replace(exact=bad))
    assert sim.get_state().identical(state)


# ---------------------------------------------------------------- the float engine counts what exact arithmetic counts


def lockstep(g, v, *, seed, scheduler, steps, chunk=1, **kwargs):
    """Float and exact runs of the same chain, compared after every ``chunk`` steps: the same
    collisions (so the same collision at the same step) and velocities within 1e-12 of each other."""
    floats = pb.Simulation(g, v, scheduler=scheduler, seed=seed, **kwargs)
    exact = pb.Simulation(g, v, scheduler=scheduler, seed=seed, arithmetic="exact", **kwargs)
    while floats.steps < steps and not (floats.is_frozen() and exact.is_frozen()):
        floats.run(steps=chunk)
        exact.run(steps=chunk)
        assert floats.collisions == exact.collisions, f"step {floats.steps}"
        np.testing.assert_allclose(floats.velocities, exact.velocities, rtol=0, atol=1e-12)
    assert floats.get_state().replace(exact=None).identical(exact.get_state().replace(exact=None)) or \
        np.allclose(floats.velocities, exact.velocities, atol=1e-12)
    return floats, exact


starts = st.sampled_from(["inward", "oblique", "several"])


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(rows=st.integers(2, 7), cols=st.integers(2, 9), across=st.booleans(), seed=st.integers(0, 2**20),
       start=starts, scheduler=st.sampled_from(["uniform", "sweep", "random_sweep", "colored"]))
def test_collision_for_collision_on_half_planes(rows, cols, across, seed, start, scheduler):
    g = pb.HalfPlane(rows, cols, orientation="across" if across else "along")
    rng = np.random.default_rng(seed)
    v = np.zeros((g.n_balls, 2))
    b = g.boundary_center()
    if start == "inward":
        v[b] = -np.sqrt(200.0) * g.boundary.outward[b]
    elif start == "oblique":
        v[b] = np.sqrt(200.0) * np.array([rng.uniform(-0.8, 0.8), 1.0]) / np.hypot(rng.uniform(-0.8, 0.8), 1.0)
    else:
        for k in rng.choice(g.n_balls, size=min(4, g.n_balls), replace=False):
            v[k] = rng.normal(size=2)
    make = {"uniform": pb.UniformRandomPair, "sweep": pb.Sweep, "random_sweep": pb.RandomSweep,
            "colored": pb.ColoredSweep}[scheduler]
    floats, exact = lockstep(g, v, seed=seed, scheduler=make(), steps=20_000, chunk=7)
    assert floats.is_frozen() and exact.is_frozen() and floats.steps == exact.steps


@settings(max_examples=10, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**20), masses=st.booleans(), r=st.sampled_from([1.0, 0.5]))
def test_collision_for_collision_on_a_torus_of_fixed_length(seed, masses, r):
    """At equilibrium (Gaussian velocities), with unequal masses and inelastic rules too."""
    g = pb.FlatTorus(6, 6)
    rng = np.random.default_rng(seed)
    m = rng.choice([1.0, 2.0, 0.5], size=g.n_balls) if masses else None
    lockstep(g, rng.normal(size=(g.n_balls, 2)), seed=seed, scheduler=pb.UniformRandomPair(), steps=3_000, chunk=50,
             masses=m, rule=pb.Restitution(r))


@pytest.mark.slow
@pytest.mark.parametrize("length, depth, seed, direction, collisions, steps", [
    (20, 10, 1, (0.0, 1.0), 224, 1_596),
    (40, 20, 1, (0.0, 1.0), 2_194, 15_753),
    (40, 20, 2, (0.3, 1.7), 2_367, 14_477),
    (100, 50, 1, (0.0, 1.0), 48_022, 243_682),
])
def test_the_half_plane_table_in_both_arithmetics(length, depth, seed, direction, collisions, steps):
    """docs/collisions.md's table: one boundary ball sent in with energy 100, run until frozen."""
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = np.sqrt(200.0) * np.array(direction) / np.linalg.norm(direction)
    for arithmetic in ("exact", "float"):
        sim = pb.Simulation(g, v, seed=seed, arithmetic=arithmetic)
        assert sim.run_until_frozen(max_steps=10**8)
        assert (sim.collisions, sim.steps) == (collisions, steps)
