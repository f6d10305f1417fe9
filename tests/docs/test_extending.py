"""The examples of docs/extending.md run, and do what the page says."""

import re
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb

DOC = Path(__file__).resolve().parents[2] / "docs" / "extending.md"


@pytest.fixture(scope="module")
def doc():
    """The namespace after running every python block of the page, in order."""
    ns = {}
    for block in re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S):
        exec(compile(block, str(DOC), "exec"), ns)
    return ns


def test_chain_geometry_is_a_path_with_flat_units(doc):
    chain = doc["Chain"](5)
    assert chain.n_contacts == 4 and chain.dim == 2
    assert chain.contacts.flat
    assert sorted(chain.degrees()) == [1, 1, 2, 2, 2]
    ref = pb.GraphGeometry.from_positions(chain.positions)
    np.testing.assert_array_equal(ref.contacts.pairs, chain.contacts.pairs)
    np.testing.assert_array_equal(ref.contacts.t_i, chain.contacts.t_i)


def test_newtons_cradle_on_the_chain(doc):
    """Equal masses on a line: the velocity passes to the far end, and the chain freezes."""
    chain = doc["Chain"](5)
    v = np.zeros((5, 2))
    v[0, 0] = 1.0
    sim = pb.Simulation(chain, v, scheduler=pb.Sweep())
    assert sim.run_until_frozen(max_steps=100)
    expected = np.zeros((5, 2))
    expected[4, 0] = 1.0
    np.testing.assert_array_equal(sim.velocities, expected)
    assert sim.collisions == 4


def test_sticky_with_keep_one_is_elastic_bit_for_bit(doc):
    torus = pb.FlatTorus(6, 6)
    v = np.random.default_rng(3).normal(size=(torus.n_balls, 2))
    a = pb.Simulation(torus, v, rule=doc["Sticky"](1.0), seed=5)
    b = pb.Simulation(torus, v, rule=pb.Elastic(), seed=5)
    a.run(steps=20_000)
    b.run(steps=20_000)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    assert a.collisions == b.collisions


def test_sticky_loses_energy_keeps_momentum(doc):
    torus = pb.FlatTorus(6, 6)
    v = np.random.default_rng(4).normal(size=(torus.n_balls, 2))
    sim = pb.Simulation(torus, v, rule=doc["Sticky"](0.5), seed=1)
    e0, p0 = sim.energy(), sim.momentum()
    sim.run(steps=5_000)
    assert sim.energy() < 0.5 * e0
    np.testing.assert_allclose(sim.momentum(), p0, atol=1e-12 * np.sqrt(e0) * torus.n_balls)


def test_among_touches_only_its_contacts(doc):
    torus = pb.FlatTorus(8, 8)
    v = np.random.default_rng(5).normal(size=(torus.n_balls, 2))
    chosen = np.arange(0, 30, 3)
    sim = pb.Simulation(torus, v, scheduler=doc["Among"](chosen), seed=2)
    sim.run(steps=2_000)
    touched = np.unique(torus.contacts.pairs[chosen].astype(np.int64))
    untouched = np.setdiff1d(np.arange(torus.n_balls), touched)
    assert sim.collisions > 0
    np.testing.assert_array_equal(sim.velocities[untouched], v[untouched])
    with pytest.raises(ValueError, match="contacts: must be a non-empty list of indices below 192"):
        pb.Simulation(torus, v, scheduler=doc["Among"]([192]))


def test_schedulers_and_rules_compare_by_parameters_and_hash(doc):
    among = doc["Among"]
    assert among([1, 2]) == among([1, 2]) and among([1, 2]) != among([1, 3])
    assert pb.Sweep() == pb.Sweep() and pb.Sweep() != pb.RandomSweep()
    assert pb.Restitution(0.5) != pb.Restitution(0.6) and pb.Restitution(1.0) != pb.Elastic()
    table = {pb.Elastic(): "e", pb.Restitution(0.5): "r", pb.Sweep(): "s", among([1, 2]): "a"}
    assert table[pb.Elastic()] == "e" and table[pb.Restitution(0.5)] == "r"
    assert table[pb.Sweep()] == "s" and table[among([1, 2])] == "a"


def test_by_ball_tries_each_ball_s_contacts_in_turn_and_freezes_a_chain(doc):
    """On separate approaching pairs ball 0's contact collides first, ball 1's (the same, now
    receding) next, then ball 2's; on a chain the run freezes after exactly the inversions, and a
    state outside the sweep is refused before anything runs."""
    from helpers import chain, matching

    geom = matching(6, dim=1)
    v = np.zeros((12, 1))
    v[0::2, 0], v[1::2, 0] = 1.0, -1.0
    sim = pb.Simulation(geom, v, scheduler=doc["ByBall"](), seed=0)
    sim.run(steps=2)
    np.testing.assert_array_equal(np.flatnonzero(sim.velocities[:, 0] != v[:, 0]), [0, 1])
    sim.run(steps=1)
    np.testing.assert_array_equal(np.flatnonzero(sim.velocities[:, 0] != v[:, 0]), [0, 1, 2, 3])
    assert sim.collisions == 2
    line = chain(30)
    v = np.random.default_rng(1).normal(size=(30, 1))
    inversions = sum(int(a > b) for k, a in enumerate(v[:, 0]) for b in v[k + 1:, 0])
    sim = pb.Simulation(line, v, scheduler=doc["ByBall"](), seed=0)
    assert sim.run_until_frozen(max_steps=10**6)
    assert sim.collisions == inversions
    with pytest.raises(ValueError, match=r"scheduler_state: ball 3, offset 7 is not a place in the sweep"):
        sim.set_state(sim.get_state().replace(scheduler_state=np.array([3, 7])))


def test_recorded_chain_run(doc):
    """Collisions along a chain come one at a time; the snapshots land on the counts asked for."""
    res = doc["res"]
    assert [s.collisions for s in res.snapshots] == [0, 2, 4, 6] and res.frozen and res.collisions == 7
    assert res.spec is None and res.run["geometry"]["class"].endswith("Chain")
    resumed = doc["resumed"]
    np.testing.assert_array_equal(resumed.velocities, doc["sim"].velocities)
    assert resumed.steps == doc["sim"].steps and type(resumed.scheduler) is pb.Sweep


def test_registered_observable_is_recorded(doc):
    sim = pb.Simulation(doc["Chain"](3), np.array([[1.0, 0], [0, 0], [0, 0]]), scheduler=pb.Sweep())
    sim.run(steps=14, writers=[doc["measured"]])
    res = pb.load(doc["measured"].out_dir)
    assert res.observables["steps"].tolist() == [7, 14]
    assert res.observables["speed_of_last_ball"].tolist() == [1.0, 1.0]  # the cradle passed it on


def test_a_plain_python_pick_or_collide_is_refused_naming_the_component():
    """A pick or collide without @njit would fail inside the compiled loop with a numba TypingError;
    it is refused up front with a TypeError naming the scheduler or the rule."""
    from numba import config

    from pinnedballs.rules import CollisionRule, collide_equal
    from pinnedballs.schedulers import Scheduler

    if config.DISABLE_JIT:
        pytest.skip("with NUMBA_DISABLE_JIT every function is plain Python, so nothing to tell apart")

    def plain_pick(state, rng, n_contacts):
        return np.uint64(0), rng

    def plain_collide(v, units, i, j, a, b, masses, params, dim, flat, write):
        return collide_equal(v, units, i, j, a, b, masses, params, dim, flat, write)

    class Plain(Scheduler):
        def kernel(self):
            return plain_pick

    class PlainRule(CollisionRule):
        def kernel(self, equal_masses):
            return plain_collide, np.array([1.0])

    geom = pb.HalfPlane(2, 2)
    v = np.zeros((4, 2))
    with pytest.raises(TypeError, match=r"^scheduler: Plain.kernel\(\)'s pick must be a numba-compiled function "
                                        r"\(decorate it with @numba.njit\), got <function"):
        pb.Simulation(geom, v, scheduler=Plain())
    with pytest.raises(TypeError, match=r"^rule: PlainRule.kernel\(\)'s collide must be a numba-compiled"):
        pb.Simulation(geom, v, rule=PlainRule())


def test_spring_given_by_its_impulse_is_elastic_at_no_softening(doc):
    """``soft = 0`` is the elastic rule for any masses (c_i = 2 m_j w / (m_i + m_j)): the impulse form's
    collide, branchy or branch-free, gives the built-in rule's bits on a torus in equilibrium; with
    ``soft > 0`` momentum is kept and energy lost."""
    torus = pb.FlatTorus(6, 6)
    v = np.random.default_rng(8).normal(size=(torus.n_balls, 2))
    masses = np.random.default_rng(9).uniform(0.5, 2.0, torus.n_balls)
    a = pb.Simulation(torus, v, rule=doc["Spring"](0.0), masses=masses, seed=2)
    b = pb.Simulation(torus, v, rule=pb.Elastic(), masses=masses, seed=2)
    a.run(steps=20_000)
    b.run(steps=20_000)
    np.testing.assert_array_equal(a.velocities, b.velocities)
    soft = pb.Simulation(torus, v, rule=doc["Spring"](0.5), masses=masses, seed=2)
    soft.run(steps=20_000)
    np.testing.assert_allclose(soft.momentum(), b.momentum(), atol=1e-9)
    assert soft.energy() < 0.5 * b.energy()


@pytest.mark.cuda
def test_both_rules_run_on_the_gpu_with_the_cpus_bits(doc):
    """The page's claim: a user's rule, whole or by its impulse, runs on ``device="cuda"`` (here numba-cuda's
    simulator) with the CPU's bits."""
    half = pb.HalfPlane.from_size(16, 8)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.0, 3.0]
    for rule in (doc["Sticky"](0.5), doc["Spring"](0.25)):
        runs = []
        for device in ("cpu", "cuda"):
            sim = pb.Simulation(half, v, rule=rule, scheduler=pb.UniformRandomPair(stream="counter"), seed=4,
                                device=device)
            sim.run_until_frozen(max_steps=10**6, progress=False)
            runs.append((sim.velocities.tobytes(), sim.steps, sim.collisions))
        assert runs[0] == runs[1] and runs[0][2] > 10
