"""The paper's chain by deterministic reservations on threads (`engine.threads.reservations`): on the counter
stream, the bits of the sequential loop (velocities, counters, stream, margin) for any number of threads,
any batch size and every kind of limit."""

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.chain import COUNTERS, LIVE, NO_LIMIT, Chain
from pinnedballs.engine.margin import new_margin
from pinnedballs.engine.rows import decode, row_pattern
from pinnedballs.engine.sequential.choice import new_tune
from pinnedballs.engine.sequential.loops import NO_PATTERN, live_kernel, loops
from pinnedballs.engine.streams.philox import counter_stream
from pinnedballs.engine.streams.xoshiro import seed_state
from pinnedballs.engine.threads.reservations import (
    BALLS_PER_WORD,
    CROSSING,
    MAX_CROSSING_SHARE,
    MIN_BATCH,
    ReservationChain,
    batch_size,
    range_bounds,
    row_contact,
)
from pinnedballs.engine.threads.tuning import using
from pinnedballs.rules import threshold


def _system(geometry, start, rule=None, masses=None):
    """``(geometry, v, masses, collide, params)``: one moving ball on the boundary (``start = "one ball"``)
    or Gaussian velocities, the rule's kernel and its params with the threshold last (as a simulation
    makes them)."""
    if start == "one ball":
        v = np.zeros((geometry.n_balls, geometry.dim))
        v[geometry.boundary_center()] = [0.4, np.sqrt(200.0)]
    else:
        v = np.random.default_rng(5).normal(size=(geometry.n_balls, geometry.dim))
    masses = np.ones(geometry.n_balls) if masses is None else masses
    collide, params = (rule or pb.Elastic()).kernel(bool(np.all(masses == masses[0])))
    return geometry, v, masses, collide, np.append(params, threshold(v, masses))


def _limits(system, kwargs):
    """``(max_steps, max_collisions, until_frozen, chunk)`` as a simulation hands them to the loops."""
    steps, collisions, frozen = kwargs.get("steps", NO_LIMIT), kwargs.get("collisions", NO_LIMIT), kwargs.get(
        "frozen", False)
    plain = collisions == NO_LIMIT and not frozen
    return steps, collisions, frozen, 1 << 23 if plain else max(4096, 4 * system[0].n_contacts)


def _loop(system, pattern):
    """The sequential limited loop of the counter stream's selector, and that selector's ``aux`` (its own)."""
    g, collide = system[0], system[3]
    s = pb.UniformRandomPair(stream="counter").selector(g)
    assert s.counter
    compiled = loops(collide, s.select, s.begin, s.changed, s.skips, g.dim, g.contacts.flat)
    return (compiled.limited_rows if pattern is not NO_PATTERN else compiled.limited), np.copy(s.aux)


def _arrays(system, seed):
    g, v, masses, collide, params = system
    c = g.contacts
    return (Chain(v.copy(), c.pairs, c.ends, c.units, masses, params), counter_stream(seed_state(seed)),
            np.zeros(COUNTERS, np.int64), new_margin())


def _sequential(system, kwargs, seed=9, pattern=NO_PATTERN):
    """The sequential loop on the counter stream: ``(taken, v, rng, counters, margin)``."""
    chain, rng, counters, margin = _arrays(system, seed)
    limited, aux = _loop(system, pattern)
    steps, collisions, frozen, chunk = _limits(system, kwargs)
    taken = limited(*chain, pattern, np.zeros(1, np.int64), aux, rng, counters, margin, steps, collisions, frozen,
                    chunk, np.zeros(1, np.int64), np.empty((0, 2), np.int64), new_tune())
    return taken, chain.v, rng, counters, margin


def _reserved(system, kwargs, batch, seed=9, pattern=NO_PATTERN, ranges=2, threads=None, split=None):
    """The same run by reservations on ``ranges`` ranges and numba's ``threads`` (None: all), in calls of at
    most ``split`` steps each (None: one call) until the limit is reached."""
    g, collide = system[0], system[3]
    chain, rng, counters, margin = _arrays(system, seed)
    limited, aux = _loop(system, pattern)
    reserved = ReservationChain.build(collide, g.dim, g.contacts.flat, g.contacts.pairs, g.n_balls,
                                      pattern is not NO_PATTERN, ranges, batch=batch)
    assert reserved is not None and reserved.batch == batch
    _, any_live = live_kernel(collide, g.dim, g.contacts.flat)
    steps, collisions, frozen, chunk = _limits(system, kwargs)
    taken = 0
    with using(threads):
        while True:
            part = steps - taken if split is None else min(split, steps - taken)
            taken += reserved.run(chain, pattern, limited, any_live, np.zeros(1, np.int64), aux, rng, counters, margin,
                                  part, collisions, frozen, chunk)
            if taken >= steps or counters[1] >= collisions or (frozen and counters[LIVE] == 0):
                break
    return taken, chain.v, rng, counters, margin


def _same(one, many):
    """The same steps, velocities (bit patterns), stream words, counters and margin."""
    assert one[0] == many[0]
    np.testing.assert_array_equal(one[1].view(np.uint64), many[1].view(np.uint64))
    for a, b in zip(one[2:], many[2:]):
        np.testing.assert_array_equal(a, b)


BATCHES = [1, 3, 64, 1000, 5000]  # 5000: more steps than balls


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("batch", BATCHES)
def test_one_ball_on_a_half_plane_freezes_at_the_same_step(threads, batch):
    """The paper's half-plane from one moving ball, run until frozen: the same last collision (the run
    ends right after it), collisions, velocities, stream and margin, on one thread or two."""
    system = _system(pb.HalfPlane(40, 60), "one ball")
    one = _sequential(system, {"frozen": True})
    many = _reserved(system, {"frozen": True}, batch, threads=threads)
    _same(one, many)
    assert many[3][LIVE] == 0 and many[3][3] == many[3][0]  # frozen, and stopped right after the last collision


@pytest.mark.parametrize("batch", BATCHES)
@pytest.mark.parametrize("kwargs", [{"steps": 300_001}, {"collisions": 40_001}], ids=["steps", "collisions"])
def test_a_flat_torus_with_gaussian_velocities_keeps_the_bits(kwargs, batch):
    """A torus (its wrap-around contacts join the first and the last range) keeps colliding: a steps limit,
    and a collision target that stops right after its collision."""
    system = _system(pb.FlatTorus(40, 60), "gaussian")
    one = _sequential(system, kwargs)
    many = _reserved(system, kwargs, batch)
    _same(one, many)
    if "collisions" in kwargs:
        assert many[3][1] == kwargs["collisions"] and many[3][3] == many[3][0]


@pytest.mark.parametrize("rule", [pb.Elastic(), pb.Restitution(0.5)], ids=["elastic", "restitution 0.5"])
@pytest.mark.parametrize("batch", [3, 64, 5000])
def test_unequal_masses_keep_the_bits(rule, batch):
    half = pb.HalfPlane(40, 60)
    system = _system(half, "gaussian", rule, np.random.default_rng(6).uniform(0.5, 2.0, half.n_balls))
    for kwargs in ({"steps": 200_000}, {"collisions": 30_000}):
        _same(_sequential(system, kwargs), _reserved(system, kwargs, batch))


@pytest.mark.parametrize("batch", [1, 64, 2000])
def test_a_three_dimensional_packing_under_restitution_keeps_the_bits(batch):
    """An FCC packing (12 contacts a ball, 12 % of them joining the two ranges), Gaussian velocities in
    3-D, restitution 0.5 (equal masses): to a collision target, then until frozen."""
    system = _system(pb.FCC(6, 6, 6), "gaussian", pb.Restitution(0.5))
    for kwargs in ({"collisions": 50_000}, {"frozen": True}):
        _same(_sequential(system, kwargs), _reserved(system, kwargs, batch))


@pytest.mark.parametrize("batch", [64, 3000])
def test_the_row_pattern_and_three_ranges_on_two_threads_keep_the_bits(batch):
    """Contacts read from the lattice's row pattern, the balls cut into more ranges than threads run them."""
    half = pb.HalfPlane(40, 60)
    pattern = row_pattern(half.contacts.pairs, half.contacts.ends, 40, 60, min_balls=1)
    assert pattern is not None
    for start, kwargs in (("gaussian", {"steps": 250_000}), ("one ball", {"frozen": True})):
        system = _system(half, start)
        _same(_sequential(system, kwargs, pattern=pattern), _reserved(system, kwargs, batch, pattern=pattern, ranges=3))


def test_forty_ranges_on_two_threads_keep_the_bits():
    """Many more ranges than threads: a long, narrow half-plane cut into 40 ranges (12 % of its contacts
    crossing), run by numba's two threads."""
    system = _system(pb.HalfPlane(220, 24), "gaussian")
    for kwargs in ({"steps": 300_000}, {"collisions": 40_000}):
        _same(_sequential(system, kwargs), _reserved(system, kwargs, 4096, ranges=40))


@pytest.mark.parametrize("kwargs", [{"steps": 400_000}, {"collisions": 60_000}, {"frozen": True}],
                         ids=["steps", "collisions", "until frozen"])
def test_a_run_split_into_calls_is_the_run_in_one(kwargs):
    """Calls of 33,333 steps each (each stopping mid-batch), up to the limit, leave what one call leaves."""
    system = _system(pb.HalfPlane(40, 60), "gaussian" if "frozen" not in kwargs else "one ball")
    _same(_sequential(system, kwargs), _reserved(system, kwargs, 777, split=33_333))


def test_ranges_are_whole_words_of_balls_with_equal_shares_of_the_contacts():
    half = pb.HalfPlane(100, 60)
    pairs = half.contacts.pairs
    bounds = range_bounds(pairs, half.n_balls, 3)
    assert bounds[0] == 0 and bounds[-1] == half.n_balls and np.all(bounds[1:-1] % BALLS_PER_WORD == 0)
    low = np.searchsorted(bounds, pairs.min(axis=1), side="right") - 1
    shares = np.bincount(low, minlength=3) / len(pairs)
    assert np.all(np.abs(shares - 1 / 3) < 0.02)
    random_pairs = np.random.default_rng(1).integers(0, 2000, size=(6000, 2))
    assert range_bounds(random_pairs, 2000, 2) is None  # half the contacts would join the two ranges
    assert MAX_CROSSING_SHARE < 0.5
    assert ReservationChain.build(pb.Elastic().kernel(True)[0], 2, True, pairs, half.n_balls, False, 1) is None
    assert range_bounds(pairs[:10], 100, 2) is None  # too few balls for two words


@pytest.mark.parametrize("geometry", [pb.HalfPlane(100, 60), pb.FlatTorus(40, 60)], ids=["half-plane", "torus"])
def test_a_contact_read_without_a_branch_is_the_row_patterns(geometry):
    """`row_contact` gives `rows.decode`'s ``(i, j, a, b)`` for every contact (the tables' own), and every
    contact's range is its balls' or `CROSSING`."""
    c = geometry.contacts
    pattern = row_pattern(c.pairs, c.ends, geometry.rows, geometry.cols, min_balls=1)
    assert pattern is not None
    for k in range(len(c.pairs)):
        assert row_contact(pattern, np.int64(k)) == decode(pattern, np.int64(k))
    chain = ReservationChain.build(pb.Elastic().kernel(True)[0], 2, True, c.pairs, geometry.n_balls, True, 3, batch=8)
    owner, contact_owner = chain.owners
    ends = owner[c.pairs // BALLS_PER_WORD]
    np.testing.assert_array_equal(contact_owner, np.where(ends[:, 0] == ends[:, 1], ends[:, 0], CROSSING))
    assert np.array_equal(np.repeat(np.arange(3), np.diff(chain.bounds))[::BALLS_PER_WORD], owner)


def test_the_default_batch_grows_with_the_threads_within_its_bounds():
    assert batch_size(577_000, 2) == 1 << 17 and batch_size(2_310_000, 16) == 1 << 19
    assert batch_size(10**9, 64) == 1 << 20
    assert batch_size(100, 2) == MIN_BATCH
    for balls in (10, 10**4, 10**6, 10**8):
        for threads in (2, 3, 16, 64):
            size = batch_size(balls, threads)
            assert size & (size - 1) == 0


@pytest.mark.slow
def test_a_simulation_on_two_threads_is_the_simulation_on_one():
    """`UniformRandomPair(stream="counter", threads=2)` through `Simulation` (a lattice large enough for the
    threaded chain): steps, a collision target, then the freeze of a half-plane from one ball, with the
    bits of ``threads=1``."""
    runs = []
    for threads in (1, 2):
        half = pb.HalfPlane(120, 200)
        v = np.random.default_rng(1).normal(size=(half.n_balls, 2))
        sim = pb.Simulation(half, v, seed=3, scheduler=pb.UniformRandomPair(threads=threads, stream="counter"))
        sim.run(steps=2_000_000)
        sim.run(collisions=sim.collisions + 54_321)
        runs.append((sim.steps, sim.collisions, sim.velocities.copy(), sim.get_state().rng_state,
                     sim.engine.state.margin.copy()))
    assert runs[0][:2] == runs[1][:2]
    for a, b in zip(runs[0][2:], runs[1][2:]):
        np.testing.assert_array_equal(a.view(np.uint64) if a.dtype == np.float64 else a,
                                      b.view(np.uint64) if b.dtype == np.float64 else b)
