"""A geometry built in Python and recorded by a ResultsWriter reads back with its boundary, frames
and view: its boundary observables, its energy-by-distance figure and its GSD types are there."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import call, frames_of

import pinnedballs as pb
from pinnedballs.analysis import observables as obs
from pinnedballs.results import trajectory
from pinnedballs.results.load import load


class Rod(pb.GraphGeometry):
    """A user's geometry with no spec: a chain of balls whose boundary is its left end."""

    @property
    def boundary(self) -> pb.Boundary:
        return pb.Boundary(self.positions[:, 0].copy(), np.full((self.n_balls, 1), -1.0))


def record(geometry, v, out, **run) -> pb.Results:
    sim = pb.Simulation(geometry, v, seed=1)
    sim.run(**run, writers=[pb.ResultsWriter(out, snapshots={"every_collisions": 2})])
    return load(out)


@pytest.mark.parametrize("make", [lambda: pb.HalfPlane(rows=4, cols=6), lambda: Rod.from_positions(
    2.0 * np.arange(7.0)[:, None])], ids=["HalfPlane passed straight", "GraphGeometry subclass with a boundary"])
def test_the_boundary_is_read_back_with_its_observables_and_figure(tmp_path, make):
    geometry = make()
    v = np.zeros((geometry.n_balls, geometry.dim))
    v[-1, -1] = -3.0                                       # the far ball sent towards the boundary
    res = record(geometry, v, tmp_path / "run", collisions=10**4)
    read = res.geometry
    assert read.boundary is not None
    assert np.array_equal(read.boundary.distance, geometry.boundary.distance)
    assert np.array_equal(read.boundary.outward, geometry.boundary.outward)
    mine, theirs = obs.summary(res.velocities, read), obs.summary(res.velocities, geometry)
    assert {"boundary_share", "boundary_outward_fraction"} <= set(mine)
    assert mine["boundary_share"] == theirs["boundary_share"]
    code, stdout, _ = call("plot", tmp_path / "run")
    assert code == 0 and str(tmp_path / "run" / "energy_by_distance.png") in stdout.split()
    first = frames_of(trajectory.export(res, tmp_path / "t.gsd"))[0]
    assert np.array_equal(first.particles.typeid, (geometry.boundary.distance == 0).astype(np.uint32))


def test_a_sphere_from_points_reads_back_with_its_frames_and_view(tmp_path):
    points = pb.Sphere.geodesic(2).positions[::-1]         # a sphere with no spec
    sphere = pb.Sphere.from_points(points)
    v = np.random.default_rng(0).standard_normal((sphere.n_balls, 2))
    read = record(sphere, v, tmp_path / "s", steps=500).geometry
    assert read.view == "sphere" and read.curved and read.boundary is None
    assert np.array_equal(read.frames(), sphere.frames())
