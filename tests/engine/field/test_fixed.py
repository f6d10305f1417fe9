"""The fixed-point chain against the rational one (`RationalChain`), collision for collision: the same
collisions at the same steps, the same velocities bit for bit and the same exact values; its exact
policy widening without changing a bit; its certified policy making exact arithmetic's decisions,
or saying in one line that it cannot."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from gmpy2 import mpq
from helpers import SQRT3, chain, chain_along, cubic, fcc_cluster
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs.engine.field.fixed import FixedChain, UncertifiedDecision, lines_of
from pinnedballs.engine.field.fixed_state import CertifiedState
from pinnedballs.engine.field.rational import RationalChain
from pinnedballs.util.errors import FieldError

FEW = settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])


def rational(g, v, **kwargs) -> pb.Simulation:
    """An exact simulation run by the rational chain (today's `RationalChain`), whatever the geometry."""
    sim = pb.Simulation(g, v, arithmetic="exact", **kwargs)
    sim.engine.state.field_chain = RationalChain(g, sim.velocities.copy(), sim.engine.model.masses,
                                                 pb.Elastic().exact_kick)
    sim.velocities = sim.engine.state.field_chain.shadow
    return sim


def with_chain(sim: pb.Simulation, **chain_kwargs) -> pb.Simulation:
    """``sim`` with its fixed-point chain built again with ``chain_kwargs`` (a starting width)."""
    sim.engine.state.field_chain = FixedChain(sim.geometry, sim.velocities.copy(), lines_of(sim.geometry),
                                              sim.arithmetic, **chain_kwargs)
    sim.velocities = sim.engine.state.field_chain.shadow
    return sim


class Log:
    """A collision listener keeping every collision's step and contact."""

    def __init__(self, sim: pb.Simulation):
        self.steps, self.contacts = [], []
        sim.collision_listeners.append(self)

    def __call__(self, steps, contacts):
        self.steps += steps.tolist()
        self.contacts += contacts.tolist()


def run_both(g, v, seed, steps, others=("exact",), chunk=None, **kwargs):
    """The rational chain and the fixed-point ones (``others``) on the same picks, to frozen or
    ``steps``, in calls of ``chunk`` steps: each pair has the same collisions at the same steps."""
    sims = [rational(g, v, seed=seed, **kwargs)] + [
        pb.Simulation(g, v, seed=seed, arithmetic=a, **kwargs) for a in others]
    logs = [Log(s) for s in sims]
    for s in sims:
        if chunk is None:
            s.run(steps=steps, until_frozen=True)  # a torus never freezes: no FreezeWarning to say so
        else:
            while s.steps < steps and not s.run(steps=chunk, until_frozen=True) == 0 and not s.is_frozen():
                pass
    for s, log in zip(sims[1:], logs[1:]):
        assert (log.steps, log.contacts) == (logs[0].steps, logs[0].contacts)
        assert (s.steps, s.collisions, s.is_frozen()) == (sims[0].steps, sims[0].collisions, sims[0].is_frozen())
    return sims


def assert_same_exactly(a: pb.Simulation, b: pb.Simulation) -> None:
    """The same velocities bit for bit and, for two exact runs, the same exact numbers."""
    np.testing.assert_array_equal(a.velocities, b.velocities)
    if a.arithmetic == b.arithmetic == "exact":
        assert np.array_equal(a.get_state().exact, b.get_state().exact)


INWARD_SCALE = np.sqrt(200.0)


def inward(g, scale=INWARD_SCALE) -> np.ndarray:
    v = np.zeros((g.n_balls, g.dim))
    b = g.boundary_center()
    v[b] = -scale * g.boundary.outward[b]
    return v


# ---------------------------------------------------------------- collision for collision


@FEW
@given(rows=st.integers(2, 8), cols=st.integers(2, 10), across=st.booleans(), seed=st.integers(0, 2**20),
       start=st.sampled_from(["inward", "oblique", "several"]))
def test_half_planes_collision_for_collision_with_the_rational_chain(rows, cols, across, seed, start):
    g = pb.HalfPlane(rows, cols, orientation="across" if across else "along")
    rng = np.random.default_rng(seed)
    v = inward(g) if start == "inward" else np.zeros((g.n_balls, 2))
    if start == "oblique":
        v[g.boundary_center()] = np.sqrt(200.0) * np.array([rng.uniform(-0.8, 0.8), 1.0])
    elif start == "several":
        v[rng.choice(g.n_balls, size=min(4, g.n_balls), replace=False)] = rng.normal(size=(min(4, g.n_balls), 2))
    old, exact, certified = run_both(g, v, seed, 10**6, others=("exact", "certified"))
    assert old.is_frozen()
    assert_same_exactly(old, exact)
    assert certified.error_bound[1] > 0 or np.array_equal(certified.velocities, old.velocities)
    np.testing.assert_allclose(certified.velocities, old.velocities, rtol=0, atol=1e-60)


@FEW
@given(seed=st.integers(0, 2**20), n=st.sampled_from([4, 6]), chunk=st.sampled_from([None, 37]))
def test_tori_at_equilibrium_collision_for_collision(seed, n, chunk):
    """Gaussian velocities (every ball moving, every float mantissa full), for 3,000 steps, in one
    call or in calls of 37 steps."""
    g = pb.FlatTorus(n, n)
    v = np.random.default_rng(seed).normal(size=(g.n_balls, 2))
    old, exact, certified = run_both(g, v, seed, 3_000, others=("exact", "certified"), chunk=chunk or 3_000)
    assert old.collisions > 100
    assert_same_exactly(old, exact)
    G, largest = certified.error_bound
    assert np.abs(certified.velocities - old.velocities).max() <= largest + 1e-15 * np.abs(old.velocities).max()


@pytest.mark.parametrize("make", [lambda: chain(9), lambda: cubic(3), lambda: fcc_cluster(2),
                                  lambda: pb.FCC(2, 2, 2), lambda: pb.FlatTorus(4, 6)],
                         ids=["chain", "cubic", "fcc cluster", "fcc", "torus"])
def test_every_field_the_chain_takes_agrees_with_the_rational_chain(make):
    """Q (chains, cubic packings), Q(sqrt 2) (FCC, 3-D), Q(sqrt 3) (the triangular lattice)."""
    g = make()
    v = np.random.default_rng(3).normal(size=(g.n_balls, g.dim))
    old, exact, certified = run_both(g, v, 5, 5_000, others=("exact", "certified"))
    assert old.collisions > 5
    assert_same_exactly(old, exact)


def test_closing_speeds_far_below_the_float_criterion_are_collisions():
    """Two balls approaching at 2^-60 and 2^-1070 (a subnormal float) of each other's speed, and a
    pair whose exact closing speed is zero although their velocities differ in the last bit."""
    g = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0], [10.0, 0.0], [12.0, 0.0], [20.0, 0.0], [22.0, 0.0]])
    v = np.array([[1.0 + 2.0**-52, 0.5], [1.0, 0.0],
                  [2.0**-1070, 0.0], [0.0, 1.0],
                  [3.0, 1.0], [3.0, 1.0 + 2.0**-52]])
    old, exact, certified = run_both(g, v, 0, 100, others=("exact", "certified"))
    assert old.collisions == exact.collisions == 2  # contacts 0 and 1 collide, contact 2 (w = 0) never
    assert_same_exactly(old, exact)
    assert_same_exactly(old, certified)


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.5, SQRT3 / 2)], ids=["horizontal", "slanted"])
def test_a_cradle_stays_exact_in_certified_arithmetic(direction):
    """One ball sent along a line of balls at rest passes everything on: in certified arithmetic at the
    smallest precision the kicks are never rounded (each hands on an omega already rounded), so the
    bounds stay 0 and the run is exact arithmetic's, bit for bit."""
    g = chain_along(12, direction)
    v = np.zeros((12, 2))
    v[0] = 0.7390851332151607 * np.asarray(direction)  # a full mantissa
    v[0, 1] += 0.1  # and a component across the line, kept
    old = rational(g, v, seed=1)
    certified = pb.Simulation(g, v, seed=1, arithmetic="certified", precision=64)
    for s in (old, certified):
        assert s.run_until_frozen(max_steps=10**5)
    assert certified.collisions == old.collisions >= 11 and certified.error_bound == (0.0, 0.0)
    assert_same_exactly(old, certified)


# ---------------------------------------------------------------- exact policy: widening


@pytest.mark.parametrize("start", ["inward", "equilibrium"])
def test_widening_changes_nothing(start):
    """Started one limb wide, the exact policy widens many times; started wide, it never needs to:
    the same collisions, steps and exact numbers."""
    g = pb.HalfPlane.from_size(40, 20) if start == "inward" else pb.FlatTorus(6, 6)
    v = inward(g) if start == "inward" else np.random.default_rng(2).normal(size=(g.n_balls, 2))
    narrow = with_chain(pb.Simulation(g, v, seed=4, arithmetic="exact"))
    wide = with_chain(pb.Simulation(g, v, seed=4, arithmetic="exact"), precision=64 * 40)
    assert narrow.engine.state.field_chain.P == 1 or start == "equilibrium"
    logs = [Log(narrow), Log(wide)]
    for s in (narrow, wide):
        s.run(steps=20_000, until_frozen=True)
    assert narrow.engine.state.field_chain.widenings >= 2 and wide.engine.state.field_chain.widenings == 0
    assert (logs[0].steps, logs[0].contacts) == (logs[1].steps, logs[1].contacts) and narrow.collisions > 50
    assert_same_exactly(narrow, wide)


# ---------------------------------------------------------------- certified policy


def test_a_precision_too_small_to_decide_stops_the_run_in_one_line():
    """At 64 bits the rounding of the half-plane's kicks soon hides an exactly zero closing speed: the
    run stops at the pick it cannot decide, with its counts those of exact arithmetic up to the pick
    before."""
    g = pb.HalfPlane.from_size(20, 10)
    v = inward(g)
    certified = pb.Simulation(g, v, seed=1, arithmetic="certified", precision=64)
    with pytest.raises(UncertifiedDecision) as info:
        certified.run_until_frozen(max_steps=10**6)
    message = str(info.value)
    assert "\n" not in message and message.startswith("arithmetic: certified arithmetic cannot decide contact ")
    assert 'use arithmetic="exact" or a larger precision (now 64 bits)' in message
    step = int(message.split(" at step ")[1].split(":")[0].replace(",", ""))
    assert certified.steps == step - 1
    old = rational(g, v, seed=1)
    old.run(steps=certified.steps)
    assert old.collisions == certified.collisions
    assert isinstance(info.value, ValueError) and info.value.field == "arithmetic"
    certified.run(steps=0)  # the state stays usable, and the same decision fails again
    with pytest.raises(UncertifiedDecision):
        certified.run(steps=10)


@pytest.mark.slow
@pytest.mark.parametrize("length, depth, collisions, steps",
                         [(100, 50, 48_022, 243_682), (200, 100, 492_708, 3_085_842)])
def test_certified_counts_are_the_exact_counts_of_the_paper_half_plane(length, depth, collisions, steps):
    """docs/collisions.md's half-plane (seed 1): the counts of the rational chain, and every collision
    at its step (against the exact policy), in certified arithmetic at 256 bits, where kicks are
    rounded (the velocities need 286 bits at 100x50, 718 at 200x100)."""
    g = pb.HalfPlane.from_size(length, depth)
    v = inward(g)
    exact = pb.Simulation(g, v, seed=1, arithmetic="exact")
    certified = pb.Simulation(g, v, seed=1, arithmetic="certified", precision=256)
    logs = [Log(exact), Log(certified)]
    for s in (exact, certified):
        assert s.run_until_frozen(max_steps=10**9)
        assert (s.collisions, s.steps) == (collisions, steps)
    assert logs[0].steps == logs[1].steps and logs[0].contacts == logs[1].contacts
    G, largest = certified.error_bound
    assert 0 < largest <= G < 1e-60
    assert np.abs(certified.velocities - exact.velocities).max() <= 1e-15 * np.sqrt(200.0)


# ---------------------------------------------------------------- certified policy: narrowing behind the front


def _at_rest(sim: pb.Simulation) -> int:
    """The balls of ``sim``'s fixed-point chain exactly at rest."""
    return int(np.count_nonzero(~np.any(sim.engine.state.field_chain.X, axis=(1, 2, 3))))


def late(g, v, seed, precision, late_precision, every) -> pb.Simulation:
    """A certified simulation narrowing to ``late_precision`` checked every ``every`` steps (0: never)."""
    sim = pb.Simulation(g, v, seed=seed, arithmetic="certified", precision=precision, late_precision=late_precision)
    sim.engine.state.field_chain.every = every
    return sim


def test_narrowing_behind_the_front_keeps_exact_arithmetics_collisions():
    """The paper's half-plane 60x30, seed 5, certified at 384 bits with ``late_precision=128``: it
    narrows to 2 limbs at the first step checked after which no ball is at rest and no ball (at most
    a thousandth of its 510) is exact but too long for 2 limbs; it makes exact arithmetic's
    collisions at the same steps, and every ball's velocity stays within the bound it reports of
    the exact one."""
    g = pb.HalfPlane.from_size(60, 30)
    v = inward(g)
    exact = pb.Simulation(g, v, seed=5, arithmetic="exact")
    narrowing = late(g, v, 5, 384, 128, 1_000)
    logs = [Log(exact), Log(narrowing)]
    for s in (exact, narrowing):
        assert s.run_until_frozen(max_steps=10**7)
    assert (narrowing.collisions, narrowing.steps) == (exact.collisions, exact.steps) and exact.collisions > 5_000
    assert (logs[0].steps, logs[0].contacts) == (logs[1].steps, logs[1].contacts)
    chain = narrowing.engine.state.field_chain
    assert chain.P == 2 and chain.S == 128 - chain.top and chain.narrowed % 1_000 == 0
    before = late(g, v, 5, 384, 128, 0)  # checked by hand: settled at that step, not at the one checked before
    before.run(steps=chain.narrowed - 1_001)
    assert not before.engine.state.field_chain.settled()
    before.run(steps=1_000)
    assert _at_rest(before) == 0 and before.engine.state.field_chain.settled()
    G, largest = narrowing.error_bound
    assert 0.0 < largest <= G < 2.0**-100
    errors = [max(abs(float(sum(a - b for a, b in zip(x, y)))) for x, y in zip(row_a, row_b)) for row_a, row_b in
              zip(exact.engine.state.field_chain.v, chain.v)]
    assert 0.0 < max(errors) <= largest


def test_narrowing_happens_at_one_step_however_the_run_is_split():
    """The same state bit for bit, narrowed at the same step, run whole, in calls of 997 steps, and
    resumed from a state saved before the narrowing."""
    g = pb.HalfPlane.from_size(60, 30)
    v = inward(g)
    whole = late(g, v, 5, 384, 128, 1_000)
    whole.run_until_frozen(max_steps=10**7)
    assert whole.engine.state.field_chain.narrowed is not None and whole.get_state().certified.limbs.shape[-1] == 2
    split, saved = late(g, v, 5, 384, 128, 1_000), None
    while not split.run(steps=997, until_frozen=True) == 0 and not split.is_frozen():
        if saved is None and split.steps > whole.engine.state.field_chain.narrowed // 2:
            saved = split.get_state()
    assert saved is not None and saved.certified.limbs.shape[-1] == 6
    resumed = late(g, v, 5, 384, 128, 1_000)
    resumed.set_state(saved)
    resumed.run_until_frozen(max_steps=10**7)
    for s in (split, resumed):
        assert (s.steps, s.collisions) == (whole.steps, whole.collisions)
        assert s.engine.state.field_chain.narrowed == whole.engine.state.field_chain.narrowed
        assert s.get_state().certified.identical(whole.get_state().certified)
        assert np.array_equal(s.velocities, whole.velocities)


def test_a_decision_failing_after_the_narrowing_says_so():
    """Narrowed too early (by hand, in the middle of the first wave), the half-plane soon meets a closing
    speed the rounding hides; the message names the narrowing."""
    g = pb.HalfPlane.from_size(20, 10)
    sim = late(g, inward(g), 1, 256, 64, 0)
    sim.run(steps=200)
    sim.engine.state.field_chain.narrow(201)
    assert sim.engine.state.field_chain.P == 1 and sim.engine.state.field_chain.narrowed == 201
    with pytest.raises(UncertifiedDecision) as info:
        sim.run_until_frozen(max_steps=10**6)
    assert str(info.value).endswith('use arithmetic="exact" or a larger precision (now 64 bits, the late_precision '
                                    'it narrowed to once the first wave had passed)')


def test_no_narrowing_while_a_ball_rests():
    """A chain whose middle ball is sent towards one end (a Newton's cradle: the balls behind it never
    move, those it passes through come to rest again): balls rest at every step, so the state keeps its
    precision to the freeze, checked at every step."""
    g = chain_along(12, (1.0, 0.0))
    v = np.zeros((12, 2))
    v[5] = [0.7390851332151607, 0.1]
    sim = late(g, v, 2, 256, 64, 1)
    assert sim.run_until_frozen(max_steps=10**5)
    assert _at_rest(sim) == 10 and sim.collisions == 6 and sim.engine.state.field_chain.P == 4
    assert sim.engine.state.field_chain.narrowed is None


# ---------------------------------------------------------------- choosing the arithmetic


@pytest.mark.parametrize("kwargs, words", [
    ({"masses": np.r_[1.0, 2.0, np.ones(10)]}, "the masses are not all equal"),
    ({"rule": pb.Restitution(0.5)}, "collisions are not elastic (restitution 0.5)"),
])
def test_certified_arithmetic_refuses_what_only_the_rational_chain_runs(kwargs, words):
    g = pb.HalfPlane(3, 4)
    v = inward(g)
    with pytest.raises(ValueError) as info:
        pb.Simulation(g, v, arithmetic="certified", **kwargs)
    assert str(info.value).startswith("arithmetic: certified arithmetic needs equal masses")
    assert words in str(info.value)
    assert 'arithmetic="exact" runs it' in str(info.value)
    assert isinstance(pb.Simulation(g, v, arithmetic="exact", **kwargs).engine.state.field_chain, RationalChain)


def test_hcp_keeps_the_rational_chain_and_certified_says_why():
    g = pb.HCP(3, 3, 2, periodic=False)
    v = np.random.default_rng(0).normal(size=(g.n_balls, 3))
    assert isinstance(pb.Simulation(g, v, arithmetic="exact").engine.state.field_chain, RationalChain)
    with pytest.raises(ValueError, match=r"^arithmetic: certified .* not in Q or one Q\(sqrt d\)"):
        pb.Simulation(g, v, arithmetic="certified")


@pytest.mark.parametrize("arithmetic, precision, message", [
    ("certified", 32, "precision: must be an integer in [64, 4096], got 32"),
    ("certified", 2.5, "precision: must be an integer, got 2.5"),
    ("exact", 256, "precision: is the precision of certified arithmetic; this run's is 'exact'"),
    ("float", 256, "precision: is the precision of certified arithmetic; this run's is 'float'"),
])
def test_a_bad_precision_is_named(arithmetic, precision, message):
    g = pb.HalfPlane(3, 4)
    with pytest.raises(ValueError) as info:
        pb.Simulation(g, inward(g), arithmetic=arithmetic, precision=precision)
    assert str(info.value) == message


@pytest.mark.parametrize("arithmetic, options, message", [
    ("certified", {"late_precision": 4160}, "late_precision: must be an integer in [64, 4096], got 4160"),
    ("certified", {"late_precision": 32}, "late_precision: must be an integer in [64, 4096], got 32"),
    ("certified", {"late_precision": 800}, "late_precision: must be at most precision (768 bits), got 800"),
    ("certified", {"precision": 256, "late_precision": 320},
     "late_precision: must be at most precision (256 bits), got 320"),
    ("exact", {"late_precision": 128},
     "late_precision: is certified arithmetic's precision behind the first wave; this run's is 'exact'"),
])
def test_a_bad_late_precision_is_named(arithmetic, options, message):
    g = pb.HalfPlane(3, 4)
    with pytest.raises(ValueError) as info:
        pb.Simulation(g, inward(g), arithmetic=arithmetic, **options)
    assert str(info.value) == message


@pytest.mark.parametrize("arithmetic", ["exact", "certified"])
def test_a_system_at_rest_is_frozen_at_once(arithmetic):
    g = pb.HalfPlane(3, 4)
    sim = pb.Simulation(g, np.zeros((g.n_balls, 2)), arithmetic=arithmetic)
    assert sim.run_until_frozen(max_steps=100) and sim.steps == 0 and sim.approaching() == 0
    assert sim.run(steps=50) == 50 and sim.collisions == 0 and not sim.velocities.any()


_PLAIN = r"""
import json, sys
import numpy as np
import pinnedballs as pb
g = pb.HalfPlane(3, 4)
v = np.zeros((g.n_balls, 2))
v[g.boundary_center()] = [0.3, 14.0]
out = {}
late = pb.HalfPlane.from_size(10, 5)  # narrows at step 120 (checked every 8 steps)
w = np.zeros((late.n_balls, 2))
w[late.boundary_center()] = [0.0, np.sqrt(200.0)]  # inward
for name, arithmetic, options in (("exact", "exact", {}), ("certified", "certified", {"precision": 128}),
                                  ("late", "certified", {"precision": 128, "late_precision": 64})):
    sim = pb.Simulation(*((late, w) if name == "late" else (g, v)), seed=3 if name == "late" else 2,
                        arithmetic=arithmetic, **options)
    if name == "late":
        sim.engine.state.field_chain.every = 8
    sim.run_until_frozen(10**5)
    state = sim.get_state()
    out[name] = [sim.steps, sim.collisions, sim.velocities.tolist(),
                 getattr(sim.engine.state.field_chain, "narrowed", None),
                 state.exact.tolist() if state.exact is not None else state.certified.limbs.tolist()]
print(json.dumps(out))
"""


@pytest.mark.slow
def test_the_compiled_chain_and_its_plain_python_twin_agree_bit_for_bit():
    """With NUMBA_DISABLE_JIT=1 every kernel runs as plain Python (the limbs' accumulator on Python's
    integers): the same steps, collisions, velocities and fixed-point integers as compiled."""
    import json
    import os
    import subprocess
    import sys

    env = dict(os.environ, NUMBA_DISABLE_JIT="1", PYTHONWARNINGS="ignore::RuntimeWarning")
    plain = subprocess.run([sys.executable, "-c", _PLAIN], capture_output=True, text=True, env=env, check=True)
    compiled = subprocess.run([sys.executable, "-c", _PLAIN], capture_output=True, text=True, check=True)
    a, b = json.loads(plain.stdout), json.loads(compiled.stdout)
    assert a == b and a["exact"][1] > 10 and a["exact"][:2] == a["certified"][:2]
    assert a["certified"][3] is None and a["late"][3] == 120 and a["late"][1] == 25  # narrowed, at the same step


# ---------------------------------------------------------------- certified policy past 960 bits


def _deep_velocities(g, bits: int, seed: int) -> list:
    """Exact velocities ``(n_balls, 2)`` of Q(sqrt 3) elements whose coefficients have ``bits``
    fractional bits: every kick of a certified run narrower than that rounds."""
    rng = np.random.default_rng(seed)
    tiny = mpq(1, 1 << bits)

    def coefficient():
        return mpq(int(rng.integers(-2**20, 2**20)), 1 << 22) + int(rng.integers(1, 2**40)) * tiny

    return [[(coefficient(), coefficient()) for _ in range(2)] for _ in range(g.n_balls)]


def test_certified_past_960_bits_decides_as_exact_arithmetic_within_its_bounds():
    """A 1,536-bit certified run (bounds near 2^-1,500, below the smallest float) of velocities with
    1,519 fractional bits, so that every kick rounds: exact arithmetic's collisions at the same
    steps, and every ball's velocity within the bound it reports of the exact one, checked in
    rationals (in units of the last place: 2^-1,500 is no float)."""
    g = pb.HalfPlane(8, 6)
    exact, certified = rational(g, inward(g), seed=3), pb.Simulation(g, inward(g), seed=3, arithmetic="certified",
                                                                     precision=1536)
    chain = certified.engine.state.field_chain
    deep = _deep_velocities(g, chain.S - 6, seed=1)
    for s in (exact, certified):
        s.engine.state.field_chain.set_velocities(deep)
        s.velocities = s.engine.state.field_chain.sync()
    assert chain.P == 24 and chain.S > 1500 and np.array_equal(exact.velocities, certified.velocities)
    logs = [Log(exact), Log(certified)]
    for s in (exact, certified):
        assert s.run_until_frozen(max_steps=10**5)
    assert (logs[0].steps, logs[0].contacts) == (logs[1].steps, logs[1].contacts) and exact.collisions > 150
    state = certified.get_state().certified
    assert state.bound_scale == chain.S and 0 < state.bounds.max() < 2.0**40
    G, largest = certified.error_bound
    assert largest == 5e-324 and G == 5e-324  # below the smallest float: reported as it, never 0
    per_ball = np.min(np.hypot(state.bounds[:, 0], state.bounds[:, 1]), axis=1)
    unit, sqrt3 = 1 << chain.S, mpq(math.isqrt(3 << 6000), 1 << 3000)  # within 2^-3000
    worst = 0.0
    for b, (row_e, row_c) in enumerate(zip(exact.engine.state.field_chain.v, chain.v)):
        err = [float(((x[0] - y[0]) + (x[1] - y[1]) * sqrt3) * unit) for x, y in zip(row_e, row_c)]
        size = float(np.hypot(*err))
        assert size <= per_ball[b], (b, size, per_ball[b])
        worst = max(worst, size)
    assert worst > 0.1  # the rounding is real, in last places


def test_an_exact_zero_hidden_by_rounding_past_960_bits_stops_the_run_in_one_line():
    """Every ball moving with one velocity: exactly frozen, every closing speed exactly 0. With a
    bound of one last place (2^-1,525) on every ball, no decision can be certified: the first pick
    stops the run and the message gives the bound in powers of 2 (below the smallest float)."""
    g = pb.HalfPlane(5, 4)
    sim = pb.Simulation(g, inward(g), seed=2, arithmetic="certified", precision=1536)
    chain = sim.engine.state.field_chain
    chain.set_velocities([[(mpq(3, 8), mpq(0)), (mpq(-1, 4), mpq(1, 16))] for _ in range(g.n_balls)])
    sim.velocities = chain.sync()
    state = sim.get_state()
    c = state.certified
    sim.set_state(state.replace(certified=dataclasses.replace(c, bounds=np.ones_like(c.bounds), rounding=1.0)))
    assert sim.error_bound == (5e-324, 5e-324)
    with pytest.raises(UncertifiedDecision) as info:
        sim.run(steps=1)
    message = str(info.value)
    assert "\n" not in message and sim.steps == 0
    assert f"its closing speed 0 is within the error bound 1 * 2^-{chain.S - 1}" in message  # 2 (1 + 2^-50) last places


def test_a_certified_state_of_the_step_order_bound_rule_is_refused_in_one_line():
    """States of pinnedballs < 1.0 held their bounds absolute (``bound_scale`` 0) and grew them under the bound
    rule in step order (``bound_batch`` 0), which the chain no longer keeps: such a state is refused in one line
    saying why, and the simulation keeps the state it had."""
    g = pb.HalfPlane.from_size(40, 20)  # rounds at 128 bits
    half = pb.Simulation(g, inward(g), seed=1, arithmetic="certified", precision=128)
    while not half.get_state().certified.bounds.any():  # to the first rounding, and a little further
        half.run(steps=500)
    half.run(steps=500)
    state = half.get_state()
    c = state.certified
    old = CertifiedState(c.limbs, c.scale, np.ldexp(c.bounds, -c.scale), math.ldexp(c.rounding, -c.scale), 0)
    assert old.bound_batch == 0
    resumed = pb.Simulation(g, inward(g), seed=1, arithmetic="certified", precision=128)
    before = resumed.get_state()
    with pytest.raises(FieldError, match=r"^certified: a state written under the step-order bound rule of "
                                         r"pinnedballs < 1\.0 does not resume; run it again from its start$"):
        resumed.set_state(state.replace(certified=old))
    assert resumed.get_state().identical(before) and resumed.steps == 0
