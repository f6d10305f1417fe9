"""The sphere, the hyperbolic plane, FCC/HCP packings, the paper's half-plane orientation, and the
capabilities (``boundary``, ``frames``) that code above the engine uses instead of types.

Facts checked: ball and contact counts and degrees; every ``t_i`` is the unit tangent at
``x_i`` of the geodesic to ``x_j``; long runs conserve energy and the angular-momentum
bivector ``sum_i x_i ^ V_i`` (velocities lifted to embedding coordinates with ``frames()``),
and momentum in flat space; each geometry runs bit for bit as the `GraphGeometry` of its own
`contact_graph()`; bad arguments raise errors naming the argument.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.analysis import observables as obs
from pinnedballs.run.ensemble import state_row
from pinnedballs.specs import SpecError, parse_spec

Q7_LENGTH = 2 * math.acosh(math.cos(math.pi / 3) / math.sin(math.pi / 7))
MINKOWSKI = np.array([-1.0, 1.0, 1.0])
EUCLIDEAN = np.ones(3)


def lifted_tangents(geom, metric=EUCLIDEAN):
    """``T_i, T_j (E, k)``: the contacts' unit vectors lifted to embedding coordinates with ``frames()``."""
    f, c = geom.frames(), geom.contacts
    p = c.pairs.astype(np.int64)
    return np.einsum("ed,edk->ek", c.t_i, f[p[:, 0]]), np.einsum("ed,edk->ek", c.t_j, f[p[:, 1]])


def bivector(positions, velocities, frames) -> np.ndarray:
    """``(k, k)`` antisymmetric ``sum_i x_i V_i^T - V_i x_i^T`` with ``V = einsum("nd,ndk->nk", v, frames)``."""
    V = np.einsum("nd,ndk->nk", velocities, frames)
    m = positions.T @ V
    return m - m.T


def gaussian(geom, seed=0):
    return np.random.default_rng(seed).standard_normal((geom.n_balls, geom.dim))


# ---------------------------------------------------------------- the sphere


@pytest.mark.parametrize("f", [1, 2, 3, 6])
def test_geodesic_grid_counts_and_degrees(f):
    s = pb.Sphere.geodesic(f)
    assert (s.n_balls, s.n_contacts, s.dim) == (10 * f * f + 2, 30 * f * f, 2)
    deg = s.degrees()
    assert (deg == 5).sum() == 12 and (deg == 6).sum() == s.n_balls - 12
    np.testing.assert_allclose(np.linalg.norm(s.positions, axis=1), 1.0, rtol=1e-15)
    assert s.boundary is None


def test_icosahedron_contacts_subtend_63_43_degrees():
    s = pb.Sphere.geodesic(1)
    p = s.positions[s.contacts.pairs.astype(np.int64)]
    angle = np.degrees(np.arccos(np.einsum("ek,ek->e", p[:, 0], p[:, 1])))
    np.testing.assert_allclose(angle, math.degrees(math.atan(2.0)), rtol=1e-13)  # 63.43 degrees


@pytest.mark.parametrize("make", [lambda: pb.Sphere.geodesic(4),
                                  lambda: pb.Sphere.from_points(_random_sphere(300))])
def test_sphere_tangents_are_great_circle_tangents(make):
    s = make()
    frames = s.frames()
    np.testing.assert_allclose(np.einsum("nak,nbk->nab", frames, frames), np.broadcast_to(np.eye(2), (s.n_balls, 2, 2)),
                               atol=1e-15)
    np.testing.assert_allclose(np.einsum("nak,nk->na", frames, s.positions), 0, atol=1e-15)
    T_i, T_j = lifted_tangents(s)
    p = s.contacts.pairs.astype(np.int64)
    xi, xj = s.positions[p[:, 0]], s.positions[p[:, 1]]
    cos = np.einsum("ek,ek->e", xi, xj)[:, None]
    sin = np.sqrt(1 - cos**2)
    np.testing.assert_allclose(T_i, (xj - cos * xi) / sin, atol=1e-12)
    np.testing.assert_allclose(T_j, (xi - cos * xj) / sin, atol=1e-12)
    # the identity that makes the bivector conserved: x_i ^ t_i = -x_j ^ t_j
    wedge = lambda x, t: x[:, :, None] * t[:, None, :] - t[:, :, None] * x[:, None, :]  # noqa: E731
    np.testing.assert_allclose(wedge(xi, T_i), -wedge(xj, T_j), atol=1e-12)


def _random_sphere(n, seed=3):
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return 2.5 * p / np.linalg.norm(p, axis=1, keepdims=True)


def test_from_points_contacts_are_the_delaunay_edges():
    s = pb.Sphere.from_points(_random_sphere(200))
    np.testing.assert_allclose(np.linalg.norm(s.positions, axis=1), 1.0, rtol=1e-15)  # scaled onto the unit sphere
    assert s.n_contacts == 3 * s.n_balls - 6  # a triangulation of the sphere (Euler)
    # Delaunay: a triangle is a face when no point lies inside its circumcircle, i.e. above the plane of its
    # three points; the faces must number 2n - 4 and hold every contact exactly twice
    faces = []
    for tri in (c for c in nx.enumerate_all_cliques(s.contact_graph()) if len(c) == 3):
        a, b, c = s.positions[tri]
        n = np.cross(b - a, c - a)
        if np.all((s.positions - a) @ (n if n @ a > 0 else -n) < 1e-12):
            faces.append(tri)
    assert len(faces) == 2 * s.n_balls - 4
    per_edge = Counter(tuple(sorted(e)) for f in faces for e in ((f[0], f[1]), (f[1], f[2]), (f[0], f[2])))
    assert set(per_edge.values()) == {2} and len(per_edge) == s.n_contacts
    ico = pb.Sphere.from_points(pb.Sphere.geodesic(1).positions)
    assert ico.n_contacts == 30 and set(ico.degrees()) == {5}


def test_from_points_in_a_cap_triangulate_the_cap_only():
    """Points within 60 degrees of the north pole: a triangulated disc, E = 3n - 3 - h (h on its rim)."""
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(8)
    z = rng.uniform(0.5, 1.0, 150)
    angle = rng.uniform(0, 2 * np.pi, 150)
    p = np.column_stack([np.sqrt(1 - z**2) * np.cos(angle), np.sqrt(1 - z**2) * np.sin(angle), z])
    s = pb.Sphere.from_points(p)
    rim = len(ConvexHull(p[:, :2] / p[:, 2:]).vertices)  # great circles are straight lines in the gnomonic chart
    assert s.n_contacts == 3 * s.n_balls - 3 - rim


@pytest.mark.parametrize("points, match", [
    (np.vstack([_random_sphere(10), [[0, 0, 2.6]]]), "points: ball 10 is off the sphere"),
    (np.vstack([_random_sphere(10), _random_sphere(10)[3:4]]), "points: balls 3 and 10 are at the same place"),
    (np.zeros((3, 3)) + [1, 0, 0], r"points: must have shape \(n, 3\) with n >= 4"),
    ([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], "points: no convex hull"),
])
def test_from_points_refuses_bad_points(points, match):
    with pytest.raises(ValueError, match=match):
        pb.Sphere.from_points(points)


def peak_bytes(make) -> tuple[int, BaseException]:
    """The most memory Python held while ``make()`` raised, and what it raised."""
    import tracemalloc

    tracemalloc.start()
    try:
        make()
    except Exception as exc:  # noqa: BLE001 - returned to be checked
        raised = exc
    else:
        raised = None
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert raised is not None, "not refused"
    return peak, raised


def test_a_geodesic_sphere_too_large_is_refused_from_its_size_before_building():
    """Issue 26: frequency 10^6 was refused after a minute and 3.5 GB. Its size is known at once:
    10 f^2 + 2 balls and 30 f^2 contacts, about 1.1 kB a ball while built plus the run's arrays
    (`run_bytes`), 1.79 kB a ball in all; nothing is allocated before the refusal."""
    peak, raised = peak_bytes(lambda: pb.Sphere.geodesic(10**6))
    assert isinstance(raised, pb.FieldError) and raised.field == "frequency"
    assert str(raised).startswith("frequency: a geodesic sphere of frequency 1,000,000 (10,000,000,000,002 balls) "
                                  "needs about 17.9 PB of memory, more than the ")
    assert peak < 1 << 20


def test_a_geodesic_sphere_beyond_what_a_grid_is_built_with_is_refused(monkeypatch):
    from pinnedballs.util import limits

    monkeypatch.setattr(limits, "available_memory", lambda: None)  # a machine that does not say
    with pytest.raises(pb.FieldError, match=r"^frequency: a geodesic sphere of frequency 1,415 has 20,022,252 balls, "
                                            r"more than the 20,000,000 a grid is built with "
                                            r"\(frequency at most 1,414\)$"):
        pb.Sphere.geodesic(1415)


def test_geodesic_refuses_frequency_0():
    with pytest.raises(ValueError, match="frequency: must be an integer >= 1, got 0"):
        pb.Sphere.geodesic(0)
    with pytest.raises(TypeError, match="frequency: must be an integer"):
        pb.Sphere.geodesic(2.0)


# ---------------------------------------------------------------- the hyperbolic plane


def test_hyperbolic_rings_degrees_and_contact_length():
    h = pb.HyperbolicPlane(q=7, layers=7)
    assert np.bincount(h.ring).tolist() == [1, 7, 21, 56, 147, 385, 1008, 2639]
    deg = h.degrees()
    assert np.all(deg[h.ring < 7] == 7) and set(deg[h.ring == 7]) == {3, 4}
    x = h.positions
    np.testing.assert_allclose(-x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2, -1.0, atol=1e-9 * 1)  # |x|^2 up to 7.7e5
    # every contact 1.090550 long, measured stably from polar coordinates (cosh of boosted products would cancel)
    r, phi = h.polar()
    i, j = h.contacts.pairs.astype(np.int64).T
    cosh_d = np.cosh(r[i] - r[j]) + 2 * np.sinh(r[i]) * np.sinh(r[j]) * np.sin((phi[i] - phi[j]) / 2) ** 2
    assert round(Q7_LENGTH, 6) == 1.090550
    assert np.abs(np.arccosh(cosh_d) - Q7_LENGTH).max() < 1e-12
    np.testing.assert_allclose(np.cosh(r), x[:, 0], rtol=1e-15)
    assert np.hypot(*h.poincare().T).max() == pytest.approx(0.99886, abs=1e-5)  # ring 7 in the Poincare disk


def test_hyperbolic_q8_every_interior_ball_touches_eight():
    h = pb.HyperbolicPlane(q=8, layers=4)
    assert np.all(h.degrees()[h.ring < 4] == 8) and np.bincount(h.ring)[:2].tolist() == [1, 8]


def test_hyperbolic_tangents_are_geodesic_tangents():
    h = pb.HyperbolicPlane(q=7, layers=4)
    f = h.frames()
    gram = np.einsum("nak,nbk->nab", f * MINKOWSKI, f)
    np.testing.assert_allclose(gram, np.broadcast_to(np.eye(2), gram.shape), atol=1e-10)
    T_i, T_j = lifted_tangents(h)
    i, j = h.contacts.pairs.astype(np.int64).T
    xi, xj = h.positions[i], h.positions[j]
    mdot = lambda a, b: np.einsum("ek,ek->e", a * MINKOWSKI, b)  # noqa: E731
    scale = np.abs(xi).max(axis=1) * np.abs(xj).max(axis=1)
    assert np.all(np.abs(mdot(T_i, xi)) < 1e-12 * scale) and np.all(np.abs(mdot(T_i, T_i) - 1) < 1e-12 * scale)
    ch, sh = math.cosh(Q7_LENGTH), math.sinh(Q7_LENGTH)
    np.testing.assert_allclose(T_i, (xj - ch * xi) / sh, atol=1e-11 * scale.max())
    np.testing.assert_allclose(T_j, (xi - ch * xj) / sh, atol=1e-11 * scale.max())


def test_hyperbolic_boundary_is_the_outermost_ring():
    h = pb.HyperbolicPlane(q=7, layers=3)
    b = h.boundary
    assert np.array_equal(b.distance == 0, h.ring == 3)
    np.testing.assert_allclose(b.distance, (3 - h.ring) * Q7_LENGTH, rtol=1e-15)
    # outward is the radial direction: lifted, it points away from ball 0
    V = np.einsum("nd,ndk->nk", b.outward, h.frames())
    assert np.all(V[1:, 0] > 0)
    assert h.ring[h.boundary_center()] == 3


@pytest.mark.parametrize("kwargs, error, match", [
    ({"q": 6, "layers": 3}, ValueError, "q: must be an integer >= 7, got 6"),
    ({"q": 7, "layers": -1}, ValueError, "layers: must be an integer >= 0, got -1"),
    ({"q": 7, "layers": 2.5}, TypeError, "layers: must be an integer"),
])
def test_hyperbolic_refuses_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        pb.HyperbolicPlane(**kwargs)


@pytest.mark.parametrize("q, layers", [(7, 6), (8, 5), (9, 4), (12, 3)])
def test_ring_sizes_count_the_balls_of_each_ring(q, layers):
    """1, q, q (q - 4), then each ring (q - 4) times the one before less the one before that."""
    from pinnedballs.geometry.hyperbolic import ring_sizes

    assert ring_sizes(q, layers) == np.bincount(pb.HyperbolicPlane(q, layers).ring).tolist()


@pytest.mark.parametrize("layers, words", [
    (10**6, "layers: 1,000,000 rings of the {3,7} tiling hold ~10^417,975 balls, more than the 20,000,000 a tiling "
            "is built with (they would need about 10^417,979 bytes of memory)"),
    (17, "layers: 17 rings of the {3,7} tiling hold 64,592,249 balls, more than the 20,000,000 a tiling is built "
         "with (they would need about 71.1 GB of memory)"),
])
def test_a_tiling_too_large_is_refused_from_its_ring_sizes_before_building(layers, words):
    """Issue 26: layers = 10^6 was refused after 60-120 s and 3.5 GB (ring after ring, up to 20
    million balls). Rings grow by a factor 2.618 for q = 7: the size is known at once."""
    peak, raised = peak_bytes(lambda: pb.HyperbolicPlane(7, layers))
    assert isinstance(raised, pb.FieldError) and str(raised) == words
    assert peak < 1 << 20


def test_a_tiling_beyond_the_memory_there_is_is_refused_with_both(monkeypatch):
    from pinnedballs.util import limits

    monkeypatch.setattr(limits, "available_memory", lambda: 10**6)
    with pytest.raises(pb.FieldError, match=r"^layers: 10 rings of the \{3,7\} tiling \(76,616 balls\) needs about "
                                            r"1[0-9][0-9]\.\d MB of memory, more than the 1\.0 MB this machine has"):
        pb.HyperbolicPlane(7, 10)


# ---------------------------------------------------------------- conservation on curved surfaces


@pytest.mark.parametrize("make, least", [(lambda: pb.Sphere.geodesic(4), 50_000),
                                         (lambda: pb.HyperbolicPlane(q=7, layers=4), 500)],
                         ids=["sphere", "hyperbolic"])
def test_long_runs_conserve_energy_and_the_bivector(make, least):
    """The sphere keeps colliding (like the torus); the finite hyperbolic disk freezes, as the theory says."""
    geom = make()
    frames = geom.frames()
    sim = pb.Simulation(geom, gaussian(geom), seed=5)
    e0, b0 = sim.energy(), bivector(geom.positions, sim.velocities, frames)
    V = np.einsum("nd,ndk->nk", sim.velocities, frames)
    size = np.abs(geom.positions).max() * np.abs(V).sum()  # scale of the bivector's terms
    sim.run(steps=300_000)
    assert sim.collisions > least
    assert abs(sim.energy() - e0) <= 1e-12 * e0
    drift = np.abs(bivector(geom.positions, sim.velocities, frames) - b0).max()
    assert drift <= 1e-11 * size, drift
    # the check has teeth: the flat-space momentum of the frame components is not conserved here
    assert np.abs(sim.momentum() - gaussian(geom).sum(axis=0)).max() > 1e-3


def test_a_wrong_tangent_breaks_the_bivector():
    """The sphere with every t_i turned by 0.05 rad in its tangent plane: energy still conserved, the bivector not."""
    s = pb.Sphere.geodesic(3)
    g = s.contact_graph()
    c, w = math.cos(0.05), math.sin(0.05)
    for _, _, d in g.edges(data=True):
        d["units"] = {a: (c * t[0] - w * t[1], w * t[0] + c * t[1]) for a, t in d["units"].items()}
    bad = pb.GraphGeometry(g)
    sim = pb.Simulation(bad, gaussian(bad), seed=5)
    e0, b0 = sim.energy(), bivector(s.positions, sim.velocities, s.frames())
    sim.run(steps=20_000)
    assert abs(sim.energy() - e0) <= 1e-12 * e0
    assert np.abs(bivector(s.positions, sim.velocities, s.frames()) - b0).max() > 1e-2


# ---------------------------------------------------------------- 3-D packings


@pytest.mark.parametrize("cls", [pb.FCC, pb.HCP])
def test_periodic_packing_counts_and_minimum_image_contacts(cls):
    g = cls(3, 3, 4)
    assert (g.n_balls, g.n_contacts, g.dim) == (144, 144 * 6, 3) and np.all(g.degrees() == 12)
    p = g.contacts.pairs.astype(np.int64)
    d = g.positions[p[:, 1]] - g.positions[p[:, 0]]
    d -= g.period * np.round(d / g.period)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 2.0, rtol=1e-14)
    np.testing.assert_allclose(g.contacts.t_i, d / 2, atol=1e-14)
    assert g.contacts.flat and g.boundary is None
    # every minimum-image pair at distance 2 is a contact
    all_d = g.positions[:, None] - g.positions[None]
    all_d -= g.period * np.round(all_d / g.period)
    i, j = np.nonzero(np.abs(np.linalg.norm(all_d, axis=-1) - 2.0) < 1e-9)
    assert {(a, b) for a, b in zip(i.tolist(), j.tolist()) if a < b} == {tuple(sorted(e)) for e in p.tolist()}


@pytest.mark.parametrize("cls", [pb.FCC, pb.HCP])
def test_open_block_equals_graph_geometry_from_positions(cls):
    g = cls(3, 4, 3, periodic=False)
    ref = pb.GraphGeometry.from_positions(g.positions)
    ours = {tuple(sorted(e)): (t if e[0] < e[1] else -t) for e, t in zip(g.contacts.pairs.tolist(), g.contacts.t_i)}
    assert set(ours) == {tuple(e) for e in ref.contacts.pairs.tolist()}
    for e, t in zip(ref.contacts.pairs.tolist(), ref.contacts.t_i):
        np.testing.assert_allclose(ours[tuple(e)], t, atol=1e-15)
    assert g.degrees().max() == 12


def test_open_z_is_a_half_space_with_the_bottom_layer_as_boundary():
    g = pb.FCC(4, 4, 3, periodic=(True, True, False))
    b = g.boundary
    np.testing.assert_array_equal(b.distance, g.positions[:, 2])
    assert (b.distance == 0).sum() == 2 * 4 * 4 and np.all(b.outward == [0, 0, -1])
    assert np.all(g.degrees()[b.distance == 0] == 8)  # 4 in the layer, 4 above
    assert g.positions[g.boundary_center(), 2] == 0
    v = np.zeros((g.n_balls, 3))
    v[g.boundary_center()] = [0, 0, -1]
    row = state_row(g, v)
    assert row["boundary_share"] == 1.0 and row["boundary_outward_fraction"] == 1.0


def test_fcc_conserves_energy_and_momentum():
    g = pb.FCC(3, 3, 3)
    sim = pb.Simulation(g, gaussian(g), seed=2)
    e0, p0 = sim.energy(), sim.momentum()
    sim.run(steps=200_000)
    assert sim.collisions > 10_000
    assert abs(sim.energy() - e0) <= 1e-12 * e0
    np.testing.assert_allclose(sim.momentum(), p0, atol=1e-11 * np.abs(sim.velocities).sum())


@pytest.mark.parametrize("kwargs, error, match", [
    ({"nx": 0, "ny": 3, "nz": 3}, ValueError, "nx: must be an integer >= 1, got 0"),
    ({"nx": 3, "ny": 3, "nz": 1}, ValueError, "nz: must be >= 2 when periodic"),
    ({"nx": 3, "ny": 3, "nz": 3, "periodic": (True, False)}, TypeError, "periodic: must be a bool or a triple"),
])
def test_packings_refuse_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match):
        pb.FCC(**kwargs)


def test_hcp_needs_three_cells_along_a_periodic_x():
    with pytest.raises(ValueError, match="nx: must be >= 3 when periodic"):
        pb.HCP(2, 3, 2)
    assert pb.HCP(2, 3, 2, periodic=(False, True, True)).n_balls == 48


# ---------------------------------------------------------------- the paper's orientation


def test_half_plane_across_is_the_papers_1425_balls():
    g = pb.HalfPlane.from_size(100, 50, orientation="across")
    assert (g.rows, g.cols, g.n_balls) == (57, 25, 1425)
    p = g.positions
    d = g.boundary.distance
    assert set(np.unique(d[d < 2]).tolist()) == {0.0, 1.0}
    assert (d == 0).sum() == 29 and (d == 1).sum() == 28
    c = g.contacts.pairs.astype(np.int64)
    delta = p[c[:, 1]] - p[c[:, 0]]
    np.testing.assert_allclose(np.linalg.norm(delta, axis=1), 2.0, rtol=1e-14)
    np.testing.assert_allclose(g.contacts.t_i, delta / 2, atol=1e-14)
    assert g.contacts.flat and g.degrees().max() == 6
    ref = pb.GraphGeometry.from_positions(p)
    assert {tuple(sorted(e)) for e in c.tolist()} == {tuple(e) for e in ref.contacts.pairs.tolist()}
    assert pb.HalfPlane.from_size(100, 50).n_balls == 1450  # "along" is unchanged


def test_half_plane_refuses_an_unknown_orientation():
    with pytest.raises(ValueError, match="orientation: must be 'along' or 'across', got 'diagonal'"):
        pb.HalfPlane(3, 3, orientation="diagonal")
    with pytest.raises(ValueError, match="orientation: must be 'along' or 'across'"):
        pb.HalfPlane.from_size(10, 5, orientation=None)


# ---------------------------------------------------------------- each geometry is its own contact graph

GEOMETRIES = {
    "sphere": lambda: pb.Sphere.geodesic(3),
    "sphere_points": lambda: pb.Sphere.from_points(_random_sphere(60)),
    "hyperbolic": lambda: pb.HyperbolicPlane(q=7, layers=3),
    "fcc": lambda: pb.FCC(2, 2, 2),
    "hcp_half_space": lambda: pb.HCP(3, 3, 2, periodic=(True, True, False)),
    "half_plane_across": lambda: pb.HalfPlane(6, 5, orientation="across"),
}


@pytest.mark.parametrize("make", GEOMETRIES.values(), ids=GEOMETRIES.keys())
def test_geometry_runs_bit_for_bit_as_the_graph_geometry_of_its_contact_graph(make):
    geom = make()
    twin = pb.GraphGeometry(geom.contact_graph())
    assert twin.dim == geom.dim and twin.curved == geom.curved
    np.testing.assert_array_equal(twin.frames(), geom.frames())
    runs = []
    for g in (geom, twin):
        sim = pb.Simulation(g, gaussian(geom, 7), seed=11)
        sim.run(steps=20_000)
        runs.append((sim.velocities.copy(), sim.steps, sim.collisions))
    assert np.array_equal(runs[0][0], runs[1][0]) and runs[0][1:] == runs[1][1:]


# ---------------------------------------------------------------- specs


def _spec(geometry, ball=0, direction=(1.0, 0.0)):
    return {"geometry": geometry, "initial": {"kind": "single_ball", "ball": ball, "direction": list(direction),
                                              "energy": 1.0}, "stop": {"steps": 100}}


@pytest.mark.parametrize("geometry, n", [
    ({"kind": "sphere", "frequency": 3}, 92),
    ({"kind": "hyperbolic_plane", "q": 7, "layers": 2}, 29),
    ({"kind": "half_plane", "length": 100, "depth": 50, "orientation": "across"}, 1425),
])
def test_new_geometry_specs_build(geometry, n):
    assert parse_spec(_spec(geometry)).build().geometry.n_balls == n


@pytest.mark.parametrize("kind", ["fcc", "hcp"])
def test_packing_specs_take_a_periodic_triple(kind):
    spec = _spec({"kind": kind, "nx": 3, "ny": 3, "nz": 2, "periodic": [True, True, False]}, "boundary_center",
                 (0, 0, 1))
    sim = parse_spec(spec).build()
    assert sim.geometry.n_balls == 72 and sim.geometry.boundary is not None
    assert sim.geometry.positions[np.flatnonzero(sim.velocities[:, 2])[0], 2] == 0


def test_boundary_center_works_for_any_geometry_with_a_boundary():
    sim = parse_spec(_spec({"kind": "hyperbolic_plane", "layers": 2}, "boundary_center")).build()
    assert sim.geometry.ring[np.flatnonzero(np.any(sim.velocities, axis=1))[0]] == 2
    with pytest.raises(SpecError, match='initial.ball: "boundary_center" needs a geometry with a boundary, got Sphere'):
        parse_spec(_spec({"kind": "sphere", "frequency": 2}, "boundary_center")).build()


@pytest.mark.parametrize("geometry, message", [
    ({"kind": "sphere", "frequency": 0}, "geometry.frequency: must be an integer >= 1, got 0"),
    ({"kind": "sphere", "frequency": 10**6}, "geometry.frequency: a geodesic sphere of frequency 1,000,000 "
                                             "(10,000,000,000,002 balls) needs about 17.9 PB of memory"),
    ({"kind": "hyperbolic_plane", "layers": 10**6}, "geometry.layers: 1,000,000 rings of the {3,7} tiling hold "
                                                    "~10^417,975 balls"),
    ({"kind": "sphere"}, "geometry: give exactly one of frequency or points"),
    ({"kind": "hyperbolic_plane", "q": 6, "layers": 2}, "geometry.q: must be an integer >= 7, got 6"),
    ({"kind": "hyperbolic_plane", "layers": -1}, "geometry.layers: must be an integer >= 0, got -1"),
    ({"kind": "fcc", "nx": 0, "ny": 2, "nz": 2}, "geometry.nx: must be an integer >= 1, got 0"),
    ({"kind": "hcp", "nx": 3, "ny": 3, "nz": 2, "periodic": [True]},
     "geometry.periodic: must be true, false or a list"),
    ({"kind": "half_plane", "rows": 3, "cols": 3, "orientation": "diagonal"}, "geometry.orientation: input should be"),
])
def test_bad_geometry_specs_exit_2_with_one_line(tmp_path, capsys, geometry, message):
    from pinnedballs.run.cli import main as cli

    path = tmp_path / "spec.json"
    import json

    path.write_text(json.dumps(_spec(geometry)))
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and message in err, err


def test_summary_uses_the_boundary_capability():
    sphere = pb.Sphere.geodesic(2)
    keys = obs.summary(gaussian(sphere), sphere)
    assert "boundary_share" not in keys and not any(k.startswith("momentum") for k in keys)  # no global momentum
    assert {"momentum_x", "momentum_y", "momentum_z"} <= set(obs.summary(gaussian(pb.FCC(2, 2, 2)), pb.FCC(2, 2, 2)))
    h = pb.HyperbolicPlane(q=7, layers=2)
    v = np.zeros((h.n_balls, 2))
    v[h.ring == 2] = [1.0, 0.0]  # every boundary ball moving radially outward
    row = state_row(h, v)
    assert row["boundary_share"] == 1.0 and row["boundary_outward_fraction"] == 1.0 and row["far_row_share"] == 0.0


# ---------------------------------------------------------------- recorded runs


@pytest.mark.parametrize("geometry", [
    {"kind": "sphere", "points": "points.npy"},
    {"kind": "hyperbolic_plane", "q": 7, "layers": 2},
    {"kind": "hcp", "nx": 3, "ny": 3, "nz": 2, "periodic": [True, True, False]},
], ids=["sphere_points", "hyperbolic", "hcp"])
def test_results_rebuild_the_geometry_and_plot_says_what_it_wrote(tmp_path, capsys, geometry):
    import json

    from pinnedballs.run.cli import main as cli

    np.save(tmp_path / "points.npy", _random_sphere(40))
    dim = 3 if geometry["kind"] == "hcp" else 2
    spec = {"geometry": geometry, "initial": {"kind": "gaussian", "energy": 10.0}, "stop": {"steps": 5_000},
            "seed": 4}
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    assert cli.main(["run", str(tmp_path / "spec.json"), "--out", str(tmp_path / "run"), "--quiet",
                     "--no-figures"]) == 0
    (tmp_path / "points.npy").unlink()  # a recorded run needs no input file to be redrawn
    res = pb.load(tmp_path / "run")
    g = res.geometry
    assert g.dim == dim and len(g.contacts) == len(res.pairs)
    assert np.array_equal(g.contacts.pairs, res.pairs)
    capsys.readouterr()
    assert cli.main(["plot", str(tmp_path / "run")]) == 0
    printed = capsys.readouterr().out.split()
    assert printed and all(Path(p).is_file() for p in printed)
    assert "state_final.png" in {Path(p).name for p in printed}


def test_plot_lists_the_figures_of_a_one_dimensional_chain(tmp_path, capsys):
    """Changed by issue 11: a 1-D chain now gets figures (it got none, and plot said so)."""
    import json

    from pinnedballs.run.cli import main as cli

    np.save(tmp_path / "chain.npy", np.arange(5.0)[:, None] * 2)
    spec = {"geometry": {"kind": "graph_positions", "positions": "chain.npy"},
            "initial": {"kind": "single_ball", "ball": 0, "velocity": [1.0]}, "stop": {"steps": 10}}
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    assert cli.main(["run", str(tmp_path / "spec.json"), "--out", str(tmp_path / "run"), "--quiet",
                     "--no-figures"]) == 0
    capsys.readouterr()
    assert cli.main(["plot", str(tmp_path / "run")]) == 0
    printed = [Path(p) for p in capsys.readouterr().out.split()]
    assert [p.name for p in printed] == ["state_initial.png", "state_final.png", "velocity_histograms.png"]
    assert all(p.parent == tmp_path / "run" and p.stat().st_size > 0 for p in printed)
