"""A run as tidy data (issue 24, item 6): `Results.to_pandas` (a row per snapshot, the final state
last, scalar columns) and `Results.to_xarray` (labelled arrays, the velocities read lazily)."""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, call, spec, write

import pinnedballs as pb
from pinnedballs import ResultsError


def run(tmp_path, data: dict, name: str = "run"):
    assert call("run", write(tmp_path / f"{name}.json", data), "--out", tmp_path / name, "--quiet",
                "--no-figures")[0] == 0
    return pb.load(tmp_path / name)


@pytest.fixture(scope="module")
def frozen(tmp_path_factory):
    """A half-plane that froze between two snapshots: the final state is not a snapshot."""
    res = run(tmp_path_factory.mktemp("tables"), spec(HALF_PLANE, snapshots={"every_collisions": 20},
                                                      checkpoint={"every_seconds": 0}))
    assert res.frozen and res.snapshots.steps[-1] < res.steps
    return res


def test_to_pandas_has_a_row_per_snapshot_then_the_final_state(frozen):
    res = frozen
    df = res.to_pandas()
    assert list(df.columns) == ["steps", "collisions", "final", "energy", "momentum_x", "momentum_y", "approaching",
                                "frozen"]
    assert df.index.name == "snapshot" and len(df) == len(res.snapshots) + 1
    assert df["final"].tolist() == [False] * len(res.snapshots) + [True]
    last = df.iloc[-1]
    assert (last.steps, last.collisions, last.approaching, bool(last.frozen)) == (res.steps, res.collisions, 0, True)
    assert (last.energy, last.momentum_x, last.momentum_y) == (res.energy, *res.momentum)
    snaps = df.iloc[:-1]
    assert snaps["steps"].tolist() == res.snapshots.steps.tolist()
    assert snaps["collisions"].tolist() == list(range(20, 20 * len(res.snapshots) + 1, 20))
    assert np.array_equal(snaps[["momentum_x", "momentum_y"]].to_numpy(), res.observables["momentum"])
    assert np.array_equal(snaps["energy"].to_numpy(), res.observables["energy"])
    assert not snaps["frozen"].any() and (snaps["approaching"] > 0).all()
    assert all(df[c].dtype.kind in "iufb" for c in df.columns)      # scalar columns only


def test_a_run_ending_on_a_snapshot_has_it_as_its_final_row(tmp_path):
    res = run(tmp_path, TORUS)                                       # snapshots at 0, 250, 1000 = the stop
    df = res.to_pandas()
    assert df["steps"].tolist() == [0, 250, 1000] and df["final"].tolist() == [False, False, True]
    assert df["energy"].iloc[-1] == res.energy and not df["frozen"].any()


def test_a_users_observable_is_a_column_and_nan_on_an_unrecorded_final_state(tmp_path):
    name = "tables_test_top_speed"
    if name not in pb.analysis.observables.OBSERVABLES:
        pb.register_observable(name, lambda sim: float(np.abs(sim.velocities).max()))
    sim = pb.Simulation(pb.FlatTorus(4, 4), np.eye(16, 2), seed=1)
    sim.run(steps=250, writers=[pb.ResultsWriter(tmp_path / "r", snapshots={"every_steps": 100},
                                                 observables=["energy", name])])
    df = pb.load(tmp_path / "r").to_pandas()
    assert list(df.columns) == ["steps", "collisions", "final", "energy", name]
    assert df["steps"].tolist() == [100, 200, 250]
    assert np.isnan(df[name].iloc[-1]) and (df[name].iloc[:-1] > 0).all()


def test_to_xarray_labels_every_array_and_reads_velocities_lazily(frozen, tmp_path):
    res = frozen
    ds = res.to_xarray()
    count, n = len(res.snapshots) + 1, res.positions.shape[0]
    assert dict(ds.sizes) == {"snapshot": count, "ball": n, "component": 2, "coordinate": 2}
    assert ds["velocities"].dims == ("snapshot", "ball", "component")
    assert ds["momentum"].dims == ("snapshot", "component")
    assert ds["energy"].dims == ("snapshot",) and ds["boundary_distance"].dims == ("ball",)
    assert ds["component"].values.tolist() == ["x", "y"]
    assert ds["steps"].values.tolist() == [*res.snapshots.steps.tolist(), res.steps]
    assert ds["final"].values.tolist() == [False] * (count - 1) + [True]
    assert ds["velocities"].chunks[0] == (1,) * count                   # dask: one chunk per snapshot
    eager = np.stack([*(s.velocities for s in res.snapshots), res.velocities])
    assert ds["velocities"].values.tobytes() == eager.tobytes()
    assert np.array_equal(ds["positions"].values, res.positions)
    assert ds["velocities"].isel(snapshot=-1).values.tobytes() == res.velocities.tobytes()
    assert ds.attrs["status"] == "done" and ds.attrs["frozen"] == 1 and ds.attrs["seed"] == HALF_PLANE["seed"]


def test_to_xarray_reads_nothing_until_computed(frozen, tmp_path):
    """The Dataset opens without reading a frame: a segment removed after it was made is found only when
    its snapshot is computed, and refused by name."""
    shutil.copytree(frozen.run_dir, tmp_path / "run")
    res = pb.load(tmp_path / "run")
    ds = res.to_xarray()
    gone = res.snapshots.files[-1]
    gone.path.unlink()
    assert ds["velocities"].isel(snapshot=0).values.tobytes() == res.snapshots[0].velocities.tobytes()
    with pytest.raises(ResultsError, match=f"snapshot {gone.first} \\({gone.path.name}\\): the file is gone"):
        ds["velocities"].isel(snapshot=gone.first).values
