"""Every order of collisions (`pb.explore_orders`) and the scheduler that replays one (`pb.Replay`).

Exact small facts: a collinear chain collides as many times as its velocities have
inversions, in every order; a triangle and the paper's 4-ball rhombus worked by hand;
the search agrees with a plain recursion over every sequence (`reference.OrderTree`),
and every returned order replays through the engine to the reported count, frozen.
"""

from __future__ import annotations

import itertools
import math
import re
from pathlib import Path

import numpy as np
import pytest
from helpers import (
    RHOMBUS_V,
    SQRT3,
    TorusLessOne,
    chain,
    energy,
    icosahedron_sphere,
    momentum,
    rhombus,
    tangent_velocities,
    triangle,
)
from reference import OrderTree, ReferenceSimulation, ReplayPicker, collide
from scipy import stats

import pinnedballs as pb
from pinnedballs.analysis.orders import order_kernels, orders_against_random

P_MIN = 1e-3  # fixed seeds, so the statistical tests are deterministic


def inversions(values) -> int:
    return sum(1 for a, b in itertools.combinations(values, 2) if a > b)


def replay(geom, v, order, **kwargs) -> pb.Simulation:
    """The engine following ``order`` until frozen (at most ``len(order)`` steps)."""
    sim = pb.Simulation(geom, v, scheduler=pb.Replay(order), **kwargs)
    sim.run_until_frozen(max_steps=max(len(order), 1))
    return sim


def assert_replays(geom, v, result, **kwargs):
    """Both orders of ``result`` reach their counts in the engine, one collision per step, ending frozen."""
    for count, order in ((result.min_collisions, result.min_order), (result.max_collisions, result.max_order)):
        assert len(order) == count
        sim = replay(geom, v, order, **kwargs)
        assert (sim.steps, sim.collisions) == (count, count)
        assert sim.is_frozen()


# ---------------------------------------------------------------- exact small facts


@pytest.mark.parametrize("n", [2, 3, 4, 5])
def test_chain_collides_once_per_inversion_in_every_order(n):
    """Every permutation of 0..n-1 as velocities on a 1-D chain: fewest = most = inversions, and
    the velocities end sorted (the exchanges are exact on small integers)."""
    geom = chain(n)
    for perm in itertools.permutations(range(n)):
        v = np.array(perm, dtype=float)[:, None]
        r = pb.explore_orders(geom, v)
        assert r.exhaustive
        assert r.min_collisions == r.max_collisions == inversions(perm), perm
        sim = replay(geom, v, r.max_order)
        np.testing.assert_array_equal(sim.velocities[:, 0], np.arange(n, dtype=float))


def test_chain_with_ties_and_signs_counts_strict_inversions():
    """Equal velocities never collide (w = 0): only strict inversions count, 5 + 0 + 4 + 1 + 0 + 1 = 11."""
    values = [3.0, -1.0, 3.0, 0.5, -1.0, 2.0, 0.5]
    r = pb.explore_orders(chain(len(values)), np.array(values)[:, None])
    assert r.exhaustive and r.min_collisions == r.max_collisions == inversions(values) == 11


def test_triangle_one_or_two_collisions_by_hand():
    """A moves at (1, 0); B and C rest. Live at first: AB (w = 1) and AC (w = 1/2).

    AB first: A stops, B takes (1, 0); AC and BC now separate: 1 collision.
    AC first: A = (3/4, -sqrt3/4), C = (1/4, sqrt3/4); then only AB is live (w = 3/4):
    A = (0, -sqrt3/4), B = (3/4, 0), frozen: 2 collisions. Four states in all.
    """
    geom = triangle()
    v = np.array([[1.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    r = pb.explore_orders(geom, v)
    assert (r.min_collisions, r.max_collisions, r.states, r.exhaustive) == (1, 2, 4, True)
    assert (r.min_order, r.max_order) == ((0,), (1, 0))
    sim = replay(geom, v, r.max_order)
    np.testing.assert_allclose(sim.velocities, [[0.0, -SQRT3 / 4], [0.75, 0.0], [0.25, SQRT3 / 4]], atol=1e-15)
    sim = replay(geom, v, r.min_order)
    np.testing.assert_array_equal(sim.velocities, [[0.0, 0.0], [1.0, 0.0], [0.0, 0.0]])


def test_rhombus_two_to_six_collisions_matches_every_sequence():
    """The paper's rhombus: 2 to 6 collisions for one set of velocities, as a plain recursion
    over every sequence of live contacts finds; the same distinct states too."""
    geom = rhombus()
    r = pb.explore_orders(geom, RHOMBUS_V)
    tree = OrderTree.from_geometry(geom, RHOMBUS_V)
    lengths = {len(s) for s in tree.sequences()}
    assert (r.min_collisions, r.max_collisions) == (min(lengths), max(lengths)) == (2, 6)
    assert r.exhaustive and r.states == len(tree.states())
    assert r.min_order in tree.sequences() and r.max_order in tree.sequences()
    assert_replays(geom, RHOMBUS_V, r)


@pytest.mark.parametrize("case", ["rhombus", "half_plane_2x3", "masses", "restitution"])
def test_search_agrees_with_every_sequence_on_random_velocities(case):
    """Fewest, most and the number of distinct states equal the plain recursion's, for random
    velocities on small systems, with unequal masses and with restitution 0.8 too."""
    geom = pb.HalfPlane(rows=2, cols=3) if case == "half_plane_2x3" else rhombus()
    rng = np.random.default_rng(["rhombus", "half_plane_2x3", "masses", "restitution"].index(case))
    checked = 0
    for _ in range(4):
        v = rng.standard_normal((geom.n_balls, 2))
        masses = rng.uniform(0.5, 2.0, geom.n_balls) if case == "masses" else None
        r_coef = 0.8 if case == "restitution" else 1.0
        rule = pb.Restitution(r_coef) if case == "restitution" else None
        r = pb.explore_orders(geom, v, masses=masses, rule=rule)
        tree = OrderTree.from_geometry(geom, v, r=r_coef, masses=masses)
        lengths = [len(s) for s in tree.sequences()]
        assert (r.min_collisions, r.max_collisions) == (min(lengths), max(lengths))
        assert r.states == len(tree.states())
        checked += r.max_collisions > r.min_collisions
    assert checked >= 1  # at least one case where the order matters


# ---------------------------------------------------------------- replay and physics


@pytest.mark.parametrize("masses", [None, "unequal"])
def test_orders_replay_in_engine_and_twin_bit_for_bit(masses):
    """Both orders on a 2x3 half-plane replay to their counts, and the engine's velocities equal
    the twin's following the same order, bit for bit; energy and momentum conserved."""
    geom = pb.HalfPlane(rows=2, cols=3)
    rng = np.random.default_rng(11)
    v = rng.standard_normal((geom.n_balls, 2))
    m = rng.uniform(0.5, 2.0, geom.n_balls) if masses else None
    r = pb.explore_orders(geom, v, masses=m)
    assert r.exhaustive and r.max_collisions > r.min_collisions
    assert_replays(geom, v, r, masses=m)
    for order in (r.min_order, r.max_order):
        sim = replay(geom, v, order, masses=m)
        twin = ReferenceSimulation.from_geometry(geom, v, masses=m)
        twin.picker = ReplayPicker(order)
        assert twin.run_until_frozen(max_steps=len(order))
        np.testing.assert_array_equal(sim.velocities, twin.velocities)
        assert math.isclose(energy(sim.velocities, m), energy(v, m), rel_tol=1e-13)
        np.testing.assert_allclose(momentum(sim.velocities, m), momentum(v, m), atol=1e-13)


def test_a_frozen_start_has_no_collisions_in_any_order():
    geom = rhombus()
    v = np.array([[-1.0, 0.0], [0.0, -1.0], [0.0, 0.0], [0.0, 0.0]])  # A and B move away from every contact
    r = pb.explore_orders(geom, v)
    assert (r.min_collisions, r.max_collisions, r.min_order, r.max_order, r.states) == (0, 0, (), (), 1)
    assert_replays(geom, v, r)


def test_same_inputs_give_the_same_result():
    geom = pb.HalfPlane(rows=3, cols=3)
    v = np.random.default_rng(5).standard_normal((geom.n_balls, 2))
    assert pb.explore_orders(geom, v, max_states=200, seed=3) == pb.explore_orders(geom, v, max_states=200, seed=3)
    assert pb.explore_orders(geom, v) == pb.explore_orders(geom, v)


# ---------------------------------------------------------------- bounds when max_states stops the search


def test_truncated_search_brackets_the_exhaustive_answer():
    """The paper's set-up on a 3x3 half-plane (one boundary ball moving inward): in exact arithmetic
    5 to 21 collisions over 34,547 distinct states. Stopped early, the figures are bounds reached by
    real orders, and say so."""
    geom = pb.HalfPlane(rows=3, cols=3)
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, math.sqrt(200.0)]
    full = pb.explore_orders(geom, v)
    assert (full.min_collisions, full.max_collisions, full.states, full.exhaustive) == (5, 21, 34_547, True)
    assert full.arithmetic == "exact"
    assert "at least" not in str(full) and "at most" not in str(full)
    for max_states in (1, 100, 5_000):
        part = pb.explore_orders(geom, v, max_states=max_states, restarts=20)
        assert not part.exhaustive and part.states == max_states
        assert full.min_collisions <= part.min_collisions <= part.max_collisions <= full.max_collisions
        assert f"fewest at most {part.min_collisions}" in str(part)
        assert f"most at least {part.max_collisions}" in str(part)
        assert "max_collisions=at least" in repr(part)
        assert_replays(geom, v, part)


def test_exact_and_float_searches_agree_on_the_fewest_and_the_most():
    """On the 3x3 half-plane exact arithmetic finds 5 to 21 over 34,547 states. The float engine,
    which leaves out closing speeds below its remnant threshold, finds the same 5 to 21, over 35,623
    states: 1,076 exact states reached along different orders differ in their last bits. (The float
    engine that counted every bit-changing pick as a collision made it 6 to 70 over 91,484, 54 of
    the 70 rounding remnants.) Every closing speed of the exact most order is positive and above
    1e-3, so leaving out contacts closing at or below any threshold from 1e-14 to 1e-3 changes
    nothing; the orders replay collision for collision in either arithmetic."""
    geom = pb.HalfPlane(rows=3, cols=3)
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, math.sqrt(200.0)]
    exact = pb.explore_orders(geom, v, arithmetic="exact")
    floats = pb.explore_orders(geom, v, arithmetic="float")
    assert (exact.min_collisions, exact.max_collisions, exact.states) == (5, 21, 34_547)
    assert (floats.min_collisions, floats.max_collisions, floats.states) == (5, 21, 35_623)
    assert floats.arithmetic == "float"
    sim = pb.Simulation(geom, v, arithmetic="exact")
    speeds = []
    for k in exact.max_order:
        speeds.append(sim.engine.state.field_chain.field.to_float(sim.engine.state.field_chain.closing(k)))
        assert sim.engine.state.field_chain.collide(k)
    assert min(speeds) > 1e-3
    for threshold in (1e-14, 1e-12, 1e-3):
        r = pb.explore_orders(geom, v, min_closing_speed=threshold)
        assert (r.min_collisions, r.max_collisions, r.exhaustive) == (5, 21, True)
    for order in (exact.min_order, exact.max_order, floats.min_order, floats.max_order):
        for arithmetic in ("exact", "float"):
            sim = pb.Simulation(geom, v, scheduler=pb.Replay(order), arithmetic=arithmetic)
            assert sim.run_until_frozen(max_steps=len(order))
            assert sim.collisions == len(order) and sim.steps == len(order)


@pytest.mark.parametrize("geometry, message", [
    ("torus", r"^velocities: an order returns to a state it passed \(by contact \d+\), so this system can"),
    ("sphere", r"^max_collisions: an order of 300 collisions has not frozen; raise max_collisions"),
])
def test_a_system_that_never_freezes_is_refused(geometry, message):
    """On the torus and the sphere (no boundary) one moving ball keeps the balls colliding
    forever: on the torus (leaving out closing speeds up to 1e-9, so not refused at once) an order
    comes back to a state exactly, on the sphere orders run on."""
    geom = pb.FlatTorus(rows=4, cols=3) if geometry == "torus" else icosahedron_sphere()
    v = np.zeros((geom.n_balls, geom.dim))
    v[0] = [1.0, 0.5] if geometry == "torus" else tangent_velocities(geom, 1)[0]
    slow = {"min_closing_speed": 1e-9} if geometry == "torus" else {}
    with pytest.raises(ValueError, match=message):
        pb.explore_orders(geom, v, max_states=300, max_collisions=300, **slow)


@pytest.mark.parametrize("rule", [pb.Restitution(0.5), pb.Elastic()], ids=["r=0.5", "elastic"])
@pytest.mark.parametrize("arithmetic", ["exact", "float"])
def test_a_torus_no_order_can_freeze_is_refused_at_once(monkeypatch, rule, arithmetic):
    """Issue 34, item 10: Restitution(0.5) on a 4x4 torus gave no answer in 240 s (503 MB): energy
    falls at every collision, so no state repeats, the numbers grow along an order and none ends.
    On a torus frozen means every closing speed 0 (`Contacts.closed_rows`), which elastic collisions
    never reach, nor in exact arithmetic any r > 0: refused before any state is made. (r = 1/2 in
    float64 is not: rounding freezes it.) A torus started frozen is no question."""
    from pinnedballs.analysis.order_systems import ExactSystem, FloatSystem

    made = count_calls(monkeypatch, ExactSystem, "child") + count_calls(monkeypatch, FloatSystem, "child")
    geom = pb.FlatTorus(4, 4)
    v = np.random.default_rng(0).normal(size=(16, 2))
    if arithmetic == "float" and rule.r < 1:
        assert pb.explore_orders(geom, v, rule=rule, max_states=100, arithmetic="float").min_collisions > 0
        return
    with pytest.raises(ValueError, match=r"^velocities: no order of this system ever freezes: on a torus \(every "
                                         r"contact on a closed row of balls\) "):
        pb.explore_orders(geom, v, rule=rule, max_states=1000, arithmetic=arithmetic)
    assert made == []
    r = pb.explore_orders(geom, np.tile([0.25, -1.0], (16, 1)), rule=rule, arithmetic=arithmetic)
    assert (r.min_collisions, r.max_collisions, r.exhaustive) == (0, 0, True)


def test_the_bound_counts_the_work_of_growing_exact_numbers(monkeypatch):
    """With r < 1 exact numbers grow along an order, and a state's time with them. On the 4x4 torus
    less one contact (not refused: one row is open), r = 1/2, max_states=200 and sampled orders of
    2,000 collisions, the 2,200 states made held numbers of up to 5 kB, 3,832 times 2 kB in all (with
    the default floor of 10,000 collisions: up to 25 kB, 126 MB in 19 s; the default bound gave no
    answer in 600 s). A state now counts 1 + b // 2048 for the b bytes of its two collided balls'
    numbers, and the states made stay within the bound's 2,200; the error says why fewer collisions
    were made."""
    import gmpy2

    from pinnedballs.analysis import orders
    from pinnedballs.analysis.order_systems import ExactSystem

    made, child = [], ExactSystem.child

    def recorded(self, node, k, speeds=False):
        out = child(self, node, k, speeds)
        made.append(sum(len(gmpy2.to_binary(q)) for ball in self.pairs[k] for x in out.v[ball] for q in x))
        return out

    monkeypatch.setattr(ExactSystem, "child", recorded)
    monkeypatch.setattr(orders, "WALK_FLOOR", 2000)
    v = np.random.default_rng(0).normal(size=(16, 2))
    with pytest.raises(ValueError, match=r"^max_states: no order reached frozen within the bound: the search of "
                                         r"200 states, then 2,000 collisions along sampled orders \(on numbers "
                                         r"grown large, one counting as several\); "):
        pb.explore_orders(TorusLessOne(), v, rule=pb.Restitution(0.5), max_states=200)
    assert sum(1 + b // 2048 for b in made) <= 200 + 2000


def test_max_states_equal_to_the_count_is_still_exhaustive():
    geom = rhombus()
    n = pb.explore_orders(geom, RHOMBUS_V).states
    assert pb.explore_orders(geom, RHOMBUS_V, max_states=n).exhaustive
    assert not pb.explore_orders(geom, RHOMBUS_V, max_states=n - 1).exhaustive


# ---------------------------------------------------------------- against the paper's random order


def test_random_order_distribution_matches_exact_law_on_rhombus():
    """400 runs of the paper's scheduler on the rhombus: every count within [2, 6], and the counts
    follow the exact law (next collision uniform among live contacts) by a chi-square test."""
    out = orders_against_random(rhombus(), RHOMBUS_V, replicas=400, seed=1)
    assert (out["min_collisions"], out["max_collisions"], out["exhaustive"]) == (2, 6, True)
    assert 2 <= out["random_min"] and out["random_max"] <= 6
    law = OrderTree.from_geometry(rhombus(), RHOMBUS_V).random_order_law()
    assert math.isclose(sum(law.values()), 1.0)
    counts = np.zeros(7)
    for k in range(400):  # the same seeds as orders_against_random
        sim = pb.Simulation(rhombus(), RHOMBUS_V, seed=np.random.SeedSequence(1, spawn_key=(k,)))
        sim.run_until_frozen(max_steps=10**6)
        counts[sim.collisions] += 1
    expected = np.array([law.get(n, 0.0) for n in range(7)]) * 400
    assert counts[:2].sum() == 0 and expected[:2].sum() == 0
    # bins 2, 3, 4 and "5 or 6" (6 alone expects 4.2 runs: too few for the chi-square)
    observed = np.append(counts[2:5], counts[5:].sum())
    assert stats.chisquare(observed, np.append(expected[2:5], expected[5:].sum())).pvalue > P_MIN
    assert out["random_histogram"] == [[n, int(counts[n])] for n in range(7) if counts[n]]
    mean = sum(n * p for n, p in law.items())
    assert math.isclose(out["random_mean"], counts @ np.arange(7) / 400)
    assert abs(out["random_mean"] - mean) < 4 * out["random_sd"] / math.sqrt(400)


# ---------------------------------------------------------------- the kernels against the twin


@pytest.mark.parametrize("kind", ["torus", "masses", "restitution"])
def test_order_kernels_equal_the_twin_bit_for_bit(kind):
    """Live contacts, closing speeds and children of random states equal `reference.collide`'s."""
    geom = pb.FlatTorus(rows=4, cols=4)
    rng = np.random.default_rng(8)
    v = rng.standard_normal((geom.n_balls, 2))
    m = rng.uniform(0.5, 2.0, geom.n_balls) if kind == "masses" else np.ones(geom.n_balls)
    rule = pb.Restitution(0.6) if kind == "restitution" else pb.Elastic()
    collide_fn, params = rule.kernel(kind != "masses")
    kernels = order_kernels(collide_fn, 2, True)
    c = geom.contacts
    twin = ReferenceSimulation.from_geometry(geom, v, r=rule.r, masses=m)
    tables = (c.pairs, c.ends, c.units, m, np.append(params, twin.threshold))
    ks, ws = kernels.live(v, *tables, 0.0)
    assert ks.tolist() == [k for k in range(geom.n_contacts) if twin.live(k)]
    assert ws.tolist() == [twin.w(k) for k in ks]
    threshold = float(np.median(ws))
    fast, _ = kernels.live(v, *tables, threshold)
    assert fast.tolist() == [k for k in ks.tolist() if twin.w(k) > threshold] and 0 < len(fast) < len(ks)
    for k in ks[:6].tolist():
        expected = [list(row) for row in twin.v]
        i, j = twin.pairs[k]
        assert collide(expected, i, j, *twin.units(k), twin.r, twin.masses)
        np.testing.assert_array_equal(kernels.child(v, *tables, k), expected)
        w = v.copy()
        assert kernels.collide_at(w, *tables, k)
        np.testing.assert_array_equal(w, expected)


# ---------------------------------------------------------------- the replay scheduler


def test_replay_refuses_to_go_past_its_order():
    geom = rhombus()
    sim = pb.Simulation(geom, RHOMBUS_V, scheduler=pb.Replay([0, 2]))
    sim.run(steps=2)
    with pytest.raises(ValueError, match=r"^Replay: every contact of its order has been picked"):
        sim.run(steps=1)


def test_replay_resumes_from_a_checkpoint():
    """Two steps, a checkpoint, the rest in a new simulation: the same as one go."""
    geom = rhombus()
    order = pb.explore_orders(geom, RHOMBUS_V).max_order
    whole = replay(geom, RHOMBUS_V, order)
    first = pb.Simulation(geom, RHOMBUS_V, scheduler=pb.Replay(order))
    first.run(steps=2)
    second = pb.Simulation(geom, RHOMBUS_V, scheduler=pb.Replay(order))
    second.set_state(first.get_state())
    assert second.run_until_frozen(max_steps=len(order) - 2)
    np.testing.assert_array_equal(second.velocities, whole.velocities)
    assert (second.steps, second.collisions) == (whole.steps, whole.collisions) == (6, 6)
    other = pb.Simulation(geom, RHOMBUS_V, scheduler=pb.Replay(order[::-1]))
    with pytest.raises(ValueError, match=r"^scheduler_state: holds a different order"):
        other.set_state(first.get_state())


@pytest.mark.parametrize("order, error, message", [
    ([[0, 1]], ValueError, "order: must be a 1-D sequence"),
    ([0.5, 1], TypeError, "order: contact indices must be integers"),
    ([True], TypeError, "order: contact indices must be integers"),
    ([0, -1], ValueError, "order: contact indices must be >= 0"),
    ([0, 5], ValueError, "order: contact 5 does not exist; the geometry has 5 contacts"),
])
def test_replay_bad_order_names_the_argument(order, error, message):
    with pytest.raises(error, match="^" + message):
        pb.Simulation(rhombus(), RHOMBUS_V, scheduler=pb.Replay(order))


# ---------------------------------------------------------------- bad arguments


@pytest.mark.parametrize("kwargs, error, message", [
    ({"geometry": "rhombus"}, TypeError, "geometry: must be a pinnedballs Geometry"),
    ({"velocities": np.zeros((4, 3))}, ValueError, r"velocities: must have shape \(n_balls, dim\)"),
    ({"velocities": [[np.nan, 0]] * 4}, ValueError, "velocities: ball 0 has a NaN"),
    ({"masses": [1, 1, -1, 1]}, ValueError, "masses: must all be finite and > 0"),
    ({"rule": "elastic"}, TypeError, "rule: must be a CollisionRule"),
    ({"max_states": 0}, ValueError, "max_states: must be >= 1, got 0"),
    ({"max_states": 1e6}, TypeError, "max_states: must be an integer"),
    ({"restarts": -1}, ValueError, "restarts: must be >= 0, got -1"),
    ({"max_collisions": 0}, ValueError, "max_collisions: must be >= 1, got 0"),
    ({"seed": -2}, ValueError, "seed: must be a non-negative integer"),
    ({"seed": "x"}, TypeError, "seed: must be a non-negative int or numpy SeedSequence"),
    ({"min_closing_speed": -1e-9}, ValueError, "min_closing_speed: must be finite and >= 0"),
    ({"min_closing_speed": float("nan")}, ValueError, "min_closing_speed: must be finite and >= 0"),
    ({"min_closing_speed": "tiny"}, TypeError, "min_closing_speed: must be a number"),
])
def test_explore_orders_bad_arguments_name_the_argument(kwargs, error, message):
    args = {"geometry": rhombus(), "velocities": RHOMBUS_V, **kwargs}
    with pytest.raises(error, match="^" + message):
        pb.explore_orders(**args)


def test_docs_example_runs_and_says_what_the_page_says():
    """The python block of docs/orders.md: the rhombus, 2 to 6, replayed to 6 collisions, frozen."""
    page = Path(__file__).resolve().parents[2] / "docs" / "orders.md"
    ns: dict = {}
    for block in re.findall(r"```python\n(.*?)```", page.read_text(), flags=re.S):
        exec(compile(block, str(page), "exec"), ns)
    assert str(ns["r"]) in page.read_text()
    assert (ns["r"].min_collisions, ns["r"].max_collisions) == (2, 6)
    assert ns["sim"].collisions == 6 and ns["sim"].is_frozen()


# ---------------------------------------------------------------- bounds that bound (issue 26, item 5)


def test_a_search_bound_beyond_the_memory_there_is_is_refused_at_once():
    """320 bytes a state: 10^13 states need 3.2 PB. Refused before any state is made."""
    import tracemalloc

    geom = pb.HalfPlane(rows=3, cols=3)
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, 1.0]
    tracemalloc.start()
    with pytest.raises(pb.FieldError, match=r"^max_states: a search of 10,000,000,000,000 states of 9 balls needs "
                                            r"about 3.2 PB of memory, more than the ") as info:
        pb.explore_orders(geom, v, max_states=10**13)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert info.value.field == "max_states" and peak < 1 << 20


def count_calls(monkeypatch, cls, name: str) -> list:
    """Every call of ``cls.name`` recorded (its arguments after self), the method still doing its work."""
    calls, method = [], getattr(cls, name)

    def recorded(self, *args, **kwargs):
        calls.append(args)
        return method(self, *args, **kwargs)

    monkeypatch.setattr(cls, name, recorded)
    return calls


def test_an_exact_state_retests_only_the_contacts_at_its_two_balls(monkeypatch):
    """Before, every state of an exact search tested every contact (4,193 on the paper's half-plane,
    about 100 ms a state): a state now tests the at most 11 contacts at the two balls that collided,
    the others keeping their parent's answer, and finds the same states (34,547 on the 3x3 half-plane)."""
    from pinnedballs.analysis.order_systems import ExactSystem

    tested = count_calls(monkeypatch, ExactSystem, "_approaching")
    made = count_calls(monkeypatch, ExactSystem, "child")
    geom = pb.HalfPlane(rows=3, cols=3)
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, math.sqrt(200.0)]
    r = pb.explore_orders(geom, v)
    assert (r.min_collisions, r.max_collisions, r.states, r.exhaustive) == (5, 21, 34_547, True)
    assert len(tested) <= geom.n_contacts + 11 * len(made)


@pytest.mark.slow
def test_a_small_bound_on_a_1450_ball_half_plane_ends_within_it_and_says_why():
    """Issue 26: max_states=1000 on HalfPlane.from_size(100, 50) (1,450 balls) ran more than 300 s (every
    sampled order tested every contact at every step, for up to 10^6 collisions each). Now the whole
    call makes at most 1,000 states and 10,000 more along the sampled orders; this system's orders
    are longer (48,022 collisions at random), so no order reaches frozen within the bound: it says so."""
    from pinnedballs.analysis import order_systems

    geom = pb.HalfPlane.from_size(100, 50)
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, math.sqrt(200.0)]
    made = []
    child = order_systems.ExactSystem.child
    order_systems.ExactSystem.child = lambda self, *a, **k: made.append(1) or child(self, *a, **k)
    try:
        with pytest.raises(ValueError, match=r"^max_states: no order reached frozen within the bound: the search of "
                                             r"1,000 states, then 10,000 collisions along sampled orders; this "
                                             r"system's orders are longer \(raise max_states\), or never end"):
            pb.explore_orders(geom, v, max_states=1000)
    finally:
        order_systems.ExactSystem.child = child
    assert len(made) <= 1_000 + 10_000


def test_progress_counts_the_states_then_the_sampled_orders(capfd):
    geom = pb.HalfPlane(rows=3, cols=3)
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, math.sqrt(200.0)]
    pb.explore_orders(geom, v, max_states=500, restarts=5, progress=True)
    err = capfd.readouterr().err
    assert "orders: 100%" in err and "| 500/500 [" in err and " states/s]" in err
    assert re.search(r"sampled orders: [1-9]\d* collisions \[", err)
    pb.explore_orders(geom, v, max_states=500, restarts=5)
    assert capfd.readouterr().err == ""  # None: not on a terminal, not in a notebook
