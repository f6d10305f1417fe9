"""GSDWriter: the frames a Python run or ``pinnedballs run`` writes while it runs equal the snapshots
of the results file, and a resumed run appends to the trajectory without losing or doubling a frame."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import TORUS, call, frames_of, reference, resume, spec, write

import pinnedballs as pb
from pinnedballs.results import trajectory
from pinnedballs.results.load import load
from pinnedballs.util.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


def assert_same_frames(a: list, b: list) -> None:
    """Every chunk of every frame equal: steps, box, particles and the log."""
    assert [int(f.configuration.step) for f in a] == [int(f.configuration.step) for f in b]
    for x, y in zip(a, b):
        assert np.array_equal(x.configuration.box, y.configuration.box)
        for name in ("N", "types", "typeid", "position", "velocity", "diameter"):
            assert np.array_equal(getattr(x.particles, name), getattr(y.particles, name)), name
        assert x.log.keys() == y.log.keys()
        assert all(np.array_equal(x.log[k], y.log[k]) for k in x.log)


def torus_sim(seed: int = 5) -> pb.Simulation:
    torus = pb.FlatTorus(6, 6)
    v = np.random.default_rng(seed).standard_normal((torus.n_balls, 2))
    return pb.Simulation(torus, v, seed=seed)


# ---------------------------------------------------------------- written while running = exported after


def test_frames_written_during_a_run_are_the_exported_snapshots(tmp_path):
    sim = torus_sim()
    every = pb.EverySteps(500)
    sim.run(steps=4_000, writers=[pb.GSDWriter(tmp_path / "live.gsd", snapshots=every),
                                  pb.ResultsWriter(tmp_path / "run", snapshots=every)])
    res = load(tmp_path / "run")
    live = frames_of(tmp_path / "live.gsd")
    assert [int(f.configuration.step) for f in live] == list(range(500, 4_001, 500)) == [s.steps for s in res.snapshots]
    assert_same_frames(live, frames_of(trajectory.export(res, tmp_path / "exported.gsd")))
    assert np.array_equal(live[-1].particles.velocity[:, :2], sim.velocities.astype(np.float32))


@pytest.mark.parametrize("trigger", [pb.EverySteps(700), pb.EveryCollisions(300)], ids=["steps", "collisions"])
def test_continuing_and_resuming_append_each_frame_once(tmp_path, trigger):
    """One run in one go; the same run stopped at 3,000, its trajectory carried on alone to 5,000 (as
    a kill after frames the results had not checkpointed leaves it), then resumed from the results'
    state at 3,000 to 10,000: the same frames, none twice."""
    whole = torus_sim()
    whole.run(steps=10_000, writers=[pb.GSDWriter(tmp_path / "whole.gsd", snapshots=trigger)])

    first = torus_sim()  # the two runs a kill ends write no final frame
    first.run(steps=3_000, writers=[pb.GSDWriter(tmp_path / "split.gsd", snapshots=trigger, final=False),
                                    pb.ResultsWriter(tmp_path / "run", snapshots=trigger)])
    ahead = load(tmp_path / "run").simulation()
    ahead.run(steps=2_000, writers=[pb.GSDWriter(tmp_path / "split.gsd", snapshots=trigger, resume=True, final=False)])
    assert max(int(f.configuration.step) for f in frames_of(tmp_path / "split.gsd")) > 3_000

    again = load(tmp_path / "run").simulation()
    assert again.steps == 3_000
    again.run(steps=7_000, writers=[pb.GSDWriter(tmp_path / "split.gsd", snapshots=trigger, resume=True),
                                    pb.ResultsWriter(tmp_path / "run", snapshots=trigger, resume=True)])
    whole_frames = frames_of(tmp_path / "whole.gsd")
    assert len(whole_frames) >= 5 and int(whole_frames[-1].configuration.step) == 10_000  # ends on the final state
    assert_same_frames(frames_of(tmp_path / "split.gsd"), whole_frames)


def test_one_writer_over_several_runs_appends(tmp_path):
    """Each run ends on its final state (250, 500), or with ``final=False`` the trigger's frames only,
    as one run of 500 steps writes them."""
    for final, steps in ((True, [100, 200, 250, 300, 400, 500]), (False, [100, 200, 300, 400, 500])):
        sim = torus_sim()
        w = pb.GSDWriter(tmp_path / f"t{final}.gsd", snapshots={"every_steps": 100}, final=final)
        sim.run(steps=250, writers=[w])
        sim.run(steps=250, writers=[w])
        frames = frames_of(tmp_path / f"t{final}.gsd")
        assert [int(f.configuration.step) for f in frames] == steps
        assert np.array_equal(frames[-1].particles.velocity[:, :2], sim.velocities.astype(np.float32))


def test_the_writer_refuses_what_it_must_not_overwrite(tmp_path):
    sim = torus_sim()
    path = tmp_path / "t.gsd"
    sim.run(steps=200, writers=[pb.GSDWriter(path, snapshots={"every_steps": 100})])
    with pytest.raises(InputError, match=r"t\.gsd: exists; pass force=True"):
        sim.run(steps=100, writers=[pb.GSDWriter(path, snapshots={"every_steps": 100})])
    other = pb.Simulation(pb.FlatTorus(4, 4), np.ones((16, 2)), seed=0)
    with pytest.raises(InputError, match=r"t\.gsd: holds frames of another run \(36 balls, this run has 16\)"):
        other.run(steps=100, writers=[pb.GSDWriter(path, snapshots={"every_steps": 100}, resume=True)])
    (tmp_path / "bad.gsd").write_bytes(b"not a trajectory")
    with pytest.raises(InputError, match=r"bad\.gsd: not a readable GSD trajectory"):
        sim.run(steps=100, writers=[pb.GSDWriter(tmp_path / "bad.gsd", snapshots={"every_steps": 100}, resume=True)])
    assert len(frames_of(path)) == 2
    sim.run(steps=100, writers=[pb.GSDWriter(path, snapshots={"every_steps": 100}, force=True)])
    assert [int(f.configuration.step) for f in frames_of(path)] == [200, 300]  # a new writer checks the start too
    with pytest.raises(ValueError, match="snapshots: a GSDWriter needs a trigger"):
        pb.GSDWriter(path, snapshots=None)
    with pytest.raises(pb.SpecError, match="snapshots.every_step"):
        pb.GSDWriter(path, snapshots={"every_step": 10})


# ---------------------------------------------------------------- the command line: "trajectory" in a spec


TRAJECTORY = spec(TORUS, geometry__rows=8, geometry__cols=8, initial={"kind": "gaussian", "energy": 100.0},
                  stop={"steps": 200_000}, snapshots={"every_steps": 40_000}, trajectory={"every_steps": 2_000},
                  checkpoint={"every_seconds": 0}, seed=11)


def test_a_spec_with_a_trajectory_writes_it_beside_the_results(tmp_path):
    data = spec(TORUS, trajectory={"every_collisions": 50})
    code, out, err = call("run", write(tmp_path / "s.json", data), "--out", tmp_path / "r", "--quiet", "--no-figures")
    assert code == 0, err
    res = load(tmp_path / "r")
    frames = frames_of(tmp_path / "r" / "trajectory.gsd")
    collisions = [int(f.log["collisions"][0]) for f in frames]
    # then the final state
    assert res.collisions % 50 and collisions == [*range(50, res.collisions + 1, 50), res.collisions]
    assert np.array_equal(frames[-1].particles.velocity[:, :2], res.velocities.astype(np.float32))
    assert len(res.snapshots) == 3                                         # the snapshots are their own
    # run again without one: --force leaves no trajectory of the replaced run
    assert call("run", write(tmp_path / "t.json", TORUS), "--out", tmp_path / "r", "--quiet", "--no-figures",
                "--force")[0] == 0
    assert not (tmp_path / "r" / "trajectory.gsd").exists()


def test_a_trajectory_at_listed_steps_must_end_before_the_stop(tmp_path):
    code, _, err = call("validate", write(tmp_path / "s.json", spec(TORUS, trajectory={"at_steps": [10, 2_000]})))
    assert code == 2 and "trajectory.at_steps: 2000 is beyond the stop at 1000" in err


CHILD = """
import sys
from pinnedballs.run.cli import main as cli
from pinnedballs.engine import driver
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 500, 0  # many small chunks, a checkpoint after each
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.slow
def test_sigkill_then_resume_appends_the_trajectory_without_a_gap_or_a_double(tmp_path):
    spec_path = write(tmp_path / "s.json", TRAJECTORY)
    out = tmp_path / "killed"
    child = subprocess.Popen([sys.executable, "-c", CHILD, "run", str(spec_path), "--out", str(out), "--quiet",
                              "--no-figures"], env={**os.environ, "PYTHONPATH": str(ROOT)}, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 90
    while not ((out / "results.h5").exists() and _steps(out) >= 45_000):
        assert child.poll() is None and time.monotonic() < deadline, "the run ended before it could be killed"
        time.sleep(0.02)
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    on_disk = [int(f.configuration.step) for f in frames_of(out / "trajectory.gsd")]
    assert on_disk == list(range(2_000, on_disk[-1] + 1, 2_000)) and 45_000 <= on_disk[-1] < 200_000
    assert resume(spec_path, out) == 0
    ref = reference(tmp_path, TRAJECTORY)
    mine = frames_of(out / "trajectory.gsd")
    assert [int(f.configuration.step) for f in mine] == list(range(2_000, 200_001, 2_000))
    assert_same_frames(mine, frames_of(ref.run_dir / "trajectory.gsd"))


def _steps(out: Path) -> int:
    try:
        return load(out).steps
    except (OSError, ValueError):  # not there yet
        return -1
