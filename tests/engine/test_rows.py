"""Contacts read from their index (`engine.rows`): the lattice's row pattern gives every contact of
its tables, and the loop that reads it makes the same picks and the same bits."""

import numpy as np
import pytest
from helpers import pick_loops

import pinnedballs as pb
from pinnedballs.engine.chain import NO_LIMIT
from pinnedballs.engine.margin import new_margin
from pinnedballs.engine.rows import decode, row_pattern
from pinnedballs.engine.sequential.choice import new_tune
from pinnedballs.engine.sequential.loops import NO_PATTERN
from pinnedballs.engine.streams.xoshiro import seed_state
from pinnedballs.rules import collide_elastic, collide_masses
from pinnedballs.schedulers.simple import pick_uniform

LATTICES = [pb.FlatTorus(4, 3), pb.FlatTorus(6, 5), pb.FlatTorus(10, 7), pb.HalfPlane(3, 1), pb.HalfPlane(3, 2),
            pb.HalfPlane(5, 4), pb.HalfPlane(6, 9), pb.HalfPlane(7, 8, orientation="across"), pb.HalfPlane(29, 50)]


def _pattern(geometry):
    c = geometry.contacts
    return row_pattern(c.pairs, c.ends, *geometry.row_shape(), min_balls=1)


@pytest.mark.parametrize("geometry", LATTICES, ids=repr)
def test_the_pattern_decodes_every_contact_of_the_tables(geometry):
    pattern, c = _pattern(geometry), geometry.contacts
    assert pattern is not None
    decoded = np.array([decode(pattern, np.int64(k)) for k in range(geometry.n_contacts)])
    np.testing.assert_array_equal(decoded[:, :2], c.pairs)
    np.testing.assert_array_equal(decoded[:, 2:], c.ends)


def test_tables_without_a_row_pattern_have_none():
    c = pb.HalfPlane(6, 9).contacts
    shuffled = np.random.default_rng(0).permutation(len(c.pairs))
    assert row_pattern(c.pairs[shuffled], c.ends[shuffled], 6, 9, min_balls=1) is None
    ends = c.ends.copy()
    per_row = 3 * 9 - 2
    ends[3 * per_row + 5, 1] = 5 - ends[3 * per_row + 5, 1]  # one contact of row 3 differs from row 1's
    assert row_pattern(c.pairs, ends, 6, 9, min_balls=1) is None
    assert row_pattern(c.pairs, c.ends, 6, 9) is None  # small: the tables stay in cache anyway


def test_only_lattices_offer_a_pattern_and_only_when_large():
    assert pb.HalfPlane(300, 310).row_pattern is not None
    assert pb.FlatTorus(200, 200).row_pattern is not None
    assert pb.HalfPlane(29, 50).row_pattern is None
    assert pb.GraphGeometry(pb.HalfPlane(29, 50).contact_graph()).row_pattern is None


def _limited(loop, geometry, v, pattern, masses, params, seed, steps, collisions=NO_LIMIT, until_frozen=False):
    c = geometry.contacts
    rng, counters, margin = seed_state(seed), np.zeros(4, np.int64), new_margin()
    chunk = steps if collisions == NO_LIMIT and not until_frozen else 4096
    loop(v, c.pairs, c.ends, c.units, masses, params, pattern, np.zeros(1, np.int64), np.zeros(0, np.int64), rng,
         counters, margin, steps, collisions, until_frozen, chunk, np.zeros(1, np.int64), np.empty((0, 2), np.int64),
         new_tune())
    return v, rng, counters, margin


@pytest.mark.parametrize("geometry",
                         [pb.FlatTorus(10, 7), pb.HalfPlane(6, 9), pb.HalfPlane(7, 8, orientation="across")], ids=repr)
@pytest.mark.parametrize("unequal", [False, True])
def test_the_row_loop_gives_the_bits_of_the_table_loops(geometry, unequal):
    loops = pick_loops(collide_masses if unequal else collide_elastic, pick_uniform, 2, True)
    rng = np.random.default_rng(3)
    v0 = rng.normal(size=(geometry.n_balls, 2))
    masses = rng.uniform(0.5, 2.0, geometry.n_balls) if unequal else np.ones(geometry.n_balls)
    params = np.array([2.0 if unequal else 1.0, 1e-14])
    for kwargs in ({"steps": 5000}, {"steps": 50_000, "collisions": 777}):
        runs = [_limited(loop, geometry, v0.copy(), pattern, masses, params, 7, **kwargs)
                for loop, pattern in ((loops.limited, NO_PATTERN), (loops.limited_prefetched, NO_PATTERN),
                                      (loops.limited_rows, _pattern(geometry)))]
        for v, rng_words, counters, margin in runs[1:]:
            np.testing.assert_array_equal(v, runs[0][0])
            np.testing.assert_array_equal(rng_words, runs[0][1])
            np.testing.assert_array_equal(counters, runs[0][2])
            np.testing.assert_array_equal(margin, runs[0][3])
        if "collisions" in kwargs:
            assert runs[0][2][1] == 777 or runs[0][2][0] == 50_000  # the target, or the steps ran out


@pytest.mark.slow
def test_a_large_lattice_runs_its_row_pattern_to_the_same_freeze():
    """A half-plane large enough for the row loop, frozen from one moving ball: the same step,
    collisions and velocities as the table loop (the pattern hidden from the same geometry)."""
    half = pb.HalfPlane(300, 310)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.0, np.sqrt(200.0)]
    runs = []
    for hide in (False, True):
        geometry = pb.HalfPlane(300, 310)
        if hide:
            geometry.__dict__["row_pattern"] = None  # the cached property, as a lattice without a pattern
        sim = pb.Simulation(geometry, v, seed=2)
        sim.run(steps=3_000_000)
        sim.run(collisions=sim.collisions + 5000)
        runs.append((sim.steps, sim.collisions, sim.velocities.copy(), sim.get_state().rng_state))
    assert runs[0][:2] == runs[1][:2]
    np.testing.assert_array_equal(runs[0][2], runs[1][2])
    np.testing.assert_array_equal(runs[0][3], runs[1][3])
