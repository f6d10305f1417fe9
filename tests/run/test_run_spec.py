"""Specs from Python (issue 24, item 4): `pb.load_spec` gives a `RunSpec` or the command line's one-line
message as a ValueError; `pb.run_spec` runs it as ``pinnedballs run`` does, into the same files, and
returns the `Results`."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, call, spec, write

import pinnedballs as pb


def test_load_spec_says_the_command_lines_one_line_as_a_value_error(tmp_path):
    good = pb.load_spec(write(tmp_path / "s.json", TORUS))
    assert isinstance(good, pb.RunSpec) and good.geometry.kind == "flat_torus" and good.seed == 1
    typo = write(tmp_path / "typo.json", spec(HALF_PLANE, geometry={"kind": "half_plane", "lenght": 10, "depth": 5}))
    with pytest.raises(ValueError) as caught:
        pb.load_spec(typo)
    message = str(caught.value)
    assert message == ("geometry.lenght: unknown key; did you mean 'length'? (valid keys: kind, rows, cols, length, "
                       "depth, radius, orientation)")
    code, _, err = call("validate", typo)
    assert code == 2 and err == f"pinnedballs: error: {message}\n"
    with pytest.raises(ValueError, match=r"nowhere\.json: no such spec file$"):
        pb.load_spec(tmp_path / "nowhere.json")


def test_run_spec_writes_what_pinnedballs_run_writes_and_returns_the_results(tmp_path):
    path = write(tmp_path / "s.json", TORUS)
    res = pb.run_spec(path, tmp_path / "py")
    assert call("run", path, "--out", tmp_path / "cli", "--quiet")[0] == 0
    cli = pb.load(tmp_path / "cli")
    assert isinstance(res, pb.Results) and res.complete and res.run_dir == tmp_path / "py"
    assert (res.steps, res.collisions) == (cli.steps, cli.collisions) == (1000, res.collisions)
    assert res.velocities.tobytes() == cli.velocities.tobytes()
    assert all(a.velocities.tobytes() == b.velocities.tobytes() for a, b in zip(res.snapshots, cli.snapshots))
    assert sorted(p.name for p in (tmp_path / "py").iterdir()) == sorted(p.name for p in (tmp_path / "cli").iterdir())
    again = pb.run_spec(pb.load_spec(path), tmp_path / "py", resume=True)    # finished: left as it is
    assert again.checkpoints == res.checkpoints and again.velocities.tobytes() == res.velocities.tobytes()


def test_run_spec_refuses_what_the_command_line_refuses(tmp_path):
    s = pb.load_spec(write(tmp_path / "s.json", TORUS))
    pb.run_spec(s, tmp_path / "out", figures=False)
    assert not list((tmp_path / "out").glob("*.png"))
    with pytest.raises(pb.InputError, match="not empty"):
        pb.run_spec(s, tmp_path / "out")
    with pytest.raises(pb.InputError, match="^force, resume: give one of them, not both$"):
        pb.run_spec(s, tmp_path / "out", force=True, resume=True)
    with pytest.raises(pb.InputError, match="^spec: must be a RunSpec or the path of a spec file, got dict$"):
        pb.run_spec(TORUS, tmp_path / "other")
    replaced = pb.run_spec(s, tmp_path / "out", force=True, figures=False)
    assert replaced.checkpoints >= 1 and np.isfinite(replaced.energy)
