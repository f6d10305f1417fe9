"""The most collisions over velocities and orders (`pb.search_max_collisions`).

Known answer: a collinear chain of n balls collides once per inversion of its velocities in every
order, so at most n(n-1)/2 times, exactly when its velocities decrease along the chain. The result's
order replays exactly; the search is seeded; it never does worse than its start; a system that never
freezes, or has no exact arithmetic, is treated as documented.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import RHOMBUS_V, SQRT3, chain, chain_along, icosahedron_sphere, rhombus, triangle

import pinnedballs as pb
from pinnedballs.analysis.maxima import moved, normalised, random_velocities


def star() -> pb.GraphGeometry:
    """A centre touching three balls at 120 degrees (4 balls, 3 contacts, Q(sqrt 3))."""
    return pb.GraphGeometry.from_positions([[0, 0], [2, 0], [-1, SQRT3], [-1, -SQRT3]])


def assert_replays_exactly(geom, r) -> None:
    """The result's order, replayed in exact arithmetic, collides at every pick and ends frozen."""
    assert len(r.order) == r.collisions
    sim = pb.Simulation(geom, r.velocities, scheduler=pb.Replay(r.order), arithmetic="exact")
    assert sim.run_until_frozen(max_steps=len(r.order))
    assert sim.steps == sim.collisions == r.collisions


# ---------------------------------------------------------------- the known answer: a chain


@pytest.mark.parametrize("dim", [1, 2])
@pytest.mark.parametrize("n", [2, 3, 4, 5, 6])
def test_a_chain_makes_every_pair_collide_once_at_most(n, dim):
    """The search finds n(n-1)/2 and no more, every order reaching it (fewest = most), with velocities
    strictly decreasing along the chain: every pair an inversion."""
    geom = chain(n) if dim == 1 else chain_along(n, (1.0, 0.0))
    r = pb.search_max_collisions(geom, trials=200, seed=0)
    assert r.collisions == r.min_collisions == n * (n - 1) // 2
    assert r.exhaustive_orders and r.arithmetic == "exact"
    assert np.all(np.diff(r.velocities[:, 0]) < 0)
    assert_replays_exactly(geom, r)


# ---------------------------------------------------------------- the result


def test_the_result_replays_exactly_and_its_orders_are_bracketed():
    """On the star the result's order replays exactly to its count, frozen; the count is the most over
    every order for those velocities (explore_orders, exact, agrees), the fewest too."""
    geom = star()
    r = pb.search_max_collisions(geom, trials=60, seed=3, patience=10)
    assert_replays_exactly(geom, r)
    orders = pb.explore_orders(geom, r.velocities, arithmetic="exact")
    assert r.exhaustive_orders and orders.exhaustive
    assert (r.min_collisions, r.collisions, r.states) == (orders.min_collisions, orders.max_collisions, orders.states)
    assert r.min_collisions < r.collisions
    assert r.velocities.shape == (4, 2) and r.velocities.dtype == np.float64
    assert not r.velocities.flags.writeable
    assert 0.5 <= np.abs(r.velocities).max() < 1.0  # normalised by a power of two
    assert r.trials == 60 and 1 <= r.found_at <= 60
    assert 2 <= r.climbs <= math.ceil(60 / 11)  # a climb lasts at least patience + 1 trials
    assert f"Most collisions found: {r.collisions} (best of 60 trials in {r.climbs} climbs" in str(r)


def test_same_seed_same_result_and_another_seed_other_velocities():
    geom = rhombus()
    a, b = (pb.search_max_collisions(geom, trials=40, seed=7) for _ in range(2))
    assert np.array_equal(a.velocities, b.velocities)
    assert (a.collisions, a.order, a.min_collisions, a.found_at) == (b.collisions, b.order, b.min_collisions,
                                                                     b.found_at)
    c = pb.search_max_collisions(geom, trials=40, seed=np.random.SeedSequence(8))
    assert not np.array_equal(a.velocities, c.velocities)


@pytest.mark.parametrize("case", ["rhombus", "triangle", "star"])
def test_never_fewer_than_the_most_over_orders_of_its_start(case):
    """From ``start``, the most found is at least the most over orders of the start's velocities; with
    one trial it is exactly that, for the start scaled by a power of two (which changes no count)."""
    geom = {"rhombus": rhombus, "triangle": triangle, "star": star}[case]()
    v = RHOMBUS_V if case == "rhombus" else np.random.default_rng(4).standard_normal((geom.n_balls, 2))
    most = pb.explore_orders(geom, v).max_collisions
    one = pb.search_max_collisions(geom, trials=1, start=v)
    assert one.collisions == most and one.found_at == 1
    assert np.array_equal(one.velocities, normalised(v))  # v times a power of two
    assert pb.search_max_collisions(geom, trials=40, start=v).collisions >= most


def test_rhombus_beats_the_papers_example():
    """The paper's rhombus velocities reach 6 in their most order; the search finds more: 7."""
    r = pb.search_max_collisions(rhombus(), trials=100, seed=0, start=RHOMBUS_V)
    assert pb.explore_orders(rhombus(), RHOMBUS_V).max_collisions == 6
    assert r.collisions == 7 and r.exhaustive_orders


# ---------------------------------------------------------------- velocities and moves


def test_counts_do_not_depend_on_the_scale_of_the_velocities():
    """A collision is linear in the velocities and liveness is a sign: c v has the counts of v (c > 0)."""
    geom = rhombus()
    v = np.random.default_rng(5).standard_normal((4, 2))
    base = pb.explore_orders(geom, v)
    for c in (2.0**-30, 0.3, 7.0, 1e6):
        r = pb.explore_orders(geom, c * v)
        assert (r.min_collisions, r.max_collisions) == (base.min_collisions, base.max_collisions)


def test_normalised_velocities_are_scaled_exactly_by_a_power_of_two():
    rng = np.random.default_rng(1)
    for scale in (1e-300, 1e-3, 1.0, 3.0, 1e200):
        v = scale * rng.standard_normal((5, 2))
        w = normalised(v)
        assert 0.5 <= np.abs(w).max() < 1.0
        exponent = math.frexp(np.abs(v).max())[1]
        assert np.array_equal(np.ldexp(w, exponent), v)
    r = random_velocities(rng, 4, 3)
    assert r.shape == (4, 3) and 0.5 <= np.abs(r).max() < 1.0


def test_a_move_swaps_two_balls_or_moves_one():
    """About a quarter of the moves exchange two balls' velocities; the others change one ball's and
    scale the whole by a power of two (so every other ball keeps its velocity's direction exactly)."""
    rng = np.random.default_rng(2)
    v = random_velocities(rng, 6, 2)
    swaps = 0
    for _ in range(200):
        w = moved(v, rng)
        differ = np.flatnonzero(np.any(w != v, axis=1))
        if len(differ) == 2 and np.array_equal(w[differ], v[differ[::-1]]):
            swaps += 1
            continue
        kept = max(np.sum(np.all(w == c * v, axis=1)) for c in (w[:, 0] / v[:, 0]))
        assert kept == 5
    assert 30 < swaps < 70


# ---------------------------------------------------------------- refusals and errors


@pytest.mark.parametrize("geometry, words", [
    ("torus", "geometry: FlatTorus has no most collisions until frozen: velocities: no order of this system ever "
              "freezes: on a torus"),
    ("sphere", "geometry: GraphGeometry has no most collisions until frozen: max_collisions: an order of 2,000"),
])
def test_a_system_that_never_freezes_is_refused(geometry, words):
    geom = pb.FlatTorus(rows=4, cols=3) if geometry == "torus" else icosahedron_sphere()
    with pytest.raises(pb.FieldError) as info:
        pb.search_max_collisions(geom, trials=3, max_collisions=2000)
    assert info.value.field == "geometry"
    assert str(info.value).startswith(words) and "\n" not in str(info.value)


def test_without_exact_arithmetic_the_search_is_in_float():
    """A chain along a direction at 1 radian has normals in no known number field: ``"auto"`` searches
    and replays in float (the engine's remnant threshold), still finding n(n-1)/2; ``"exact"`` refuses."""
    geom = chain_along(4, (math.cos(1.0), math.sin(1.0)))
    r = pb.search_max_collisions(geom, trials=100, seed=0)
    assert r.arithmetic == "float" and r.exhaustive_orders
    assert r.collisions == r.min_collisions == 6
    sim = pb.Simulation(geom, r.velocities, scheduler=pb.Replay(r.order))
    assert sim.run_until_frozen(max_steps=6) and sim.collisions == sim.steps == 6
    with pytest.raises(pb.FieldError, match=r"^arithmetic: exact arithmetic needs every contact normal"):
        pb.search_max_collisions(geom, trials=1, arithmetic="exact")
    assert pb.search_max_collisions(chain(3), trials=5, arithmetic="float").arithmetic == "float"


@pytest.mark.parametrize("kwargs, message", [
    ({"trials": 0}, "trials: must be an integer >= 1, got 0"),
    ({"trials": 2.5}, "trials: must be an integer, got 2.5"),
    ({"seed": -1}, "seed: must be a non-negative integer, got -1"),
    ({"seed": "x"}, "seed: must be a non-negative int or numpy SeedSequence, got str"),
    ({"patience": 0}, "patience: must be an integer >= 1, got 0"),
    ({"max_states": 0}, "max_states: must be an integer >= 1, got 0"),
    ({"final_states": -5}, "final_states: must be an integer >= 1, got -5"),
    ({"max_collisions": True}, "max_collisions: must be an integer, got True"),
    ({"arithmetic": "fast"}, "arithmetic: must be 'auto' or 'exact' or 'float', got 'fast'"),
    ({"start": np.zeros((3, 1))}, "start: must have shape (n_balls, dim) = (4, 2), got (3, 1)"),
    ({"start": np.zeros((4, 2))}, "start: is all zero: no direction to start from"),
    ({"start": np.full((4, 2), np.nan)}, "start: has a NaN or infinite component"),
    ({"start": [["a", "b"]] * 4}, "start: must be an array of numbers"),
])
def test_bad_arguments_are_one_line_naming_the_argument(kwargs, message):
    with pytest.raises(pb.FieldError) as info:
        pb.search_max_collisions(rhombus(), **kwargs)
    assert str(info.value).startswith(message) and "\n" not in str(info.value)
    assert info.value.field == message.split(":")[0]


def test_a_geometry_must_be_a_geometry_with_contacts():
    with pytest.raises(pb.FieldTypeError, match=r"^geometry: must be a pinnedballs Geometry, got list$"):
        pb.search_max_collisions([[0, 0], [2, 0]])
    apart = pb.GraphGeometry.from_positions([[0.0, 0.0], [5.0, 0.0]])
    with pytest.raises(pb.FieldError, match=r"^geometry: has no contacts"):
        pb.search_max_collisions(apart)
