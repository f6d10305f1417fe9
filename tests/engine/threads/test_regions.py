"""The paper's chain on several threads (`engine.threads.regions`): the stream jumped ahead word for word, the
lattice cut into regions, and the run's bits those of one thread for every kind of limit."""

import numpy as np
import pytest
from helpers import pick_loops
from numba import njit

import pinnedballs as pb
from pinnedballs.engine.chain import COUNTERS, NO_LIMIT
from pinnedballs.engine.margin import new_margin
from pinnedballs.engine.rows import row_pattern
from pinnedballs.engine.sequential.choice import new_tune
from pinnedballs.engine.sequential.loops import NO_PATTERN, live_kernel
from pinnedballs.engine.streams.jump import jump, jump_polynomial
from pinnedballs.engine.streams.xoshiro import load, next_uint64, seed_state
from pinnedballs.engine.threads.regions import (
    BAND_HOPS,
    MIN_PARALLEL_CONTACTS,
    ParallelChain,
    _by_index,
    _reach,
    bands_pay,
    contact_windows,
    region_cuts,
)
from pinnedballs.engine.threads.tuning import using
from pinnedballs.rules import collide_elastic, collide_masses
from pinnedballs.schedulers.simple import pick_uniform


@njit
def _ahead(words, count):
    s = load(words)
    for _ in range(count):
        _, s = next_uint64(s)
    return np.array(s)


@njit
def _jumped(words, poly):
    return np.array(jump(load(words), poly))


@pytest.mark.parametrize("count", [0, 1, 2, 255, 256, 257, 1000, 1 << 14, 123_457])
def test_a_jump_lands_where_drawing_the_words_would(count):
    words = seed_state(11)
    np.testing.assert_array_equal(_jumped(words, jump_polynomial(count)), _ahead(words, count))


def test_regions_cut_a_lattice_into_halves_of_contacts_with_few_crossings():
    half = pb.HalfPlane(100, 60)
    pairs = half.contacts.pairs
    cuts = region_cuts(pairs, half.n_balls, 2)
    assert cuts.shape == (1,)
    low = pairs.min(axis=1)
    assert abs((low < cuts[0]).mean() - 0.5) < 0.01
    crossing = ((pairs[:, 0] < cuts[0]) != (pairs[:, 1] < cuts[0])).sum()
    assert 2 * 60 - 2 <= crossing <= 2 * 60 + 2  # about an up-left and an up-right contact per ball of one row
    random_pairs = np.random.default_rng(1).integers(0, 2000, size=(6000, 2))
    assert region_cuts(random_pairs, 2000, 2) is None  # random contacts: half of them cross any cut


def test_no_regions_where_a_contact_reaches_across_the_balls():
    """A torus's wrap-around contacts join balls N - 1 apart in index: the bands watched around a cut
    would hold every ball (every pick watched: 0.35x of one thread), so a simulation on 2 threads runs
    one; a half-plane of the same size gets its regions (its bands: 11 % of the balls)."""
    torus, half = pb.FlatTorus(160, 160), pb.HalfPlane.from_size(500, 250)
    assert min(len(torus.contacts), len(half.contacts)) >= MIN_PARALLEL_CONTACTS
    for geometry, pays in ((torus, False), (half, True)):
        c = geometry.contacts
        assert region_cuts(c.pairs, geometry.n_balls, 2) is not None  # few crossings on both
        assert bands_pay(c.pairs, geometry.n_balls, 2) == pays
        v = np.random.default_rng(2).normal(size=(geometry.n_balls, 2))
        sim = pb.Simulation(geometry, v, seed=3, scheduler=pb.UniformRandomPair(threads=2))
        assert (sim.engine.parallel_chain() is not None) == pays
    assert bands_pay(np.array([[0, 9]]), 10, 2) is False and bands_pay(np.array([[0, 1]]), 64, 2) is True


def _sequential(geometry, v, masses, params, pattern, loops, kwargs, seed):
    c = geometry.contacts
    rng, counters, margin = seed_state(seed), np.zeros(COUNTERS, np.int64), new_margin()
    limited = loops.limited_rows if pattern is not NO_PATTERN else loops.limited
    steps, collisions, frozen = (kwargs.get("steps", NO_LIMIT), kwargs.get("collisions", NO_LIMIT),
                                 kwargs.get("frozen", False))
    plain = collisions == NO_LIMIT and not frozen
    chunk = steps if plain else max(4096, 4 * len(c))
    taken = limited(v, c.pairs, c.ends, c.units, masses, params, pattern, np.zeros(1, np.int64), np.zeros(0, np.int64),
                    rng, counters, margin, steps, collisions, frozen, chunk, np.zeros(1, np.int64),
                    np.empty((0, 2), np.int64), new_tune())
    return taken, v, rng, counters, margin


def _parallel(geometry, v, masses, params, pattern, loops, collide, kwargs, seed, words, tuned=False):
    from pinnedballs.engine.chain import Chain
    c = geometry.contacts
    chain = Chain(v, c.pairs, c.ends, c.units, masses, params)
    parallel = ParallelChain.build(collide, 2, True, c.pairs, geometry.n_balls, pattern is not NO_PATTERN, 2,
                                   words=words, tuned=tuned)
    assert parallel is not None
    rng, counters, margin = seed_state(seed), np.zeros(COUNTERS, np.int64), new_margin()
    limited = loops.limited_rows if pattern is not NO_PATTERN else loops.limited
    steps, collisions, frozen = (kwargs.get("steps", NO_LIMIT), kwargs.get("collisions", NO_LIMIT),
                                 kwargs.get("frozen", False))
    plain = collisions == NO_LIMIT and not frozen
    _, any_live = live_kernel(collide, 2, True)
    taken = parallel.run(chain, pattern, limited, any_live, np.zeros(1, np.int64), np.zeros(0, np.int64),
                         rng, counters, margin, steps, collisions, frozen, 1 << 23 if plain else max(4096, 4 * len(c)))
    return taken, v, rng, counters, margin


def _same(a, b):
    assert a[0] == b[0]
    for x, y in zip(a[1:], b[1:]):
        np.testing.assert_array_equal(x, y)


CASES = [({"steps": 200_000}, "gaussian"), ({"steps": 10**8, "collisions": 40_001}, "gaussian"),
         ({"steps": 10**8, "frozen": True}, "one ball")]


@pytest.mark.parametrize("rows", [False, True], ids=["tables", "row pattern"])
@pytest.mark.parametrize("kwargs, start", CASES, ids=["steps", "collisions", "until frozen"])
@pytest.mark.parametrize("words", [64, 1024])
def test_two_threads_give_the_bits_of_one(rows, kwargs, start, words):
    """Steps, a collision target and the freeze: the same steps, collisions, velocities, stream, margin
    and stop step, with small blocks (many crossings, partial blocks, the freeze inside a block)."""
    half = pb.HalfPlane(40, 60)
    pattern = row_pattern(half.contacts.pairs, half.contacts.ends, 40, 60, min_balls=1) if rows else NO_PATTERN
    if start == "gaussian":
        v = np.random.default_rng(5).normal(size=(half.n_balls, 2))
    else:
        v = np.zeros((half.n_balls, 2))
        v[half.boundary_center()] = [0.4, np.sqrt(200.0)]
    masses, params = np.ones(half.n_balls), np.array([1.0, 4 * 2.0**-53 * np.sqrt(2 * 0.5 * (v * v).sum())])
    loops = pick_loops(collide_elastic, pick_uniform, 2, True)
    one = _sequential(half, v.copy(), masses, params, pattern, loops, kwargs, 9)
    two = _parallel(half, v.copy(), masses, params, pattern, loops, collide_elastic, kwargs, 9, words)
    _same(one, two)
    if kwargs.get("frozen"):
        assert one[3][2] == 0 and two[3][2] == 0  # frozen: no live contact left


def test_unequal_masses_and_a_tuned_thread_count_keep_the_bits():
    half = pb.HalfPlane(40, 60)
    rng = np.random.default_rng(6)
    v, masses = rng.normal(size=(half.n_balls, 2)), rng.uniform(0.5, 2.0, half.n_balls)
    params = np.array([1.5, 1e-13])
    loops = pick_loops(collide_masses, pick_uniform, 2, True)
    kwargs = {"steps": 300_000}
    one = _sequential(half, v.copy(), masses, params, NO_PATTERN, loops, kwargs, 3)
    two = _parallel(half, v.copy(), masses, params, NO_PATTERN, loops, collide_masses, kwargs, 3, 128, tuned=True)
    _same(one, two)


def test_threads_that_run_one_after_the_other_still_finish():
    """With numba set to one thread the regions' iterations run in turn: each claims what it finds
    unclaimed, and a late one skips what is done; no thread waits for another that is not running."""
    half = pb.HalfPlane(40, 60)
    v = np.random.default_rng(7).normal(size=(half.n_balls, 2))
    masses, params = np.ones(half.n_balls), np.array([1.0, 1e-14])
    loops = pick_loops(collide_elastic, pick_uniform, 2, True)
    one = _sequential(half, v.copy(), masses, params, NO_PATTERN, loops, {"steps": 100_000}, 4)
    with using(1):
        two = _parallel(half, v.copy(), masses, params, NO_PATTERN, loops, collide_elastic, {"steps": 100_000}, 4, 256)
    _same(one, two)


@pytest.mark.slow
def test_a_simulation_on_two_threads_is_the_simulation_on_one():
    """`UniformRandomPair(threads=2)` on a lattice large enough to run by regions, through `Simulation`:
    steps, then a collision target, with the bits of `threads=1`."""
    runs = []
    for threads in (1, 2):
        half = pb.HalfPlane(120, 200)
        v = np.random.default_rng(1).normal(size=(half.n_balls, 2))
        sim = pb.Simulation(half, v, seed=3, scheduler=pb.UniformRandomPair(threads=threads))
        sim.run(steps=2_000_000)
        sim.run(collisions=sim.collisions + 54_321)
        assert bool(sim.engine.parallel_chain()) == (threads == 2)
        runs.append((sim.steps, sim.collisions, sim.velocities.copy(), sim.get_state().rng_state,
                     sim.engine.state.margin.copy()))
    assert runs[0][:2] == runs[1][:2]
    for a, b in zip(runs[0][2:], runs[1][2:]):
        np.testing.assert_array_equal(a, b)


def test_the_thread_count_is_part_of_the_scheduler_and_its_spec():
    assert pb.UniformRandomPair(threads=2).to_spec() == {"kind": "uniform_random_pair", "threads": 2}
    assert pb.UniformRandomPair().to_spec() == {"kind": "uniform_random_pair"}
    assert repr(pb.UniformRandomPair(threads=3)) == "UniformRandomPair(threads=3)"
    with pytest.raises(pb.FieldError, match="^threads: must be an integer >= 1, got 0$"):
        pb.UniformRandomPair(threads=0)


@pytest.mark.parametrize("threads", [2, 3])
def test_a_contact_filed_by_its_index_is_in_its_region_and_far_from_every_cut(threads):
    """Phase G files a pick outside every cut's window by its contact index alone: on a half-plane (contacts
    numbered by their lower ball) that is its region exactly, and it neither crosses a cut nor touches a
    ball within the watched band; the windows hold every contact that does. Contacts not numbered so
    get one window holding them all (each decoded)."""
    g = pb.HalfPlane.from_size(500, 250)
    pairs = g.contacts.pairs.astype(np.int64)
    cuts = region_cuts(pairs, g.n_balls, threads)
    assert cuts is not None and len(cuts) == threads - 1
    band = BAND_HOPS * _reach(pairs)
    windows = contact_windows(pairs, cuts, band)
    by_index = [_by_index(windows, np.int64(k)) for k in range(len(pairs))]
    region = np.searchsorted(cuts, pairs, side="right")  # each ball's region
    near = np.zeros(len(pairs), dtype=bool)
    for c in cuts:
        near |= ((pairs >= c - band) & (pairs < c + band)).any(axis=1)
    decoded = np.array([d for _, d in by_index])
    assert decoded.sum() < 0.5 * len(pairs) and (decoded | ~near).all()  # every pick near a cut is decoded
    assert (decoded | (region[:, 0] == region[:, 1])).all()  # and every crossing
    filed = np.array([r for r, _ in by_index])
    assert np.array_equal(filed[~decoded], region[~decoded, 0])
    shuffled = pairs[np.random.default_rng(0).permutation(len(pairs))]
    assert all(_by_index(contact_windows(shuffled, cuts, band), np.int64(k))[1] for k in range(0, len(pairs), 97))


def test_threaded_blocks_keep_the_row_pattern_they_were_built_for(monkeypatch):
    """A half-plane whose limited loop is timed, row-pattern loop first (the system put between 1 and 16 times
    a CPU's L2 and beyond the lookahead's reach): its threaded blocks are built to decode the row pattern. Once
    the timing prefers the table loop (which reads no pattern), the threaded blocks still get theirs (handed
    none, they read outside it: a 1000x500 half-plane to frozen died of a segmentation fault), and the run ends
    on the bits of one thread."""
    from pinnedballs.engine.sequential import sizes

    monkeypatch.delenv("PINNEDBALLS_LOOP", raising=False)
    monkeypatch.setattr(sizes, "l2_bytes", lambda: 512 << 10)
    monkeypatch.setattr(sizes, "LOOKAHEAD_BYTES", 512 << 10)
    g = pb.HalfPlane.from_size(400.0, 200.0)  # 23,000 balls, 68,371 contacts: regions pay on two threads
    v = np.random.default_rng(1).normal(size=(g.n_balls, 2))

    def run(threads: int) -> tuple:
        sim = pb.Simulation(g, v, seed=3, scheduler=pb.UniformRandomPair(threads=threads))
        sim.run(steps=200_000)
        choice = sim.engine.choice()
        assert choice.candidates == ("rows", "tables") and choice.by == "measured"
        if threads > 1:
            assert sim.engine.parallel_chain() is not None and sim.engine._parallel_loop[1] is not NO_PATTERN
        choice.tuner.rates.update(rows=1.0, tables=1e12)  # the table loop measured the faster from now on
        choice.tuner.due = float("inf")
        assert choice.name == "tables"
        sim.run(steps=500_000)
        sim.run_until_frozen(max_steps=300_000)
        return sim.velocities.tobytes(), sim.steps, sim.collisions, sim.engine.state.rng.tolist()

    assert run(2) == run(1)
