"""Results files and the run loop: exact snapshots, stored physics, reading back, bad files.

The loop must end where the plain Python calls end (``run(steps=)``,
``run(collisions=)``, ``run_until_frozen(max_steps=)``), bit for bit, and take
each snapshot at exactly its step or collision count, however it is chunked.
"""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from helpers import HALF_PLANE, spec

import pinnedballs as pb
from pinnedballs.engine import driver
from pinnedballs.results.format import ResultsError
from pinnedballs.results.load import load
from pinnedballs.run import execute as runner
from pinnedballs.specs import parse_spec

REL = 1e-12


def run(tmp_path, data: dict, name: str = "run", **options):
    s = parse_spec(data)
    runner.execute(s, tmp_path / name, figures=False, progress=False, **options)
    return s, load(tmp_path / name)


def direct(data: dict) -> pb.Simulation:
    """The same run through the Python API alone, no snapshots."""
    s = parse_spec(data)
    sim = s.build()
    stop = s.stop
    if stop.kind == "steps":
        sim.run(steps=stop.steps)
    elif stop.kind == "collisions":
        sim.run(collisions=stop.collisions)
    else:
        sim.run_until_frozen(max_steps=stop.max_steps)
    return sim


def assert_same_state(res, sim: pb.Simulation) -> None:
    state = sim.get_state()
    assert np.array_equal(res.velocities, state.velocities)
    assert (res.steps, res.collisions) == (state.steps, state.collisions)
    assert np.array_equal(res.rng_state, state.rng_state)
    assert np.array_equal(res.scheduler_state, state.scheduler_state)


# ---------------------------------------------------------------- the loop against the Python API

TORUS_RUN = spec(geometry__rows=8, geometry__cols=8, stop={"steps": 60_000},
                 snapshots={"at_steps": [0, 1, 12_345, 60_000]})
STOPS = {
    "steps, at_steps": TORUS_RUN,
    "steps, every_collisions": spec(TORUS_RUN, snapshots={"every_collisions": 5_000}),
    "collisions, at_steps": spec(TORUS_RUN, stop={"collisions": 20_000}),
    "frozen, at_collisions": spec(HALF_PLANE, snapshots={"at_collisions": [0, 10, 200]}),
    "frozen, every_steps, random_sweep": spec(HALF_PLANE, snapshots={"every_steps": 500},
                                              scheduler={"kind": "random_sweep"}),
    "collisions unreachable": spec(HALF_PLANE, stop={"collisions": 10**6}, snapshots={"at_collisions": [5, 10**6]}),
    "frozen but max_steps first": spec(TORUS_RUN, stop={"frozen": True, "max_steps": 30_001}, snapshots=...),
    "restitution, masses, sweep": spec(TORUS_RUN, rule={"kind": "restitution", "r": 0.8}, masses=2.5,
                                       scheduler={"kind": "sweep"}),
}


@pytest.mark.parametrize("data", STOPS.values(), ids=STOPS.keys())
@pytest.mark.parametrize("chunk", [1 << 20, 37])
def test_final_state_is_the_python_api(tmp_path, monkeypatch, data, chunk):
    monkeypatch.setattr(driver, "CHUNK_STEPS", chunk)
    monkeypatch.setattr(driver, "CHUNK_PER_CONTACT", 0 if chunk < 100 else 2)
    s, res = run(tmp_path, data)
    assert res.complete
    assert_same_state(res, direct(data))
    assert res.frozen == direct(data).is_frozen()


@pytest.mark.parametrize("data", STOPS.values(), ids=STOPS.keys())
def test_snapshots_at_exact_counts(tmp_path, data):
    s, res = run(tmp_path, data)
    snaps = s.snapshots
    if snaps is None:
        assert res.snapshots == []
        return
    for n, snap in enumerate(res.snapshots):
        count = snap.steps if snaps.counter == "steps" else snap.collisions
        assert count == snaps.target(n)
        again = parse_spec(data).build()
        if snaps.counter == "steps":
            again.run(steps=snap.steps)
        else:
            again.run(collisions=snap.collisions)
        assert (again.steps, again.collisions) == (snap.steps, snap.collisions)
        assert np.array_equal(again.velocities, snap.velocities)
    # every target up to where the run ended was taken, none beyond
    reached = res.steps if snaps.counter == "steps" else res.collisions
    expected = [snaps.target(n) for n in range(len(res.snapshots) + 1)]
    assert expected[-1] is None or expected[-1] > reached


def test_stop_reasons(tmp_path):
    assert run(tmp_path, STOPS["steps, at_steps"], "a")[1].stop_reason == "steps"
    assert run(tmp_path, STOPS["collisions, at_steps"], "b")[1].stop_reason == "collisions"
    frozen = run(tmp_path, STOPS["frozen, at_collisions"], "c")[1]
    assert (frozen.stop_reason, frozen.frozen, frozen.approaching) == ("frozen", True, 0)
    unreachable = run(tmp_path, STOPS["collisions unreachable"], "d")[1]
    assert (unreachable.stop_reason, unreachable.frozen) == ("frozen", True)
    assert unreachable.collisions < 10**6 and [s.collisions for s in unreachable.snapshots] == [5]
    capped = run(tmp_path, STOPS["frozen but max_steps first"], "e")[1]
    assert (capped.stop_reason, capped.steps, capped.frozen) == ("max_steps", 30_001, False)


# ---------------------------------------------------------------- what the file holds


def test_file_layout_and_physics(tmp_path):
    s, res = run(tmp_path, TORUS_RUN)
    g = pb.FlatTorus(8, 8)
    assert np.array_equal(res.positions, g.positions)
    assert np.array_equal(res.pairs, g.contacts.pairs)
    assert np.array_equal(res.t_i, g.contacts.t_i) and np.array_equal(res.t_j, g.contacts.t_j)
    assert res.masses is None and res.spec == s and res.version == pb.__version__
    obs = res.observables
    assert obs["steps"].tolist() == [0, 1, 12_345, 60_000]
    assert obs["collisions"].tolist() == [snap.collisions for snap in res.snapshots]
    assert obs["collisions"][-1] == res.collisions > 20_000
    # energy and momentum conserved (elastic, flat torus), to rounding
    assert np.abs(obs["energy"] / 100.0 - 1).max() < REL
    assert np.abs(obs["momentum"] - obs["momentum"][0]).max() < REL * np.sqrt(200.0)
    assert res.initial_energy == pytest.approx(100.0, rel=1e-15)
    assert np.array_equal(res.initial_velocities, res.snapshots[0].velocities)
    for snap, energy, approaching in zip(res.snapshots, obs["energy"], obs["approaching"]):
        sim = pb.Simulation(g, snap.velocities)
        assert energy == sim.energy() and approaching == sim.approaching()
    with h5py.File(res.path) as f:
        assert f.attrs["format"] == "pinnedballs-results"
        assert f["snapshots/velocities"].shape == (4, 64, 2)
        assert f.attrs["format_version"] == 3 and f["snapshots/velocities"].is_virtual  # over the segments
        listed = [s[0] for s in json.loads(f.attrs["segments"])]
        assert f.userblock_size == 512 and sorted(json.loads(f.attrs["digests"])) == sorted([*listed, "static.h5"])
        assert f["state/rng_state"].dtype == np.uint64 and f["state/scheduler_state"].dtype == np.int64
        assert set(f) == {"geometry", "initial", "snapshots", "observables", "state", "provenance"}
    assert sorted(p.name for p in res.path.parent.iterdir()) == ["results.data", "results.h5", "spec.json"]
    assert parse_spec((res.path.parent / "spec.json").read_text()) == s


def test_restitution_never_gains_energy(tmp_path, monkeypatch):
    masses = np.linspace(0.5, 2.0, 64)
    np.save(tmp_path / "m.npy", masses)
    data = spec(TORUS_RUN, rule={"kind": "restitution", "r": 0.9}, masses=str(tmp_path / "m.npy"),
                initial={"kind": "gaussian", "energy": 10.0}, snapshots={"every_steps": 2000})
    _, res = run(tmp_path, data)
    energy = res.observables["energy"]
    assert len(energy) == 30 and np.all(np.diff(energy) <= 1e-12 * energy[0]) and energy[-1] < 0.5 * energy[0]
    assert np.array_equal(res.masses, masses)
    assert np.abs(res.observables["momentum"] - res.observables["momentum"][0]).max() < 1e-12 * 10


def test_results_continue_the_run(tmp_path):
    _, res = run(tmp_path, TORUS_RUN)
    sim = res.simulation()
    sim.run(steps=5_000)
    longer = direct(spec(TORUS_RUN, stop={"steps": 65_000}, snapshots=...))
    assert np.array_equal(sim.velocities, longer.velocities)
    assert np.array_equal(sim.get_state().rng_state, longer.get_state().rng_state)


def test_geometry_of_graph_positions_needs_no_file(tmp_path):
    np.save(tmp_path / "p.npy", pb.HalfPlane(4, 5).positions)
    data = spec(HALF_PLANE, geometry={"kind": "graph_positions", "positions": str(tmp_path / "p.npy")},
                initial={"kind": "single_ball", "ball": 2, "direction": [0, 1], "energy": 1})
    _, res = run(tmp_path, data)
    (tmp_path / "p.npy").unlink()
    again = load(res.path)
    assert isinstance(again.geometry, pb.GraphGeometry) and again.geometry.n_contacts == pb.HalfPlane(4, 5).n_contacts
    assert again.frozen and np.array_equal(again.simulation().velocities, res.velocities)


def test_half_plane_geometry_rebuilt(tmp_path):
    _, res = run(tmp_path, HALF_PLANE)
    assert isinstance(res.geometry, pb.HalfPlane)
    assert np.array_equal(res.geometry.boundary_distance(), res.positions[:, 1])


def test_same_spec_same_bits(tmp_path):
    _, a = run(tmp_path, STOPS["frozen, every_steps, random_sweep"], "a")
    _, b = run(tmp_path, STOPS["frozen, every_steps, random_sweep"], "b")
    assert_same_state(a, b.simulation())
    assert all(np.array_equal(x.velocities, y.velocities) and x[:2] == y[:2] for x, y in zip(a.snapshots, b.snapshots))


# ---------------------------------------------------------------- files that are not results


def test_load_missing(tmp_path):
    with pytest.raises(FileNotFoundError, match="no results.h5 in this directory"):
        load(tmp_path)
    with pytest.raises(FileNotFoundError, match=r"nope\.h5: no such file"):
        load(tmp_path / "nope.h5")


def test_load_foreign_hdf5(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(ResultsError, match=r"other\.h5: not a pinnedballs results file"):
        load(tmp_path / "other.h5")


@pytest.mark.parametrize("keep", [0, 100, 0.5])
def test_load_truncated_or_not_hdf5(tmp_path, keep):
    _, res = run(tmp_path, TORUS_RUN)
    data = res.path.read_bytes()
    bad = tmp_path / "bad.h5"
    bad.write_bytes(data[: int(keep * len(data)) if isinstance(keep, float) else keep] if keep else b"hello, world\n")
    with pytest.raises(ResultsError, match=r"bad\.h5: (not a readable HDF5 file|damaged results file)"):
        load(bad)


def test_load_damaged(tmp_path):
    _, res = run(tmp_path, TORUS_RUN)
    with h5py.File(res.path, "r+") as f:
        del f["state"]
    with pytest.raises(ResultsError, match=r"results\.h5: damaged results file"):
        load(res.path)


def test_a_snapshot_counts_steps_like_the_results_and_step_still_works():
    """``Snapshot.steps`` is the name ``Results.steps`` and the spec use; ``step`` is a deprecated alias."""
    from pinnedballs.results.format import Snapshot

    snap = Snapshot(250, 40, np.zeros((3, 2)))
    assert (snap.steps, snap.collisions) == (250, 40) and snap._fields == ("steps", "collisions", "velocities")
    with pytest.warns(DeprecationWarning, match="Snapshot.steps"):
        assert snap.step == 250
