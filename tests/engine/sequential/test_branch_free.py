"""The table loop without a branch on each collision (`engine.sequential.loops` ``chunk_blocks``, the branch-free form
`engine.closing.branch_free_form` of a rule given by its impulse: the built-in rules and a user's) gives the bits of the
loop with one: velocities (to the sign of a zero), counters, the random stream, the scheduler's state and the closing
margin, however a run stops.

``PINNEDBALLS_LOOP`` forces each way (`engine.sequential.choice`): ``branch_free`` runs every block but the first
without a branch, ``branch`` none (the loop as it was), ``threshold`` as the block before collided, and the default
(``auto``) as their costs, timed on this CPU, choose: all four give the same bits.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np
import pytest
import user_rules
from helpers import chain, icosahedron_sphere, tangent_velocities, thin_torus
from numba import njit

import pinnedballs as pb
from pinnedballs.engine.closing import WRITE, branch_free_form, choose, compiled_form
from pinnedballs.engine.jit.intrinsics import TICKS
from pinnedballs.engine.sequential.choice import PICKS, POLICY, THRESHOLD, TUNED
from pinnedballs.rules import collide_elastic, collide_equal, collide_masses

#: the ways of running the table loop's blocks (``PINNEDBALLS_LOOP``); the first is the reference
WAYS = ("branch", "branch_free", "threshold", "auto")


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint64)


def _run(monkeypatch, way: str, make, calls) -> tuple:
    """The state after ``calls(sim)`` on ``make()`` built under ``PINNEDBALLS_LOOP=way``, and its loop's ``tune``."""
    with monkeypatch.context() as m:
        m.setenv("PINNEDBALLS_LOOP", way)
        sim = make()
    results = calls(sim)
    return (_bits(sim.velocities), sim.steps, sim.collisions, sim.engine.state.counters.copy(),
            sim.engine.state.rng.copy(), sim.engine.state.scheduler.copy(), _bits(sim.engine.state.margin),
            results), sim.engine.tune


def _same(monkeypatch, make, calls) -> tuple:
    """The state of every way (`WAYS`), equal; returns the first's. The default (``auto``) times both ways where
    the CPU's counter counts (its first blocks try each), and keeps the former threshold where it does not."""
    first, _ = _run(monkeypatch, WAYS[0], make, calls)
    for way in WAYS[1:]:
        other, tune = _run(monkeypatch, way, make, calls)
        for x, y in zip(first, other):
            assert np.array_equal(x, y), (way, x, y)
        if way == "auto":
            assert tune[POLICY] == (TUNED if TICKS else THRESHOLD)
    return first


def _gaussian(geom, seed=1):
    return np.random.default_rng(seed).standard_normal((geom.n_balls, geom.dim))


def test_the_paper_chain_on_a_torus(monkeypatch):
    """Elastic, flat 2-D: steps split anywhere, a collision target, and a run until frozen that never freezes."""
    g = pb.FlatTorus(6, 8)
    v = np.zeros((g.n_balls, 2))
    v[0, 0] = np.sqrt(200.0)

    def calls(sim):
        sim.run(steps=1000)
        sim.run(steps=4321)
        sim.run(collisions=sim.collisions + 777)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # a torus never freezes, and says so
            return sim.run_until_frozen(max_steps=3000)

    state = _same(monkeypatch, lambda: pb.Simulation(g, v, seed=3), calls)
    assert state[2] > 2000  # collided on about half its picks: the blocks without a branch ran
    _, tune = _run(monkeypatch, "auto", lambda: pb.Simulation(g, v, seed=3), calls)
    assert tune[PICKS] > 0 and tune[PICKS + 1] > 0  # the default ran blocks both ways (a call's first has a branch)


def test_a_thin_margin(monkeypatch):
    """Collisions within a few thresholds (near collisions) and remnants set aside: the margin's four numbers."""
    g, v = thin_torus()
    state = _same(monkeypatch, lambda: pb.Simulation(g, v, seed=0), lambda sim: sim.run(steps=20_000))
    margin = state[6].view(np.float64)
    assert margin[2] > 0 and margin[1] > 0 and margin[3] > 0  # near collisions, a remnant, near remnants


def test_a_half_plane_until_frozen(monkeypatch):
    """The freeze rewinds a chunk to its last collision, and the margin's remnant side with it."""
    half = pb.HalfPlane(rows=12, cols=10)
    v = np.zeros((half.n_balls, 2))
    b = half.boundary_center()
    v[b] = -np.sqrt(200.0) * half.boundary.outward[b]
    state = _same(monkeypatch, lambda: pb.Simulation(half, v, seed=7),
                  lambda sim: sim.run_until_frozen(max_steps=10**8))
    assert state[7] is True and state[6].view(np.float64)[1] > 0  # frozen, with remnants set aside


@pytest.mark.parametrize("seed", range(4))
def test_remnants_around_the_last_collision(monkeypatch, seed):
    """A line of 20 balls that freezes, beside a pair closing at a remnant's speed for ever: picks set aside
    come before and after the last collision in one block, and the margin the run ends with is the one as of
    that collision (``at_last``)."""
    g = pb.GraphGeometry.from_positions(np.concatenate([2.0 * np.arange(20), [1000.0, 1002.0]]))
    v = np.random.default_rng(seed).standard_normal(g.n_balls)
    v[-2:] = [1.0, 1.0 - 2.0**-52]  # w = 2^-52, a remnant (below 4 * 2^-53 * V, V about 6)
    state = _same(monkeypatch, lambda: pb.Simulation(g, v[:, None], seed=seed),
                  lambda sim: sim.run_until_frozen(max_steps=10**6))
    assert state[7] is True and state[6].view(np.float64)[3] > 0  # frozen, with near remnants counted


@pytest.mark.parametrize("r", [1.0, 0.6])
def test_unequal_masses_and_restitution(monkeypatch, r):
    g = pb.FlatTorus(4, 6)
    masses = np.random.default_rng(2).uniform(0.5, 2.0, g.n_balls)
    _same(monkeypatch, lambda: pb.Simulation(g, _gaussian(g), rule=pb.Restitution(r), masses=masses, seed=5),
          lambda sim: (sim.run(steps=3000), sim.run(collisions=sim.collisions + 100)))


def test_restitution_on_a_line(monkeypatch):
    """Equal masses with restitution (``collide_equal``), dim 1."""
    g = chain(9)
    _same(monkeypatch, lambda: pb.Simulation(g, _gaussian(g), rule=pb.Restitution(0.7), seed=2),
          lambda sim: (sim.run(steps=3000), sim.run_until_frozen(max_steps=10**6)))


def test_a_users_rule_given_by_its_impulse(monkeypatch):
    """A user's rule written by its impulse (`engine.closing.impulse_rule`) runs without a branch too, with the
    bits of its loop with one: unequal masses on a torus in equilibrium, where about half the picks collide."""
    g = pb.FlatTorus(4, 6)
    masses = np.random.default_rng(3).uniform(0.5, 2.0, g.n_balls)
    assert branch_free_form(user_rules.collide_spring, 2, True) is not None
    state = _same(monkeypatch, lambda: pb.Simulation(g, _gaussian(g), rule=user_rules.Spring(0.3), masses=masses,
                                                     seed=6),
                  lambda sim: (sim.run(steps=3000), sim.run(collisions=sim.collisions + 100)))
    assert state[2] > 1000


def test_a_curved_surface(monkeypatch):
    """``t_j != -t_i`` (dim 3, the icosahedron's sphere)."""
    g = icosahedron_sphere()
    _same(monkeypatch, lambda: pb.Simulation(g, tangent_velocities(g, 4), seed=9), lambda sim: sim.run(steps=5000))


# ---------------------------------------------------------------- the rules' forms, one pick at a time


@functools.cache
def _pair_kernels(collide, dim: int, flat: bool):
    branchy, free = compiled_form(collide, dim, flat), branch_free_form(collide, dim, flat)

    @njit
    def both(v, units, i, j, a, b, masses, params, w):
        v1, v2 = v.copy(), v.copy()
        return (branchy(v1, units, i, j, a, b, masses, params, WRITE, w), v1,
                free(v2, units, i, j, a, b, masses, params, params[-1], w), v2)

    return both


@pytest.mark.parametrize("collide, factor", [(collide_elastic, 1.0), (collide_equal, 0.85), (collide_masses, 1.7),
                                             (user_rules.collide_spring, 0.3)])
def test_each_rule_form_writes_the_same_bits(collide, factor):
    """Closing speeds below, at and just above the threshold, collisions too small to change a component,
    and zeros of either sign, which a collision may flip without changing a value."""
    both = _pair_kernels(collide, 2, True)
    tau = 4 * 2.0**-53
    params = np.array([factor, tau])
    masses = np.array([1.0, 0.75, 1.5])
    units = np.array([[1.0, -0.0], [0.5, np.sqrt(3) / 2], [-0.0, 1.0]])
    rng = np.random.default_rng(0)
    starts = [rng.standard_normal((3, 2)), np.array([[-0.0, 0.0], [0.0, -0.0], [1e10, -1e10]]),
              np.array([[1e12, 3.0], [-1e12, 0.0], [-0.0, -0.0]])]
    speeds = [-1.0, 0.0, tau, np.nextafter(tau, 1.0), 3 * tau, 1e-9, 0.5, 7.0]
    for v in starts:
        for w in speeds:
            for i, j in ((0, 1), (1, 2), (2, 0)):
                for a in range(3):
                    hit, v1, hit_free, v2 = both(v, units, i, j, a, a, masses, params, w)
                    assert hit == hit_free and np.array_equal(_bits(v1), _bits(v2)), (v, w, i, j, a)


def test_choose_selects_without_changing_a_bit():
    @njit
    def pick(c, a, b):
        return choose(c, a, b)

    assert _bits(np.array([pick(True, -0.0, 0.0)]))[0] == _bits(np.array([-0.0]))[0]
    assert pick(False, 1, 2) == 2 and pick(True, np.inf, 1.0) == np.inf


def test_a_rule_written_whole_has_no_branch_free_form():
    @njit
    def collide(v, units, i, j, a, b, masses, params, dim, flat, write):
        return False

    assert branch_free_form(collide, 2, True) is None
