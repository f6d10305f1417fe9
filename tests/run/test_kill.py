"""SIGKILL at any moment, including in the middle of a checkpoint, leaves a run directory that
opens and resumes to exactly the bits of an uninterrupted run.

The child runs a spec whose checkpoints (a segment and the index, after every chunk of 500
steps) take most of its time. It is killed either at a chosen file commit (before or after
the rename of a segment, of the index, of the static data) or at a random moment.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import TORUS, assert_identical, reference, resume, spec, write

from pinnedballs.results.load import load

pytestmark = pytest.mark.slow  # subprocesses, full runs: the full suite (CI) runs these

ROOT = Path(__file__).resolve().parents[2]

RUN = spec(TORUS, geometry__rows=10, geometry__cols=10, initial={"kind": "gaussian", "energy": 100.0},
           stop={"steps": 4_000}, snapshots={"every_steps": 250}, checkpoint={"every_seconds": 0}, seed=21)

CHILD = """
import os, signal, sys
from pinnedballs.run.cli import main as cli
from pinnedballs.engine import driver
from pinnedballs.util import atomic as io
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 500, 0
at, when = int(os.environ.get("KILL_AT", "0")), os.environ.get("KILL_WHEN", "")
commits, commit = [0], io._commit
def killing(tmp, path):
    commits[0] += 1
    if commits[0] == at and when == "before":
        os.kill(os.getpid(), signal.SIGKILL)
    commit(tmp, path)
    if commits[0] == at and when == "after":
        os.kill(os.getpid(), signal.SIGKILL)
io._commit = killing
sys.exit(cli.main(sys.argv[1:]))
"""


def child(spec_path: Path, out: Path, **env) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    return subprocess.Popen([sys.executable, "-c", CHILD, "run", str(spec_path), "--out", str(out), "--quiet",
                             "--no-figures"], env=env, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def ref(tmp_path_factory):
    return reference(tmp_path_factory.mktemp("ref"), RUN)


def check_killed_then_resume(spec_path: Path, out: Path, ref) -> None:
    if (out / "results.h5").exists():
        killed = load(out)  # opens after the kill
        if killed.complete:  # killed after its last commit, on its way out: it must be the whole run
            assert_identical(killed, ref)
        else:  # a checkpoint at most at the stop (a kill between the last checkpoint and "done" leaves it there)
            assert killed.steps <= ref.steps
            if killed.steps == ref.steps:
                assert np.array_equal(killed.velocities, ref.velocities)
        assert [s[:2] for s in killed.snapshots] == [s[:2] for s in ref.snapshots[:len(killed.snapshots)]]
    assert resume(spec_path, out) == 0
    assert_identical(load(out), ref)
    assert not list(out.glob("*.tmp")) and not list((out / "results.data").glob("*.tmp"))
    with h5py.File(out / "results.h5") as f:  # no segment left over that the index does not list
        listed = {s[0] for s in json.loads(f.attrs["segments"])}
    assert {p.name for p in (out / "results.data").iterdir()} == listed | {"static.h5"}


# commits: 1 static data, 2 first index, 3 spec.json, then per chunk: a segment, the index
KILLS = [(1, "before"), (2, "before"), (3, "before"), (4, "before"), (4, "after"), (5, "before"), (5, "after"),
         (12, "after")]


@pytest.mark.parametrize("at,when", KILLS, ids=[f"{w} commit {a}" for a, w in KILLS])
def test_kill_at_a_commit_then_resume(tmp_path, ref, at, when):
    spec_path = write(tmp_path / "s.json", RUN)
    out = tmp_path / "out"
    c = child(spec_path, out, KILL_AT=str(at), KILL_WHEN=when)
    c.wait(timeout=120)
    assert c.returncode == -signal.SIGKILL, c.stderr.read()
    check_killed_then_resume(spec_path, out, ref)


@pytest.mark.parametrize("seed", range(3))
def test_kill_at_a_random_moment_then_resume(tmp_path, ref, seed):
    spec_path = write(tmp_path / "s.json", RUN)
    out = tmp_path / "out"
    c = child(spec_path, out)
    deadline = time.monotonic() + 120
    while not (out / "results.h5").exists() and c.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    time.sleep(random.Random(seed).uniform(0.0, 2.5))
    c.send_signal(signal.SIGKILL)
    c.wait(timeout=60)
    if c.returncode == 0:  # it finished first: nothing to resume, but it must be the reference
        assert_identical(load(out), ref)
        return
    assert c.returncode == -signal.SIGKILL
    check_killed_then_resume(spec_path, out, ref)
