"""The closing margin in results files (issue 27, items 3 and 4): every checkpoint and the end keep
the raw margin ``(4,)`` with the run's threshold and resolution; `Results.closing_margin` reads it
back; the resolution is recorded with the run, so a loaded run continues with the same criterion;
files written before margins were kept load with none."""

from __future__ import annotations

import shutil
import warnings

import h5py
import numpy as np
import pytest
from helpers import HALF_PLANE, ROOT, TORUS, spec

import pinnedballs as pb
from pinnedballs.engine.margin import ClosingMargin, MarginWarning
from pinnedballs.results.format import Record
from pinnedballs.results.store import ResultsStore
from pinnedballs.rules import DEFAULT_RESOLUTION
from pinnedballs.run import execute as runner
from pinnedballs.specs import parse_spec

DATA = ROOT / "tests" / "data"


def _half_plane(resolution=None) -> pb.Simulation:
    g = pb.HalfPlane(6, 10)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.3, 10.0]
    return pb.Simulation(g, v, seed=5, resolution=resolution)


def _stored(run) -> tuple[np.ndarray, dict]:
    with h5py.File(run / "results.h5", "r") as f:
        return f["state/margin"][()], dict(f["state/margin"].attrs)


def test_every_checkpoint_and_the_end_keep_the_margin(tmp_path):
    """A run recorded in three calls: after each, the file holds the simulation's margin bit for bit, and
    `Results.closing_margin` is `sim.closing_margin()`; the margin moved on between them."""
    sim = _half_plane()
    writer = pb.ResultsWriter(tmp_path / "r", checkpoint_seconds=0)
    seen = []
    for _ in range(3):
        sim.run(steps=300, writers=[writer])
        res = pb.load(tmp_path / "r")
        margin, attrs = _stored(tmp_path / "r")
        assert margin.dtype == np.float64 and np.array_equal(margin, sim.get_state().margin)
        assert attrs == {"threshold": sim.threshold, "resolution": DEFAULT_RESOLUTION}
        assert res.closing_margin == sim.closing_margin() and np.array_equal(res.latest.margin, margin)
        seen.append(margin)
    assert not np.array_equal(seen[0], seen[-1])  # later picks changed it: each checkpoint wrote its own


def test_a_loaded_run_continues_with_its_criterion_and_margin(tmp_path):
    """A chosen resolution is recorded (the spec's field; a Python run's description) and the simulation a
    loaded run gives has it, the same threshold and the stored margin; run on, it ends as the unbroken run."""
    unbroken = _half_plane(resolution=1e-9)
    unbroken.run_until_frozen(max_steps=10**6)
    first = _half_plane(resolution=1e-9)
    first.run(steps=150, writers=[pb.ResultsWriter(tmp_path / "py")])
    res = pb.load(tmp_path / "py")
    assert res.run["resolution"] == 1e-9 and res.closing_margin.resolution == 1e-9
    sim = res.simulation()
    assert (sim.resolution, sim.threshold) == (1e-9, first.threshold)
    assert np.array_equal(sim.get_state().margin, first.get_state().margin)
    sim.run_until_frozen(max_steps=10**6)
    assert sim.get_state().identical(unbroken.get_state()) and sim.closing_margin() == unbroken.closing_margin()

    s = parse_spec(spec(HALF_PLANE, resolution=1e-9))
    runner.execute(s, tmp_path / "spec", figures=False, progress=False)
    res = pb.load(tmp_path / "spec")
    assert res.spec.resolution == 1e-9 and '"resolution": 1e-9' in (tmp_path / "spec" / "spec.json").read_text()
    assert res.closing_margin.resolution == 1e-9 and res.simulation().resolution == 1e-9


def test_the_default_resolution_is_recorded_as_the_default():
    """A Python run at the default criterion records None, so a loaded one warns as the original would."""
    from pinnedballs.run.writers import describe_run

    assert describe_run(_half_plane())["resolution"] is None
    assert describe_run(_half_plane(resolution=1e-6))["resolution"] == 1e-6


@pytest.mark.parametrize("name", ["results_v1.h5", "format2"])
def test_files_written_before_margins_load_with_none(tmp_path, name):
    """Formats 1 and 2 (and 3 before margins) hold no margin: unknown, None; continuing such a run keeps it
    unknown (its later picks alone could not speak for the run)."""
    run = tmp_path / "old"
    if name.endswith(".h5"):
        run.mkdir()
        shutil.copy(DATA / name, run / "results.h5")
    else:
        shutil.copytree(DATA / name, run)
    old = pb.load(run)
    assert old.format_version in (1, 2) and old.closing_margin is None and old.latest.margin is None
    sim = old.simulation()
    assert sim.closing_margin() == ClosingMargin.of(np.array([np.inf, 0, 0, 0]), sim.threshold, sim.resolution)
    sim.run(steps=100)
    assert sim.closing_margin().smallest_collision is not None  # the margin of the 100 steps alone
    store = ResultsStore.reopen(run)  # as a run continuing it does: format 3 from now on
    store.checkpoint([], Record.of(sim, ()))
    again = pb.load(run)
    assert again.format_version == 3 and again.closing_margin is None and again.steps == old.steps + 100
    with h5py.File(run / "results.h5", "r") as f:
        assert "margin" not in f["state"]


def test_an_exact_run_keeps_no_margin(tmp_path):
    g = pb.FlatTorus(4, 4)
    v = np.zeros((16, 2))
    v[0] = (1.0, 0.0)
    sim = pb.Simulation(g, v, seed=2, arithmetic="exact")
    sim.run(steps=50, writers=[pb.ResultsWriter(tmp_path / "e")])
    res = pb.load(tmp_path / "e")
    assert res.collisions > 0 and res.closing_margin is None and res.latest.margin is None


def test_a_thin_run_from_python_stays_a_warning(tmp_path):
    """`pb.run_spec` of a thin run until frozen: a `MarginWarning` in Python (the command line says it as a
    note); for its steps, or with a wide margin, no word."""
    from helpers import THIN, thin_spec

    with pytest.warns(MarginWarning, match=r"^" + THIN.replace("(", r"\(")):
        res = pb.run_spec(parse_spec(thin_spec(tmp_path)), tmp_path / "r", figures=False)
    assert res.closing_margin.thin and res.closing_margin.near_collisions == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        pb.run_spec(parse_spec(spec(TORUS, seed=2)), tmp_path / "wide", figures=False)  # a wide margin: no word
        for_steps = pb.run_spec(parse_spec(spec(thin_spec(tmp_path), stop={"steps": 10})), tmp_path / "t",
                                figures=False)
    assert for_steps.closing_margin == res.closing_margin
