"""Python runs recorded by writers: the same results directory as ``pinnedballs run``, the same bits
as a plain ``sim.run``, triggers that land on exact counts, and resuming in Python."""

from __future__ import annotations

import pickle
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, spec, write

import pinnedballs as pb
from pinnedballs.analysis import observables as observe
from pinnedballs.engine import driver
from pinnedballs.results.load import load
from pinnedballs.results.store import ResultsStore
from pinnedballs.run import execute as runner
from pinnedballs.run.cli import main as cli
from pinnedballs.specs import parse_spec

DATA = Path(__file__).resolve().parents[1] / "data"

TORUS_RUN = spec(geometry__rows=8, geometry__cols=8, initial={"kind": "gaussian", "energy": 50.0},
                 stop={"steps": 30_000}, snapshots={"every_steps": 4_000}, seed=5)


def same_state(a: pb.Simulation, b: pb.Simulation) -> bool:
    return a.get_state().identical(b.get_state())


@pytest.fixture(params=[1 << 20, 97], ids=["default chunks", "small chunks"])
def chunk(request, monkeypatch):
    monkeypatch.setattr(driver, "CHUNK_STEPS", request.param)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0 if request.param < 100 else 2)
    return request.param


# ---------------------------------------------------------------- the same final state as a plain run

CALLS = {
    "steps": dict(steps=25_000),
    "collisions": dict(collisions=9_000),
    "steps and collisions": dict(steps=25_000, collisions=9_000),
    "steps until frozen": dict(steps=25_000, until_frozen=True),
}


@pytest.mark.parametrize("call", CALLS.values(), ids=CALLS.keys())
@pytest.mark.parametrize("geometry", [pb.FlatTorus(8, 8), pb.HalfPlane(6, 10)], ids=["torus", "half-plane"])
def test_run_with_writers_ends_where_a_plain_run_ends(tmp_path, chunk, call, geometry):
    v = np.random.default_rng(2).standard_normal((geometry.n_balls, 2))
    plain, recorded = (pb.Simulation(geometry, v, scheduler=pb.RandomSweep(), seed=9) for _ in range(2))
    taken = plain.run(**call)
    w = pb.ResultsWriter(tmp_path / "out", snapshots=pb.EverySteps(1_000) | pb.AtCollisions([3, 500]),
                         checkpoint_seconds=0)
    assert recorded.run(**call, writers=[w]) == taken
    assert same_state(plain, recorded)
    res = load(tmp_path / "out")
    assert res.complete and res.spec is None and res.steps == plain.steps
    assert np.array_equal(res.velocities, plain.velocities)
    # every snapshot is the state a plain run reaches at that count
    for snap in res.snapshots:
        again = pb.Simulation(geometry, v, scheduler=pb.RandomSweep(), seed=9)
        if snap.steps % 1_000 == 0 and snap.steps > 0:
            again.run(steps=snap.steps)
        else:
            again.run(collisions=snap.collisions)
        assert (again.steps, again.collisions) == snap[:2] and np.array_equal(again.velocities, snap.velocities)


def test_frozen_with_writers(tmp_path, chunk):
    g = pb.HalfPlane(6, 10)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = (0, 3)
    plain, recorded = pb.Simulation(g, v, seed=3), pb.Simulation(g, v, seed=3)
    assert plain.run_until_frozen(10**7)
    assert recorded.run_until_frozen(10**7, writers=[pb.ResultsWriter(tmp_path / "out")])
    assert same_state(plain, recorded)
    res = load(tmp_path / "out")
    assert (res.stop_reason, res.frozen, res.approaching) == ("frozen", True, 0)


# ---------------------------------------------------------------- the directory pinnedballs run writes


def test_python_run_records_what_the_command_line_records(tmp_path, capsys):
    s = parse_spec(TORUS_RUN)
    runner.execute(s, tmp_path / "cli", figures=False, progress=False)
    sim = s.build()
    w = pb.ResultsWriter(tmp_path / "py", snapshots={"every_steps": 4_000}, checkpoint_seconds=0)
    sim.run(steps=30_000, writers=[w])
    a, b = load(tmp_path / "cli"), load(tmp_path / "py")
    assert [x[:2] for x in a.snapshots] == [x[:2] for x in b.snapshots] and len(a.snapshots) == 7
    assert all(np.array_equal(x.velocities, y.velocities) for x, y in zip(a.snapshots, b.snapshots))
    assert a.observables.keys() == b.observables.keys()
    assert all(np.array_equal(a.observables[k], b.observables[k]) for k in a.observables)
    assert np.array_equal(a.velocities, b.velocities) and np.array_equal(a.rng_state, b.rng_state)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.t_i, b.t_i)
    # a Python run keeps a description of what it was built from
    assert b.spec is None and b.run["geometry"] == {"kind": "flat_torus", "rows": 8, "cols": 8, "radius": 1.0}
    assert b.run["rule"] == {"kind": "elastic"} and b.run["scheduler"] == {"kind": "uniform_random_pair"}
    assert isinstance(b.geometry, pb.FlatTorus)
    # info and plot read it
    assert cli.main(["info", str(tmp_path / "py")]) == 0
    info = capsys.readouterr().out
    assert "geometry:    flat_torus: 64 balls, 192 contacts, dim 2\n" in info
    assert "run:         given velocities, elastic, uniform_random_pair, built in Python\n" in info
    assert "snapshots:   7 at steps 4,000, 8,000, 12,000, 16,000, 20,000, ... (7 in all)\n" in info
    assert cli.main(["plot", str(tmp_path / "py")]) == 0
    assert (tmp_path / "py" / "state_final.png").exists()


def test_resume_in_python_is_bit_identical(tmp_path):
    g = pb.GraphGeometry(pb.FlatTorus(6, 6).contact_graph())  # a geometry without a spec
    v = np.random.default_rng(1).standard_normal((g.n_balls, 2))
    whole = pb.Simulation(g, v, scheduler=pb.RandomSweep(), seed=4)
    whole.run(steps=20_000, writers=[pb.ResultsWriter(tmp_path / "whole", snapshots={"every_steps": 3_000})])

    first = pb.Simulation(g, v, scheduler=pb.RandomSweep(), seed=4)
    first.run(steps=7_777, writers=[pb.ResultsWriter(tmp_path / "split", snapshots={"every_steps": 3_000})])
    res = load(tmp_path / "split")
    assert res.run["geometry"]["class"] == "pinnedballs.geometry.graph.GraphGeometry"
    again = res.simulation()  # the stored contacts, the described scheduler
    assert same_state(again, first)
    w = pb.ResultsWriter(tmp_path / "split", snapshots={"every_steps": 3_000}, resume=True)
    again.run(steps=20_000 - 7_777, writers=[w])
    a, b = load(tmp_path / "whole"), load(tmp_path / "split")
    assert same_state(again, whole)
    assert [x[:2] for x in a.snapshots] == [x[:2] for x in b.snapshots] == [(k * 3_000, x.collisions)
                                                                            for k, x in enumerate(a.snapshots, 1)]
    assert all(np.array_equal(x.velocities, y.velocities) for x, y in zip(a.snapshots, b.snapshots))


def test_one_writer_over_several_runs(tmp_path):
    g = pb.FlatTorus(6, 6)
    v = np.random.default_rng(3).standard_normal((g.n_balls, 2))
    once, twice = pb.Simulation(g, v, seed=1), pb.Simulation(g, v, seed=1)
    once.run(steps=10_000, writers=[pb.ResultsWriter(tmp_path / "a", snapshots=pb.AtCollisions([0, 100, 2_000]))])
    w = pb.ResultsWriter(tmp_path / "b", snapshots=pb.AtCollisions([0, 100, 2_000]))
    for _ in range(4):
        twice.run(steps=2_500, writers=[w])
    a, b = load(tmp_path / "a"), load(tmp_path / "b")
    assert [x[:2] for x in a.snapshots] == [x[:2] for x in b.snapshots]
    assert [x.collisions for x in b.snapshots] == [0, 100, 2_000]
    assert same_state(once, twice) and b.steps == 10_000


def test_resume_refuses_a_simulation_elsewhere(tmp_path):
    g = pb.FlatTorus(4, 4)
    sim = pb.Simulation(g, np.ones((16, 2)), seed=1)
    sim.run(steps=100, writers=[pb.ResultsWriter(tmp_path / "r")])
    other = pb.Simulation(g, np.ones((16, 2)), seed=1)
    with pytest.raises(ValueError, match=r"^resume: the simulation is at step 0, not at the state stored in"):
        other.run(steps=1, writers=[pb.ResultsWriter(tmp_path / "r", resume=True)])


def test_writer_refuses_a_full_directory_and_bad_arguments(tmp_path):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    sim = pb.Simulation(pb.FlatTorus(4, 4), np.ones((16, 2)))
    with pytest.raises(ValueError, match=r"^out_dir .*full: directory is not empty \(x\); pass force=True to "
                                         r"overwrite or resume=True to continue$"):
        sim.run(steps=1, writers=[pb.ResultsWriter(tmp_path / "full")])
    with pytest.raises(ValueError, match=r"^checkpoint_seconds: must be a number >= 0, got -1"):
        pb.ResultsWriter(tmp_path / "a", checkpoint_seconds=-1)
    with pytest.raises(ValueError, match=r"^snapshots.every_steps: input should be greater than or equal to 1"):
        pb.ResultsWriter(tmp_path / "a", snapshots={"every_steps": 0})
    with pytest.raises(ValueError, match=r"^observables: unknown observable 'entropy'"):
        pb.ResultsWriter(tmp_path / "a", observables=["entropy"])
    with pytest.raises(TypeError, match=r"^writers: must be Writer objects"):
        sim.run(steps=1, writers=["DIR"])
    assert sim.steps == 0


# ---------------------------------------------------------------- triggers


def test_triggers_name_exact_counts():
    every, at = pb.EverySteps(100), pb.AtCollisions([0, 7])
    both = every | at
    assert [every.next_steps(s) for s in (0, 99, 100, 250)] == [100, 100, 200, 300]
    assert every.next_collisions(5) is None and at.next_steps(5) is None
    assert [at.next_collisions(c) for c in (0, 6, 7)] == [7, 7, None]
    assert (both.next_steps(100), both.next_collisions(0)) == (200, 7)
    assert both.fires(None, (0, 0)) and not every.fires(None, (0, 0))
    # a collision count fires once, when it is reached, not while later steps leave it unchanged
    assert at.fires((40, 6), (41, 7)) and not at.fires((41, 7), (90, 7))
    assert every.fires((99, 7), (100, 7)) and both.fires((99, 7), (100, 7))
    assert repr(both) == "EverySteps(100) | AtCollisions([0, 7])"
    assert pickle.loads(pickle.dumps(both)) == both and pickle.loads(pickle.dumps(at)) != every
    with pytest.raises(ValueError, match=r"^period: must be an integer >= 1, got 0"):
        pb.EverySteps(0)
    with pytest.raises(ValueError, match=r"^counts: must be an integer >= 0, got -1"):
        pb.AtSteps([5, -1])


# ---------------------------------------------------------------- observables by name


def test_user_observable_is_stored_per_snapshot(tmp_path, monkeypatch):
    monkeypatch.setitem(observe.OBSERVABLES, "energy_per_ball", lambda sim: 0.5 * (sim.velocities ** 2).sum(axis=1))
    g = pb.FlatTorus(4, 4)
    sim = pb.Simulation(g, np.random.default_rng(0).standard_normal((16, 2)), seed=2)
    w = pb.ResultsWriter(tmp_path / "o", snapshots={"every_steps": 500}, observables=["energy_per_ball", "energy"])
    sim.run(steps=2_000, writers=[w])
    res = load(tmp_path / "o")
    assert list(res.observables) == ["steps", "collisions", "energy_per_ball", "energy"]
    per_ball = res.observables["energy_per_ball"]
    assert per_ball.shape == (4, 16)
    for row, snap, energy in zip(per_ball, res.snapshots, res.observables["energy"]):
        assert np.array_equal(row, 0.5 * (snap.velocities ** 2).sum(axis=1))
        assert row.sum() == pytest.approx(energy, rel=1e-13)  # energy conserved, split over balls


def test_observables_in_a_spec(tmp_path):
    data = spec(TORUS, observables=["approaching"])
    runner.execute(parse_spec(data), tmp_path / "r", figures=False, progress=False)
    res = load(tmp_path / "r")
    assert list(res.observables) == ["steps", "collisions", "approaching"]
    for snap, approaching in zip(res.snapshots, res.observables["approaching"]):
        assert approaching == pb.Simulation(pb.FlatTorus(4, 4), snap.velocities).approaching()
    with pytest.raises(ValueError, match=r"^observables\[1\]: unknown observable 'nope' \(known: steps, "):
        parse_spec(spec(TORUS, observables=["energy", "nope"]))


def test_register_observable():
    with pytest.raises(ValueError, match=r"^name: 'energy' is already registered"):
        observe.register_observable("energy", lambda sim: 0)
    with pytest.raises(ValueError, match=r"^name: must be an identifier"):
        observe.register_observable("two words", lambda sim: 0)


# ---------------------------------------------------------------- format 1 still loads


def test_format_1_file_loads_and_continues(tmp_path):
    """tests/data/results_v1.h5: runspecs.TORUS written by the format-1 code."""
    old = load(DATA / "results_v1.h5")
    assert old.format_version == 1 and old.complete and old.spec == parse_spec(spec(TORUS, checkpoint={
        "every_seconds": 0}))
    fresh = old.spec.build()
    fresh.run(steps=1_000)
    assert np.array_equal(old.velocities, fresh.velocities) and old.steps == 1_000
    assert [s.steps for s in old.snapshots] == [0, 250, 1_000]
    assert list(old.observables) == ["steps", "collisions", "energy", "momentum", "approaching"]
    # continuing it converts it to format 3, snapshots and state unchanged
    run_dir = tmp_path / "old"
    run_dir.mkdir()
    shutil.copy(DATA / "results_v1.h5", run_dir / "results.h5")
    ResultsStore.reopen(run_dir)
    new = load(run_dir)
    assert new.format_version == 3 and new.complete
    assert [s[:2] for s in new.snapshots] == [s[:2] for s in old.snapshots]
    assert all(np.array_equal(a.velocities, b.velocities) for a, b in zip(new.snapshots, old.snapshots))
    assert np.array_equal(new.velocities, old.velocities) and np.array_equal(new.rng_state, old.rng_state)
    assert all(np.array_equal(new.observables[k], old.observables[k]) for k in old.observables)


def test_missing_segment_is_damage(tmp_path):
    runner.execute(parse_spec(TORUS_RUN), tmp_path / "r", figures=False, progress=False)
    with h5py.File(tmp_path / "r" / "results.h5") as f:
        assert f.attrs["checkpoints"] > 1
    segment = sorted((tmp_path / "r" / "results.data").glob("frames_*.h5"))[0]
    segment.unlink()
    with pytest.raises(ValueError, match=rf"results\.h5: damaged results file \({segment} is missing\)"):
        load(tmp_path / "r")


def test_half_plane_python_run_draws_the_energy_profile(tmp_path):
    s = parse_spec(HALF_PLANE)
    sim = s.build()
    sim.run_until_frozen(10**7, writers=[pb.ResultsWriter(tmp_path / "h")])
    assert isinstance(load(tmp_path / "h").geometry, pb.HalfPlane)
    assert cli.main(["plot", str(tmp_path / "h")]) == 0
    assert (tmp_path / "h" / "energy_by_distance.png").exists()


def test_resume_of_a_format_1_run_converts_it_and_is_bit_identical(tmp_path):
    """tests/data/results_v1_running.h5: the same run killed by the format-1 code at step 250."""
    data = spec(TORUS, checkpoint={"every_seconds": 0})
    out = tmp_path / "old"
    out.mkdir()
    shutil.copy(DATA / "results_v1_running.h5", out / "results.h5")
    old = load(out)
    assert (old.format_version, old.status, old.steps, len(old.snapshots)) == (1, "running", 250, 2)
    spec_path = write(tmp_path / "s.json", data)
    assert cli.main(["run", str(spec_path), "--out", str(out), "--resume", "--quiet", "--no-figures"]) == 0
    runner.execute(parse_spec(data), tmp_path / "ref", figures=False, progress=False)
    a, b = load(out), load(tmp_path / "ref")
    assert a.format_version == 3 and a.complete
    assert [s[:2] for s in a.snapshots] == [s[:2] for s in b.snapshots] and len(a.snapshots) == 3
    assert all(np.array_equal(x.velocities, y.velocities) for x, y in zip(a.snapshots, b.snapshots))
    assert np.array_equal(a.velocities, b.velocities) and np.array_equal(a.rng_state, b.rng_state)
    # the snapshots the format-1 code wrote keep its observables; those after the resume are today's, bit for
    # bit; the old ones agree with today's to the last few bits (its energy and momentum summed by the BLAS, whose
    # bits depend on the machine's threads: `util.sums`)
    kept = len(old.snapshots)
    for k in b.observables:
        assert np.array_equal(a.observables[k][:kept], old.observables[k]), k
        assert np.array_equal(a.observables[k][kept:], b.observables[k][kept:]), k
        np.testing.assert_allclose(a.observables[k][:kept], b.observables[k][:kept], rtol=1e-13, atol=1e-13)
