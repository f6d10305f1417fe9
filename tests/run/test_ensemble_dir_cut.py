"""An ensemble directory whose ``replicas.csv`` was cut short (issue 42, item 4, from a hostile battery): never read
as a whole ensemble, never a traceback: `pb.load_ensemble` raises an `InputError` naming the file, and ``info``
says it in one line with exit status 2."""

from __future__ import annotations

import shutil

import pytest
from helpers import assert_input_error, call

import pinnedballs as pb
from pinnedballs.run import ensemble as ens
from pinnedballs.specs import parse_spec

HALF_PLANE = {"geometry": {"kind": "half_plane", "rows": 6, "cols": 10},
              "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0], "energy": 100.0},
              "stop": {"frozen": True, "max_steps": 10**8}, "snapshots": {"at_collisions": [50]}, "seed": 11}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """An ensemble directory of 3 replicas, each with a snapshot row and a final row."""
    out = tmp_path_factory.mktemp("ensemble") / "out"
    ens.run_ensemble(parse_spec(HALF_PLANE), 3, workers=1).save(out, figures=False)
    return out


def damaged(written, tmp_path, cut) -> tuple:
    out = tmp_path / "out"
    shutil.copytree(written, out)
    table = out / "replicas.csv"
    table.write_text(cut(table.read_text()))
    return out, table


@pytest.mark.parametrize("cut, words", [
    (lambda text: text[:len(text) - 40], "row 7: has fewer cells than the header has columns (cut short, or damaged)"),
    (lambda text: text.splitlines(keepends=True)[0], "holds no rows, but summary.json counts 3 replicas (cut short, "
                                                     "or damaged)"),
    (lambda text: "".join(text.splitlines(keepends=True)[:5]), "holds no row of replica 2, but summary.json counts 3 "
                                                               "replicas (cut short, or damaged)"),
])
def test_a_table_cut_short_is_refused_naming_it(written, tmp_path, cut, words):
    assert len(pb.load_ensemble(written).rows) == 6
    out, table = damaged(written, tmp_path, cut)
    with pytest.raises(pb.InputError) as caught:
        pb.load_ensemble(out)
    assert str(caught.value) == f"{table}: {words}"
    code, stdout, err = call("info", out)
    assert_input_error(code, err, f"{table}: {words}")
    assert stdout == ""
    code, stdout, err = call("plot", out)
    assert_input_error(code, err, f"{table}: {words}")
