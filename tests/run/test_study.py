"""Parameter studies (issue 48): a study of three sizes from one command into a signac project that signac opens;
its table is the point-by-point ensembles' on the same seeds; a killed or interrupted study resumes to the same
table; a point added later runs alone; bad points are refused in one line with nothing written."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from helpers import assert_input_error, call, write

from pinnedballs.run import ensemble as ens
from pinnedballs.run.reproduction.fit import fit_exponent
from pinnedballs.run.study import run_study
from pinnedballs.run.study_dir import ENSEMBLE_DIR, PARTIAL_DIR, load_study
from pinnedballs.specs.study import PointError, load_study_spec
from pinnedballs.util.errors import InputError

ROOT = Path(__file__).resolve().parents[2]

BASE = {"geometry": {"kind": "half_plane", "length": 10, "depth": 5},
        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
        "stop": {"frozen": True, "max_steps": 10**7}}
#: three sizes of the paper's half-plane, 15 to 60 balls
THREE = {"description": "three half-planes", "base": BASE,
         "zip": {"geometry.length": [10, 16, 20], "geometry.depth": [5, 8, 10]}, "replicas": 3, "seed": 7}


def study_file(where: Path, **changes) -> Path:
    return write(where / "study.json", {**THREE, **changes})


@pytest.fixture(scope="module")
def three(tmp_path_factory):
    """THREE run by ``pinnedballs study`` on two local processes: ``(study file, directory, stdout)``."""
    where = tmp_path_factory.mktemp("study")
    path, out = study_file(where), where / "out"
    code, stdout, err = call("study", path, "--out", out, "--workers", 2)
    assert code == 0, err
    return path, out, stdout


def test_one_command_writes_a_signac_project_a_job_a_point(three):
    import signac

    path, out, stdout = three
    assert stdout == f"3 points done (3 run now), 9 of 9 replicas; wrote {out}\n"
    project = signac.get_project(out, search=False)
    study = load_study_spec(path)
    assert len(project) == 3
    (job,) = project.find_jobs({"geometry.length": 16})
    assert job.statepoint() == {"base": study.digest(), "geometry": {"length": 16, "depth": 8}}
    held = json.loads((Path(job.path) / ENSEMBLE_DIR / "spec.json").read_text())
    assert (held["geometry"]["length"], held["geometry"]["depth"]) == (16.0, 8.0)
    assert job.document["replicas"] == 3 and job.document["n_balls"] == 40
    frame = project.to_dataframe()
    assert sorted(frame["sp.base"]) == [study.digest()] * 3 and sorted(frame["doc.n_balls"]) == [15, 40, 60]


def test_the_table_is_the_point_by_point_ensembles_on_the_same_seeds(three):
    """Run here on one process, each point's spec gives its rows in the study (run on two) bit for bit."""
    path, out, _ = three
    table = load_study(out).to_pandas()
    for k, point in enumerate(load_study_spec(path).expand()):
        alone = ens.run_ensemble(point.spec, point.replicas, workers=1, progress=False).to_pandas().reset_index()
        mine = table[table["point"] == k].drop(columns=["point", "job", "geometry.length", "geometry.depth",
                                                         "n_balls"]).reset_index(drop=True)
        pd.testing.assert_frame_equal(mine, alone)
        assert (table[table["point"] == k]["geometry.length"] == point.overrides["geometry.length"]).all()


def test_summary_fit_and_figure_read_the_table(three):
    _, out, _ = three
    res = load_study(out)
    table, summary = res.to_pandas(), res.summary(["collisions", "steps"])
    assert list(summary["n_balls"]) == [15, 40, 60] and list(summary["replicas"]) == [3, 3, 3]
    for k, row in summary.iterrows():
        x = table[table["point"] == k]["collisions"].to_numpy(dtype=float)
        assert row["collisions_mean"] == x.mean() and row["collisions_sd"] == x.std(ddof=1)
        assert row["collisions_se"] == x.std(ddof=1) / np.sqrt(3)
    fit = res.fit("collisions", against="n_balls")
    again = fit_exponent(summary["n_balls"], summary["collisions_mean"], summary["collisions_se"])
    assert {k: fit[k] for k in again} == again and len(fit["local_exponents"]) == 2
    assert fit["local_exponents"][0] == pytest.approx(np.log(summary["collisions_mean"][1] / summary[
        "collisions_mean"][0]) / np.log(40 / 15), rel=1e-12)
    fig = res.plot("collisions")
    (ax,) = fig.axes
    assert (ax.get_xscale(), ax.get_yscale()) == ("log", "log") and ax.get_xlabel() == "balls N"
    assert ax.get_ylabel().startswith("collisions (count), mean ± se over replicas")
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend[0] == "mean ± se over replicas"
    assert legend[1].startswith(f"fit: {fit['prefactor']:.3g} N^({fit['exponent']:.3f} ± ")
    linear = res.plot("energy", against="geometry.length")
    assert linear.axes[0].get_xscale() == "linear" and linear.axes[0].get_xlabel() == "geometry.length (ball radii)"
    assert "3 of 3 done" in res._repr_html_()


def test_info_and_plot_commands_on_a_study_directory(three):
    _, out, _ = three
    code, stdout, _ = call("info", out)
    lines = stdout.splitlines()
    assert code == 0 and lines[1] == "points:      3 of 3 done, varying geometry.length, geometry.depth"
    assert lines[4].startswith('  done  {"geometry.length": 16, "geometry.depth": 8}: 40 balls, 3 replicas; collisions')
    code, stdout, _ = call("plot", out)
    png = Path(stdout.strip())
    assert code == 0 and png == out / "figures" / "collisions_against_n_balls.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_point_added_later_runs_alone(tmp_path, three):
    """Two sizes, then the third added between them: only it runs (the others' files untouched), and the table
    is the three-size study's."""
    _, reference, _ = three
    two = THREE["zip"]["geometry.length"][::2], THREE["zip"]["geometry.depth"][::2]
    out = tmp_path / "out"
    first = run_study({**THREE, "zip": {"geometry.length": two[0], "geometry.depth": two[1]}}, out, workers=1,
                      progress=False)
    files = sorted(p for k in range(2) for p in (first.job_dir(k) / ENSEMBLE_DIR).iterdir())
    before = {p: p.stat().st_mtime_ns for p in files}
    res = run_study(THREE, out, workers=1, progress=False, resume=True)
    assert res.ran == [1] and {p: p.stat().st_mtime_ns for p in files} == before
    pd.testing.assert_frame_equal(res.to_pandas(), load_study(reference).to_pandas())
    assert run_study(THREE, out, workers=1, progress=False, resume=True).ran == []  # nothing left to run


def test_a_study_without_a_seed_keeps_the_one_its_directory_records(tmp_path):
    out = tmp_path / "out"
    first = run_study({**THREE, "seed": None, "zip": {"geometry.length": [10], "geometry.depth": [5]}}, out,
                      workers=1, progress=False)
    drawn = json.loads((out / "study.json").read_text())["seed"]
    again = run_study({**THREE, "seed": None}, out, workers=1, progress=False, resume=True)
    assert again.ran == [1, 2] and json.loads((out / "study.json").read_text())["seed"] == drawn
    pd.testing.assert_frame_equal(again.to_pandas()[again.to_pandas()["point"] == 0], first.to_pandas())
    seeds = [p.spec.seed for p in load_study_spec(write(tmp_path / "s.json", {**THREE, "seed": drawn})).expand()]
    assert [p["seed"] for p in again.points] == seeds


def test_a_study_is_refused_where_it_would_not_be_the_same_study(tmp_path, three):
    path, reference, _ = three
    with pytest.raises(InputError, match="directory is not empty .*; resume=True \\(--resume\\) continues a study"):
        run_study(path, reference, progress=False)
    out = tmp_path / "out"
    run_study({**THREE, "zip": {"geometry.length": [10], "geometry.depth": [5]}}, out, workers=1, progress=False)
    record = (out / "points.json").read_text()
    with pytest.raises(InputError, match=r'point \{"geometry.length": 10, "geometry.depth": 5\}: .* holds 3 replicas '
                                         r"of another run spec \(seed \d+\); the study gives it 3 replicas of seed"):
        run_study({**THREE, "seed": 8}, out, workers=1, progress=False, resume=True)
    assert (out / "points.json").read_text() == record


def test_bad_overrides_are_one_line_exit_2_and_nothing_written(tmp_path):
    out = tmp_path / "out"
    path = study_file(tmp_path, grid={"geometry.lenght": [12]})
    code, _, err = call("study", path, "--out", out)
    assert_input_error(code, err, 'point {"geometry.length": 10, "geometry.depth": 5, "geometry.lenght": 12}: '
                                  "geometry.lenght: unknown key; did you mean 'length'?")
    path = study_file(tmp_path, points=[{"initial.energy": 1.0}, {"initial.energy": -1.0}])
    code, _, err = call("study", path, "--out", out)
    assert_input_error(code, err, 'point {"geometry.length": 10, "geometry.depth": 5, "initial.energy": -1.0}: '
                                  "initial.energy: input should be greater than or equal to 0, got -1.0")
    path = study_file(tmp_path, points=[{"initial.ball": 3}, {"initial.ball": 20}])  # valid, but 15 balls at 10x5
    code, _, err = call("study", path, "--out", out)
    assert_input_error(code, err, 'point {"geometry.length": 10, "geometry.depth": 5, "initial.ball": 20}: '
                                  "initial.ball: must be < n_balls = 15, got 20")
    assert not out.exists()


def test_ctrl_c_keeps_the_points_done_and_resume_finishes_the_table(tmp_path, monkeypatch, three):
    _, reference, _ = three
    run, calls = ens.run_ensemble, []

    def interrupted_at_the_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return run(*args, **kwargs)

    monkeypatch.setattr(ens, "run_ensemble", interrupted_at_the_second)
    path, out = study_file(tmp_path), tmp_path / "out"
    code, _, err = call("study", path, "--out", out, "--workers", 1)
    assert code == 130
    assert err == f"pinnedballs: interrupted; 1 of 3 points done, kept in {out}: continue with --resume\n"
    assert load_study(out).done() == [True, False, False]
    code, stdout, _ = call("study", path, "--out", out, "--workers", 1, "--resume")
    assert code == 0 and stdout.startswith("3 points done (2 run now)")
    pd.testing.assert_frame_equal(load_study(out).to_pandas(), load_study(reference).to_pandas())


CHILD = """
import os, signal, sys
from pinnedballs.run.cli import main as cli
from pinnedballs.run import ensemble as ens
from pinnedballs.run import ensemble_files as ens_files
where, at, calls = os.environ["KILL_IN"], int(os.environ["KILL_AT"]), [0]
def killing(original, before):
    def call(*args, **kwargs):
        calls[0] += 1
        if before and calls[0] == at:
            os.kill(os.getpid(), signal.SIGKILL)
        out = original(*args, **kwargs)
        if not before and calls[0] == at:
            os.kill(os.getpid(), signal.SIGKILL)
        return out
    return call
if where == "running":    # the point's replicas running
    ens.run_ensemble = killing(ens.run_ensemble, True)
elif where == "written":  # its ensemble written whole, not yet renamed
    ens_files.write_outputs = killing(ens_files.write_outputs, False)
elif where == "starting":  # the signac project made, the study's record being written
    from pinnedballs.run import study
    study.write_text_atomic = killing(study.write_text_atomic, True)
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.mark.slow
@pytest.mark.parametrize("where,at", [("starting", 2), ("running", 2), ("written", 3), ("anywhere", 0)])
def test_a_killed_study_resumes_to_the_same_table(tmp_path, three, where, at):
    """SIGKILL as the study starts (its project made, its record half written), while a point runs, after the last
    point's ensemble is written but before it is renamed, or at a random moment: ``--resume`` gives the table of
    the study never killed."""
    _, reference, _ = three
    path, out = study_file(tmp_path), tmp_path / "out"
    argv = [sys.executable, "-c", CHILD, "study", str(path), "--out", str(out), "--workers", "2", "--quiet"]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "KILL_IN": where, "KILL_AT": str(at)}
    child = subprocess.Popen(argv, env=env, stderr=subprocess.PIPE, text=True)
    if where == "anywhere":  # within the first 4 s: importing, checking the points, or running them
        try:
            child.wait(timeout=float(np.random.default_rng(48).uniform(1.0, 4.0)))
        except subprocess.TimeoutExpired:
            child.send_signal(signal.SIGKILL)
        assert child.wait(timeout=120) in (0, -signal.SIGKILL), child.stderr.read()
    else:
        assert child.wait(timeout=120) == -signal.SIGKILL, child.stderr.read()
    if where == "written":
        assert len(list(out.glob(f"workspace/*/{PARTIAL_DIR}"))) == 1
    code, _, err = call("study", path, "--out", out, "--workers", 1, "--resume", "--quiet")
    assert code == 0, err
    assert not list(out.glob(f"workspace/*/{PARTIAL_DIR}"))
    pd.testing.assert_frame_equal(load_study(out).to_pandas(), load_study(reference).to_pandas())


@pytest.mark.slow
def test_signac_find_and_view_work_on_a_study(three, tmp_path):
    _, out, _ = three
    import signac

    (job,) = signac.get_project(out, search=False).find_jobs({"geometry.length": 20})
    found = subprocess.run(["signac", "find", "geometry.length", "20"], cwd=out, capture_output=True, text=True,
                           check=True)
    assert found.stdout.split() == [job.id]
    subprocess.run(["signac", "view", "--prefix", str(tmp_path / "view")], cwd=out, capture_output=True, check=True)
    link = tmp_path / "view" / "geometry.depth" / "10" / "geometry.length" / "20" / "job"
    assert link.resolve() == Path(job.path).resolve() and (link / ENSEMBLE_DIR / "replicas.csv").is_file()


@pytest.mark.slow
@pytest.mark.cuda
def test_a_study_on_the_gpu_has_the_cpus_table(tmp_path):
    """The counter stream's chain on device "cuda" (numba-cuda's simulator here: tests/conftest.py), a GPU thread a
    replica: every point's rows are the CPU's, bit for bit."""
    counter = {**THREE, "base": {**BASE, "scheduler": {"kind": "uniform_random_pair", "stream": "counter"}},
               "zip": {"geometry.length": [6, 10], "geometry.depth": [4, 5]}, "replicas": 2}
    on_gpu = run_study(counter, tmp_path / "gpu", device="cuda", progress=False)
    on_cpu = run_study(counter, tmp_path / "cpu", workers=1, progress=False)
    assert on_gpu.ensemble(0).where == "GPU" and on_cpu.ensemble(0).where == "in-process"
    pd.testing.assert_frame_equal(on_gpu.to_pandas(), on_cpu.to_pandas())
    with pytest.raises(PointError, match=r'point \{"geometry.length": 10, "geometry.depth": 5\}: device: '):
        run_study(THREE, tmp_path / "xoshiro", device="cuda", progress=False)  # the xoshiro stream: the CPU's
    assert not (tmp_path / "xoshiro").exists()

