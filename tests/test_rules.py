"""One collision at a time: the laws a single collision must obey.

Each example builds a two-ball geometry with arbitrary unit vectors ``t_i, t_j``
(antiparallel in flat space, or, in 3-D, not: as on a curved surface), arbitrary
velocities and masses, and runs one step, so that the one contact is tried once
(with one contact every scheduler picks it; the scheduler is chosen among those
whose compiled loop the engine tests already use, see `cases.LOOPS`).

Tolerances: rounding in one collision is a few ulps of the quantities involved,
so energies are compared to 1e-12 of the pair's kinetic energy, momenta to 1e-12
of ``m_i |v_i| + m_j |v_j|`` and closing speeds to 1e-12 of ``|v_i| + |v_j|``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import FAST, SCHEDULER_CLASSES, chain, rule_kind, schedulers_for, two_balls
from hypothesis import assume, example, given
from hypothesis import strategies as st
from reference import ReferenceSimulation, closing_speed

import pinnedballs as pb

REL = 1e-12

# velocity components: exact zeros or magnitudes in [1e-6, 1e3] (no subnormal underflow games)
component = st.one_of(
    st.just(0.0),
    st.floats(1e-6, 1e3).flatmap(lambda x: st.sampled_from([x, -x])),
)
mass = st.floats(0.01, 100.0)


@st.composite
def unit_vector(draw, d: int):
    x = np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=d, max_size=d)))
    norm = float(np.linalg.norm(x))
    assume(norm > 0.1)
    return x / norm


@st.composite
def one_contact(draw, flat: bool | None = None, equal_masses: bool | None = None):
    """(geometry, velocities (2, d), masses or None, r) for one contact."""
    d = draw(st.sampled_from([1, 2, 3]))
    t_i = draw(unit_vector(d))
    if flat is None:
        flat = draw(st.booleans()) if d == 3 else True
    t_j = -t_i if flat else draw(unit_vector(d))
    v = np.array(draw(st.lists(component, min_size=2 * d, max_size=2 * d))).reshape(2, d)
    if equal_masses is None:
        equal_masses = draw(st.booleans())
    masses = None if equal_masses else np.array([draw(mass), draw(mass)])
    r = draw(st.one_of(st.just(1.0), st.just(0.0), st.floats(0.0, 1.0)))
    return two_balls(t_i, t_j), v, masses, r


def rule_for(r: float) -> pb.CollisionRule:
    return pb.Elastic() if r == 1.0 else pb.Restitution(r)


def scheduler_name(geom, masses, r) -> str:
    c = geom.contacts
    flat = bool(np.array_equal(c.t_j, -c.t_i))
    unequal = masses is not None and masses[0] != masses[1]
    return schedulers_for(geom.dim, flat, rule_kind(r, unequal))[0]


def collide_once(geom, v, masses, r):
    """Run one step on the engine; return (velocities after, collided?, w before)."""
    sched = SCHEDULER_CLASSES[scheduler_name(geom, masses, r)]()
    sim = pb.Simulation(geom, v, rule=rule_for(r), scheduler=sched, masses=masses, seed=0)
    sim.run(steps=1)
    c = geom.contacts
    w = closing_speed(v.tolist(), 0, 1, c.t_i[0].tolist(), c.t_j[0].tolist())
    assert sim.steps == 1
    return sim.velocities, sim.collisions == 1, w


def pair_scales(v, masses):
    m = np.ones(2) if masses is None else masses
    speeds = np.linalg.norm(v, axis=1)
    return {
        "energy": 0.5 * float(np.sum(m * speeds**2)),
        "momentum": float(np.sum(m * speeds)),
        "speed": float(np.sum(speeds)),
        "m": m,
    }


@FAST
@given(one_contact())
@example((two_balls([-9e-262, 1.0], [9e-262, -1.0]), np.array([[-1.0, -1.0], [0.0, -1.0]]), None, 1.0))  # w = 9e-262
def test_collides_exactly_when_approaching_and_matches_twin(case):
    """A pick collides only if w > 0, and whenever w is more than rounding (1e-12 of the speeds):
    a closing speed of 1e-262 left by cancellation changes no bit, so it is no collision. The
    engine's velocities equal the plain-Python twin's bit for bit."""
    geom, v, masses, r = case
    after, collided, w = collide_once(geom, v, masses, r)
    assert not collided or w > 0.0
    if w > REL * pair_scales(v, masses)["speed"]:
        assert collided
    assert collided == (not np.array_equal(after, v))
    twin = ReferenceSimulation.from_geometry(geom, v, r=r, masses=masses, scheduler=scheduler_name(geom, masses, r))
    twin.run(steps=1)
    assert np.array_equal(after, twin.velocities)
    assert twin.collisions == int(collided)


@FAST
@given(one_contact())
@example((two_balls([1.0, 0.0], [-1.0, 0.0]), np.zeros((2, 2)), None, 1.0))  # w = 0: at rest
@example((two_balls([1.0, 0.0], [-1.0, 0.0]), np.array([[0.0, 3.0], [0.0, -2.0]]), None, 1.0))  # w = 0: sliding past
def test_no_collision_when_not_approaching_leaves_velocities_bit_identical(case):
    geom, v, masses, r = case
    c = geom.contacts
    if closing_speed(v.tolist(), 0, 1, c.t_i[0].tolist(), c.t_j[0].tolist()) > 0.0:
        v = -v  # negating every velocity negates w exactly
    after, collided, w = collide_once(geom, v, masses, r)
    assert w <= 0.0
    assert not collided
    assert np.array_equal(after, v)


@FAST
@given(one_contact())
def test_after_a_collision_closing_speed_is_minus_r_times_before(case):
    """Exact theory: w' = -r w, so the pair no longer approaches (up to rounding when r = 0)."""
    geom, v, masses, r = case
    after, collided, w = collide_once(geom, v, masses, r)
    assume(collided)
    c = geom.contacts
    w_after = closing_speed(after.tolist(), 0, 1, c.t_i[0].tolist(), c.t_j[0].tolist())
    tol = REL * (pair_scales(v, masses)["speed"] + abs(w))
    assert w_after == pytest.approx(-r * w, rel=0, abs=tol)
    assert w_after <= tol


@FAST
@given(one_contact())
def test_energy_loss_is_one_minus_r_squared_half_reduced_mass_w_squared(case):
    """Elastic keeps energy; restitution r loses exactly (1 - r^2)/2 * m_i m_j/(m_i + m_j) * w^2, never gains.

    Holds for any unit vectors t_i, t_j (flat or curved).
    """
    geom, v, masses, r = case
    after, collided, w = collide_once(geom, v, masses, r)
    assume(collided)
    s = pair_scales(v, masses)
    m = s["m"]
    before_e = 0.5 * float(np.sum(m * np.sum(v * v, axis=1)))
    after_e = 0.5 * float(np.sum(m * np.sum(after * after, axis=1)))
    loss = 0.5 * (1.0 - r * r) * m[0] * m[1] / (m[0] + m[1]) * w * w
    tol = REL * s["energy"]
    assert after_e == pytest.approx(before_e - loss, rel=0, abs=tol)
    assert after_e <= before_e + tol
    if r == 1.0:
        assert after_e == pytest.approx(before_e, rel=0, abs=tol)


@FAST
@given(one_contact(flat=True))
def test_momentum_is_conserved_in_flat_space(case):
    geom, v, masses, r = case
    after, collided, w = collide_once(geom, v, masses, r)
    m = pair_scales(v, masses)["m"]
    tol = REL * pair_scales(v, masses)["momentum"]
    np.testing.assert_allclose(m @ after, m @ v, rtol=0, atol=tol)


@FAST
@given(one_contact(flat=True, equal_masses=True))
def test_equal_masses_elastic_exchanges_components_along_line_of_centres(case):
    """The paper's Algorithm 1: normal components are swapped, tangential components kept."""
    geom, v, _, _ = case
    after, collided, w = collide_once(geom, v, None, 1.0)
    assume(collided)
    t = geom.contacts.t_i[0]
    tol = REL * pair_scales(v, None)["speed"]
    assert after[0] @ t == pytest.approx(v[1] @ t, rel=0, abs=tol)
    assert after[1] @ t == pytest.approx(v[0] @ t, rel=0, abs=tol)
    for k in range(2):
        np.testing.assert_allclose(after[k] - (after[k] @ t) * t, v[k] - (v[k] @ t) * t, rtol=0, atol=tol)


@FAST
@given(st.floats(-100, 100), st.floats(-100, 100), mass, mass)
def test_textbook_one_dimensional_elastic_collision(u1, u2, m1, m2):
    """Head-on in 1-D: u1' = ((m1 - m2) u1 + 2 m2 u2) / (m1 + m2), and symmetrically."""
    assume(u1 > u2)  # ball 0 sits left of ball 1 and catches up
    geom = chain(2)
    v = np.array([[u1], [u2]])
    after, collided, _ = collide_once(geom, v, np.array([m1, m2]), 1.0)
    assert collided
    tol = REL * (abs(u1) + abs(u2))
    assert after[0, 0] == pytest.approx(((m1 - m2) * u1 + 2 * m2 * u2) / (m1 + m2), rel=0, abs=tol)
    assert after[1, 0] == pytest.approx(((m2 - m1) * u2 + 2 * m1 * u1) / (m1 + m2), rel=0, abs=tol)


def test_perfectly_inelastic_head_on_pair_ends_with_common_velocity():
    geom = chain(2)
    after, collided, _ = collide_once(geom, np.array([[3.0], [-1.0]]), np.array([1.0, 3.0]), 0.0)
    assert collided
    np.testing.assert_allclose(after[:, 0], [0.0, 0.0], atol=1e-15)  # momentum 3 - 3 = 0


def test_newtons_cradle_passes_the_velocity_down_the_chain_exactly():
    """Five equal balls in a row, the first moving: after one sweep only the last moves, with the same speed."""
    geom = pb.GraphGeometry.from_positions(np.column_stack([2.0 * np.arange(5), np.zeros(5)]))
    v = np.zeros((5, 2))
    v[0, 0] = 1.0
    sim = pb.Simulation(geom, v, scheduler=pb.Sweep(), seed=0)
    assert sim.run_until_frozen(max_steps=100)
    assert sim.steps == 4 and sim.collisions == 4
    assert np.array_equal(sim.velocities[:, 0], [0.0, 0.0, 0.0, 0.0, 1.0])
    assert np.array_equal(sim.velocities[:, 1], np.zeros(5))


def test_restitution_one_is_elastic_bit_for_bit():
    geom = pb.HalfPlane(rows=4, cols=5)
    v = np.random.default_rng(3).standard_normal((geom.n_balls, 2))
    a = pb.Simulation(geom, v, rule=pb.Elastic(), seed=1)
    b = pb.Simulation(geom, v, rule=pb.Restitution(1.0), seed=1)
    a.run(steps=500)
    b.run(steps=500)
    assert np.array_equal(a.velocities, b.velocities) and a.collisions == b.collisions


def test_equal_nonunit_masses_give_the_equal_mass_dynamics():
    """Scaling every mass by the same factor changes nothing (only mass ratios matter)."""
    geom = pb.HalfPlane(rows=4, cols=5)
    v = np.random.default_rng(4).standard_normal((geom.n_balls, 2))
    a = pb.Simulation(geom, v, rule=pb.Restitution(0.6), seed=2)
    b = pb.Simulation(geom, v, rule=pb.Restitution(0.6), masses=np.full(geom.n_balls, 7.5), seed=2)
    a.run(steps=500)
    b.run(steps=500)
    assert np.array_equal(a.velocities, b.velocities)
    assert b.energy() == pytest.approx(7.5 * a.energy(), rel=1e-14)


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize("r", [-0.1, 1.0000001, 2.0, math.nan, math.inf, -math.inf])
def test_restitution_outside_unit_interval_is_refused(r):
    with pytest.raises(ValueError, match=r"^r: .*\[0, 1\]"):
        pb.Restitution(r)


@pytest.mark.parametrize("r", ["0.5", None, True, [0.5]])
def test_restitution_must_be_a_number(r):
    with pytest.raises(TypeError, match=r"^r: .*number"):
        pb.Restitution(r)


@pytest.mark.parametrize("r", [0, 0.0, 0.25, 1, np.float64(0.5)])
def test_restitution_accepts_the_closed_unit_interval(r):
    assert pb.Restitution(r).r == float(r)
