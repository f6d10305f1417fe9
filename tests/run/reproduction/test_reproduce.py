"""`pinnedballs reproduce` on tiny sizes: every figure and report row, the set-ups, the CLI's refusals.

The real ``reproduce --quick`` takes too long for unit tests; `reproduce` runs here
with a tiny plan, which exercises the same code.
"""

import json
import math
import re

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.run import reproduction as rp
from pinnedballs.run.cli import main as cli
from pinnedballs.util.errors import InputError

pytestmark = pytest.mark.slow  # subprocesses, full runs: the full suite (CI) runs these

TINY = dict(sizes=((10, 5), (20, 10)), detail=(20, 10), torus=(8, 8), steps=(3_000, 6_000), long_steps=20_000,
            collisions=30, replicas=4, size_replicas=2)
PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce") / "out"
    report = rp.reproduce(out, workers=1, **TINY)
    return out, report


def test_every_figure_is_a_png(tiny):
    out, _ = tiny
    plan = rp.Plan(**TINY)
    names = rp.expected_figures(plan)
    assert names == [
        "fig1_half_plane_initial.png", "fig2_half_plane_step_3000.png", "fig2_half_plane_step_6000.png",
        "fig3_energy_by_distance_collisions_30.png", "fig3_energy_by_distance_final.png",
        "fig4_energy_by_distance_sizes.png", "fig5_torus_initial.png", "fig5_torus_step_3000.png",
        "fig5_torus_step_6000.png", "fig6_torus_components_step_3000.png", "fig6_torus_components_step_6000.png",
        "fig7_correlation_line_of_centres.png", "fig8_correlation_xy.png", "extra_collisions_until_frozen.png",
        "extra_far_share_by_size.png", "extra_paper_lattice_energy_by_distance.png"]
    assert sorted(p.name for p in out.glob("*.png")) == sorted(names)
    for name in names:
        assert (out / name).read_bytes()[:8] == PNG


def test_report_has_one_table_row_per_check_with_a_verdict(tiny):
    out, report = tiny
    text = report.read_text()
    results = json.loads((out / "results.json").read_text())
    checks = results["checks"]
    rows = [line for line in text.splitlines() if re.match(r"\| \d+ \|", line)]
    assert len(rows) == len(checks) == 17
    for k, (row, check) in enumerate(zip(rows, checks), 1):
        cells = [c.strip() for c in row.strip("|").split(" | ")]
        assert cells[0] == str(k) and cells[1] == check["statement"]
        assert cells[-2] == check["criterion"].replace("|", "\\|")
        assert cells[-1] == {True: "**yes**", False: "**no**", None: "—"}[check["agrees"]]
    for statement in ("About 30 % of the energy ends in the boundary row", "pointing outward",
                      "A little energy settles at the far side", "follows 45,158 collisions",
                      "The bigger the system, the less energy far from the boundary",
                      "Torus, 3,000 steps: x- and y-components look normal", "Torus, 6,000 steps: equipartition",
                      "line-of-centres components of touching pairs is near 0", "x- and y-components is near 0",
                      "Finite systems freeze", "keeps colliding forever", "Torus, 20,000 steps"):
        assert sum(statement in c["statement"] for c in checks) >= 1, statement
    agree = re.search(r"(\d+) of (\d+) comparisons agree", text)
    assert agree and (int(agree.group(1)), int(agree.group(2))) == (
        sum(c["agrees"] is True for c in checks), sum(c["agrees"] is not None for c in checks))
    wall = re.search(r"Wall time: \*\*([\d.]+) s\*\*", text)
    assert wall and math.isclose(float(wall.group(1)), results["wall_seconds"], abs_tol=0.05)
    for name in rp.expected_figures(rp.Plan(**TINY)):
        assert f"]({name})" in text


def test_tiny_run_facts(tiny):
    out, _ = tiny
    results = json.loads((out / "results.json").read_text())
    detail = results["detail"]
    assert (detail["rows"], detail["cols"], detail["balls"]) == (6, 10, 60)
    assert detail["frozen"] and detail["final"]["approaching_fraction"] == 0
    assert math.isclose(detail["final"]["energy"], 100.0, rel_tol=1e-12)
    frozen = next(c for c in results["checks"] if c["statement"].startswith("Finite systems freeze"))
    assert frozen["agrees"] is True and frozen["ours"].startswith("10 of 10 half-plane runs frozen")
    for name, n in (("half_plane_10x5", 2), ("half_plane_20x10", 4), ("paper_lattice", 4), ("torus", 4)):
        summary = json.loads((out / "ensembles" / name / "summary.json").read_text())
        assert (summary["replicas"], summary["succeeded"]) == (n, n)
    torus = json.loads((out / "ensembles" / "torus" / "summary.json").read_text())
    assert list(torus["statistics"]) == ["steps=3000", "steps=6000", "final"]
    assert torus["statistics"]["final"]["steps"]["mean"] == 20_000
    spec = pb.RunSpec.model_validate_json((out / "specs" / "torus.json").read_text())
    assert spec.stop.steps == 6_000 and spec.snapshots.at_steps == [3_000]


def test_reproduce_refuses_a_non_empty_directory_and_bad_plans(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(InputError, match="not empty"):
        rp.reproduce(tmp_path, workers=1, **TINY)
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]
    with pytest.raises(InputError, match="replicas: must be an integer >= 1"):
        rp.reproduce(tmp_path / "new", **{**TINY, "replicas": 0})
    with pytest.raises(InputError, match="steps: must be increasing"):
        rp.reproduce(tmp_path / "new", **{**TINY, "steps": (6_000, 3_000)})
    assert not (tmp_path / "new").exists()


def test_cli_reproduce_bad_input_exits_2(tmp_path, capsys):
    assert cli.main(["reproduce", "--out", str(tmp_path / "x"), "--workers", "0"]) == 2
    assert "--workers: must be an integer >= 1, got 0" in capsys.readouterr().err
    (tmp_path / "keep.txt").write_text("mine")
    assert cli.main(["reproduce", "--out", str(tmp_path), "--quick"]) == 2
    assert "not empty" in capsys.readouterr().err


# ---------------------------------------------------------------- the set-ups


def test_paper_set_ups():
    plan = rp.FULL
    half = rp.half_plane_spec((100, 50), plan).build()
    g = half.geometry
    assert (g.rows, g.cols, g.n_balls) == (29, 50, 1450)
    moving = np.flatnonzero(np.any(half.velocities != 0, axis=1))
    assert moving.tolist() == [g.boundary_center()] and np.array_equal(half.velocities[moving[0]], [0, math.sqrt(200)])
    torus = rp.torus_spec(plan).build()
    assert torus.geometry.n_balls == 1444 and math.isclose(torus.energy(), 100.0, rel_tol=1e-15)
    assert rp.torus_spec(plan).stop.steps == 422_834 and rp.torus_spec(plan).snapshots.at_steps == [211_417]
    assert rp.QUICK.sizes == rp.PAPER_SIZES[:4] and rp.QUICK.replicas == 24


def test_paper_lattice_has_the_papers_ball_count_and_a_zigzag_boundary():
    sim = rp.paper_lattice_spec(rp.FULL).build()
    g = sim.geometry
    p = g.positions
    assert p.shape == (1425, 2) and (g.rows, g.cols) == (57, 25)
    lengths = np.linalg.norm(p[g.contacts.pairs[:, 1]] - p[g.contacts.pairs[:, 0]], axis=1)
    assert np.allclose(lengths, 2.0)
    assert g.degrees().max() == 6
    assert (p[:, 1] == 0).sum() == 29 and (p[:, 1] == 1).sum() == 28  # boundary: distances 0 and 1 alternate
    start = int(np.flatnonzero(np.any(sim.velocities != 0, axis=1))[0])
    assert p[start, 1] == 0 and abs(p[start, 0] - p[:, 0].max() / 2) <= math.sqrt(3)
