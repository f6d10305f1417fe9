"""The compiled loop equals the plain-Python twin (`reference.py`) step for step.

"Equal" means bit-identical: ``np.array_equal`` velocities, the same step and
collision counters and the same final xoshiro256** state, for schedulers x rules
x geometries of dims 1, 2 and 3 (flat, and curved where ``t_j != -t_i``), however
a run is split into calls, and for each way of stopping a run.

Each (scheduler, kind of collision, dim, flat) is a separately compiled loop
costing seconds on a cold cache, so the cases follow `cases.LOOPS` (stepping) and
`cases.LIMITED` (runs to a collision count or the freeze): the full product in
flat 2-D (torus and half-plane), a covering set elsewhere.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import (
    LIMITED,
    LOOPS,
    SCHEDULER_CLASSES,
    chain,
    cubic,
    fcc_cluster,
    icosahedron_sphere,
    random_state,
    rule_kind,
    tangent_velocities,
)
from reference import ReferenceRejectionFree, ReferenceSimulation

import pinnedballs as pb

STEPS = 2000

#: name -> (restitution r, unequal masses?)
RULES = {
    "elastic": (1.0, False),
    "elastic_masses": (1.0, True),
    "restitution": (0.7, False),
    "restitution_masses": (0.7, True),
}

#: name -> (factory, (dim, flat))
GEOMETRIES = {
    "chain1d": (lambda: chain(9), (1, True)),
    "torus2d": (lambda: pb.FlatTorus(rows=4, cols=5), (2, True)),
    "halfplane2d": (lambda: pb.HalfPlane(rows=4, cols=5), (2, True)),
    "fcc3d": (lambda: fcc_cluster(2), (3, True)),
    "sphere3d": (icosahedron_sphere, (3, False)),
}

_cache: dict = {}


def geometry(name: str) -> pb.Geometry:
    if name not in _cache:
        make, (dim, flat) = GEOMETRIES[name]
        g = make()
        assert g.dim == dim
        assert np.array_equal(g.contacts.t_j, -g.contacts.t_i) == flat
        _cache[name] = g
    return _cache[name]


def cases(geom_names, rule_names=tuple(RULES), table=LOOPS):
    """(geometry, rule, scheduler) triples whose compiled loop is in ``table``."""
    out = []
    for g in geom_names:
        allowed = table[GEOMETRIES[g][1]]
        for rule in rule_names:
            for sched, kinds in allowed.items():
                if rule_kind(*RULES[rule]) in kinds:
                    out.append(pytest.param(g, rule, sched, id=f"{g}-{rule}-{sched}"))
    return out


def inputs(geom_name, rule_name, seed):
    """``(geom, v, masses, r, rule)`` of one case: random velocities (tangent on the sphere)."""
    geom = geometry(geom_name)
    r, unequal = RULES[rule_name]
    v, m = random_state(geom, seed=seed, unequal_masses=unequal)
    if geom_name == "sphere3d":
        v = tangent_velocities(geom, seed)
    return geom, v, m, r, pb.Elastic() if r == 1.0 else pb.Restitution(r)


def pair(geom_name, rule_name, sched_name, seed=11):
    """An engine simulation and its twin with the same inputs."""
    geom, v, m, r, rule = inputs(geom_name, rule_name, seed)
    sim = pb.Simulation(geom, v, rule=rule, scheduler=SCHEDULER_CLASSES[sched_name](), masses=m, seed=seed)
    twin = ReferenceSimulation.from_geometry(geom, v, r=r, masses=m, scheduler=sched_name, seed=seed)
    return sim, twin


def rng_words(sim) -> list[int]:
    return [int(x) for x in np.asarray(sim.get_state().rng_state, dtype=np.uint64)]


def assert_same(sim, twin):
    assert sim.steps == twin.steps
    assert sim.collisions == twin.collisions
    assert np.array_equal(sim.velocities, twin.velocities), np.max(np.abs(sim.velocities - twin.velocities))
    assert rng_words(sim) == twin.rng_state


@pytest.mark.parametrize("geom_name, rule_name, sched_name", cases(GEOMETRIES))
def test_engine_equals_twin_for_2000_steps(geom_name, rule_name, sched_name):
    sim, twin = pair(geom_name, rule_name, sched_name)
    sim.run(steps=STEPS)
    twin.run(steps=STEPS)
    assert twin.collisions > 0  # the comparison is not vacuous
    assert_same(sim, twin)


def test_every_scheduler_rule_and_dimension_is_covered():
    """The covering set really covers: every scheduler in every geometry, every rule in every
    geometry, and every scheduler with every rule (in flat 2-D)."""
    for table, geoms in [(LOOPS, list(GEOMETRIES)), (LIMITED, ["chain1d", "halfplane2d", "fcc3d"])]:
        triples = {tuple(p.values) for p in cases(geoms, table=table)}
        for g in geoms:
            assert {s for gg, _, s in triples if gg == g} == set(SCHEDULER_CLASSES)
            assert {rule_kind(*RULES[r]) for gg, r, _ in triples if gg == g} == {"exchange", "equal", "masses"}
        kinds = {(rule_kind(*RULES[r]), s) for _, r, s in triples}
        assert kinds == {(k, s) for k in ("exchange", "equal", "masses") for s in SCHEDULER_CLASSES}


@pytest.mark.parametrize("geom_name, rule_name, sched_name",
                         cases(["torus2d", "fcc3d", "sphere3d"], ["elastic_masses", "restitution"]))
def test_engine_equals_twin_when_the_run_is_split_into_odd_pieces(geom_name, rule_name, sched_name):
    sim, twin = pair(geom_name, rule_name, sched_name, seed=3)
    for piece in [1, 3, 0, 17, 979, 1000]:
        sim.run(steps=piece)
        twin.run(steps=piece)
        assert_same(sim, twin)
    assert sim.steps == STEPS


@pytest.mark.parametrize("geom_name, rule_name, sched_name",
                         cases(["chain1d", "halfplane2d", "fcc3d"], ["elastic", "restitution", "elastic_masses"],
                               table=LIMITED))
def test_engine_equals_twin_until_frozen(geom_name, rule_name, sched_name):
    """Finite systems freeze; both stop right after the same last collision."""
    sim, twin = pair(geom_name, rule_name, sched_name, seed=7)
    assert sim.run_until_frozen(max_steps=10**6)
    assert twin.run_until_frozen(max_steps=10**6)
    assert_same(sim, twin)
    assert sim.steps == twin.collision_steps[-1]


@pytest.mark.parametrize("geom_name, rule_name, sched_name",
                         cases(["torus2d"], ["elastic", "restitution", "restitution_masses"], table=LIMITED))
def test_engine_equals_twin_when_running_to_a_collision_count(geom_name, rule_name, sched_name):
    sim, twin = pair(geom_name, rule_name, sched_name, seed=4)
    for total in [1, 2, 50, 51, 400]:
        sim.run(collisions=total)
        twin.run(collisions=total)
        assert sim.collisions == total
        assert_same(sim, twin)


@pytest.mark.parametrize("geom_name, rule_name, sched_name",
                         cases(["halfplane2d"], ["elastic", "restitution", "elastic_masses"], table=LIMITED))
def test_engine_equals_twin_with_both_limits(geom_name, rule_name, sched_name):
    """``run(steps=, collisions=)`` stops at whichever limit comes first."""
    sim, twin = pair(geom_name, rule_name, sched_name, seed=2)
    sim.run(steps=10, collisions=10**6)  # steps first
    twin.run(steps=10, collisions=10**6)
    assert_same(sim, twin)
    assert sim.steps == 10
    sim.run(steps=10**6, collisions=sim.collisions + 3)  # collisions first
    twin.run(steps=10**6, collisions=twin.collisions + 3)
    assert_same(sim, twin)


@pytest.mark.parametrize(
    "make, sched_name",
    [
        (lambda: cubic(5), "random_sweep"),  # 300 contacts, 600 unit vectors: wider unit indices
        (lambda: pb.GraphGeometry.from_positions(  # 33,540 contacts, 67,080 unit vectors
            2.0 * np.array(np.meshgrid(np.arange(130), np.arange(130))).reshape(2, -1).T), "uniform"),
    ],
    ids=["cubic5", "grid130"],
)
def test_engine_equals_twin_on_bigger_graphs(make, sched_name):
    geom = make()
    v, m = random_state(geom, seed=6, unequal_masses=True)
    sim = pb.Simulation(geom, v, scheduler=SCHEDULER_CLASSES[sched_name](), masses=m, seed=6)
    twin = ReferenceSimulation.from_geometry(geom, v, masses=m, scheduler=sched_name, seed=6)
    sim.run(steps=STEPS)
    twin.run(steps=STEPS)
    assert twin.collisions > 0
    assert_same(sim, twin)


def test_engine_equals_twin_on_a_torus_too_big_for_cache():
    """400 x 250 torus (100,000 balls, 300,000 contacts: tables of several MB, where the loop may
    take another path, e.g. prefetching); 20,000 steps, half of them collisions."""
    geom = pb.FlatTorus(rows=250, cols=400)
    v, _ = random_state(geom, seed=12)
    sim = pb.Simulation(geom, v, seed=12)
    twin = ReferenceSimulation.from_geometry(geom, v, seed=12)
    for piece in [20_000, 7]:
        sim.run(steps=piece)
        twin.run(steps=piece)
        assert_same(sim, twin)
    assert twin.collisions > 5000


def test_zero_velocity_runs_consume_the_same_random_numbers():
    """With nothing moving no pick is visible, yet the random stream must advance as the twin's does."""
    geom = pb.HalfPlane(rows=6, cols=9)
    for name, cls in SCHEDULER_CLASSES.items():
        sim = pb.Simulation(geom, np.zeros((geom.n_balls, 2)), scheduler=cls(), seed=123)
        twin = ReferenceSimulation.from_geometry(geom, np.zeros((geom.n_balls, 2)), scheduler=name, seed=123)
        sim.run(steps=5000)
        twin.run(steps=5000)
        assert sim.collisions == 0
        assert_same(sim, twin)


def test_fresh_state_is_seed_sequence_words():
    """Before any step, the random state is SeedSequence(seed)'s 4 words."""
    geom = pb.HalfPlane(rows=2, cols=2)
    for seed in [0, 1, 2**40 + 7]:
        sim = pb.Simulation(geom, np.zeros((4, 2)), seed=seed)
        expected = [int(x) for x in np.random.SeedSequence(seed).generate_state(4, dtype=np.uint64)]
        assert rng_words(sim) == expected


# ---------------------------------------------------------------- schedulers that own their loops

#: (geometry, rule) cases for RejectionFree and ColoredSweep: every dimension, flat and curved,
#: and every kind of collision
OWN_LOOPS = [("chain1d", "restitution"), ("torus2d", "elastic"), ("halfplane2d", "elastic_masses"),
             ("fcc3d", "restitution_masses"), ("sphere3d", "elastic")]
OWN_SCHEDULERS = {"rejection_free": pb.RejectionFree, "colored_sweep": lambda: pb.ColoredSweep(),
                  "colored_sweep_shuffle": lambda: pb.ColoredSweep(shuffle=True)}


def own_pair(geom_name, rule_name, sched_name, seed=11):
    """An engine simulation with a loop-owning scheduler and its twin."""
    geom, v, m, r, rule = inputs(geom_name, rule_name, seed)
    sim = pb.Simulation(geom, v, rule=rule, scheduler=OWN_SCHEDULERS[sched_name](), masses=m, seed=seed)
    if sched_name == "rejection_free":
        twin = ReferenceRejectionFree.from_geometry(geom, v, r=r, masses=m, seed=seed)
    else:
        twin = ReferenceSimulation.from_geometry(geom, v, r=r, masses=m, scheduler=sched_name, seed=seed)
    return sim, twin


def own_cases():
    return [pytest.param(g, r, s, id=f"{g}-{r}-{s}") for g, r in OWN_LOOPS for s in OWN_SCHEDULERS]


@pytest.mark.parametrize("geom_name, rule_name, sched_name", own_cases())
def test_own_loops_equal_twin_in_odd_pieces(geom_name, rule_name, sched_name):
    """Step-bounded runs in pieces (a piece may end between a rejection-free draw and its live
    pick, or inside a colour class), then to a collision count, then to the freeze (finite
    flat geometries): engine and twin agree bit for bit after every call."""
    sim, twin = own_pair(geom_name, rule_name, sched_name)
    for piece in [1, 3, 0, 17, 979, 1000]:
        sim.run(steps=piece)
        twin.run(steps=piece)
        assert_same(sim, twin)
    assert twin.collisions > 0
    sim.run(collisions=sim.collisions + 5)
    twin.run(collisions=twin.collisions + 5)
    assert_same(sim, twin)
    if geom_name in ("chain1d", "halfplane2d", "fcc3d"):  # finite flat systems freeze
        before = sim.steps
        assert sim.run_until_frozen(max_steps=10**7)
        assert twin.run_until_frozen(max_steps=10**7)
        assert_same(sim, twin)
        assert sim.steps == max(before, twin.collision_steps[-1])  # right after the last collision


@pytest.mark.parametrize("sched_name", OWN_SCHEDULERS)
def test_own_loops_with_nothing_moving(sched_name):
    """Zero velocities: nothing is live, nothing collides; RejectionFree draws nothing (the chain
    would pick forever), the sweeps draw only their class orders."""
    geom = pb.HalfPlane(rows=6, cols=9)
    v = np.zeros((geom.n_balls, 2))
    sim = pb.Simulation(geom, v, scheduler=OWN_SCHEDULERS[sched_name](), seed=123)
    if sched_name == "rejection_free":
        twin = ReferenceRejectionFree.from_geometry(geom, v, seed=123)
    else:
        twin = ReferenceSimulation.from_geometry(geom, v, scheduler=sched_name, seed=123)
    assert sim.run(steps=5000) == 5000
    twin.run(steps=5000)
    assert sim.collisions == 0 and sim.steps == 5000
    assert_same(sim, twin)
