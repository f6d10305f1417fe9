"""The command line: exit codes, the one-line messages of bad input, and what good runs write."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import HALF_PLANE, THIN, TORUS, assert_input_error, call, spec, thin_spec, write

import pinnedballs as pb

ROOT = Path(__file__).resolve().parents[3]


# ---------------------------------------------------------------- bad input: exit 2, one line, no files


def _negative_masses(d: Path) -> dict:
    m = np.ones(16)
    m[5] = -1.0
    np.save(d / "m.npy", m)
    return spec(masses="m.npy")


def _nan_velocities(d: Path) -> dict:
    v = np.zeros((16, 2))
    v[3, 1] = np.nan
    np.save(d / "v.npy", v)
    return spec(initial={"kind": "from_file", "path": "v.npy"})


def _wide_velocities(d: Path) -> dict:
    np.save(d / "v.npy", np.zeros((16, 3)))
    return spec(initial={"kind": "from_file", "path": "v.npy"})


BAD_SPECS = {
    "wrong type": (lambda d: spec(geometry__cols="four"),
                   ["geometry.cols: input should be a valid integer, got 'four'"]),
    "unknown kind": (lambda d: spec(initial__kind="single"),
                     ["initial.kind: unknown kind 'single'; did you mean 'single_ball'?"]),
    "unknown key": (lambda d: spec(stop__step=10), ["stop.step: unknown key; did you mean 'steps'?"]),
    "odd torus rows": (lambda d: spec(geometry__rows=7), ["geometry.rows: must be even for a flat torus, got 7"]),
    "negative steps": (lambda d: spec(stop__steps=-5, snapshots=...),
                       ["stop.steps: input should be greater than or equal to 0, got -5"]),
    "two stops": (lambda d: spec(stop={"steps": 1, "collisions": 1}, snapshots=...),
                  ["stop: give exactly one of steps, collisions or frozen"]),
    "bad restitution": (lambda d: spec(rule={"kind": "restitution", "r": -0.1}),
                        ["rule.r: coefficient of restitution must be a number in [0, 1], got -0.1"]),
    "missing velocity file": (lambda d: spec(initial={"kind": "from_file", "path": "missing.npy"}),
                              ["initial.path: file not found:", "missing.npy"]),
    "NaN in velocity file": (_nan_velocities, ["initial.path:", "v.npy: ball 3 has a NaN or infinite component"]),
    "wrong-shape velocity file": (_wide_velocities,
                                  ["initial.path:", "must have shape (n_balls, dim) = (16, 2), got (16, 3)"]),
    "ball out of range": (lambda d: spec(initial__ball=99), ["initial.ball: must be < n_balls = 16, got 99"]),
    "snapshot after stop": (lambda d: spec(snapshots__at_steps=[2000]),
                            ["snapshots.at_steps: 2000 is beyond the stop at 1000"]),
    "boundary_center on a torus": (lambda d: spec(initial__ball="boundary_center"),
                                   ['initial.ball: "boundary_center" needs a geometry with a boundary']),
    "frozen without max_steps": (lambda d: spec(HALF_PLANE, stop={"frozen": True}),
                                 ["stop.max_steps: required with frozen"]),
    "negative mass": (lambda d: spec(masses=0), ["masses: input should be greater than 0, got 0"]),
    "negative mass in a file": (_negative_masses, ["masses:", "m.npy: must all be finite and > 0"]),
    "overflowing energy": (lambda d: spec(initial__energy=1e308),
                           ["initial.energy: too large for these masses: the speeds or the total energy overflow"]),
    "resolution out of range": (lambda d: spec(resolution=0), [
        "pinnedballs: error: resolution: must be a number in (0, 1): a pick collides when its closing speed exceeds "
        "resolution * V (V the system's speed scale), got 0"]),
    "resolution as text": (lambda d: spec(resolution="1e-9"),
                           ["pinnedballs: error: resolution: must be a number, got '1e-9'"]),
    "overflowing gaussian energy": (lambda d: spec(initial={"kind": "gaussian", "energy": 1e308}),
                                    ["initial.energy: too large for these masses"]),
}


@pytest.mark.parametrize("command", ["run", "validate"])
@pytest.mark.parametrize("make,words", BAD_SPECS.values(), ids=BAD_SPECS.keys())
def test_bad_spec(tmp_path, command, make, words):
    spec_path = write(tmp_path / "spec.json", make(tmp_path))
    before = sorted(tmp_path.iterdir())
    extra = ["--out", tmp_path / "out"] if command == "run" else []
    code, out, err = call(command, spec_path, *extra)
    assert_input_error(code, err, *words)
    assert out == ""
    assert sorted(tmp_path.iterdir()) == before  # no output directory, nothing written


def _foreign(d: Path) -> Path:
    with h5py.File(d / "results.h5", "w") as f:
        f["x"] = 1
    return d


def _truncated(d: Path) -> Path:
    code, _, _ = call("run", write(d / "s.json", TORUS), "--out", d / "r", "--quiet", "--no-figures")
    assert code == 0
    data = (d / "r" / "results.h5").read_bytes()
    (d / "r" / "results.h5").write_bytes(data[: len(data) // 2])
    return d / "r"


def _garbage(d: Path) -> Path:
    (d / "results.h5").write_text("not hdf5")
    return d / "results.h5"


BAD_FILES = {
    "missing directory": (lambda d: d / "nowhere", ["nowhere: no such file"]),
    "directory without results": (lambda d: d, ["no results.h5 in this directory"]),
    "foreign HDF5": (_foreign, ["results.h5: not a pinnedballs results file"]),
    "truncated HDF5": (_truncated, ["results.h5: damaged results file: its bytes differ from the digest written with "
                                    "them (changed or cut short since pinnedballs wrote it)"]),
    "not HDF5": (_garbage, ["results.h5: not a readable HDF5 file"]),
}


@pytest.mark.parametrize("command", ["info", "plot"])
@pytest.mark.parametrize("make,words", BAD_FILES.values(), ids=BAD_FILES.keys())
def test_bad_results(tmp_path, command, make, words):
    target = make(tmp_path)
    before = sorted(p for p in tmp_path.rglob("*"))
    code, out, err = call(command, target)
    assert_input_error(code, err, *words)
    assert out == "" and sorted(tmp_path.rglob("*")) == before


def test_non_empty_out_needs_force(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    code, stdout, err = call("run", write(tmp_path / "s.json", TORUS), "--out", out)
    assert_input_error(code, err, f"--out {out}: directory is not empty (notes.txt); use --force")
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_out_is_a_file(tmp_path):
    (tmp_path / "out").write_text("x")
    code, _, err = call("run", write(tmp_path / "s.json", TORUS), "--out", tmp_path / "out")
    assert_input_error(code, err, "exists and is not a directory")


def test_resume_with_another_spec(tmp_path):
    out = tmp_path / "out"
    assert call("run", write(tmp_path / "a.json", TORUS), "--out", out, "--quiet", "--no-figures")[0] == 0
    before = (out / "results.h5").read_bytes()
    code, _, err = call("run", write(tmp_path / "b.json", spec(seed=2)), "--out", out, "--resume")
    assert_input_error(code, err, "seed: differs from the run in", "(1 there, 2 here)")
    assert (out / "results.h5").read_bytes() == before


@pytest.mark.parametrize("argv,words", [
    (["run", "s.json", "--out", "o", "--force", "--resume"], "give --force or --resume, not both"),
    (["run", "s.json"], "the following arguments are required: --out"),
    (["frobnicate"], "invalid choice: 'frobnicate'"),
    ([], "the following arguments are required: COMMAND"),
    (["validate", "nope.json"], "nope.json: no such spec file"),
])
def test_usage_errors(tmp_path, monkeypatch, argv, words):
    monkeypatch.chdir(tmp_path)
    write(tmp_path / "s.json", TORUS)
    code, _, err = call(*argv)
    assert_input_error(code, err, words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.json"]


# ---------------------------------------------------------------- good runs


def test_run_writes_results_spec_and_figures(tmp_path):
    out = tmp_path / "out"
    code, stdout, err = call("run", write(tmp_path / "s.json", spec(HALF_PLANE, snapshots={"at_steps": [0, 50, 100]})),
                             "--out", out, "--quiet")
    assert (code, err) == (0, "")
    res = pb.load(out)
    assert res.complete and res.frozen and res.stop_reason == "frozen"
    assert [s.steps for s in res.snapshots] == [0, 50, 100]
    assert json.loads((out / "spec.json").read_text()) == json.loads(res.spec.to_json())
    names = {p.name for p in out.iterdir()}
    assert {"results.h5", "spec.json"} <= names
    assert {"state_initial.png", "state_snapshots.png", "state_final.png", "energy_by_distance.png"} <= names
    assert "state_step_100.png" not in names                 # one picture per snapshot only on request
    (out / "state_final.png").unlink()
    code, stdout, _ = call("plot", out)
    assert code == 0 and (out / "state_final.png").exists() and str(out / "state_final.png") in stdout
    code, stdout, _ = call("plot", out, "--every-snapshot")
    assert code == 0 and (out / "state_step_100.png").exists() and str(out / "state_step_100.png") in stdout


def test_a_thin_run_says_so_once_as_a_note(tmp_path):
    """A float run until frozen at the default resolution whose margin is thin: one line on stderr, the
    warning's words after ``pinnedballs: note:``, no Python warning with its file and line; the same run for
    its steps (its count not the observable) and a chosen resolution (the model) say nothing."""
    code, out, err = call("run", write(tmp_path / "s.json", thin_spec(tmp_path)), "--out", tmp_path / "r",
                          "--no-figures")
    m = pb.load(tmp_path / "r").closing_margin
    assert code == 0 and out.startswith("frozen: 1 steps, 1 collisions")
    assert err == f"pinnedballs: note: {m.warning()}\n" and err.startswith(f"pinnedballs: note: {THIN}")
    for_steps = write(tmp_path / "t.json", spec(thin_spec(tmp_path), stop={"steps": 10}))
    code, out, err = call("run", for_steps, "--out", tmp_path / "t", "--no-figures")
    assert (code, err) == (0, "") and out.startswith("steps: 10 steps, 1 collisions")
    assert pb.load(tmp_path / "t").closing_margin == m
    chosen = write(tmp_path / "c.json", spec(thin_spec(tmp_path), resolution=1e-15))
    code, _, err = call("run", chosen, "--out", tmp_path / "c", "--quiet", "--no-figures")
    assert (code, err) == (0, "") and pb.load(tmp_path / "c").closing_margin.thin


@pytest.mark.slow
def test_the_note_is_one_line_of_the_real_command(tmp_path):
    """The program itself (a subprocess): its whole stderr is the note."""
    s = write(tmp_path / "s.json", thin_spec(tmp_path))
    done = subprocess.run([sys.executable, "-m", "pinnedballs", "run", str(s), "--out", str(tmp_path / "r"),
                           "--quiet", "--no-figures"], capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert done.returncode == 0 and done.stdout == ""
    assert done.stderr == f"pinnedballs: note: {pb.load(tmp_path / 'r').closing_margin.warning()}\n"


def test_run_prints_summary_and_info(tmp_path):
    out = tmp_path / "out"
    code, stdout, err = call("run", write(tmp_path / "s.json", spec(snapshots=...)), "--out", out, "--no-figures")
    assert code == 0 and "Traceback" not in err
    res = pb.load(out)
    assert stdout == (f"steps: 1,000 steps, {res.collisions:,} collisions, energy {res.energy:.12g}, "
                      f"{'frozen' if res.frozen else 'not frozen'}; wrote {out}\n")
    code, stdout, _ = call("info", out)
    assert code == 0
    assert "status:      done (steps)" in stdout
    assert "geometry:    flat_torus: 16 balls, 48 contacts, dim 2" in stdout
    assert f"collisions:  {res.collisions:,}\n" in stdout and "steps:       1,000\n" in stdout


def test_force_replaces_and_resume_of_a_finished_run_keeps(tmp_path):
    out = tmp_path / "out"
    assert call("run", write(tmp_path / "a.json", TORUS), "--out", out, "--quiet", "--no-figures")[0] == 0
    first = pb.load(out)
    assert call("run", tmp_path / "a.json", "--out", out, "--resume", "--quiet", "--no-figures")[0] == 0
    assert pb.load(out).checkpoints == first.checkpoints and pb.load(out).updated == first.updated
    assert call("run", write(tmp_path / "b.json", spec(seed=2)), "--out", out, "--force", "--quiet",
                "--no-figures")[0] == 0
    second = pb.load(out)
    assert second.spec.seed == 2 and not np.array_equal(second.velocities, first.velocities)


def test_validate_prints_one_line(tmp_path):
    code, out, err = call("validate", write(tmp_path / "s.json", TORUS))
    assert (code, err) == (0, "")
    assert out == ("ok: flat_torus 4x4: 16 balls, 48 contacts, dim 2; single_ball, energy 100; elastic, "
                   "uniform_random_pair; stop at 1,000 steps; 3 snapshots; seed 1\n")


def test_schema_is_the_json_schema():
    code, out, _ = call("schema")
    assert code == 0 and json.loads(out) == pb.RunSpec.model_json_schema()


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "examples").glob("*.json")))
def test_examples_validate(name):
    code, out, _ = call("validate", ROOT / "examples" / name)
    assert code == 0 and out.startswith("ok: ")


def test_the_gallery_shows_each_example_spec_as_it_is():
    page = (ROOT / "docs" / "gallery.md").read_text(encoding="utf-8")
    shown = re.findall(r"`examples/(\S+\.json)`:\n\n```json\n(.*?)\n```", page, flags=re.S)
    assert [name for name, _ in shown] == ["gallery_half_plane.json", "gallery_torus.json", "gallery_sphere.json",
                                           "gallery_hyperbolic.json", "gallery_fcc.json"]
    for name, text in shown:
        assert text == (ROOT / "examples" / name).read_text(encoding="utf-8").rstrip()
    for image in re.findall(r"\]\((gallery/[^)]+)\)", page):
        assert (ROOT / "docs" / image).stat().st_size > 0


# ---------------------------------------------------------------- as a process


def _python(*argv, cwd=None) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "pinnedballs", *map(str, argv)], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


@pytest.mark.slow
def test_process_bad_input_exits_2(tmp_path):
    bad = _python("validate", write(tmp_path / "b.json", spec(geometry__rows=5)))
    assert bad.returncode == 2
    assert bad.stderr == "pinnedballs: error: geometry.rows: must be even for a flat torus, got 5\n"


def test_help_and_version_exit_0():
    code, out, _ = call("--help")
    assert code == 0 and "run" in out and "validate" in out and "info" in out
    code, out, _ = call("--version")
    assert (code, out) == (0, f"pinnedballs {pb.__version__}\n")


@pytest.mark.slow
def test_process_run_is_quiet_off_a_terminal(tmp_path):
    done = _python("run", write(tmp_path / "s.json", TORUS), "--out", tmp_path / "out", "--no-figures")
    assert done.returncode == 0 and done.stderr == ""  # stderr is a pipe: no progress bar
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["results.data", "results.h5", "spec.json"]
    assert done.stdout.startswith("steps: 1,000 steps")


@pytest.mark.parametrize("figures", [True, False], ids=["figures", "no-figures"])
def test_force_leaves_no_figure_of_the_replaced_run(tmp_path, figures):
    out = tmp_path / "out"
    assert call("run", write(tmp_path / "a.json", TORUS), "--out", out, "--quiet")[0] == 0
    assert call("plot", out, "--every-snapshot")[0] == 0
    assert (out / "state_step_250.png").exists()
    flags = () if figures else ("--no-figures",)
    b = spec(snapshots={"at_steps": [100, 200]})
    assert call("run", write(tmp_path / "b.json", b), "--out", out, "--force", "--quiet", *flags)[0] == 0
    pngs = sorted(p.name for p in out.glob("*.png"))
    expected = ["state_final.png", "state_initial.png", "state_snapshots.png", "velocity_histograms.png"]
    assert pngs == (expected if figures else [])


@pytest.mark.slow
def test_a_closed_pipe_ends_quietly():
    """``pinnedballs schema | head -1``: the reader leaves early; no traceback, exit 0."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # every write the command makes now fails with EPIPE
    try:
        proc = subprocess.run([sys.executable, "-m", "pinnedballs", "schema"], stdout=write_end,
                              stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert (proc.returncode, proc.stderr) == (0, "")


def test_an_ensemble_says_the_replicas_time_and_the_whole_commands(tmp_path):
    """It said "done in 5.3 s" of a command of 34.9 s (issue 49): the replicas' time, as summary.json keeps it,
    and the command's, which holds it."""
    out = tmp_path / "e"
    code, stdout, err = call("ensemble", write(tmp_path / "s.json", TORUS), "--replicas", 3, "--workers", 1,
                             "--out", out)
    said = re.fullmatch(r"3 of 3 replicas done in ([\d.]+) s \(in-process\), ([\d.]+) s for the whole command; "
                        r"wrote (.+)\n", stdout)
    assert (code, err) == (0, "") and said and said.group(3) == str(out)
    replicas, whole = float(said.group(1)), float(said.group(2))
    assert f"{json.loads((out / 'summary.json').read_text())['wall_seconds']:.1f}" == said.group(1)
    assert whole >= replicas
