"""The counter stream (`engine.streams.philox`): numpy's Philox4x64-10 word for word, an unbiased pick of every
step from its own counter, and a simulation on it whose pick of step s depends on the seed and s alone."""

import numpy as np
import pytest
from numba import njit
from scipy import stats

import pinnedballs as pb
from pinnedballs.engine.streams.philox import block, counter_pick, counter_stream, counter_word, lemire, stream_words
from pinnedballs.engine.streams.xoshiro import seed_state
from pinnedballs.specs.run import parse_spec


@njit
def _words(k0, k1, start, count):
    out = np.empty(count, dtype=np.uint64)
    for t in range(count):
        out[t] = counter_word(k0, k1, np.uint64(start + t), np.uint64(0))
    return out


@njit
def _picks(k0, k1, start, count, n):
    out = np.empty(count, dtype=np.uint64)
    for t in range(count):
        out[t] = counter_pick(k0, k1, np.uint64(start + t), np.uint64(n))
    return out


@pytest.mark.parametrize("key", [(0, 0), (1, 2), (0x123456789ABCDEF0, 0xFEDCBA9876543210), (2**64 - 1, 2**64 - 1)])
@pytest.mark.parametrize("start", [0, 3, 4, 2**40 + 1, 2**62 - 7])
def test_the_stream_is_numpy_philox_word_for_word(key, start):
    k0, k1 = np.uint64(key[0]), np.uint64(key[1])
    np.testing.assert_array_equal(_words(k0, k1, start, 41), stream_words(key, start, 41))


def test_a_block_is_numpys_philox_at_its_counter():
    """``Philox(key, counter=c - 1).random_raw(4)`` is the block at counter ``c`` (numpy counts up first)."""
    key, c = (77, 99), (5, 2**63 + 3, 17, 2**64 - 1)
    counter = sum(x << (64 * i) for i, x in enumerate(c))
    expected = np.random.Philox(key=np.array(key, dtype=np.uint64), counter=counter - 1).random_raw(4)
    got = block(*(np.uint64(x) for x in c), np.uint64(key[0]), np.uint64(key[1]))
    np.testing.assert_array_equal(np.array(got, dtype=np.uint64), expected)


def _reference_pick(key, s, n):
    """Step ``s``'s pick in Python integers: the first of words ``s % 4`` of blocks ``(s // 4, r, 0, 0)``,
    ``r = 0, 1, ...`` that Lemire's test accepts."""
    for r in range(100):
        counter = ((s // 4) + (r << 64) - 1) % 2**256
        x = int(np.random.Philox(key=np.array(key, dtype=np.uint64), counter=counter).random_raw(4)[s % 4])
        product = x * n
        if product % 2**64 >= (2**64 - n) % n:
            return product >> 64
    raise AssertionError("no word accepted in 100 tries")


def test_a_rejected_word_is_replaced_from_the_same_steps_counter():
    """With n = 2^63 + 1 about half the words are rejected: each step still gets the reference's pick,
    drawn from its own counter (so a step's pick never depends on another step's rejections)."""
    key, n = (2026, 11), 2**63 + 1
    k0, k1 = np.uint64(key[0]), np.uint64(key[1])
    got = _picks(k0, k1, 10, 24, n)
    assert [int(x) for x in got] == [_reference_pick(key, s, n) for s in range(10, 34)]
    rejected = sum(not lemire(np.uint64(w), np.uint64(n))[1] for w in stream_words(key, 10, 24))
    assert 4 <= rejected <= 20  # the rejection path ran


def test_picks_are_uniform_over_the_contacts():
    """70,000 picks among 7 contacts: chi-square p-value above 1e-4 (fixed key, so a fixed outcome)."""
    picks = _picks(np.uint64(5), np.uint64(6), 0, 70_000, 7)
    counts = np.bincount(picks.astype(np.int64), minlength=7)
    assert stats.chisquare(counts).pvalue > 1e-4


def _single(g):
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, np.sqrt(200.0)]
    return v


def test_a_simulation_picks_lemire_of_numpys_words():
    """The chain on the counter stream is the chain on numpy's Philox words: the same collisions as
    `Replay` of the picks computed from numpy, and the stream's words end at (key, steps)."""
    g = pb.HalfPlane.from_size(20, 10)
    sim = pb.Simulation(g, _single(g), scheduler=pb.UniformRandomPair(stream="counter"), seed=9)
    key = tuple(int(x) for x in counter_stream(seed_state(9))[:2])
    picks = [_reference_pick(key, s, g.n_contacts) for s in range(3000)]
    replay = pb.Simulation(g, _single(g), scheduler=pb.Replay(picks), seed=1)
    sim.run(steps=3000, progress=False)
    replay.run(steps=3000, progress=False)
    np.testing.assert_array_equal(sim.velocities, replay.velocities)
    assert (sim.steps, sim.collisions) == (replay.steps, replay.collisions)
    assert [int(x) for x in sim.get_state().rng_state] == [*key, 3000, 0]


def test_a_run_split_and_resumed_is_the_run_whole():
    g = pb.HalfPlane.from_size(20, 10)
    scheduler = pb.UniformRandomPair(stream="counter")
    whole = pb.Simulation(g, _single(g), scheduler=scheduler, seed=4)
    whole.run_until_frozen(max_steps=10**6, progress=False)
    first = pb.Simulation(g, _single(g), scheduler=scheduler, seed=4)
    first.run(collisions=50, progress=False)
    later = pb.Simulation(g, _single(g), scheduler=scheduler, seed=0)
    later.set_state(first.get_state())
    later.run_until_frozen(max_steps=10**6, progress=False)
    np.testing.assert_array_equal(later.velocities, whole.velocities)
    assert (later.steps, later.collisions) == (whole.steps, whole.collisions)
    np.testing.assert_array_equal(later.get_state().margin, whole.get_state().margin)


def test_the_stream_is_a_spec_field_and_is_recorded(tmp_path):
    spec = {"geometry": {"kind": "half_plane", "length": 20, "depth": 10},
            "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
            "scheduler": {"kind": "uniform_random_pair", "stream": "counter"},
            "stop": {"frozen": True, "max_steps": 10**6}, "seed": 3}
    run = pb.run_spec(parse_spec(spec), tmp_path / "run")
    sim = run.simulation()
    assert sim.scheduler == pb.UniformRandomPair(stream="counter")
    assert sim.scheduler.to_spec() == {"kind": "uniform_random_pair", "stream": "counter"}
    again = parse_spec(spec).build()
    again.run_until_frozen(max_steps=10**6, progress=False)
    np.testing.assert_array_equal(sim.velocities, again.velocities)
    with pytest.raises(ValueError, match="scheduler.stream"):
        parse_spec({**spec, "scheduler": {"kind": "uniform_random_pair", "stream": "philox"}})
    with pytest.raises(ValueError, match="stream: must be 'xoshiro' or 'counter'"):
        pb.UniformRandomPair(stream="philox")
