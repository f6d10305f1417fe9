"""Which limited loop a CPU run takes for its size (`engine.sequential.sizes.LoopChoice`): every loop it may
take gives the bits of every other, however the tuner's trials and stretches split the run, and
``PINNEDBALLS_LOOP`` forces one (or says in one line why it cannot)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.sequential import sizes
from pinnedballs.engine.tuner import Tuner


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a).view(np.uint64)


def _state(sim) -> tuple:
    st = sim.engine.state
    return (_bits(sim.velocities).tobytes(), sim.steps, sim.collisions, st.counters.tolist(), st.rng.tolist(),
            _bits(st.margin).tolist())


def _calls(sim) -> None:
    sim.run(steps=700_000)
    sim.run(collisions=sim.collisions + 40_000)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a torus never freezes, and says so
        sim.run_until_frozen(max_steps=300_000)


def _torus_sim():
    g = pb.FlatTorus(128, 128)  # 16,384 balls: a lattice with a row pattern, 0.75 MB of tables and velocities
    assert g.row_pattern is not None
    v = np.random.default_rng(4).normal(size=(g.n_balls, 2))
    return pb.Simulation(g, v, seed=5, scheduler=pb.UniformRandomPair(threads=1))


@pytest.mark.slow
def test_every_loop_and_the_timed_choice_give_the_same_bits(monkeypatch):
    """The three loops forced, and the default timing two of them against each other in short segments (the
    torus put within the band of a CPU whose L2 is a third of its bytes): the same velocities, counters,
    stream and margin; the timed run ran both loops (trials of a millisecond, rounds every few milliseconds: many
    splits) and says so in its provenance."""
    runs = {}
    for setting in ("tables", "prefetched", "rows"):
        monkeypatch.setenv("PINNEDBALLS_LOOP", setting)
        sim = _torus_sim()
        _calls(sim)
        runs[setting] = _state(sim)
        assert sim.engine.resources()["loop"]["by"] == f"PINNEDBALLS_LOOP={setting}"
    monkeypatch.delenv("PINNEDBALLS_LOOP")
    monkeypatch.setattr(sizes, "l2_bytes", lambda: 256 << 10)
    monkeypatch.setattr(sizes, "SEGMENT", 1 << 14)
    monkeypatch.setattr(Tuner, "TRIAL_SECONDS", 0.001)
    monkeypatch.setattr(Tuner, "INTERVAL", 0.002)
    sim = _torus_sim()
    assert sim.engine.choice().candidates == ("tables", "rows")
    _calls(sim)
    runs["auto"] = _state(sim)
    assert runs["tables"] == runs["prefetched"] == runs["rows"] == runs["auto"]
    loop = sim.engine.resources()["loop"]
    assert loop["by"] == "measured" and set(loop["shares"]) == {"tables", "rows"} and min(loop["shares"].values()) > 0


def test_small_and_large_systems_take_one_loop_without_timing(monkeypatch):
    monkeypatch.delenv("PINNEDBALLS_LOOP", raising=False)
    monkeypatch.setattr(sizes, "l2_bytes", lambda: 1 << 20)
    small = pb.Simulation(pb.FlatTorus(38, 38), np.ones((38 * 38, 2)), seed=1).engine.choice()
    assert small.candidates == ("tables",) and small.tuner is None and small.by == "size"
    monkeypatch.setattr(sizes, "l2_bytes", lambda: 16 << 10)
    large = _torus_sim().engine.choice()
    assert large.candidates == ("rows",) and large.tuner is None


def test_rows_forced_on_a_geometry_without_a_row_pattern_is_refused(monkeypatch):
    monkeypatch.setenv("PINNEDBALLS_LOOP", "rows")
    with pytest.raises(pb.FieldError, match=r"^PINNEDBALLS_LOOP: 'rows' reads a lattice's row pattern, and this "
                                            r"geometry has none \(a lattice of 16,384 balls or more has one\)$"):
        pb.Simulation(pb.FlatTorus(8, 8), np.ones((64, 2)), seed=1)


def test_an_unknown_setting_is_refused_in_one_line(monkeypatch):
    monkeypatch.setenv("PINNEDBALLS_LOOP", "fast")
    with pytest.raises(pb.FieldError, match=r"^PINNEDBALLS_LOOP: must be one of auto, branch, branch_free, "
                                            r"threshold, tables, prefetched, rows \(or unset\), got 'fast'$"):
        pb.Simulation(pb.FlatTorus(8, 8), np.ones((64, 2)), seed=1)
