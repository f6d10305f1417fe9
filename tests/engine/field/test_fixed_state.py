"""What exact and certified runs resume from: split runs equal one run, checkpoints round-trip through
results files and the command line, the rational chain's exact states load in the fixed-point chain
(and back), and a certified state is checked before it is taken; certified velocities are the
nearest floats."""

from __future__ import annotations

import dataclasses
import math

import gmpy2
import numpy as np
import pytest
from helpers import HALF_PLANE, call, spec, write
from hypothesis import given, settings
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs.engine import driver
from pinnedballs.engine.field.fixed import FixedChain
from pinnedballs.engine.field.fixed_state import CertifiedState, nearest_floats, precisions_problem
from pinnedballs.engine.field.rational import RationalChain


def inward(g) -> np.ndarray:
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.3, 14.0]
    return v


def rational(g, v, **kwargs) -> pb.Simulation:
    sim = pb.Simulation(g, v, arithmetic="exact", **kwargs)
    sim.engine.state.field_chain = RationalChain(g, sim.velocities.copy(), sim.engine.model.masses,
                                                 pb.Elastic().exact_kick)
    sim.velocities = sim.engine.state.field_chain.shadow
    return sim


@pytest.mark.parametrize("arithmetic", ["exact", "certified"])
def test_a_run_split_into_calls_ends_on_the_same_state(arithmetic):
    g = pb.HalfPlane(8, 10)
    v = inward(g)
    whole = pb.Simulation(g, v, seed=5, arithmetic=arithmetic)
    assert whole.run_until_frozen(max_steps=10**6)
    split = pb.Simulation(g, v, seed=5, arithmetic=arithmetic)
    for steps in (1, 2, 50, 333, 7, 1000):
        split.run(steps=steps, until_frozen=True)
    split.run(collisions=whole.collisions - 5)
    assert split.collisions == whole.collisions - 5
    split.run_until_frozen(max_steps=10**6)
    assert split.get_state().identical(whole.get_state())
    assert isinstance(whole.engine.state.field_chain, FixedChain)
    assert (whole.get_state().certified is None) == (arithmetic == "exact")


@pytest.mark.parametrize("arithmetic", ["exact", "certified"])
def test_a_checkpoint_round_trips_through_its_results_file(tmp_path, arithmetic):
    g = pb.HalfPlane(6, 8)
    v = inward(g)
    whole = pb.Simulation(g, v, seed=2, arithmetic=arithmetic)
    whole.run_until_frozen(max_steps=10**6)
    split = pb.Simulation(g, v, seed=2, arithmetic=arithmetic)
    split.run(steps=300, writers=[pb.ResultsWriter(tmp_path / "run", snapshots={"every_steps": 100})])
    res = pb.load(tmp_path / "run")
    resumed = res.simulation()
    assert resumed.arithmetic == arithmetic and resumed.get_state().identical(split.get_state())
    resumed.run_until_frozen(max_steps=10**6)
    assert resumed.get_state().identical(whole.get_state())


def test_a_run_built_in_python_resumes_from_its_file_at_its_own_bits(tmp_path):
    """A certified run built in Python (no spec) at 64 bits, resumed from its results file: at 64 bits (its state
    records them), so it ends on the state of the run never stopped, the batched rule's pending sums included."""
    g = pb.HalfPlane(8, 8)
    rng = np.random.default_rng(3)
    v = np.round(rng.normal(size=(g.n_balls, 2)) * 2**45) / 2**45
    whole = pb.Simulation(g, v, seed=4, arithmetic="certified", precision=64)
    whole.run_until_frozen(max_steps=10**5)
    split = pb.Simulation(g, v, seed=4, arithmetic="certified", precision=64)
    split.run(steps=400, writers=[pb.ResultsWriter(tmp_path / "run")])
    assert any(split.get_state().certified.pending)
    resumed = pb.load(tmp_path / "run").simulation()
    assert resumed.get_state().certified.precision == 64
    resumed.run_until_frozen(max_steps=10**5)
    assert resumed.get_state().identical(whole.get_state())


@pytest.mark.parametrize("direction", ["rational to fixed", "fixed to rational"])
def test_exact_states_move_between_the_rational_and_the_fixed_point_chains(direction):
    """A checkpoint of today's engine resumes in the fixed-point chain and the other way round: the
    same exact numbers, and the run goes on to the same state."""
    g = pb.HalfPlane(7, 9)
    v = inward(g)
    make = {"rational": lambda: rational(g, v, seed=3),
            "fixed": lambda: pb.Simulation(g, v, seed=3, arithmetic="exact")}
    source_kind, target_kind = direction.split(" to ")
    source, target, whole = make[source_kind](), make[target_kind](), make[target_kind]()
    source.run(steps=400)
    target.set_state(source.get_state())
    assert target.get_state().identical(source.get_state())
    for s in (target, whole):
        s.run_until_frozen(max_steps=10**6)
    assert target.get_state().identical(whole.get_state()) and whole.collisions > 100


def test_an_exact_coefficient_that_no_run_reaches_is_refused():
    g = pb.HalfPlane(3, 4)
    sim = pb.Simulation(g, inward(g), arithmetic="exact")
    state = sim.get_state()
    bad = state.exact.copy()
    bad[0, 0, 0], bad[0, 0, 1] = "1/3", "0"
    with pytest.raises(ValueError, match=r"^exact: the coefficient 1/3 is not a dyadic rational"):
        sim.set_state(state.replace(exact=bad, velocities=np.where(np.arange(g.n_balls)[:, None] == 0,
                                                                     [[1 / 3, state.velocities[0, 1]]],
                                                                     state.velocities)))
    assert sim.get_state().identical(state)


def test_a_certified_state_is_checked_before_it_is_taken():
    g = pb.HalfPlane(4, 5)
    sim = pb.Simulation(g, inward(g), seed=1, arithmetic="certified")
    sim.run(steps=300)
    state = sim.get_state()
    c = state.certified
    cases = [
        (state.replace(certified=None), "certified: a simulation in certified arithmetic resumes only from a "
                                        "certified state (this one holds float velocities)"),
        (state.replace(certified=CertifiedState(c.limbs[:, :, :1], c.scale, c.bounds, c.rounding)),
         "certified: limbs must be uint64 of shape (n_balls, dim, m, P)"),
        (state.replace(certified=CertifiedState(c.limbs, 10**6, c.bounds, c.rounding)), "certified: scale must be"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, -c.bounds - 1, c.rounding)),
         "certified: bounds must be finite and >= 0"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, c.bounds, float("nan"))), "certified: rounding must"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, c.bounds, c.rounding, -1)),
         "certified: bound_scale must be an integer in [0, "),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, c.bounds + 1e300, c.rounding, 0)),
         "certified: bounds must be finite in units of 2^-scale"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale + 1, c.bounds, c.rounding, c.bound_scale)),
         "certified: the fixed-point velocities do not round to the state's velocities"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, c.bounds, c.rounding, c.bound_scale, 100)),
         "certified: precision and late_precision must be whole multiples of 64 bits, got 100, 0"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, c.bounds, c.rounding, c.bound_scale, 1024, 0)),
         "certified: a state of 768 bits cannot be of a chain at precision 1024 and late_precision 0 (0: none)"),
        (state.replace(certified=CertifiedState(c.limbs, c.scale, c.bounds, c.rounding, c.bound_scale, 0, 256)),
         "certified: late_precision must be 0 where precision is (not kept), got 256"),
        (state.replace(certified=dataclasses.replace(c, bound_batch=1000)),
         "certified: bound_batch must be 0 or a power of two, got 1000"),
        (state.replace(certified=dataclasses.replace(c, bound_at=-2)),
         "certified: bound_at must be a whole number >= -1, got -2"),
        (state.replace(certified=dataclasses.replace(c, pending=(1 << 63, 0), unfolded=1.0)),
         "certified: pending must be two whole numbers in [0, 2^63), got (9223372036854775808, 0)"),
        (state.replace(certified=dataclasses.replace(c, pending=(3, 0), unfolded=0.0)),
         "certified: unfolded must be a finite float >= 0, above 0 exactly when a sum is pending, got 0.0"),
        (state.replace(certified=dataclasses.replace(c, bound_batch=0, bound_at=2)),
         "certified: a state under the bound rule in step order (bound_batch 0) has no pending sums or bound_at"),
    ]
    for bad, words in cases:
        with pytest.raises(ValueError) as info:
            sim.set_state(bad)
        assert str(info.value).startswith(words), (str(info.value), words)
        assert sim.get_state().identical(state)


def test_a_certified_run_resumes_from_the_command_line_and_info_states_its_bound(tmp_path, monkeypatch):
    """Stopped by Ctrl-C after its second chunk, resumed with ``--resume``: the bits of the unbroken run."""
    path = write(tmp_path / "run.json", spec(HALF_PLANE, arithmetic="certified", precision=320))
    code, _, err = call("run", path, "--out", tmp_path / "whole", "--quiet", "--no-figures")
    assert code == 0, err
    monkeypatch.setattr(driver, "CHUNK_STEPS", 200)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)
    calls, advance = [], driver.advance

    def interrupted(sim, *args, **kwargs):
        result = advance(sim, *args, **kwargs)
        calls.append(sim.steps)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return result

    monkeypatch.setattr(driver, "advance", interrupted)
    code, _, _ = call("run", path, "--out", tmp_path / "split", "--quiet", "--no-figures")
    monkeypatch.setattr(driver, "advance", advance)
    assert code == 130 and pb.load(tmp_path / "split").status == "interrupted"
    code, _, err = call("run", path, "--out", tmp_path / "split", "--quiet", "--no-figures", "--resume")
    assert code == 0, err
    whole, split = pb.load(tmp_path / "whole"), pb.load(tmp_path / "split")
    assert split.latest.identical(whole.latest) and whole.frozen and whole.latest.certified.limbs.shape[-1] == 5
    code, out, _ = call("info", tmp_path / "whole")
    line = next(x for x in out.splitlines() if x.startswith("arithmetic:"))
    G, largest = whole.latest.certified.error_bound()
    assert line.startswith("arithmetic:  certified (every decision proved equal to exact arithmetic's: exact counts)")
    assert f"within {largest:.3g} of exact arithmetic's (error bound G = {G:.3g}), 320 bits" in line


def test_a_spec_names_a_bad_precision():
    from pinnedballs.specs.run import parse_spec

    with pytest.raises(ValueError, match=r"^precision: "):
        parse_spec(spec(HALF_PLANE, arithmetic="certified", precision=16)).build()
    with pytest.raises(ValueError, match=r"^precision: is the precision of certified arithmetic"):
        parse_spec(spec(HALF_PLANE, precision=320)).build()


# ---------------------------------------------------------------- the nearest floats


def nearest(a: int, b: int, scale: int, d: int) -> float:
    """The float nearest ``(a + b sqrt d) / 2^scale``, from 3,000-bit arithmetic."""
    with gmpy2.context(precision=3000):
        x = (gmpy2.mpfr(a) + gmpy2.mpfr(b) * gmpy2.sqrt(d)) / gmpy2.mpfr(2) ** scale
    with gmpy2.context(precision=3000, round=gmpy2.RoundToNearest):
        return float(x)


@settings(max_examples=200, deadline=None, derandomize=True)
@given(a=st.integers(-(2**300), 2**300), b=st.integers(-(2**300), 2**300), scale=st.integers(0, 1200),
       d=st.sampled_from([2, 3]))
def test_certified_velocities_are_the_nearest_floats(a, b, scale, d):
    assert nearest_floats(np.array([[[a, b]]], dtype=object), scale, d)[0, 0] == nearest(a, b, scale, d)


@pytest.mark.parametrize("d", [2, 3])
def test_the_nearest_float_of_a_near_cancellation(d):
    """a + b sqrt(d) above a number halfway between two floats by less than 2^-452 of it."""
    root = math.isqrt(d << 800)  # sqrt(d) 2^400, rounded down
    halfway = (1 << 453) + (1 << 400)  # between 2^453 and the next float, 2^453 + 2^401
    a, b = halfway - root, 1 << 400  # a + b sqrt(d) = halfway + (sqrt(d) 2^400 - root), in (0, 1) above it
    got = nearest_floats(np.array([[[a, b]]], dtype=object), 400, d)[0, 0]
    assert got == nearest(a, b, 400, d) == math.ldexp(1 + 2.0**-52, 53)


def test_a_certified_state_records_the_bits_its_chain_ran_at():
    """Precision and late precision as built (a state narrowed to its late bits is one of them); 0 where
    files did not keep them."""
    g = pb.HalfPlane(4, 5)
    sim = pb.Simulation(g, inward(g), seed=1, arithmetic="certified", precision=256, late_precision=128)
    c = sim.get_state().certified
    assert (c.precision, c.late_precision, c.limbs.shape[-1]) == (256, 128, 4)
    assert precisions_problem(256, 128, 2) == precisions_problem(0, 0, 7) == ""
    assert precisions_problem(True, 0, 1).startswith("precision and late_precision must be whole multiples")


def test_a_narrowing_among_the_picks_a_freeze_takes_back_is_taken_back_too():
    """5x5 half-plane at 128 then 64 bits: its last collision is at step 426 and the check at step 896 would narrow.
    A run to frozen tries picks past 896 before its freeze scan and rewinds them: it ends, as a run split at step
    426, on the state not narrowed. A run of 1,000 steps narrows at 896."""
    g = pb.HalfPlane(5, 5)
    v = np.round(np.random.default_rng(0).normal(size=(g.n_balls, 2)) * 2**45) / 2**45

    def sim():
        return pb.Simulation(g, v, scheduler=pb.UniformRandomPair(stream="counter", threads=1), seed=0,
                             arithmetic="certified", precision=128, late_precision=64)

    whole, split, on = sim(), sim(), sim()
    whole.run_until_frozen(max_steps=10**5)
    split.run(steps=426)
    split.run_until_frozen(max_steps=10**5)
    on.run(steps=1000)
    assert whole.steps == split.steps == 426 and whole.get_state().identical(split.get_state())
    assert whole.engine.state.field_chain.narrowed is None and whole.get_state().certified.limbs.shape[-1] == 2
    assert on.engine.state.field_chain.narrowed == 896 and on.get_state().certified.limbs.shape[-1] == 1
