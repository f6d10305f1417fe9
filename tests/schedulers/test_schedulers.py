"""Schedulers: which contacts get tried, and how often.

Picks are invisible in the engine when nothing collides, so distributional
facts are checked on the plain-Python twin's picks (the twin equals the engine
bit for bit: `test_kernel_vs_reference.py`), and engine-level facts use a
*matching* geometry: separate touching pairs that all approach, so each
contact collides the first time it is tried and never again.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from helpers import matching
from reference import RandomSweepPicker, SweepPicker, UniformPicker, Xoshiro, seed_state
from scipy import stats

import pinnedballs as pb

P_MIN = 1e-3  # fixed seeds, so these are deterministic; the threshold only says "not absurd"


def approaching_pairs(n_pairs: int) -> tuple[pb.Geometry, np.ndarray]:
    """``n_pairs`` separate pairs in the plane, touching along x, each closing at speed 2."""
    geom = matching(n_pairs, dim=2)
    v = np.zeros((2 * n_pairs, 2))
    v[0::2, 0], v[1::2, 0] = 1.0, -1.0
    return geom, v


def collided(geom, v_before, v_after) -> np.ndarray:
    """``(n_contacts,) bool``: which contacts of a matching geometry have collided."""
    p = geom.contacts.pairs.astype(np.int64)
    return np.any(v_after[p[:, 0]] != v_before[p[:, 0]], axis=1)


# ---------------------------------------------------------------- the twin's picks


def test_uniform_pair_frequencies_pass_chi_square():
    """200,000 picks on a 108-contact half-plane: every contact equally often (chi-square), and the
    engine, run as long with nothing moving, ends on the same random state as these picks."""
    geom = pb.HalfPlane(rows=5, cols=9)
    n, picks = geom.n_contacts, 200_000
    assert n == 108
    rng, picker = Xoshiro(seed_state(2024)), UniformPicker(n)
    counts = np.bincount([picker.pick(rng) for _ in range(picks)], minlength=n)
    assert counts.sum() == picks and len(counts) == n
    assert stats.chisquare(counts).pvalue > P_MIN
    sim = pb.Simulation(geom, np.zeros((geom.n_balls, 2)), scheduler=pb.UniformRandomPair(), seed=2024)
    sim.run(steps=picks)
    assert [int(x) for x in np.asarray(sim.get_state().rng_state, dtype=np.uint64)] == rng.state


def test_engine_uniform_pair_rejection_steps_match_twin_on_a_million_ball_torus():
    """3e6 contacts: about 1 pick in 2,000 needs a second draw (Lemire's rejection), so 200,000
    zero-velocity steps exercise it; the engine must end on the twin's random state."""
    geom = pb.FlatTorus(rows=1000, cols=1000)
    n, picks = geom.n_contacts, 200_000
    rng, picker = Xoshiro(seed_state(77)), UniformPicker(n)
    for _ in range(picks):
        picker.pick(rng)
    assert rng.draws > picks + 20  # rejections happened
    sim = pb.Simulation(geom, np.zeros((geom.n_balls, 2)), scheduler=pb.UniformRandomPair(), seed=77)
    sim.run(steps=picks)
    assert sim.collisions == 0
    assert [int(x) for x in np.asarray(sim.get_state().rng_state, dtype=np.uint64)] == rng.state


def test_uniform_pair_successive_picks_are_independent():
    """Pairs of consecutive picks among 8 contacts: all 64 combinations equally likely."""
    n, picks = 8, 64_000
    rng, picker = Xoshiro(seed_state(7)), UniformPicker(n)
    seq = [picker.pick(rng) for _ in range(picks)]
    counts = np.bincount([n * a + b for a, b in zip(seq[::2], seq[1::2])], minlength=n * n)
    assert stats.chisquare(counts).pvalue > P_MIN


def test_bounded_is_unbiased_where_modulo_would_not_be():
    """n = 3 * 2**30: a plain ``x % n`` of 32 random bits would give the first third twice the weight."""
    n = 3 * 2**30
    rng = Xoshiro(seed_state(1))
    draws = np.array([rng.bounded(n) for _ in range(30_000)])
    assert draws.min() >= 0 and draws.max() < n
    counts = np.bincount(draws // 2**30, minlength=3)
    assert stats.chisquare(counts).pvalue > P_MIN


def test_bounded_edge_sizes():
    rng = Xoshiro(seed_state(0))
    assert all(rng.bounded(1) == 0 for _ in range(100))
    draws = {rng.bounded(2**32) for _ in range(1000)}
    assert max(draws) < 2**32 and len(draws) > 990


def test_sweep_is_the_contact_order_repeated():
    picker, rng = SweepPicker(5), Xoshiro(seed_state(0))
    before = rng.state
    assert [picker.pick(rng) for _ in range(12)] == [0, 1, 2, 3, 4, 0, 1, 2, 3, 4, 0, 1]
    assert rng.state == before  # no randomness


@pytest.mark.parametrize("n", [1, 2, 7, 100])
def test_random_sweep_tries_every_contact_once_per_sweep(n):
    picker, rng = RandomSweepPicker(n), Xoshiro(seed_state(n))
    sweeps = [[picker.pick(rng) for _ in range(n)] for _ in range(20)]
    for sweep in sweeps:
        assert sorted(sweep) == list(range(n))
    if n >= 7:
        assert len({tuple(s) for s in sweeps}) == 20  # a fresh order each sweep


def test_random_sweep_orders_are_uniform_permutations():
    """Over 24,000 sweeps of 4 contacts, all 24 orders are equally likely."""
    n, sweeps = 4, 24_000
    picker, rng = RandomSweepPicker(n), Xoshiro(seed_state(99))
    index = {p: k for k, p in enumerate(itertools.permutations(range(n)))}
    counts = np.zeros(len(index), dtype=int)
    for _ in range(sweeps):
        counts[index[tuple(picker.pick(rng) for _ in range(n))]] += 1
    assert stats.chisquare(counts).pvalue > P_MIN


# ---------------------------------------------------------------- the engine


@pytest.mark.parametrize("scheduler", [pb.Sweep(), pb.RandomSweep()], ids=["Sweep", "RandomSweep"])
def test_engine_sweep_tries_every_contact_exactly_once_per_sweep(scheduler):
    """On separate approaching pairs, one sweep collides every pair; a second sweep (after the
    pairs are set approaching again) collides every pair again, and nothing in between."""
    n = 40
    geom, v = approaching_pairs(n)
    sim = pb.Simulation(geom, v, scheduler=scheduler, seed=5)
    sim.run(steps=n - 1)
    assert sim.collisions == n - 1  # n - 1 distinct contacts in the first n - 1 picks
    assert np.count_nonzero(collided(geom, v, sim.velocities)) == n - 1
    sim.run(steps=1)
    assert sim.collisions == n and sim.is_frozen()
    state = sim.get_state()
    sim.set_state(state.replace(velocities=v.copy()))  # approach again, mid-stream
    sim.run(steps=n)
    assert sim.collisions == 2 * n and sim.is_frozen()


def test_engine_sweep_follows_the_geometry_contact_order():
    n = 10
    geom, v = approaching_pairs(n)
    sim = pb.Simulation(geom, v, scheduler=pb.Sweep(), seed=0)
    for k in range(1, n + 1):
        sim.run(steps=1)
        assert np.array_equal(np.flatnonzero(collided(geom, v, sim.velocities)), np.arange(k))


def test_engine_random_sweep_order_depends_on_seed():
    n = 10
    geom, v = approaching_pairs(n)
    firsts = set()
    for seed in range(8):
        sim = pb.Simulation(geom, v, scheduler=pb.RandomSweep(), seed=seed)
        sim.run(steps=3)
        firsts.add(tuple(np.flatnonzero(collided(geom, v, sim.velocities))))
    assert len(firsts) > 1


def test_engine_uniform_pair_collects_every_contact_like_a_coupon_collector():
    """Steps to freeze ``n`` separate approaching pairs = coupon collector's time:
    mean ``n H_n``, variance ``sum (1 - p_k) / p_k^2`` with ``p_k = k / n``."""
    n, runs = 30, 300
    geom, v = approaching_pairs(n)
    times = []
    for seed in range(runs):
        sim = pb.Simulation(geom, v, scheduler=pb.UniformRandomPair(), seed=seed)
        assert sim.run_until_frozen(max_steps=10**6)
        assert sim.collisions == n
        times.append(sim.steps)
    mean = n * sum(1 / k for k in range(1, n + 1))
    var = sum((1 - k / n) / (k / n) ** 2 for k in range(1, n + 1))
    z = (np.mean(times) - mean) / math.sqrt(var / runs)
    assert abs(z) < 4, (np.mean(times), mean)
    assert min(times) >= n


def test_engine_uniform_pair_does_not_sweep():
    """n uniform picks among n contacts repeat some contact (all distinct has probability n!/n^n)."""
    n = 40
    geom, v = approaching_pairs(n)
    sim = pb.Simulation(geom, v, scheduler=pb.UniformRandomPair(), seed=5)
    sim.run(steps=n)
    assert 0 < sim.collisions < n


# ---------------------------------------------------------------- every scheduler


@pytest.mark.parametrize("scheduler", [pb.UniformRandomPair(), pb.Sweep(), pb.RandomSweep(), pb.RejectionFree(),
                                       pb.ColoredSweep(), pb.ColoredSweep(shuffle=True)], ids=repr)
def test_a_chain_makes_exactly_its_inversions_in_collisions(scheduler):
    """Equal masses on a line: a collision swaps two adjacent velocities that are out of order,
    so every order of collisions ends sorted after exactly the number of inversions."""
    from helpers import chain

    geom = chain(40)
    for seed in range(5):
        v = np.random.default_rng(seed).normal(size=(40, 1))
        inversions = sum(int(a > b) for a, b in itertools.combinations(v[:, 0], 2))
        sim = pb.Simulation(geom, v, scheduler=scheduler, seed=seed)
        assert sim.run_until_frozen(max_steps=10**8)
        assert sim.collisions == inversions > 100
        # sorted, to rounding: v_i - (v_i - v_j) is v_j only to within an ulp of the larger
        np.testing.assert_allclose(sim.velocities[:, 0], np.sort(v[:, 0]), rtol=0, atol=1e-14)


def test_a_scheduler_written_for_the_old_loop_protocol_is_refused_with_what_to_do():
    """Schedulers once ran their own loops through loops() and advance(); the engine now owns the
    loop, so such a scheduler is refused when the Simulation is built, naming the way out."""
    class OwnLoop(pb.Scheduler):
        def loops(self, collide, geometry):
            return None

        def advance(self, loops, chain, live, state, rng, counters, max_steps, max_collisions, track):
            return 0

    geom = pb.FlatTorus(4, 4)
    with pytest.raises(TypeError, match=r"^scheduler: OwnLoop defines advance\(\) or loops\(\), which the engine "
                                        r"no longer calls: give it kernel\(\) \(a pick\) or selector\(\) instead"):
        pb.Simulation(geom, np.zeros((16, 2)), scheduler=OwnLoop())


# ---------------------------------------------------------------- a user's pick that cannot work


def _user_picks():
    from numba import njit

    from pinnedballs.engine.streams.xoshiro import bounded

    @njit
    def index_only(state, rng, n_contacts):
        return 0

    @njit
    def swapped(state, rng, n_contacts):
        k, rng = bounded(rng, n_contacts)
        return rng, k

    @njit
    def float_index(state, rng, n_contacts):
        return state[0.5], rng

    return index_only, swapped, float_index


class _UserScheduler(pb.Scheduler):
    def __init__(self, pick):
        self.pick = pick

    def kernel(self):
        return self.pick


@pytest.mark.parametrize("which,said", [
    (0, r"must return \(k, rng\): the contact's index \(an integer\) and the random stream "
        r"\(the 4-tuple of uint64 it was given\); it return"),
    (1, r"must return \(k, rng\)"),
    (2, r"(does not compile for \(state: int64 array, rng: 4-tuple of uint64, n_contacts: int64\): "
        r"No implementation of function .*getitem.* found|failed on a fresh state: IndexError)"),
])
def test_a_pick_of_the_wrong_type_is_named_before_the_loop_compiles(which, said):
    """Not numba's TypingError from inside the engine's loop: the scheduler, the function's name and
    what it must return, when the Simulation is built."""
    pick = _user_picks()[which]
    geom = pb.FlatTorus(4, 4)
    with pytest.raises(pb.FieldTypeError,
                       match=rf"^scheduler: _UserScheduler.kernel\(\)'s pick '{pick.__name__}' {said}"):
        pb.Simulation(geom, np.ones((geom.n_balls, 2)), scheduler=_UserScheduler(pick))
