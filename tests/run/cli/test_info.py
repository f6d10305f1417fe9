"""``pinnedballs info``: what it says of a run (issue 19 item 5.7, given to issue 20): the time a run
took, what its components are, and whether it is done, interrupted or still running."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest
from helpers import HALF_PLANE, ROOT, TORUS, call, chain, spec, thin_spec, write

import pinnedballs as pb
from pinnedballs.results.rundir import LOCK_NAME, DirLock
from pinnedballs.run.cli.commands import _duration


@pytest.mark.parametrize("seconds,text", [(0.0052913, "5.29 ms"), (0.0208, "20.8 ms"), (0.9996, "1 s"),
                                          (1.0, "1 s"), (12.345, "12.3 s"), (125.2, "2 min 05 s"),
                                          (11_220.0, "3 h 07 min")])
def test_durations_keep_three_significant_figures(seconds, text):
    assert _duration(seconds) == text


def test_info_of_a_short_run_says_how_long_it_took(tmp_path):
    out = tmp_path / "out"
    assert call("run", write(tmp_path / "s.json", TORUS), "--out", out, "--quiet", "--no-figures")[0] == 0
    res = pb.load(out)
    code, stdout, err = call("info", out)
    assert (code, err) == (0, "") and 0 < res.elapsed_seconds < 60
    assert (f"time:        {_duration(res.elapsed_seconds)} running the chain in 2 checkpoint(s) (building, compiling "
            f"and figures not counted); written by pinnedballs") in stdout
    assert "time:        0.0 s" not in stdout


def test_info_names_the_components_of_a_run_built_in_python(tmp_path):
    """A component without a spec is named by its class, the others by their kind (a user's factory:
    `test_user_components.test_a_run_of_a_users_module_reads_without_it_and_continues_with_it`)."""
    g = chain(5)
    v = np.zeros((5, 1))
    v[0] = 1.0
    sim = pb.Simulation(g, v, rule=pb.Restitution(0.5), scheduler=pb.Sweep())
    sim.run_until_frozen(1000, writers=[pb.ResultsWriter(tmp_path / "r")])
    code, stdout, err = call("info", tmp_path / "r")
    assert (code, err) == (0, "")
    assert "geometry:    pinnedballs.geometry.graph.GraphGeometry: 5 balls, 4 contacts, dim 1\n" in stdout
    assert "run:         given velocities, restitution, sweep, built in Python\n" in stdout


@pytest.fixture
def running(tmp_path):
    """A run whose file says "running" (the format-2 run of tests/data, marked so)."""
    run = tmp_path / "run"
    shutil.copytree(ROOT / "tests" / "data" / "format2", run)
    with h5py.File(run / "results.h5", "r+") as f:
        f.attrs["status"], f.attrs["stop_reason"] = "running", ""
    return run


def test_info_tells_a_running_run_from_one_killed(running):
    """"running" with the pid of the live process holding the directory; "stopped" when none does."""
    code, out, _ = call("info", running)
    assert code == 0 and ("status:      stopped (killed: no process is writing it; this is its last checkpoint: "
                          "continue with --resume)\n") in out
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (running / LOCK_NAME).write_text(dead.stdout)  # what a killed run leaves
    assert "status:      stopped (killed: " in call("info", running)[1]
    with DirLock(running):
        code, out, _ = call("info", running)
    assert code == 0 and f"status:      running (pid {os.getpid()}; this is its last checkpoint)\n" in out


# ---------------------------------------------------------------- the closing margin (issue 27)


def test_info_shows_a_thin_margin_in_two_lines(tmp_path):
    data = thin_spec(tmp_path)
    assert call("run", write(tmp_path / "s.json", data), "--out", tmp_path / "r", "--quiet", "--no-figures")[0] == 0
    code, out, err = call("info", tmp_path / "r")
    assert (code, err) == (0, "")
    assert ("margin:      smallest collision 11.3 thresholds, no remnant set aside; resolution 4.44e-16 (the default)\n"
            "             1 collision and 0 remnants within a factor 10,000 of the threshold: thin, so the count "
            "depends on the criterion\n") in out


def test_info_shows_a_wide_margin_and_a_chosen_resolution(tmp_path):
    s = write(tmp_path / "s.json", spec(HALF_PLANE, resolution=1e-9))
    assert call("run", s, "--out", tmp_path / "r", "--quiet", "--no-figures")[0] == 0
    m = pb.load(tmp_path / "r").closing_margin
    assert m.smallest_collision > 1e4 and m.near_collisions == 0 and m.resolution == 1e-9
    code, out, _ = call("info", tmp_path / "r")
    assert code == 0
    assert (f"margin:      smallest collision {m.smallest_collision:.3g} thresholds, largest remnant "
            f"{m.largest_remnant:.3g} thresholds; resolution 1e-09\n"
            f"             0 collisions and {m.near_remnants:,} remnants within a factor 10,000 of the threshold "
            f"(wide)\n") in out


def test_info_says_why_a_run_has_no_margin(tmp_path):
    """A file written before margins were kept: unknown; a run in exact arithmetic: none kept."""
    run = tmp_path / "old"
    shutil.copytree(ROOT / "tests" / "data" / "format2", run)
    assert "margin:      unknown (this run began before runs kept their closing margin)\n" in call("info", run)[1]
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.0)
    pb.Simulation(g, v, seed=2, arithmetic="exact").run(steps=30, writers=[pb.ResultsWriter(tmp_path / "e")])
    out = call("info", tmp_path / "e")[1]
    assert "margin:      none kept (exact arithmetic: every closing speed's sign is exact)\n" in out
