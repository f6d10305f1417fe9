"""A torus read back from its results file stays `Geometry.rigid` (issue 42): where the file stands in for the
geometry (a user's factory, which reading never imports; a geometry without a spec), the run continued from it
still says, as the run that wrote it would, that it can never freeze in float64 (`pb.FreezeWarning`). Files
written before the file kept it read as before."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
from helpers import call, write

import pinnedballs as pb
from pinnedballs.geometry.graph import StoredGeometry

DATA = Path(__file__).resolve().parents[1] / "data"

#: a user's module: the paper's torus from a factory of its own
MODULE = '''
import pinnedballs as pb

def torus(rows, cols):
    return pb.FlatTorus(rows, cols)
'''


def freeze_warnings(sim: pb.Simulation, steps: int = 2000) -> list[str]:
    """What ``run_until_frozen(max_steps=steps)`` warns, which must not freeze it."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert not sim.run_until_frozen(max_steps=steps)
    return [str(w.message) for w in caught if issubclass(w.category, pb.FreezeWarning)]


NEVER = "run_until_frozen: not frozen after 2,000 steps, and never will be: on a torus"


def test_a_torus_from_a_users_factory_stays_rigid(tmp_path, monkeypatch):
    name = "pb_user_rigid_torus"
    (tmp_path / f"{name}.py").write_text(MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))
    data = {"geometry": {"kind": "python", "factory": f"{name}:torus", "args": {"rows": 4, "cols": 4}},
            "initial": {"kind": "single_ball", "ball": 0, "direction": [1, 0], "energy": 100},
            "stop": {"steps": 200}, "seed": 1}
    code, _, err = call("run", write(tmp_path / "s.json", data), "--out", tmp_path / "r", "--quiet", "--no-figures")
    assert code == 0, err
    res = pb.load(tmp_path / "r")
    assert isinstance(res.geometry, StoredGeometry) and res.geometry.rigid  # the file's, the factory not imported
    sim = res.simulation()
    assert sim.geometry.rigid and sim.never_freezes() is not None
    (said,) = freeze_warnings(sim)
    assert said.startswith(NEVER)


class SpeclessTorus(pb.FlatTorus):
    """The paper's torus, as a geometry of a user's that has no spec: its results file stands in for it."""

    def to_spec(self):
        return None


def test_a_torus_without_a_spec_stays_rigid(tmp_path):
    g = SpeclessTorus(4, 6)
    v = np.random.default_rng(0).standard_normal((g.n_balls, 2))
    sim = pb.Simulation(g, v, seed=0)
    sim.run(steps=100, writers=[pb.ResultsWriter(tmp_path / "r")])
    res = pb.load(tmp_path / "r")
    assert isinstance(res.geometry, StoredGeometry) and res.geometry.rigid
    resumed = res.simulation()
    assert resumed.get_state().identical(sim.get_state())
    assert freeze_warnings(resumed) == freeze_warnings(sim) and freeze_warnings(sim)[0].startswith(NEVER)


def test_a_geometry_that_is_not_rigid_stays_so(tmp_path):
    g = pb.GraphGeometry.from_positions(np.column_stack([2.0 * np.arange(5), np.zeros(5)]))
    sim = pb.Simulation(g, np.column_stack([np.arange(5.0)[::-1], np.zeros(5)]), seed=0)
    sim.run(steps=10, writers=[pb.ResultsWriter(tmp_path / "r")])
    assert not pb.load(tmp_path / "r").stored.rigid


def test_files_written_before_read_as_before():
    """They hold no ``rigid``: the stored geometry is not rigid, the torus their spec builds is."""
    for path in (DATA / "results_v1.h5", DATA / "format2"):
        res = pb.load(path)
        assert not res.stored.rigid and isinstance(res.geometry, pb.FlatTorus) and res.geometry.rigid
