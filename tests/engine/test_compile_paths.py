"""What a first run compiles, and what a second process finds on disk (issue 42, item 8).

A user's rule defined in a notebook's cell has no source file: its loops were compiled again in every new
kernel (3.4 s). They are now keyed by the cell's source, as IPython keeps it in `linecache`, and by the
values of the globals it reads (numba compiles those in): a second kernel loads them, and a changed
constant in another cell compiles anew. Each kernel here is a fresh process sharing one numba cache; what
it compiles is told by numba's compile events (benchmarks/bench_compile.py times it).
"""

from __future__ import annotations

import json
import linecache
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.jit.cache import function_key

pytestmark = pytest.mark.slow  # subprocesses, first compiles

ROOT = Path(__file__).resolve().parents[2]

#: a notebook's cell: a rule keeping a fraction KEEP of the closing speed, KEEP a global of the cell
CELL = '''
import numpy as np
from numba import njit
from pinnedballs.rules import CollisionRule, closing_speed, remnant_threshold

KEEP = {keep}


@njit(inline="always")
def collide_keeping(v, units, i, j, a, b, masses, params, dim, flat, write):
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= remnant_threshold(params):
        return False
    c = w * (1.0 + KEEP) / 2.0
    changed = False
    for k in range(dim):
        tj = -units[a, k] if flat else units[b, k]
        new_i, new_j = v[i, k] - c * units[a, k], v[j, k] - c * tj
        changed |= (new_i != v[i, k]) | (new_j != v[j, k])
        if write:
            v[i, k], v[j, k] = new_i, new_j
    return changed


class Keeping(CollisionRule):
    def kernel(self, equal_masses):
        return collide_keeping, np.zeros(0)
'''

#: a kernel: the cell run as IPython runs it (its source in linecache under a file name no file has), a
#: 2-ball head-on collision; the functions numba compiled (not loaded) and the velocities after
KERNEL = '''
import json, linecache, os, sys
from numba.core import event
import pinnedballs as pb

compiled = []


class Compiles(event.Listener):
    def on_start(self, ev):
        compiled.append(getattr(ev.data.get("dispatcher"), "py_func", None).__qualname__)

    def on_end(self, ev):
        pass


cell = sys.argv[1]
name = f"/tmp/ipykernel_{os.getpid()}/2718281828.py"  # ipykernel's: another in every kernel
linecache.cache[name] = (len(cell), None, cell.splitlines(True), name)
ns = {"__name__": "__main__"}
exec(compile(cell, name, "exec"), ns)
g = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0]])
sim = pb.Simulation(g, [[1.0, 0.0], [0.0, 0.0]], rule=pb.Elastic(), scheduler=pb.Sweep())
sim.run(steps=1)  # the package's own parts
event.register("numba:compile", Compiles())
sim = pb.Simulation(g, [[1.0, 0.0], [0.0, 0.0]], rule=ns["Keeping"](), scheduler=pb.Sweep())
sim.run(steps=1)
print(json.dumps({"compiled": compiled, "v": sim.velocities[:, 0].tolist()}))
'''


def kernel(cache: Path, keep: float) -> dict:
    run = subprocess.run([sys.executable, "-c", KERNEL, CELL.format(keep=keep)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(cache)}, timeout=600)
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout.splitlines()[-1])


def test_a_notebook_rule_compiles_in_its_first_kernel_only(tmp_path):
    """Before: every kernel compiled the rule's loops again (3.4 s each)."""
    first, second = kernel(tmp_path, 0.5), kernel(tmp_path, 0.5)
    assert any("run_to_limits" in name for name in first["compiled"])
    assert second["compiled"] == []
    # 1 hits 2 head-on keeping half the closing speed: (1, 0) -> (1/4, 3/4), momentum kept
    assert first["v"] == second["v"] == [0.25, 0.75]


def test_a_changed_constant_in_another_cell_compiles_anew(tmp_path):
    """numba compiles a global's value into the rule: a kernel where it differs must not load the old loop."""
    kept_half, kept_none = kernel(tmp_path, 0.5), kernel(tmp_path, 0.0)
    assert kept_none["compiled"] and kept_none["v"] == [0.5, 0.5]  # they stick together
    assert kernel(tmp_path, 0.5)["v"] == kept_half["v"] == [0.25, 0.75]


def test_what_cannot_be_keyed_is_not_cached():
    """Source lost (``exec`` of a string without linecache), or a global a key cannot see into: compiled in every
    process, as before; a file's function keeps its file's key."""
    ns = {}
    exec("def lost(x):\n    return x\n", ns)
    assert function_key(ns["lost"]) is None
    assert function_key(pb.Simulation.__init__) is not None
    source = "def cell(x):\n    return x + SCALE\n"
    name = "/tmp/ipykernel_0/1.py"
    linecache.cache[name] = (len(source), None, source.splitlines(True), name)
    try:
        cell = {"SCALE": np.arange(2000.0)}
        exec(compile(source, name, "exec"), cell)
        key = function_key(cell["cell"])
        cell["SCALE"] = np.arange(2000.0)
        cell["SCALE"][1000] = -1.0  # where repr's "..." would hide it
        assert key is not None and function_key(cell["cell"]) not in (None, key)
        cell["SCALE"] = object()
        assert function_key(cell["cell"]) is None
    finally:
        del linecache.cache[name]
