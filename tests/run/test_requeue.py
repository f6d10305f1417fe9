"""A requeued job (issue 26, item 3): a cluster kills a job and runs the same command line again,
``pinnedballs run SPEC --out DIR --resume``, in every life. A directory holding no run yet starts
it; one holding a run continues it; anything else (other files, segments whose index is lost, an
index that leads nowhere, a user's folder among the run's data) is refused in one line, and
nothing is written."""

from __future__ import annotations

import hashlib
import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import TORUS, assert_identical, assert_input_error, call, reference, spec, write

import pinnedballs as pb
from pinnedballs.results.load import load
from pinnedballs.util.errors import InputError

ROOT = Path(__file__).resolve().parents[2]


def tree(directory: Path) -> dict[str, str]:
    """Every file and folder under ``directory``, with the SHA-256 of each file's bytes."""
    return {str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(directory.rglob("*"))}


def resume_argv(spec_path: Path, out: Path) -> list:
    return ["run", spec_path, "--out", out, "--resume", "--quiet", "--no-figures"]


@pytest.fixture
def done(tmp_path) -> tuple[Path, Path]:
    """A spec and the directory of its finished run."""
    spec_path = write(tmp_path / "s.json", spec(TORUS, snapshots={"every_steps": 100}, checkpoint={"every_seconds": 0}))
    out = tmp_path / "done"
    assert call("run", spec_path, "--out", out, "--quiet", "--no-figures")[0] == 0
    return spec_path, out


def test_a_directory_of_other_files_is_refused_in_one_line(tmp_path):
    spec_path = write(tmp_path / "s.json", TORUS)
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    (out / "spec.json").write_text("{}")  # what a killed run may leave, beside the user's file
    before = tree(out)
    code, stdout, err = call(*resume_argv(spec_path, out))
    assert_input_error(code, err, f"--out {out}: holds no run to continue, but other files (notes.txt); choose another "
                                  f"directory, or write into this one with --force instead of --resume")
    assert stdout == "" and tree(out) == before


def test_segments_without_their_index_are_a_run_never_started_over(done):
    spec_path, out = done
    (out / "results.h5").unlink()
    before = tree(out)
    segments = sorted(p.name for p in (out / "results.data").glob("frames_*.h5"))
    assert len(segments) >= 2
    for argv in (resume_argv(spec_path, out), resume_argv(write(spec_path.with_name("other.json"),
                                                                spec(TORUS, seed=99)), out)):
        code, stdout, err = call(*argv)
        assert_input_error(code, err, f"--out {out}: results.h5 is missing, but results.data/ holds {len(segments)} "
                                      f"segment(s) of a run ({segments[0]}, {segments[1]}, ...): its index is lost, "
                                      f"and nothing was written over it; put results.h5 back (from a backup), or move "
                                      f"the directory away to start anew (pinnedballs info {out} says what the "
                                      f"segments hold)")
        assert tree(out) == before
    sim = pb.Simulation(pb.FlatTorus(4, 4), np.eye(16, 2), seed=1)  # a Python writer resuming there: refused too
    with pytest.raises(InputError, match=r"^out_dir .*: results.h5 is missing, but results.data/ holds"):
        sim.run(steps=10, writers=[pb.ResultsWriter(out, resume=True)])
    assert tree(out) == before


def test_info_says_what_the_segments_of_a_lost_index_hold(done):
    _, out = done
    res = load(out)
    (out / "results.h5").unlink()
    segments = sorted(p.name for p in (out / "results.data").glob("frames_*.h5"))
    code, stdout, err = call("info", out)
    assert (code, err) == (0, "") and call("info", out / "results.h5") == (code, stdout, err)
    assert stdout == (
        f"results:     {out / 'results.h5'} is missing: the run's index is lost\n"
        f"segments:    {len(segments)} in {out / 'results.data'} ({segments[0]} to {segments[-1]}): "
        f"{len(res.snapshots)} snapshot(s), steps {res.snapshots[0].steps:,} to {res.snapshots[-1].steps:,}, "
        f"collisions {res.snapshots[0].collisions:,} to {res.snapshots[-1].collisions:,}\n"
        f"geometry:    16 balls, 48 contacts, dim 2 (static.h5)\n"
        f"recover:     put results.h5 back from a backup (nothing can rebuild it: it holds the last state); the "
        f"run's spec is {out / 'spec.json'}\n")


@pytest.mark.parametrize("link", ["loop", "dangling"])
def test_an_index_that_leads_nowhere_is_refused_in_one_line(done, link):
    spec_path, out = done
    (out / "results.h5").unlink()
    (out / "results.h5").symlink_to("results.h5" if link == "loop" else "gone.h5")
    before = tree(out.parent / "done" / "results.data")
    what = "a loop of symbolic links" if link == "loop" else "a dangling symbolic link (to gone.h5)"
    code, _, err = call(*resume_argv(spec_path, out))
    assert_input_error(code, err, f"--out {out}: results.h5 is {what}; the run's index cannot be read: put results.h5 "
                                  f"back, or choose another directory")
    assert tree(out / "results.data") == before and sorted(p.name for p in out.iterdir()) == [
        "results.data", "results.h5", "spec.json"]


@pytest.mark.parametrize("index", [True, False], ids=["with its index", "index lost"])
@pytest.mark.parametrize("what", ["folder", "file"])
def test_a_users_own_entry_in_the_run_data_is_refused_and_nothing_written(done, index, what):
    spec_path, out = done
    (out / "spec.json").unlink()
    if not index:
        (out / "results.h5").unlink()
    mine = out / "results.data" / "mine"
    mine.mkdir() if what == "folder" else mine.write_text("keep me")
    before = tree(out)
    for argv in (resume_argv(spec_path, out), ["run", spec_path, "--out", out, "--force", "--quiet", "--no-figures"]):
        code, _, err = call(*argv)
        assert_input_error(code, err, f"--out {out}: results.data/mine is a {what} no run wrote; move it out of "
                                      f"results.data/ (a run's own data goes there)")
        assert tree(out) == before


def test_a_python_writer_resuming_leaves_a_users_file_alone(tmp_path):
    out = tmp_path / "r"
    sim = pb.Simulation(pb.FlatTorus(4, 4), np.eye(16, 2), seed=1)
    sim.run(steps=50, writers=[pb.ResultsWriter(out, checkpoint_seconds=0)])
    (out / "results.data" / "notes.txt").write_text("keep me")
    sim = pb.load(out).simulation()
    with pytest.raises(InputError, match=rf"^out_dir {out}: results.data/notes.txt is a file no run wrote"):
        sim.run(steps=50, writers=[pb.ResultsWriter(out, resume=True)])
    assert (out / "results.data" / "notes.txt").read_text() == "keep me" and pb.load(out).steps == 50


# ---------------------------------------------------------------- the requeue loop

#: long enough that kills land mid-run: a checkpoint (a segment and the index) after every 500 steps
LONG = spec(TORUS, geometry__rows=10, geometry__cols=10, initial={"kind": "gaussian", "energy": 100.0},
            stop={"steps": 20_000}, snapshots={"every_steps": 1_000}, checkpoint={"every_seconds": 0}, seed=21)

CHILD = """
import sys
from pinnedballs.run.cli import main as cli
from pinnedballs.engine import driver
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 500, 0
sys.exit(cli.main(sys.argv[1:]))
"""


def life(spec_path: Path, out: Path) -> subprocess.Popen:
    """One life of the job: always the same command line."""
    return subprocess.Popen([sys.executable, "-c", CHILD, *map(str, resume_argv(spec_path, out))],
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, stderr=subprocess.PIPE, text=True)


def _index_version(out: Path):
    try:
        st = os.stat(out / "results.h5")
    except OSError:
        return None
    return st.st_ino, st.st_mtime_ns


@pytest.mark.slow
def test_a_job_killed_at_random_moments_and_requeued_ends_as_an_undisturbed_run(tmp_path):
    """SIGKILL at random moments, the first before anything is written; each life runs the same
    command; the last one's run equals, bit for bit, one never disturbed."""
    rng = random.Random(26)
    spec_path = write(tmp_path / "long.json", LONG)
    out = tmp_path / "job"
    # (what to wait for, then seconds more): its start; a new checkpoint of this life's own
    kills = [("start", 0.0), ("checkpoint", rng.uniform(0.1, 1.0)), ("start", rng.uniform(0.5, 5.0)),
             ("checkpoint", rng.uniform(0.1, 1.5))]
    resumed_from = []
    for k, (wait_for, delay) in enumerate(kills):
        before = _index_version(out)
        resumed_from.append(load(out).steps if before else None)
        job = life(spec_path, out)
        deadline = time.monotonic() + 120
        while wait_for == "checkpoint" and _index_version(out) == before and job.poll() is None:
            assert time.monotonic() < deadline, "no checkpoint in time"
            time.sleep(0.01)
        time.sleep(delay)
        job.kill()
        job.communicate(timeout=60)
        assert job.returncode in (-signal.SIGKILL, 0)
        if k == 0:
            assert not out.exists()  # killed before it wrote anything
    before = _index_version(out)
    job = life(spec_path, out)
    _, err = job.communicate(timeout=120)
    assert job.returncode == 0, err
    if before:
        assert err == ""
    else:  # every earlier life was killed before its first checkpoint
        assert re.fullmatch(rf"pinnedballs: --resume: {re.escape(str(out))} holds no run yet \([a-z ]+\): "
                            rf"starting it\n", err), err
    assert any(steps for steps in resumed_from if steps), f"no life continued a checkpoint: {resumed_from}"
    assert_identical(load(out), reference(tmp_path, LONG))
    assert sorted(p.name for p in out.iterdir()) == ["results.data", "results.h5", "spec.json"]
    assert not list((out / "results.data").glob("*.tmp"))
