"""The core install runs the quick start; each optional dependency's absence is one line naming its extra
(issue 47, item 4). Absence is made by blocking the import (``sys.modules[name] = None``) in a fresh process,
before pinnedballs is imported."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from helpers import TORUS, spec, write

from pinnedballs.util.extras import PACKAGES

#: what the child prints: one JSON object, name -> what happened
CHILD = r"""
import contextlib, io, json, sys
for name in sys.argv[1].split(","):
    sys.modules[name] = None
import pinnedballs as pb
from pinnedballs.run.cli.main import main

said = {}

def call(key, *argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    said[key] = [code, err.getvalue()]

def refused(key, f):
    try:
        f()
        said[key] = "ran"
    except ImportError as exc:
        said[key] = [type(exc).__name__, isinstance(exc, pb.InputError), str(exc)]

work, torus, trajectory = sys.argv[2:5]
exec(sys.argv[5])
print(json.dumps(said))
"""


def child(blocked: list[str], tmp_path, program: str) -> dict:
    """What ``program`` (run in `CHILD`) said, in a process where the modules ``blocked`` cannot be imported."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    s = write(tmp_path / "s.json", spec(TORUS, snapshots={"at_steps": [0, 500]}))
    t = write(tmp_path / "t.json", spec(TORUS, trajectory={"every_collisions": 50}))
    done = subprocess.run([sys.executable, "-c", CHILD, ",".join(blocked), str(tmp_path), str(s), str(t), program],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.splitlines()[-1])


def line(what: str, package: str, extra: str) -> str:
    return f'{what} needs {package}, which is not installed: python3 -m pip install ".[{extra}]" in the pinnedballs ' \
           f"checkout"


ALL_OPTIONAL = sorted({p for packages in PACKAGES.values() for p in packages})

#: the child's program without any optional dependency: the quick start's run, then each place an extra is
#: first needed
WITHOUT_EXTRAS = """
call("run", "run", torus, "--out", f"{work}/r", "--quiet")
call("info", "info", f"{work}/r")
res = pb.load(f"{work}/r")
refused("to_pandas", res.to_pandas)
refused("to_xarray", res.to_xarray)
refused("GSDWriter", lambda: pb.GSDWriter(f"{work}/t.gsd", snapshots={"every_steps": 10}))
call("export", "export", f"{work}/r", f"{work}/r.gsd")
call("trajectory", "run", trajectory, "--out", f"{work}/traj", "--quiet")
call("ensemble", "ensemble", torus, "--replicas", 2, "--workers", 1, "--out", f"{work}/e", "--quiet")
refused("ensemble.to_pandas", pb.load_ensemble(f"{work}/e").to_pandas)
call("dask", "ensemble", torus, "--replicas", 2, "--dask", "tcp://127.0.0.1:1", "--out", f"{work}/d", "--quiet")
refused("run_ensemble", lambda: pb.run_ensemble(pb.load_spec(torus), 2, dask_address="tcp://127.0.0.1:1"))
import pathlib
said["written"] = sorted(p.name for p in pathlib.Path(work, "r").iterdir())
said["nothing"] = [pathlib.Path(work, d).exists() for d in ("t.gsd", "r.gsd", "traj", "d")]
"""


@pytest.mark.slow
def test_the_core_install_runs_the_quick_start_and_each_extra_is_named_where_first_needed(tmp_path):
    said = child(ALL_OPTIONAL, tmp_path, WITHOUT_EXTRAS)
    assert ALL_OPTIONAL == ["dask", "distributed", "gsd", "pandas", "xarray"]
    # the quick start: a run, its results and figures, info, and an ensemble on local processes
    assert said["run"] == [0, ""] and said["info"][0] == 0 and said["ensemble"][0] == 0
    assert {"results.h5", "results.data", "spec.json", "state_initial.png", "state_final.png"} <= set(said["written"])
    for key, what, package, extra in [("to_pandas", "to_pandas", "pandas", "pandas"),
                                      ("to_xarray", "to_xarray", "xarray", "xarray"),
                                      ("GSDWriter", "a GSD trajectory", "gsd", "gsd"),
                                      ("ensemble.to_pandas", "to_pandas", "pandas", "pandas"),
                                      ("run_ensemble", "a Dask cluster", "dask", "dask")]:
        assert said[key] == ["MissingExtra", True, line(what, package, extra)], key
    for key, what, package, extra in [("export", "a GSD trajectory", "gsd", "gsd"),
                                      ("trajectory", "a GSD trajectory", "gsd", "gsd"),
                                      ("dask", "a Dask cluster", "dask", "dask")]:
        assert said[key] == [2, f"pinnedballs: error: {line(what, package, extra)}\n"], key
    assert said["nothing"] == [False, False, False, False]  # refused before anything was written


@pytest.mark.slow
def test_the_package_an_extra_lacks_is_the_one_named(tmp_path):
    """xarray installed without dask: to_xarray names dask, and the xarray extra that installs both; dask without
    distributed: a cluster names distributed."""
    program = """
call("run", "run", torus, "--out", f"{work}/r", "--quiet", "--no-figures")
refused("to_xarray", pb.load(f"{work}/r").to_xarray)
refused("pandas", pb.load(f"{work}/r").to_pandas)
"""
    said = child(["dask"], tmp_path, program)
    assert said["run"] == [0, ""] and said["pandas"] == "ran"
    assert said["to_xarray"] == ["MissingExtra", True, line("to_xarray", "dask", "xarray")]
    said = child(["distributed"], tmp_path / "b", 'refused("dask", lambda: pb.run_ensemble(pb.load_spec(torus), 2, '
                                                  'dask_address="tcp://127.0.0.1:1"))')
    assert said["dask"] == ["MissingExtra", True, line("a Dask cluster", "distributed", "dask")]
