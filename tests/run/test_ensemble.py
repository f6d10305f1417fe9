"""Ensembles: seeds, bit-identical tables wherever replicas run, failed replicas, the physics of the set-ups."""

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
from helpers import pickled_by_value, thin_spec, write

import pinnedballs as pb
from pinnedballs.analysis import observables as obs
from pinnedballs.engine.margin import MarginWarning
from pinnedballs.run import ensemble as ens
from pinnedballs.run import ensemble_files as ens_files
from pinnedballs.run.cli import main as cli
from pinnedballs.run.reproduction import torus_row
from pinnedballs.specs import parse_spec
from pinnedballs.util.errors import InputError

TORUS = {"geometry": {"kind": "flat_torus", "rows": 8, "cols": 8},
         "initial": {"kind": "single_ball", "ball": 0, "direction": [1.0, 0.0], "energy": 100.0},
         "stop": {"steps": 20_000}, "snapshots": {"at_steps": [5_000]}, "seed": 3}
HALF_PLANE = {"geometry": {"kind": "half_plane", "rows": 6, "cols": 10},
              "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0], "energy": 100.0},
              "stop": {"frozen": True, "max_steps": 10**8}, "snapshots": {"at_collisions": [50]}, "seed": 11}


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as c:
        yield c


def fail_at_two(spec, index, seed):
    """A replica task that raises for replica 2 only (module level, so it pickles)."""
    if index == 2:
        raise RuntimeError(f"boom at replica {index}")
    return ens.run_replica(spec, index, seed)


def table_bytes(result, tmp_path, name):
    return ens_files.write_table(result, tmp_path / f"{name}.csv").read_bytes()


# ---------------------------------------------------------------- seeds and rows


def test_replica_seed_is_the_spawned_child_and_reruns_that_replica_alone():
    spec = parse_spec(TORUS)
    children = np.random.SeedSequence(spec.seed).spawn(5)
    for k in range(5):
        assert np.array_equal(ens.replica_seed(spec, k).generate_state(4), children[k].generate_state(4))
    result = ens.run_ensemble(spec, 5, workers=1)
    row = [r for r in result.rows if r["replica"] == 4]
    assert ens.run_replica(spec, 4) == row
    assert (row[0]["seed_entropy"], row[0]["spawn_key"]) == (3, "[4]")


def test_rows_are_ordered_by_replica_then_time_with_the_stop_rule_obeyed():
    spec = parse_spec(TORUS)
    result = ens.run_ensemble(spec, 3, workers=1)
    assert [(r["replica"], r["at"]) for r in result.rows] == [
        (k, at) for k in range(3) for at in ("steps=5000", ens.FINAL)]
    assert [r["steps"] for r in result.rows] == [5_000, 20_000] * 3
    assert all(r["frozen"] == 0 and r["stop_reason"] == ("steps" if r["at"] == ens.FINAL else "") for r in result.rows)
    assert all(math.isclose(r["energy"], 100.0, rel_tol=1e-12) for r in result.rows)
    assert result.stages() == ["steps=5000", ens.FINAL]
    assert result.columns[:len(ens.KEY_COLUMNS)] == list(ens.KEY_COLUMNS) and result.columns[-1] == ens.ERROR_COLUMN


def test_a_replica_does_not_depend_on_the_ensemble_size():
    spec = parse_spec(HALF_PLANE)
    small, large = ens.run_ensemble(spec, 3, workers=1), ens.run_ensemble(spec, 5, workers=1)
    assert large.rows[:len(small.rows)] == small.rows


def test_half_plane_rows_freeze_with_snapshot_and_far_shares():
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 4, workers=1)
    finals = [r for r in result.rows if r["at"] == ens.FINAL]
    assert [r["stop_reason"] for r in finals] == ["frozen"] * 4
    assert all(r["frozen"] == 1 and r["approaching_fraction"] == 0.0 for r in finals)
    assert [r["collisions"] for r in result.rows if r["at"] == "collisions=50"] == [50] * 4
    assert all(0 <= r["far_row_share"] <= r["far_half_share"] <= 1 for r in finals)


# ---------------------------------------------------------------- the closing margin of each replica


def test_each_row_carries_the_closing_margin_of_its_state():
    """`MARGIN_COLUMNS` after the key columns: each replica's margin at its snapshot and at the end, as
    that replica run alone gives it (`sim.closing_margin()`)."""
    spec = parse_spec(HALF_PLANE)
    result = ens.run_ensemble(spec, 3, workers=1)
    assert result.columns[len(ens.KEY_COLUMNS):][:4] == list(ens.MARGIN_COLUMNS)
    for k in range(3):
        sim = spec.build(seed=ens.replica_seed(spec, k))
        rows = [r for r in result.rows if r["replica"] == k]
        for row, run in zip(rows, (lambda sim=sim: sim.run(collisions=50),
                                   lambda sim=sim: sim.run_until_frozen(10**8))):
            run()
            m = sim.closing_margin()
            expected = {"smallest_collision": m.smallest_collision, "near_collisions": m.near_collisions,
                        "near_remnants": m.near_remnants}
            if m.largest_remnant is not None:
                expected["largest_remnant"] = m.largest_remnant
            assert {c: row[c] for c in ens.MARGIN_COLUMNS if c in row} == expected
            assert isinstance(row["near_remnants"], int) and row["smallest_collision"] > 1e4  # a wide margin
    assert result.thin() == []


def test_an_ensemble_with_thin_margins_says_so_once(tmp_path):
    """Three replicas until frozen, each thin: one `MarginWarning` for the ensemble, none from the replicas;
    none for their steps (the counts not the observable), at a chosen resolution (the model) or where the
    margins are wide."""
    thin = parse_spec(thin_spec(tmp_path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = ens.run_ensemble(thin, 3, workers=1)
    said = [str(w.message) for w in caught if issubclass(w.category, MarginWarning)]
    assert said == [
        "the closing margin is thin in 3 of 3 replicas (collisions closing within a factor 10,000 of the "
        "threshold, the smallest at 11.3 thresholds; replicas.csv has each replica's margin): their collision "
        "counts depend on the float criterion (resolution 4.44e-16); count them exactly with \"arithmetic\": "
        "\"exact\" on the same seed"]
    assert [r["replica"] for r in result.thin()] == [0, 1, 2]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ens.run_ensemble(thin.model_copy(update={"resolution": 1e-15}), 2, workers=1)
        for_steps = ens.run_ensemble(parse_spec({**thin_spec(tmp_path), "stop": {"steps": 10}}), 2, workers=1)
        assert [r["replica"] for r in for_steps.thin()] == [0, 1]
        ens.run_ensemble(parse_spec(HALF_PLANE), 2, workers=1)


@pytest.mark.slow
def test_the_ensemble_command_says_it_in_one_line(tmp_path):
    """The program itself, replicas on two local processes: its whole stderr is one note (the workers say
    nothing), and replicas.csv has the margin columns."""
    s = write(tmp_path / "s.json", thin_spec(tmp_path))
    done = subprocess.run([sys.executable, "-m", "pinnedballs", "ensemble", str(s), "--replicas", "3", "--workers",
                           "2", "--out", str(tmp_path / "e"), "--quiet"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stdout == ""
    assert done.stderr.startswith("pinnedballs: note: the closing margin is thin in 3 of 3 replicas (")
    assert done.stderr.count("\n") == 1 and done.stderr.endswith("on the same seed\n")
    rows = ens_files.read_table(tmp_path / "e" / ens.TABLE_NAME)
    assert [(r["near_collisions"], r["near_remnants"]) for r in rows] == [("1", "0")] * 3
    assert all(float(r["smallest_collision"]) == pytest.approx(64 / (4 * math.sqrt(2)), rel=1e-13) for r in rows)


# ---------------------------------------------------------------- wherever it runs


@pytest.mark.slow
def test_tables_are_bit_identical_in_process_on_local_processes_and_on_dask(cluster, tmp_path):
    for name, data in (("torus", TORUS), ("half_plane", HALF_PLANE)):
        spec = parse_spec(data)
        one = ens.run_ensemble(spec, 6, workers=1)
        two = ens.run_ensemble(spec, 6, workers=2)
        dask = ens.run_ensemble(spec, 6, cluster=cluster)
        assert (one.where, two.where) == ("in-process", "2 local processes")
        assert dask.where.startswith("dask tcp://127.0.0.1:")
        assert one.rows == two.rows == dask.rows
        csv = table_bytes(one, tmp_path, f"{name}1")
        assert csv == table_bytes(two, tmp_path, f"{name}2") == table_bytes(dask, tmp_path, f"{name}d")
        assert len(ens_files.read_table(tmp_path / f"{name}1.csv")) == 12


def test_csv_holds_the_exact_floats(tmp_path):
    result = ens.run_ensemble(parse_spec(TORUS), 2, workers=1)
    rows = ens_files.read_table(ens_files.write_table(result, tmp_path / "t.csv"))
    for row, back in zip(result.rows, rows):
        assert float(back["line_of_centres_correlation"]) == row["line_of_centres_correlation"]
        assert float(back["energy"]) == row["energy"]


# ---------------------------------------------------------------- failures


@pytest.mark.parametrize("workers", [1, 2])
def test_a_failing_replica_is_reported_with_its_seed_and_the_others_kept(workers):
    spec = parse_spec(TORUS)
    clean = ens.run_ensemble(spec, 4, workers=1)
    result = ens.run_ensemble(spec, 4, workers=workers, task=fail_at_two)
    assert result.failures == [{"replica": 2, "seed_entropy": 3, "spawn_key": "[2]",
                                ens.ERROR_COLUMN: "RuntimeError: boom at replica 2"}]
    assert [r for r in result.rows if r["replica"] != 2] == [r for r in clean.rows if r["replica"] != 2]


def test_a_failing_replica_on_dask_is_reported_too(cluster):
    with pickled_by_value(sys.modules[__name__]):
        result = ens.run_ensemble(parse_spec(TORUS), 4, cluster=cluster, task=fail_at_two)
    assert [r["replica"] for r in result.failures] == [2]
    assert sorted({r["replica"] for r in result.rows}) == [0, 1, 2, 3]
    assert len(result.rows) == 3 * 2 + 1


def test_progress_counts_the_replicas(capfd):
    ens.run_ensemble(parse_spec(TORUS), 3, workers=1, progress=True)
    err = capfd.readouterr().err
    assert "replicas: 100%" in err and "| 3/3 [" in err
    ens.run_ensemble(parse_spec(TORUS), 2, workers=1)
    assert capfd.readouterr().err == ""  # None: not on a terminal, not in a notebook


def test_bad_arguments_are_input_errors():
    spec = parse_spec(TORUS)
    with pytest.raises(InputError, match="replicas: must be an integer >= 1, got 0"):
        ens.run_ensemble(spec, 0)
    with pytest.raises(InputError, match="workers: must be an integer >= 1"):
        ens.run_ensemble(spec, 2, workers=0)
    with pytest.raises(InputError, match="give at most one"):
        ens.run_ensemble(spec, 2, workers=1, dask_address="tcp://127.0.0.1:1")


# ---------------------------------------------------------------- physics of the paper's set-ups


def test_torus_reaches_equipartition_and_normal_components():
    """16x16 torus, one moving ball, 300,000 steps (~390 per contact), seed 1.

    Theory: each component has variance E/N; a sample variance of N normal values
    has relative standard deviation sqrt(2/N), so allow 3 sqrt(2/N) = 0.27.
    """
    spec = parse_spec({**TORUS, "geometry": {"kind": "flat_torus", "rows": 16, "cols": 16},
                       "stop": {"steps": 300_000}, "snapshots": None, "seed": 1})
    row, = ens.run_replica(spec, 0, observe=torus_row)
    n, energy = 256, 100.0
    for c in "xy":
        assert abs(row[f"variance_{c}"] * n / energy - 1) < 3 * math.sqrt(2 / n)
        assert row[f"ks_pvalue_{c}"] > 0.01
    # conservation fixes the sum of the two variances: (2E - |P|^2/N) / N, |P|^2 = 2E
    assert math.isclose(row["variance_x"] + row["variance_y"], (2 * energy - 2 * energy / n) / n, rel_tol=1e-9)
    assert row["approaching_fraction"] > 0


def test_half_plane_freezes_with_most_energy_in_the_boundary_row_moving_outward():
    geom = pb.HalfPlane.from_size(60, 30)
    spec = parse_spec({**HALF_PLANE, "geometry": {"kind": "half_plane", "length": 60.0, "depth": 30.0},
                       "snapshots": None, "seed": 0})
    for k in range(4):
        sim = spec.build(seed=ens.replica_seed(spec, k))
        assert sim.run_until_frozen(max_steps=10**8)
        _, fraction = obs.energy_profile(geom.boundary_distance(), sim.velocities)
        assert int(np.argmax(fraction)) == 0
        row = obs.boundary_rows(geom.boundary_distance())[0] == 0
        assert obs.outward_energy_fraction(sim.velocities[row]) > 0.99
        assert math.isclose(sim.energy(), 100.0, rel_tol=1e-12)


# ---------------------------------------------------------------- command line


def write_spec(tmp_path, data=TORUS):
    path = tmp_path / "spec.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("argv, message", [
    (["--replicas", "0"], "--replicas: must be an integer >= 1, got 0"),
    (["--replicas", "2", "--workers", "0"], "--workers: must be an integer >= 1, got 0"),
    (["--replicas", "2", "--workers", "1", "--dask", "tcp://127.0.0.1:1"], "give one of them, not both"),
    (["--replicas", "2", "--dask", "notanaddress"],
     "--dask notanaddress: not a Dask scheduler address such as tcp://host:8786 (missing port number"),
    (["--replicas", "2", "--dask", "foo://x:1"], "--dask foo://x:1: not a Dask scheduler address"),
])
def test_cli_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    out = tmp_path / "out"
    assert cli.main(["ensemble", str(write_spec(tmp_path)), "--out", str(out), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_cli_missing_spec_and_non_empty_out_exit_2(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["ensemble", str(tmp_path / "nope.json"), "--replicas", "2", "--out", str(out)]) == 2
    assert "no such spec file" in capsys.readouterr().err and not out.exists()
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    assert cli.main(["ensemble", str(write_spec(tmp_path)), "--replicas", "2", "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]


def test_cli_tiny_ensemble_exits_0_and_writes_table_summary_and_figures(tmp_path, capsys):
    out = tmp_path / "out"
    assert cli.main(["ensemble", str(write_spec(tmp_path)), "--replicas", "3", "--workers", "1",
                     "--out", str(out), "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    rows = ens_files.read_table(out / ens.TABLE_NAME)
    assert [(r["replica"], r["at"]) for r in rows] == [(str(k), at) for k in range(3) for at in ("steps=5000", "final")]
    summary = json.loads((out / ens.SUMMARY_NAME).read_text())
    assert (summary["replicas"], summary["succeeded"], summary["failed"]) == (3, 3, [])
    assert summary["statistics"]["final"]["steps"]["mean"] == 20_000
    assert sorted(p.name for p in (out / "figures").iterdir()) == [
        f"{name}_{at}.png" for name in sorted(ens.CORRELATIONS) for at in ("final", "steps_5000")]
    # --force writes again into it
    assert cli.main(["ensemble", str(write_spec(tmp_path)), "--replicas", "2", "--workers", "1",
                     "--out", str(out), "--quiet", "--force"]) == 0
    assert len(ens_files.read_table(out / ens.TABLE_NAME)) == 4


def test_cli_failed_replica_exits_1_after_writing_the_others(tmp_path, capsys, monkeypatch):
    real = ens.run_replica

    def task(spec, index, seed=None):
        if index == 2:
            raise RuntimeError(f"boom at replica {index}")
        return real(spec, index, seed)

    monkeypatch.setattr(ens, "run_replica", task)  # the default task, looked up when the ensemble runs
    out = tmp_path / "out"
    assert cli.main(["ensemble", str(write_spec(tmp_path)), "--replicas", "4", "--workers", "1",
                     "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "replica 2 (seed entropy 3, spawn key [2]) failed: RuntimeError: boom at replica 2" in err
    rows = ens_files.read_table(out / ens.TABLE_NAME)
    assert [r["replica"] for r in rows] == ["0", "0", "1", "1", "2", "3", "3"]
    assert rows[4] == {"replica": "2", "seed_entropy": "3", "spawn_key": "[2]",
                       "error": "RuntimeError: boom at replica 2"}
    assert json.loads((out / ens.SUMMARY_NAME).read_text())["succeeded"] == 3
