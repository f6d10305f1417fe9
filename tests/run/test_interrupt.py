"""A run recorded by `ResultsWriter` and stopped by Ctrl-C (KeyboardInterrupt) or any other exception
loses nothing (issue 20, item 2): the writer saves the state the simulation stopped in, with every
snapshot due at it, marks the results "interrupted", releases the directory and lets the exception
go on; ``pb.load(dir).simulation()`` then continues, in the same process, to the bits of an
unbroken run, snapshots included.

The exception is raised at each place it can arrive: as the compiled loop returns, inside a
writer's snapshot (before and after the `ResultsWriter` recorded its own), inside a user's
observable, and in the middle of a checkpoint (between writing its segment and its index).
A real SIGINT is sent to a child Python process at random moments too.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.analysis import observables as observe
from pinnedballs.engine import driver
from pinnedballs.results.rundir import DirLock
from pinnedballs.util import atomic

ROOT = Path(__file__).resolve().parents[2]
STEPS = 6_000
TRIGGERS = {"every 300 steps": lambda: pb.EverySteps(300), "every 97 collisions": lambda: pb.EveryCollisions(97)}


def simulation() -> pb.Simulation:
    g = pb.FlatTorus(6, 6)
    return pb.Simulation(g, np.random.default_rng(8).standard_normal((g.n_balls, 2)), seed=3)


def record(sim: pb.Simulation, out: Path, trigger, steps: int, resume: bool = False, **options):
    sim.run(steps=steps, writers=[pb.ResultsWriter(out, snapshots=trigger, checkpoint_seconds=0, resume=resume,
                                                   **options)])


@pytest.fixture
def small_chunks(monkeypatch):
    monkeypatch.setattr(driver, "CHUNK_STEPS", 200)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0)


def recorded_unbroken(name: str, tmp_path_factory):
    """``(trigger name, its results)``: the run recorded without a break."""
    out = tmp_path_factory.mktemp("unbroken") / "r"
    record(simulation(), out, TRIGGERS[name](), STEPS)
    return name, pb.load(out)


@pytest.fixture(params=list(TRIGGERS), scope="module")
def unbroken(request, tmp_path_factory):
    return recorded_unbroken(request.param, tmp_path_factory)


@pytest.fixture(scope="module")
def unbroken_steps(tmp_path_factory):
    return recorded_unbroken("every 300 steps", tmp_path_factory)


def assert_continues(out: Path, unbroken, stopped_at: int | None = None) -> None:
    """``out`` says interrupted, at ``stopped_at`` if given, with the unbroken run's snapshots so far;
    its directory is free; continuing it in this process ends on the unbroken run's bits."""
    name, whole = unbroken
    res = pb.load(out)
    assert res.status == "interrupted" and not res.complete
    if stopped_at is not None:
        assert res.steps == stopped_at
    assert [s[:2] for s in res.snapshots] == [s[:2] for s in whole.snapshots if s.steps <= res.steps]
    assert all(np.array_equal(a.velocities, b.velocities) for a, b in zip(res.snapshots, whole.snapshots))
    DirLock(out).acquire().release()  # released by the writer
    sim = res.simulation()
    assert (sim.steps, sim.collisions) == (res.steps, res.collisions)
    record(sim, out, TRIGGERS[name](), STEPS - sim.steps, resume=True)
    done = pb.load(out)
    assert done.complete and done.latest.identical(whole.latest)
    assert [s[:2] for s in done.snapshots] == [s[:2] for s in whole.snapshots]
    assert all(np.array_equal(a.velocities, b.velocities) for a, b in zip(done.snapshots, whole.snapshots))
    for column in whole.observables:
        assert np.array_equal(done.observables[column], whole.observables[column])


# ---------------------------------------------------------------- in this process


@pytest.mark.parametrize("after", [1, 7])
def test_ctrl_c_as_the_loop_returns(tmp_path, monkeypatch, small_chunks, unbroken, after):
    """KeyboardInterrupt as the compiled loop returns (where Python raises a Ctrl-C that came during it)."""
    calls, advance, stopped = [], driver.advance, []

    def interrupted(sim, *args, **kwargs):
        result = advance(sim, *args, **kwargs)
        calls.append(1)
        if len(calls) == after:
            stopped.append(sim.steps)
            raise KeyboardInterrupt
        return result

    monkeypatch.setattr(driver, "advance", interrupted)
    with pytest.raises(KeyboardInterrupt):
        record(simulation(), tmp_path / "r", TRIGGERS[unbroken[0]](), STEPS)
    monkeypatch.undo()
    assert_continues(tmp_path / "r", unbroken, stopped[0])


class Raising(driver.Writer):
    """A writer whose snapshot raises ``error`` at its ``at``-th call."""

    def __init__(self, trigger, at: int, error: BaseException):
        self.trigger, self.at, self.error, self.calls = trigger, at, error, 0

    def write(self, sim) -> None:
        self.calls += 1
        if self.calls == self.at:
            raise self.error


@pytest.mark.parametrize("first", [True, False], ids=["before the ResultsWriter", "after it"])
@pytest.mark.parametrize("error", [KeyboardInterrupt(), RuntimeError("a writer failed")], ids=["ctrl-c", "error"])
def test_an_exception_in_another_writers_snapshot(tmp_path, small_chunks, unbroken, first, error):
    """Raised while the driver records a snapshot: the ResultsWriter records its own once, whether the
    driver had reached it or not, and saves that state."""
    name = unbroken[0]
    sim = simulation()
    ours = pb.ResultsWriter(tmp_path / "r", snapshots=TRIGGERS[name](), checkpoint_seconds=0)
    other = Raising(TRIGGERS[name](), 4, error)
    with pytest.raises(type(error)):
        sim.run(steps=STEPS, writers=[other, ours] if first else [ours, other])
    assert_continues(tmp_path / "r", unbroken, sim.steps)


def test_ctrl_c_inside_the_writers_own_snapshot(tmp_path, monkeypatch, small_chunks, unbroken):
    """A one-off KeyboardInterrupt inside an observable of the ResultsWriter's 5th snapshot: taken again."""
    calls, energy = [], observe.OBSERVABLES["energy"]

    def interrupted(sim):
        calls.append(1)
        if len(calls) == 6:  # the 1st is the initial state's
            raise KeyboardInterrupt
        return energy(sim)

    monkeypatch.setitem(observe.OBSERVABLES, "energy", interrupted)
    sim = simulation()
    with pytest.raises(KeyboardInterrupt):
        record(sim, tmp_path / "r", TRIGGERS[unbroken[0]](), STEPS)
    monkeypatch.undo()
    assert_continues(tmp_path / "r", unbroken, sim.steps)


def test_a_failing_observable_saves_the_last_state_whose_snapshots_are_all_there(tmp_path, monkeypatch,
                                                                                small_chunks, unbroken):
    """An observable that fails for good at the 4th snapshot: that snapshot cannot be taken, so the
    writer saves an earlier state, one whose snapshots are all recorded (its last checkpoint)."""
    name = unbroken[0]
    fourth = unbroken[1].snapshots[3]
    energy = observe.OBSERVABLES["energy"]

    def failing(sim):
        if (sim.steps, sim.collisions) == fourth[:2]:
            raise ValueError("energy: cannot measure")
        return energy(sim)

    monkeypatch.setitem(observe.OBSERVABLES, "energy", failing)
    with pytest.raises(ValueError, match="energy: cannot measure"):
        record(simulation(), tmp_path / "r", TRIGGERS[name](), STEPS)
    monkeypatch.undo()
    res = pb.load(tmp_path / "r")
    assert len(res.snapshots) == 3 and res.snapshots[-1].steps <= res.steps < fourth.steps
    assert_continues(tmp_path / "r", unbroken)


def test_ctrl_c_between_a_segment_and_its_index(tmp_path, monkeypatch, small_chunks, unbroken):
    """Raised after a checkpoint's segment is on disk but before its index: the writer's own checkpoint
    then writes both again (no frame twice)."""
    commits, commit = [], atomic._commit

    def interrupted(tmp, path):
        commit(tmp, path)
        commits.append(path.name)
        if path.name.startswith("frames_") and len([c for c in commits if c.startswith("frames_")]) == 3:
            raise KeyboardInterrupt

    monkeypatch.setattr(atomic, "_commit", interrupted)
    sim = simulation()
    with pytest.raises(KeyboardInterrupt):
        record(sim, tmp_path / "r", TRIGGERS[unbroken[0]](), STEPS)
    monkeypatch.undo()
    assert commits[-1] == "results.h5"  # the writer's checkpoint after the interruption
    assert_continues(tmp_path / "r", unbroken, sim.steps)


def test_an_interrupted_run_says_so_in_info(tmp_path, monkeypatch, small_chunks):
    from helpers import call

    monkeypatch.setattr(driver, "advance", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        record(simulation(), tmp_path / "r", pb.EverySteps(300), STEPS)
    code, out, err = call("info", tmp_path / "r")
    assert (code, err) == (0, "")
    assert "status:      interrupted (continue with pb.load(DIR).simulation())\n" in out


# ---------------------------------------------------------------- a real SIGINT to a Python process

CHILD = """
import sys
import numpy as np
import pinnedballs as pb
from pinnedballs.engine import driver
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 200, 0
g = pb.FlatTorus(6, 6)
sim = pb.Simulation(g, np.random.default_rng(8).standard_normal((g.n_balls, 2)), seed=3)
try:
    sim.run(steps=int(sys.argv[2]), writers=[pb.ResultsWriter(sys.argv[1], snapshots=pb.EverySteps(300),
                                                              checkpoint_seconds=0)])
except KeyboardInterrupt:
    sys.exit(130)
"""


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(6))
def test_sigint_to_a_python_run_at_a_random_moment(tmp_path, unbroken_steps, seed):
    unbroken = unbroken_steps
    out = tmp_path / "r"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(out), str(STEPS)], env=env, stderr=subprocess.PIPE,
                             text=True)
    deadline = time.monotonic() + 120
    while not (out / "results.h5").exists() and child.poll() is None and time.monotonic() < deadline:
        time.sleep(0.005)
    rng = random.Random(seed)
    time.sleep(rng.uniform(0.0, 1.0))
    child.send_signal(signal.SIGINT)
    if seed % 2:  # a second Ctrl-C in quick succession
        time.sleep(rng.uniform(0.0, 0.05))
        child.send_signal(signal.SIGINT)
    _, err = child.communicate(timeout=60)
    done = pb.load(out)
    if done.complete:  # it had finished: the signal came as it exited (Python's own exit, or SIGINT's), or
        # in its last chunk, noted and delivered when the run's block ended (`util.sigint`): 130
        assert child.returncode in (0, 130, -signal.SIGINT) and done.latest.identical(unbroken[1].latest)
        return
    # 130 from the child's `except KeyboardInterrupt`; -SIGINT when a second Ctrl-C lands in that clause
    # itself, after the run was saved
    assert child.returncode in ((130, -signal.SIGINT) if seed % 2 else (130,)), err
    assert_continues(out, unbroken)
