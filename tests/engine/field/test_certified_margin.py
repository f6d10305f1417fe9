"""The margin of a certified run's decisions survives a resume (issue 42): its state keeps the smallest closing
speed counted as a collision (and the largest set aside, and the exact zeros), its results file too, bit for
bit, so a run resumed from its file knows its smallest genuine collision, as `Results` does; a file written
before certified states kept it reads as before (unknown), and stays unknown when continued."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import h5py
import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.results.digest import HEADER_SIZE, seal

#: the 6x8 half-plane, seed 2: its smallest genuine collision, about 4.4e10 thresholds, comes at step 700 or
#: so, and it freezes at step 1,693
SPLIT = 1000


def certified() -> pb.Simulation:
    g = pb.HalfPlane(6, 8)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.3, 14.0]
    return pb.Simulation(g, v, seed=2, arithmetic="certified")


@pytest.fixture(scope="module")
def whole() -> pb.Simulation:
    sim = certified()
    assert sim.run_until_frozen(max_steps=10**6)
    return sim


def split_run(where: Path) -> pb.Simulation:
    sim = certified()
    sim.run(steps=SPLIT, writers=[pb.ResultsWriter(where)])
    return sim


def rewritten(run: Path, change) -> None:
    """The run's index changed by ``change(h5py.File)`` and sealed again, as pinnedballs would have written it."""
    path = run / "results.h5"
    with h5py.File(path, "r+") as f:
        change(f)
    path.write_bytes(seal(path.read_bytes()[HEADER_SIZE:]))


def test_a_run_resumed_from_its_file_knows_its_smallest_collision(tmp_path, whole):
    smallest = whole.smallest_exact_collision
    assert 4e10 < smallest < 5e10 and whole.steps > SPLIT
    split = split_run(tmp_path / "r")
    res = pb.load(tmp_path / "r")
    assert res.smallest_exact_collision == split.smallest_exact_collision == smallest  # reached before the split
    assert np.array_equal(res.latest.certified.margin, split.get_state().certified.margin)
    resumed = res.simulation()
    assert resumed.get_state().identical(split.get_state()) and resumed.smallest_exact_collision == smallest
    resumed.run_until_frozen(max_steps=10**6)
    assert resumed.get_state().identical(whole.get_state())  # the margin of the decisions too, bit for bit
    assert resumed.smallest_exact_collision == smallest


def test_a_file_written_before_the_margin_was_kept_reads_as_unknown(tmp_path, whole):
    split_run(tmp_path / "r")
    rewritten(tmp_path / "r", lambda f: f["state/certified"].attrs.__delitem__("margin"))
    res = pb.load(tmp_path / "r")
    assert res.latest.certified.margin is None and res.smallest_exact_collision is None
    resumed = res.simulation()
    resumed.run_until_frozen(max_steps=10**6)
    # the same run, whose margin the picks since the resume cannot speak for: unknown
    assert resumed.get_state().identical(whole.get_state()) and resumed.get_state().certified.margin is None
    assert resumed.smallest_exact_collision is None


def test_a_margin_a_certified_state_cannot_hold_is_refused(tmp_path):
    sim = split_run(tmp_path / "r")
    state = sim.get_state()
    bad = state.replace(certified=dataclasses.replace(state.certified, margin=np.array([np.nan, -np.inf, 0.0])))
    with pytest.raises(ValueError, match=r"^certified: margin: the smallest collision's closing speed must be >= 0"):
        sim.set_state(bad)
    assert sim.get_state().identical(state)
    rewritten(tmp_path / "r", lambda f: f["state/certified"].attrs.__setitem__("margin", np.array([1.0, 2.0, 0.5])))
    with pytest.raises(pb.ResultsError, match=r"state/certified \(attribute margin\): the picks set aside at closing "
                                              r"speed 0 must be a whole number >= 0, got 0.5"):
        pb.load(tmp_path / "r")


def test_info_says_a_certified_runs_smallest_collision(tmp_path, whole, capsys):
    """``pinnedballs info`` on a certified run: its signs proved exact, and its smallest collision in thresholds of
    the float criterion (unknown for a file written before it was kept)."""
    from pinnedballs.run.cli.main import main

    split_run(tmp_path / "r")
    assert main(["info", str(tmp_path / "r")]) == 0
    margin, = [line for line in capsys.readouterr().out.splitlines() if line.startswith("margin:")]
    assert margin == (f"margin:      every closing speed's sign proved exact; the smallest collision: "
                      f"{whole.smallest_exact_collision:.3g} thresholds of the float criterion")
    rewritten(tmp_path / "r", lambda f: f["state/certified"].attrs.__delitem__("margin"))
    assert main(["info", str(tmp_path / "r")]) == 0
    assert "the smallest collision: unknown (a file written before certified runs kept it)" in capsys.readouterr().out



#: the paper's 30x15 half-plane at 128 bits, seed 1: 927 collisions to its freeze at step 6,199, and exact zeros
#: set aside after its last collision, before the scan that finds the freeze
HALF_PLANE_30 = {
    "geometry": {"kind": "half_plane", "length": 30, "depth": 15},
    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": "inward", "energy": 100},
    "stop": {"frozen": True, "max_steps": 10**6}, "arithmetic": "certified", "precision": 128, "seed": 1,
}


@pytest.mark.parametrize("chunk", [211, 1000])
def test_a_freeze_leaves_the_margin_of_the_run_it_ends(monkeypatch, chunk):
    """A freeze is found by a scan some picks after the last collision, and the run rewinds to it: the
    picks set aside in between are not the run's, nor their closing speeds. Run in chunks of ``chunk`` steps,
    each scanning where it ends, the margin is the one-chunk run's (before, 86 exact zeros in one chunk, 90 in
    chunks of 1,000)."""
    from pinnedballs.engine import driver
    from pinnedballs.specs import parse_spec

    whole = parse_spec(HALF_PLANE_30).build()
    assert whole.run_until_frozen(max_steps=10**6)
    monkeypatch.setattr(driver, "CHUNK_STEPS", chunk)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)
    split = parse_spec(HALF_PLANE_30).build()
    assert split.run_until_frozen(max_steps=10**6)
    assert (split.steps, split.collisions) == (whole.steps, whole.collisions) == (6199, 927)
    assert split.get_state().identical(whole.get_state())  # the margin too, bit for bit


def test_a_files_bound_rule_is_checked_and_a_file_without_one_loads_but_does_not_resume(tmp_path):
    """The batched bound rule's attributes (`CertifiedState`): damage is named; a file without them (written under
    the bound rule in step order, by pinnedballs < 1.0) loads, its state and counts as written, and its resume is
    refused in one line saying why."""
    sim = split_run(tmp_path / "r")
    assert pb.load(tmp_path / "r").latest.certified.bound_batch > 0
    rewritten(tmp_path / "r", lambda f: f["state/certified"].attrs.__setitem__("bound_batch", 1000))
    with pytest.raises(pb.ResultsError, match=r"state/certified: bound_batch must be 0 or a power of two, got 1000"):
        pb.load(tmp_path / "r")
    for name in ("bound_batch", "bound_at", "pending", "unfolded"):
        rewritten(tmp_path / "r", lambda f, name=name: f["state/certified"].attrs.__delitem__(name))
    res = pb.load(tmp_path / "r")
    old = res.latest.certified
    assert (old.bound_batch, old.bound_at, old.pending, old.unfolded) == (0, -1, (0, 0), 0.0)
    written = sim.get_state().certified
    assert (res.steps, res.collisions) == (sim.steps, sim.collisions) and np.array_equal(res.velocities, sim.velocities)
    assert np.array_equal(old.limbs, written.limbs) and np.array_equal(old.bounds, written.bounds)
    with pytest.raises(pb.InputError, match=rf"^{tmp_path / 'r'}: written under the step-order bound rule of "
                                            r"pinnedballs < 1\.0; run it again from the start$"):
        res.simulation()


@pytest.mark.slow
def test_the_command_line_reads_a_step_order_file_and_refuses_its_resume(tmp_path):
    """A certified run of a spec, written under the bound rule in step order (pinnedballs < 1.0) and stopped at a
    checkpoint: ``info`` and ``plot`` read it, ``--resume`` exits 2 in one line saying why, and writes nothing."""
    from helpers import assert_input_error, call, write

    s = write(tmp_path / "s.json", {**HALF_PLANE_30, "stop": {"steps": 2000}})
    run = tmp_path / "run"
    assert call("run", s, "--out", run, "--quiet", "--no-figures")[0] == 0
    done = pb.load(run)

    def as_before_1_0(f):  # no batched rule, and stopped at this checkpoint (killed)
        for name in ("bound_batch", "bound_at", "pending", "unfolded"):
            del f["state/certified"].attrs[name]
        f.attrs["status"], f.attrs["stop_reason"] = "running", ""

    rewritten(run, as_before_1_0)
    res = pb.load(run)
    assert (res.steps, res.collisions, res.complete) == (done.steps, done.collisions, False)
    assert res.latest.velocities.tobytes() == done.latest.velocities.tobytes()
    code, out, _ = call("info", run)
    assert code == 0 and ("status:      running at its last checkpoint; it cannot go on: written under the "
                          "step-order bound rule of pinnedballs < 1.0; run it again from its spec") in out, out
    assert call("plot", run)[0] == 0 and (run / "state_final.png").stat().st_size > 0
    before = {p: p.read_bytes() for p in run.rglob("*") if p.is_file()}
    code, out, err = call("run", s, "--out", run, "--resume", "--quiet", "--no-figures")
    assert_input_error(code, err, f"{run}: written under the step-order bound rule of pinnedballs < 1.0; run it "
                                  f"again from its spec")
    assert out == "" and {p: p.read_bytes() for p in run.rglob("*") if p.is_file()} == before
