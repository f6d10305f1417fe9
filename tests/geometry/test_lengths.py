"""Lengths a run can write and read back (issue 26, item 7): a radius whose centres would overflow,
or whose lengths would lose their digits (squares beyond float64's normal numbers), is refused
naming ``radius`` (``geometry.radius`` in a spec) before anything is written, for every geometry;
what is allowed, up to the ends of the range, runs, draws and reads back with its contact distance."""

from __future__ import annotations

import re

import networkx as nx
import numpy as np
import pytest
from helpers import TORUS, call, spec, write

import pinnedballs as pb
from pinnedballs.geometry.base import LENGTHS
from pinnedballs.specs import parse_spec
from pinnedballs.util.errors import FieldError

LOW, HIGH = LENGTHS

GEOMETRIES = {
    "flat_torus": (lambda r: pb.FlatTorus(38, 38, radius=r), {"kind": "flat_torus", "rows": 38, "cols": 38}),
    "half_plane": (lambda r: pb.HalfPlane(5, 8, radius=r), {"kind": "half_plane", "rows": 5, "cols": 8}),
    "half_plane_size": (lambda r: pb.HalfPlane.from_size(100, 50, radius=r, orientation="across"),
                        {"kind": "half_plane", "length": 100, "depth": 50, "orientation": "across"}),
    "fcc": (lambda r: pb.FCC(2, 2, 2, radius=r), {"kind": "fcc", "nx": 2, "ny": 2, "nz": 2}),
    "hcp": (lambda r: pb.HCP(3, 3, 3, radius=r), {"kind": "hcp", "nx": 3, "ny": 3, "nz": 3}),
    "sphere": (lambda r: pb.Sphere.geodesic(2, radius=r), {"kind": "sphere", "frequency": 2}),
    "hyperbolic": (lambda r: pb.HyperbolicPlane(7, 2, radius=r), {"kind": "hyperbolic_plane", "q": 7, "layers": 2}),
    "graph": (lambda r: pb.GraphGeometry(_path_graph(), radius=r), None),  # the radius only sizes the balls
    "from_positions": (lambda r: pb.GraphGeometry.from_positions(_chain(r), radius=r), None),
}


def _chain(r: float) -> np.ndarray:
    """4 touching balls of radius ``r`` on a line (inf beyond float64: the radius is refused first)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return np.arange(4.0) * (2 * r)


def _path_graph() -> nx.Graph:
    """3 balls on a line whose edges state their contacts ("units"): any radius sizes them (an edge without
    "units" must be 2 radii long, and is refused where the graph is given otherwise)."""
    g = nx.path_graph(3)
    for n in g:
        g.nodes[n]["pos"] = (2.0 * n, 0.0)
    for u, v in g.edges:
        g.edges[u, v]["units"] = {u: (1.0, 0.0), v: (-1.0, 0.0)}
    return g


def reach(kind: str) -> float:
    """How far the centres of the geometry lie from the origin, in radii (1: they do not scale with it)."""
    g = GEOMETRIES[kind][0](1.0)
    return 1.0 if g.curved or kind == "graph" else float(np.linalg.norm(g.positions, axis=1).max())


@pytest.mark.parametrize("kind", GEOMETRIES)
@pytest.mark.parametrize("radius", [1e308, 1e151, 1e-151, 1e-320])
def test_a_radius_whose_lengths_float64_cannot_hold_is_refused_naming_radius(kind, radius):
    with pytest.raises(FieldError, match=rf"^radius: must be in \[1e-150, [0-9.e+]+\].* lose their digits when "
                                         rf"squared\), got {re.escape(repr(radius))}$") as caught:
        GEOMETRIES[kind][0](radius)
    assert caught.value.field == "radius"


@pytest.mark.parametrize("kind", GEOMETRIES)
def test_the_ends_of_the_range_build_with_finite_centres_that_keep_the_contact_distance(kind):
    """The smallest radius allowed and the largest one for these centres: every centre finite, every
    contact (in flat space, across no periodic seam) 2 radii long to 1e-12."""
    top = HIGH / max(reach(kind), 1.0)
    for r in (LOW, top * (1 - 1e-12)):
        g = GEOMETRIES[kind][0](r)
        assert g.radius == r and np.isfinite(g.positions).all()
        if g.curved or kind == "graph":  # its centres are given, not made from the radius
            continue
        p, pairs = g.positions, g.contacts.pairs.astype(np.int64)
        length = np.linalg.norm(p[pairs[:, 1]] - p[pairs[:, 0]], axis=1)
        inside = length < 3 * r  # contacts across a periodic seam are longer
        assert inside.sum() >= len(length) // 2
        assert np.allclose(length[inside], 2 * r, rtol=1e-12, atol=0)
    with pytest.raises(FieldError):
        GEOMETRIES[kind][0](top * 1.01)


def test_centres_too_far_for_their_contact_distance_are_refused():
    with pytest.raises(FieldError, match=r"^positions: a centre has a coordinate of 3e\+200; lengths beyond 1e\+150 "
                                         r"lose their digits when squared: scale them down$"):
        pb.GraphGeometry.from_positions(1e200 * np.arange(1.0, 4.0), radius=1e100)
    with pytest.raises(FieldError, match=r"^radius: 1 is too small for centres up to 1e\+11 from the origin: they "
                                         r"are rounded to 1\.5e-05, more than a millionth of the contact distance 2"):
        pb.GraphGeometry.from_positions(1e11 + 2.0 * np.arange(4.0))
    g = pb.GraphGeometry.from_positions(1e8 + 2.0 * np.arange(4.0))  # rounded to 1.5e-8: still resolved
    assert g.n_contacts == 3


def test_a_spec_whose_radius_would_overflow_is_refused_and_nothing_written(tmp_path):
    """The issue's case: flat_torus with radius 1e308 ran, and its own results file was refused as damaged."""
    spec_path = write(tmp_path / "s.json", spec(TORUS, geometry={"kind": "flat_torus", "rows": 38, "cols": 38,
                                                                  "radius": 1e308}))
    line = ("pinnedballs: error: geometry.radius: must be in [1e-150, 1.01e+148] for centres up to 98.7 radii from "
            "the origin (lengths beyond [1e-150, 1e+150] lose their digits when squared), got 1e+308\n")
    for argv in (["run", spec_path, "--out", tmp_path / "out", "--quiet"], ["validate", spec_path]):
        assert call(*argv) == (2, "", line)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["flat_torus", "half_plane", "fcc"])
def test_a_run_at_the_ends_of_the_range_writes_what_it_reads_back(tmp_path, kind):
    top = float(f"{HIGH / reach(kind):.3e}") * 0.99
    for k, r in enumerate((LOW, top)):
        geometry = {**GEOMETRIES[kind][1], "radius": r}
        data = spec(TORUS, geometry=geometry, initial={"kind": "gaussian", "energy": 1.0},
                    snapshots={"at_steps": [0, 500, 1000]})
        out = tmp_path / f"r{k}"
        figures = [] if kind == "flat_torus" else ["--no-figures"]
        code, _, err = call("run", write(tmp_path / f"s{k}.json", data), "--out", out, "--quiet", *figures)
        assert (code, err) == (0, "")
        res = pb.load(out)
        built = parse_spec(data).build().geometry
        assert res.radius == r and np.array_equal(res.positions, built.positions) and res.steps == 1000
        if not figures:
            assert (out / "state_final.png").stat().st_size > 0


def test_a_trajectory_that_32_bit_floats_cannot_hold_is_refused_before_anything_is_written(tmp_path):
    big = spec(TORUS, geometry={"kind": "flat_torus", "rows": 4, "cols": 4, "radius": 1e100},
               trajectory={"every_steps": 500})
    fast = spec(TORUS, initial={"kind": "gaussian", "energy": 1e90}, trajectory={"every_steps": 500})
    for data, what in ((big, "this geometry (balls 2e+100 across, coordinates up to 8e+100; they hold 1e-30 to "
                             "1e+38)"),
                       (fast, "the speeds of this run (up to 1.41e+45; they hold at most 1e+38)")):
        code, _, err = call("run", write(tmp_path / "s.json", data), "--out", tmp_path / "out", "--quiet")
        assert (code, err) == (2, f"pinnedballs: error: trajectory: a GSD trajectory holds 32-bit floats, which "
                                  f"cannot hold {what}\n")
        assert not (tmp_path / "out").exists()
    # the run itself is fine; exporting it is refused naming the file
    no_trajectory = {k: v for k, v in big.items() if k != "trajectory"}
    assert call("run", write(tmp_path / "s.json", no_trajectory), "--out", tmp_path / "big", "--quiet",
                "--no-figures")[0] == 0
    code, _, err = call("export", tmp_path / "big", tmp_path / "big.gsd")
    assert (code, err) == (2, f"pinnedballs: error: {tmp_path / 'big.gsd'}: a GSD trajectory holds 32-bit floats, "
                              f"which cannot hold this geometry (balls 2e+100 across, coordinates up to 8e+100; they "
                              f"hold 1e-30 to 1e+38)\n")
    assert not (tmp_path / "big.gsd").exists()
