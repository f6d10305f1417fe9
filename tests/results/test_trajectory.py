"""GSD trajectories exported from a results directory: read back with ``gsd.hoomd``, every field equal
to what the results file holds (in the schema's single precision), and bad input refused with
nothing written."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, assert_input_error, call, frames_of, spec

import pinnedballs as pb
from pinnedballs.analysis.observables import boundary_rows
from pinnedballs.results import trajectory
from pinnedballs.results.load import load
from pinnedballs.run.execute import execute
from pinnedballs.specs import parse_spec

f32 = np.float32


def assert_frames_are_the_snapshots(frames: list, res, position: np.ndarray, velocities: list[np.ndarray]) -> None:
    """Each frame: the step, positions, velocities (given in the figures' coordinates), N, types and
    every recorded observable of the snapshot it stands for; then the state the run stopped in, unless
    the last snapshot is that state (``velocities`` then holds it last)."""
    assert len(frames) == len(velocities) and [int(f.configuration.step) for f in frames][-1] == res.steps
    final = len(frames) > len(res.snapshots)
    if final:  # the final state's frame: its counters and the observables the results file holds for it
        log = frames[-1].log
        assert (int(log["steps"][0]), int(log["collisions"][0]), int(log["approaching"][0])) == \
            (res.steps, res.collisions, res.approaching)
        assert np.array_equal(log["energy"], [res.energy]) and np.array_equal(log["momentum"], res.momentum)
        k = position.shape[1]
        assert np.array_equal(frames[-1].particles.velocity[:, :k], velocities[-1].astype(f32))
    origin = frames[0].log[trajectory.ORIGIN_LOG]
    for i, (frame, snap) in enumerate(zip(frames, res.snapshots)):
        p = frame.particles
        assert frame.configuration.step == snap.steps
        assert p.N == len(res.positions) and p.types == ["bulk", "boundary"]
        k = position.shape[1]
        assert np.array_equal(p.position[:, :k], (position - origin[:k]).astype(f32))
        assert np.array_equal(p.velocity[:, :k], velocities[i].astype(f32))
        assert not p.position[:, k:].any() and not p.velocity[:, k:].any()
        assert set(frame.log) == {*res.observables, trajectory.ORIGIN_LOG}
        for name, column in res.observables.items():
            assert np.array_equal(frame.log[name], np.atleast_1d(column[i])), name


def run(tmp_path, data: dict, name: str = "run"):
    execute(parse_spec(data), tmp_path / name, figures=False, progress=False)
    return load(tmp_path / name)


# ---------------------------------------------------------------- every field, geometry by geometry


def test_a_torus_exports_one_frame_per_snapshot_in_its_periodic_box(tmp_path):
    res = run(tmp_path, spec(TORUS, snapshots={"every_steps": 100}))
    assert call("export", tmp_path / "run", tmp_path / "t.gsd")[0] == 0
    frames = frames_of(tmp_path / "t.gsd")
    assert len(frames) == 10                                            # the last snapshot is the final state
    assert_frames_are_the_snapshots(frames, res, res.positions, [s.velocities for s in res.snapshots])
    first = frames[0]
    torus = pb.FlatTorus(4, 4)
    assert first.configuration.dimensions == 2
    assert np.array_equal(first.configuration.box, np.array([*torus.period, 0, 0, 0, 0], dtype=f32))
    assert np.array_equal(first.particles.diameter, np.full(16, 2.0, f32))
    assert not first.particles.typeid.any()                             # no boundary: every ball is bulk
    half_box = first.configuration.box[:2] / 2
    assert (np.abs(first.particles.position[:, :2]) <= half_box).all()  # inside GSD's box, centred on 0


def test_a_half_plane_marks_its_boundary_row_and_boxes_its_balls(tmp_path):
    res = run(tmp_path, spec(HALF_PLANE, snapshots={"every_collisions": 20}))
    path = trajectory.export(res, tmp_path / "h.gsd")
    frames = frames_of(path)
    assert res.frozen and len(frames) == len(res.snapshots) + 1        # frozen between two snapshots: then its state
    assert_frames_are_the_snapshots(frames, res, res.positions,
                                    [*(s.velocities for s in res.snapshots), res.velocities])
    half = pb.HalfPlane(6, 10)
    p = frames[0].particles
    assert np.array_equal(p.typeid, (half.boundary_distance() == 0).astype(np.uint32))
    assert p.typeid.sum() == 10                                         # row 0: the boundary
    extent = res.positions.max(axis=0) - res.positions.min(axis=0)
    assert np.array_equal(frames[0].configuration.box, np.array([*(extent + 2.0), 0, 0, 0, 0], dtype=f32))


def test_an_fcc_half_space_is_periodic_across_and_boxed_above(tmp_path):
    g = pb.FCC(2, 2, 2, periodic=(True, True, False))
    v = np.zeros((g.n_balls, 3))
    v[g.boundary_center()] = [0.0, 0.0, 5.0]
    sim = pb.Simulation(g, v, masses=np.linspace(1.0, 2.0, g.n_balls), seed=2)
    sim.run(steps=600, writers=[pb.ResultsWriter(tmp_path / "fcc", snapshots={"every_steps": 200})])
    res = load(tmp_path / "fcc")
    frames = frames_of(trajectory.export(res, tmp_path / "fcc.gsd"))
    assert_frames_are_the_snapshots(frames, res, res.positions, [s.velocities for s in res.snapshots])
    first = frames[0]
    assert first.configuration.dimensions == 3
    height = np.ptp(g.positions[:, 2]) + 2.0
    assert np.array_equal(first.configuration.box, np.array([*g.period[:2], height, 0, 0, 0], dtype=f32))
    assert np.array_equal(first.particles.typeid, (g.positions[:, 2] == 0).astype(np.uint32))
    assert np.array_equal(first.particles.mass, res.masses.astype(f32))


@pytest.mark.parametrize("geometry", [pb.Sphere.geodesic(2), pb.HyperbolicPlane(q=7, layers=2)],
                         ids=["sphere", "hyperbolic"])
def test_a_curved_surface_exports_its_embedding(tmp_path, geometry):
    """Positions and velocities in the embedding (velocities carried from each ball's frame);
    diameters are each ball's mean chord to the balls it touches."""
    v = np.random.default_rng(1).standard_normal((geometry.n_balls, 2))
    sim = pb.Simulation(geometry, v, seed=4)
    sim.run(steps=300, writers=[pb.ResultsWriter(tmp_path / "c", snapshots={"every_steps": 100})])
    res = load(tmp_path / "c")
    frames = frames_of(trajectory.export(res, tmp_path / "c.gsd"))
    frames_of_balls = geometry.frames()
    embedded = [np.einsum("nd,ndk->nk", s.velocities, frames_of_balls) for s in res.snapshots]
    assert res.snapshots.steps[-1] == res.steps
    assert_frames_are_the_snapshots(frames, res, geometry.positions, embedded)
    assert frames[0].configuration.dimensions == 3
    pairs = geometry.contacts.pairs.astype(int)
    chord = np.linalg.norm(geometry.positions[pairs[:, 0]] - geometry.positions[pairs[:, 1]], axis=1)
    ball = int(pairs[0, 0])
    mine = chord[(pairs == ball).any(axis=1)].mean()
    assert frames[0].particles.diameter[ball] == pytest.approx(mine, rel=1e-6)
    boundary = geometry.boundary
    expected = 0 if boundary is None else int((boundary_rows(boundary.distance)[0] == 0).sum())
    assert frames[0].particles.typeid.sum() == expected


# ---------------------------------------------------------------- bad input: one message, nothing written


def test_export_refuses_bad_input_and_writes_nothing(tmp_path):
    run(tmp_path, spec(TORUS, snapshots={"every_steps": 500}))
    out = tmp_path / "t.gsd"
    out.write_bytes(b"older")
    code, _, err = call("export", tmp_path / "run", out)
    assert_input_error(code, err, str(out), "exists", "--force")
    assert out.read_bytes() == b"older"
    assert call("export", tmp_path / "run", out, "--force")[0] == 0
    assert len(frames_of(out)) == 2

    for target, words in ((tmp_path / "no" / "t.gsd", ["no", "is not a directory"]),
                          (out / "t.gsd", ["t.gsd", "is not a directory"]),
                          (tmp_path / "t.xyz", ["t.xyz", "must end in .gsd"]),
                          (tmp_path, [str(tmp_path), "must end in .gsd"])):
        assert_input_error(*call("export", tmp_path / "run", target)[::2], *words)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert_input_error(*call("export", empty, tmp_path / "e.gsd")[::2], str(empty), "results.h5")
    run(tmp_path, spec(TORUS, snapshots=...), name="bare")
    assert_input_error(*call("export", tmp_path / "bare", tmp_path / "e.gsd")[::2], "bare", "no snapshots")
    assert sorted(p.name for p in tmp_path.iterdir() if p.suffix in (".gsd", ".tmp")) == ["t.gsd"]


def test_a_failed_export_leaves_no_file(tmp_path, monkeypatch):
    res = run(tmp_path, spec(TORUS, snapshots={"every_steps": 100}))
    frame = trajectory.Layout.frame

    def fail_at_the_fifth(self, steps, *args, **kw):
        if steps == 500:
            raise OSError(28, "No space left on device")
        return frame(self, steps, *args, **kw)

    monkeypatch.setattr(trajectory.Layout, "frame", fail_at_the_fifth)
    with pytest.raises(OSError, match="No space"):
        trajectory.export(res, tmp_path / "t.gsd")
    assert not list(tmp_path.glob("t.gsd*"))
