"""What ``pinnedballs schema``, ``validate`` and ``info`` load (issue 49, item 8): each imports what it needs, so
they start in about a second. Before, every command imported numba, scipy.stats and h5py at start-up (12-15 s
each on a loaded machine): the run's modules for its exception and its warning, the door, and a spec's
observables (scipy.stats) and simulation at the spec's import. The facts tested are the modules a command's
process holds when it ends, not its time."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest
from helpers import ROOT, TORUS, call, spec, write

from pinnedballs.specs.run import RunSpec

pytestmark = pytest.mark.slow  # a process per command

#: the program, run as ``python -m pinnedballs ARGS``; the modules it loaded written to the file named last
PROGRAM = """
import json, runpy, sys
*args, out = sys.argv[1:]
sys.argv = ["pinnedballs", *args]
try:
    runpy.run_module("pinnedballs", run_name="__main__")
except SystemExit as exc:
    code = exc.code
with open(out, "w") as f:
    json.dump({"code": code, "modules": sorted(sys.modules)}, f)
"""

#: what none of the three needs: the compiler, scipy's statistics, the plots, dask
NEVER = {"scipy.stats", "matplotlib", "dask", "numba.cuda"}


def loaded(tmp_path, *args) -> tuple[int, str, set[str]]:
    """``(exit status, stdout, modules loaded)`` of ``python -m pinnedballs ARGS`` in a fresh process."""
    out = tmp_path / "modules.json"
    child = subprocess.run([sys.executable, "-c", PROGRAM, *map(str, args), str(out)], capture_output=True, text=True,
                           cwd=tmp_path, env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": str(ROOT)})
    assert child.returncode == 0, child.stderr
    said = json.loads(out.read_text())
    return said["code"], child.stdout, set(said["modules"])


def test_schema_loads_pydantic_and_the_spec_models_alone(tmp_path):
    code, out, modules = loaded(tmp_path, "schema")
    assert code == 0 and json.loads(out) == RunSpec.model_json_schema()
    assert not modules & (NEVER | {"numba", "scipy", "h5py", "networkx", "gmpy2"})
    assert not {m for m in modules if m.startswith(("pinnedballs.engine.sequential", "pinnedballs.simulation",
                                                    "pinnedballs.geometry.base", "pinnedballs.results"))}


def test_validate_builds_the_simulation_without_statistics_or_results(tmp_path):
    """It builds the simulation (numba checks the contacts) on a lattice, and reads and writes no results file."""
    code, out, modules = loaded(tmp_path, "validate", write(tmp_path / "s.json", TORUS))
    assert (code, out) == (0, call("validate", tmp_path / "s.json")[1])
    assert out.startswith("ok: flat_torus 4x4: 16 balls, 48 contacts") and "numba" in modules
    assert not modules & (NEVER | {"h5py", "networkx"})  # networkx: a geometry's contact graph, asked for
    assert not {m for m in modules if m.startswith("pinnedballs.results")}


def test_info_reads_a_run_without_statistics(tmp_path):
    assert call("run", write(tmp_path / "s.json", spec(TORUS, snapshots=...)), "--out", tmp_path / "run",
                "--quiet", "--no-figures")[0] == 0
    code, out, modules = loaded(tmp_path, "info", tmp_path / "run")
    assert (code, out) == (0, call("info", tmp_path / "run")[1]) and out.startswith("results:")
    assert not modules & NEVER


def test_the_specs_word_for_auto_precision_is_the_engines():
    """The spec states ``"auto"`` itself (its field's Literal) rather than load certified arithmetic to read it."""
    from pinnedballs.engine.field import arithmetic
    from pinnedballs.specs import run

    assert run.AUTO == arithmetic.AUTO == "auto"
