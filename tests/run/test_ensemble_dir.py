"""An ensemble directory read back (issue 24, item 6): `pb.load_ensemble` gives the rows that were
written, as numbers; ``to_pandas`` a row per replica; a repr of one line; ``info`` and ``plot``
describe the directory; a damaged one is one line naming the file."""

from __future__ import annotations

import json

import pandas as pd
import pytest
from helpers import assert_input_error, call

import pinnedballs as pb
from pinnedballs.run import ensemble as ens
from pinnedballs.specs import parse_spec
from pinnedballs.util import provenance

HALF_PLANE = {"geometry": {"kind": "half_plane", "rows": 6, "cols": 10},
              "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0], "energy": 100.0},
              "stop": {"frozen": True, "max_steps": 10**8}, "snapshots": {"at_collisions": [50]}, "seed": 11}


def fail_at_two(spec, index, seed):
    if index == 2:
        raise RuntimeError(f"boom at replica {index}")
    return ens.run_replica(spec, index, seed)


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """``(directory, the EnsembleResult written there)``: 5 replicas, replica 2 failed."""
    out = tmp_path_factory.mktemp("ensemble") / "out"
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 5, workers=1, task=fail_at_two)
    paths = result.save(out)  # the public name of ensemble.write_outputs
    assert {"replicas.csv", "spec.json", "summary.json"} <= {p.name for p in paths}
    return out, result


def test_load_ensemble_gives_the_rows_written_with_their_numbers(written):
    out, result = written
    loaded = pb.load_ensemble(out)
    assert loaded.rows == result.rows and loaded.replicas == 5 and loaded.where == "in-process"
    assert loaded.spec == result.spec and loaded.wall_seconds == result.wall_seconds
    assert loaded.statistics() == result.statistics()


def test_to_pandas_has_a_row_per_replica(written):
    out, result = written
    df = pb.load_ensemble(out).to_pandas()
    assert df.index.name == "replica" and df.index.tolist() == [0, 1, 2, 3, 4]
    assert df.equals(result.to_pandas())
    final = [r for r in result.rows if r.get("at") == "final"]
    assert df.drop(index=2)["collisions"].tolist() == [r["collisions"] for r in final]
    assert df.drop(index=2)["frozen"].tolist() == [True] * 4 and df["frozen"].dtype == "boolean"
    assert df.loc[2, "error"] == "RuntimeError: boom at replica 2" and pd.isna(df.loc[2, "steps"])
    assert df.loc[0, "energy"] == pytest.approx(100.0, rel=1e-12)
    every = result.to_pandas(at=None)
    assert every.index.names == ["replica", "at"] and len(every) == len(result.rows)
    assert every.loc[(0, "collisions=50"), "collisions"] == 50


def test_to_pandas_has_the_closing_margin_of_each_replica(written):
    out, result = written
    df = pb.load_ensemble(out).to_pandas()
    assert list(df.columns[len(ens.KEY_COLUMNS) - 2:][:4]) == list(ens.MARGIN_COLUMNS)  # replica, at: not columns
    final = {r["replica"]: r for r in result.rows if r.get("at") == "final"}
    for k, row in final.items():
        assert [df.loc[k, c] for c in ens.MARGIN_COLUMNS] == [row[c] for c in ens.MARGIN_COLUMNS]
    assert df["near_collisions"].drop(index=2).tolist() == [0] * 4 and pd.isna(df.loc[2, "smallest_collision"])


def test_an_ensemble_written_before_margins_loads_without_them(written, tmp_path):
    """replicas.csv without the margin columns (as ensembles wrote it before): no such columns, no margin line."""
    import csv
    import shutil

    out = tmp_path / "old"
    shutil.copytree(written[0], out)
    with open(out / ens.TABLE_NAME, newline="") as f:
        table = list(csv.reader(f))
    keep = [k for k, name in enumerate(table[0]) if name not in ens.MARGIN_COLUMNS]
    assert len(keep) == len(table[0]) - 4
    with open(out / ens.TABLE_NAME, "w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows([[row[k] for k in keep] for row in table])
    old = pb.load_ensemble(out)
    assert not set(ens.MARGIN_COLUMNS) & set(old.columns) and not set(ens.MARGIN_COLUMNS) & set(old.to_pandas())
    assert old.thin() == [] and "margin:" not in call("info", out)[1]


def test_a_clean_ensemble_has_no_error_column(tmp_path):
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 2, workers=1)
    df = result.to_pandas()
    assert "error" not in df and not df["frozen"].isna().any() and len(df) == 2


def test_the_repr_is_one_short_line(written):
    _, result = written
    text = repr(result)
    assert text == (f"EnsembleResult(5 replicas of half_plane, seed 11: 4 done, 1 failed; 9 rows; in-process, "
                    f"{result.wall_seconds:.3g} s)")


def test_info_and_plot_describe_an_ensemble_directory(written, tmp_path):
    out, _ = written
    code, text, err = call("info", out)
    assert (code, err) == (0, "")
    lines = text.splitlines()
    assert lines[0] == f"ensemble:    {out}"
    assert lines[1] == "replicas:    5 (4 done, 1 failed), seeds spawned from 11"
    assert lines[4] == "stages:      2: collisions=50, final"
    assert lines[-6] == "frozen:      4 of 4 final states"
    final = [r for r in pb.load_ensemble(out).rows if r.get("at") == "final"]
    assert lines[-4:] == provenance.lines([pb.load_ensemble(out).provenance])  # how it was made (test_lineage.py)
    assert lines[-5] == (f"margin:      thin in 0 of 4 final states; smallest collision "
                         f"{min(r['smallest_collision'] for r in final):.3g} thresholds, largest remnant "
                         f"{max(r['largest_remnant'] for r in final):.3g} thresholds (over all replicas)")
    code, text, err = call("plot", out)
    assert (code, err) == (0, "")
    drawn = text.splitlines()
    assert sorted(p.rsplit("/", 1)[1] for p in drawn) == sorted(  # the correlations, the mean energy profile
        f"{name}_{at}.png" for name in (*ens.CORRELATIONS, "energy_by_distance") for at in ("collisions_50", "final"))
    assert all(open(p, "rb").read(8) == b"\x89PNG\r\n\x1a\n" for p in drawn)


@pytest.mark.parametrize("damage, words", [
    (lambda d: (d / "summary.json").write_text("{"), "summary.json: not readable JSON"),
    (lambda d: (d / "spec.json").unlink(), "spec.json: missing"),
    (lambda d: (d / "replicas.csv").write_text((d / "replicas.csv").read_text().replace(",50,", ",fifty,", 1)),
     "replicas.csv: row 2: column collisions: must be an integer, got 'fifty'"),
    (lambda d: (d / "summary.json").write_text(json.dumps({"replicas": 0})), "summary.json: replicas: must be a count"),
])
def test_a_damaged_ensemble_directory_is_one_line_naming_the_file(written, tmp_path, damage, words):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(written[0], out)
    damage(out)
    with pytest.raises(pb.InputError, match=words.replace("(", r"\(")):
        pb.load_ensemble(out)
    if (out / "summary.json").exists():
        code, _, err = call("info", out)
        assert_input_error(code, err, words)


def test_a_directory_that_is_no_ensemble_is_refused(tmp_path):
    with pytest.raises(pb.InputError, match=f"{tmp_path}: not an ensemble directory \\(no replicas.csv\\)"):
        pb.load_ensemble(tmp_path)
