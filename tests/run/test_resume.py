"""Nothing lost: a killed run leaves a readable file, and resuming it ends bit for bit where an
uninterrupted run ends (velocities, counters, random and scheduler state, every snapshot)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, assert_identical, assert_input_error, call, reference, resume, spec, write

import pinnedballs as pb
from pinnedballs.engine import driver
from pinnedballs.results.load import load
from pinnedballs.results.rundir import LOCK_NAME
from pinnedballs.run import execute as runner
from pinnedballs.specs import parse_spec
from pinnedballs.util.errors import InputError

ROOT = Path(__file__).resolve().parents[2]

LONG = spec(TORUS, geometry__rows=8, geometry__cols=8, initial={"kind": "gaussian", "energy": 100.0},
            stop={"steps": 200_000}, snapshots={"every_steps": 40_000}, checkpoint={"every_seconds": 0}, seed=11)


# ---------------------------------------------------------------- a real kill


CHILD = """
import sys
from pinnedballs.run.cli import main as cli
from pinnedballs.engine import driver
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 500, 0  # many small chunks, a checkpoint after each
sys.exit(cli.main(sys.argv[1:]))
"""


def start_child(spec_path: Path, out: Path) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.Popen([sys.executable, "-c", CHILD, "run", str(spec_path), "--out", str(out), "--quiet",
                             "--no-figures"], env=env, stderr=subprocess.PIPE, text=True)


def wait_for_checkpoint(child: subprocess.Popen, out: Path, steps: int, timeout: float = 90.0) -> None:
    """Wait until the results file holds a checkpoint at ``steps`` or more."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert child.poll() is None, "the run ended before it could be stopped"
        if (out / "results.h5").exists():
            try:
                if load(out).steps >= steps:
                    return
            except (OSError, ValueError):  # not there yet
                pass
        time.sleep(0.02)
    child.kill()
    pytest.fail("no checkpoint in time")


@pytest.mark.parametrize("scheduler", [None, {"kind": "rejection_free"}, {"kind": "colored_sweep", "shuffle": True}],
                         ids=["uniform", "rejection_free", "colored_sweep"])
@pytest.mark.slow
def test_sigkill_then_resume_is_bit_identical(tmp_path, scheduler):
    data = LONG if scheduler is None else spec(LONG, scheduler=scheduler)
    spec_path = write(tmp_path / "long.json", data)
    out = tmp_path / "killed"
    child = start_child(spec_path, out)
    wait_for_checkpoint(child, out, 45_000)
    child.send_signal(signal.SIGKILL)
    child.wait(timeout=30)
    assert child.returncode == -signal.SIGKILL

    ref = reference(tmp_path, data)
    killed = load(out)  # readable after the kill
    assert killed.status == "running" and not killed.complete
    assert 45_000 <= killed.steps < 200_000 and killed.steps % 500 == 0  # a checkpoint lies between chunks
    assert 1 <= len(killed.snapshots) < 5
    for mine, theirs in zip(killed.snapshots, ref.snapshots):
        assert mine[:2] == theirs[:2] and np.array_equal(mine.velocities, theirs.velocities)

    assert resume(spec_path, out) == 0
    assert not (out / "results.h5.tmp").exists()
    assert_identical(load(out), ref)


@pytest.mark.slow
def test_sigterm_checkpoints_and_says_so(tmp_path):
    spec_path = write(tmp_path / "long.json", LONG)
    out = tmp_path / "stopped"
    child = start_child(spec_path, out)
    wait_for_checkpoint(child, out, 1_000)  # the loop is running
    child.send_signal(signal.SIGTERM)
    _, err = child.communicate(timeout=60)
    assert child.returncode == 130, err
    stopped = load(out)
    assert err == (f"pinnedballs: interrupted at step {stopped.steps:,}; the checkpoint in {out} is complete: "
                   f"continue with --resume\n")
    assert not stopped.complete and 0 < stopped.steps < 200_000
    assert resume(spec_path, out) == 0
    assert_identical(load(out), reference(tmp_path, LONG))


# ---------------------------------------------------------------- crashes anywhere, in process

CRASHES = {
    "torus steps": LONG,
    "torus collisions, random sweep": spec(LONG, stop={"collisions": 30_000}, scheduler={"kind": "random_sweep"},
                                           snapshots={"at_collisions": [0, 7, 10_000, 29_999]}),
    "half-plane frozen": spec(HALF_PLANE, snapshots={"every_steps": 300}, checkpoint={"every_seconds": 0}),
    "half-plane collisions unreachable": spec(HALF_PLANE, stop={"collisions": 10**6}, checkpoint={"every_seconds": 0},
                                              snapshots={"every_collisions": 50}),
    "half-plane frozen, rejection free": spec(HALF_PLANE, scheduler={"kind": "rejection_free"},
                                              snapshots={"every_steps": 300}, checkpoint={"every_seconds": 0}),
    "torus steps, colored sweep": spec(LONG, scheduler={"kind": "colored_sweep", "shuffle": True}),
}


class Crash(Exception):
    pass


@pytest.mark.parametrize("crash_after", [1, 5])
@pytest.mark.parametrize("data", CRASHES.values(), ids=CRASHES.keys())
def test_crash_then_resume_is_bit_identical(tmp_path, monkeypatch, data, crash_after):
    ref = reference(tmp_path, data)
    monkeypatch.setattr(driver, "CHUNK_STEPS", 211)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)
    calls = []
    advance = driver.advance

    def crashing(*args, **kwargs):
        calls.append(1)
        if len(calls) == crash_after:
            raise Crash
        return advance(*args, **kwargs)

    spec_path = write(tmp_path / "s.json", data)
    out = tmp_path / "crashed"
    monkeypatch.setattr(driver, "advance", crashing)
    with pytest.raises(Crash):
        runner.execute(parse_spec(data), out, figures=False, progress=False)
    monkeypatch.undo()  # resume with the default chunks
    if crash_after == 1:  # failed before its first step: it leaves nothing (as a refusal), --resume starts it
        assert not out.exists()
    else:
        crashed = load(out)
        assert not crashed.complete and crashed.steps <= 211 * (crash_after - 1) < ref.steps
    assert resume(spec_path, out) == 0
    assert_identical(load(out), ref)


def test_resume_after_a_kill_mid_write(tmp_path, monkeypatch):
    """A kill while a checkpoint was being written leaves a stray temporary file: resuming ignores it."""
    data = CRASHES["half-plane frozen"]
    spec_path = write(tmp_path / "s.json", data)
    out = tmp_path / "out"
    monkeypatch.setattr(driver, "CHUNK_STEPS", 100)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)

    calls, advance = [], driver.advance

    def crash(*args, **kwargs):  # after one chunk: a run that fails at its first leaves nothing
        calls.append(1)
        if len(calls) == 2:
            raise Crash
        return advance(*args, **kwargs)

    monkeypatch.setattr(driver, "advance", crash)
    with pytest.raises(Crash):
        runner.execute(parse_spec(data), out, figures=False, progress=False)
    (out / "results.h5.tmp").write_bytes((out / "results.h5").read_bytes()[:1000])
    monkeypatch.undo()
    assert resume(spec_path, out) == 0
    assert sorted(p.name for p in out.iterdir()) == ["results.data", "results.h5", "spec.json"]
    assert_identical(load(out), reference(tmp_path, data))


@pytest.mark.parametrize("empty", [False, True], ids=["missing", "empty"])
def test_resume_starts_a_run_where_there_is_none_yet(tmp_path, empty):
    """Issue 26, item 3 (GROMACS's -cpi): a requeued job runs the same command line in every life, so
    --resume of a missing or empty directory starts the run, saying so in one line. A Python writer's
    resume=True still refuses one (issue 20, item 6): its simulation must be at the run's state."""
    spec_path = write(tmp_path / "s.json", TORUS)
    out = tmp_path / "fresh"
    if empty:
        out.mkdir()
    what = "an empty directory" if empty else "no such directory"
    sim = parse_spec(TORUS).build()
    with pytest.raises(InputError, match=rf"^out_dir {out}: {what}, so no run to continue; check the path, or pass "
                                         rf"resume=False to start one$"):
        sim.run(steps=10, writers=[pb.ResultsWriter(out, resume=True)])
    assert sim.steps == 0 and (list(out.iterdir()) == [] if empty else not out.exists())
    code, stdout, err = call("run", spec_path, "--out", out, "--resume", "--quiet", "--no-figures")
    assert (code, stdout, err) == (0, "", f"pinnedballs: --resume: {out} holds no run yet ({what}): starting it\n")
    assert_identical(load(out), reference(tmp_path, TORUS))


def test_resume_starts_over_a_run_killed_before_its_first_checkpoint(tmp_path):
    """What such a run leaves (its lock file, results.data/ with a half-written static file) is its own:
    --resume starts it again, and says so."""
    spec_path = write(tmp_path / "s.json", TORUS)
    out = tmp_path / "born"
    (out / "results.data").mkdir(parents=True)
    (out / "results.data" / "static.h5.tmp").write_bytes(b"\x89HDF")
    (out / LOCK_NAME).write_text("999999999\n")
    code, stdout, err = call("run", spec_path, "--out", out, "--resume", "--quiet", "--no-figures")
    assert (code, stdout) == (0, "")
    assert err == f"pinnedballs: --resume: {out} holds no run yet (only what a run killed before its first " \
                  f"checkpoint left): starting it\n"
    assert_identical(load(out), reference(tmp_path, TORUS))


def test_resume_may_change_checkpoint_and_description(tmp_path, monkeypatch):
    data = CRASHES["half-plane frozen"]
    out = tmp_path / "out"
    monkeypatch.setattr(driver, "advance", lambda *a, **k: (_ for _ in ()).throw(Crash()))
    with pytest.raises(Crash):
        runner.execute(parse_spec(data), out, figures=False, progress=False)
    monkeypatch.undo()
    changed = write(tmp_path / "changed.json", spec(data, checkpoint={"every_seconds": 5}, description="again"))
    assert resume(changed, out) == 0
    assert_identical(load(out), reference(tmp_path, data))


def test_a_run_split_by_resume_ends_with_the_margin_of_one_unbroken_run(tmp_path, monkeypatch):
    """The closing margin is saved with the checkpoint and restored by --resume: the later picks add to it
    (the margin at the split is not the final one), and it ends bit for bit as the unbroken run's."""
    data = spec(HALF_PLANE, initial__direction=[0.3, 1.0], checkpoint={"every_seconds": 0})
    ref = reference(tmp_path, data)
    monkeypatch.setattr(driver, "CHUNK_STEPS", 200)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)
    advance, calls = driver.advance, []

    def crashing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise Crash
        return advance(*args, **kwargs)

    monkeypatch.setattr(driver, "advance", crashing)
    out = tmp_path / "split"
    with pytest.raises(Crash):
        runner.execute(parse_spec(data), out, figures=False, progress=False)
    monkeypatch.undo()
    split = load(out)
    assert split.steps == 200 and split.closing_margin != ref.closing_margin
    assert split.closing_margin.near_remnants < ref.closing_margin.near_remnants
    assert resume(write(tmp_path / "s.json", data), out) == 0
    done = load(out)
    assert np.array_equal(done.latest.margin, ref.latest.margin) and done.closing_margin == ref.closing_margin
    assert_identical(done, ref)


def test_resume_with_another_resolution_is_refused(tmp_path):
    """The resolution is the model: a run continues only with its own."""
    out = tmp_path / "out"
    assert call("run", write(tmp_path / "a.json", TORUS), "--out", out, "--quiet", "--no-figures")[0] == 0
    before = (out / "results.h5").read_bytes()
    code, _, err = call("run", write(tmp_path / "b.json", spec(TORUS, resolution=1e-9)), "--out", out, "--resume")
    assert_input_error(code, err, f"resolution: differs from the run in {out} (None there, 1e-09 here)")
    assert (out / "results.h5").read_bytes() == before
