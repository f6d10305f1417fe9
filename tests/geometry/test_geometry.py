"""Geometries: where the balls sit and which of them touch.

Every contact must be a pair of centres exactly ``2 * radius`` apart (under the
minimum image on the torus) with ``t_i`` the unit vector from ``i`` to ``j``;
every touching pair must be a contact; each lattice must equal the
`GraphGeometry` rebuilt from its own `contact_graph()`.
"""

from __future__ import annotations

import itertools
import math

import networkx as nx
import numpy as np
import pytest
from helpers import FAST, TorusLessOne, chain, cubic, fcc_cluster, icosahedron_sphere, ints
from hypothesis import given
from hypothesis import strategies as st

import pinnedballs as pb

SQRT3 = math.sqrt(3.0)


def contact_map(geom) -> dict[tuple[int, int], tuple[tuple, tuple]]:
    """``{(i, j): (t_i, t_j)}`` with ``i < j`` (ends swapped where needed), for order-free comparison."""
    c = geom.contacts
    out = {}
    for (i, j), a, b in zip(ints(c.pairs).tolist(), c.t_i.tolist(), c.t_j.tolist()):
        key, value = ((i, j), (tuple(a), tuple(b))) if i < j else ((j, i), (tuple(b), tuple(a)))
        assert key not in out, f"contact {key} listed twice"
        out[key] = value
    return out


def brute_force_pairs(p: np.ndarray, contact: float, tol: float = 1e-9) -> set[tuple[int, int]]:
    """All pairs of centres ``contact`` apart, by checking every pair."""
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)
    i, j = np.nonzero(np.abs(d - contact) <= tol * contact)
    return {(a, b) for a, b in zip(i.tolist(), j.tolist()) if a < b}


def check_flat_contacts(geom, radius=1.0, period=None):
    """Every contact at distance 2 radius (minimum image if periodic), t_i = unit displacement, t_j = -t_i."""
    c = geom.contacts
    p = ints(c.pairs)
    assert np.all(p[:, 0] != p[:, 1])
    d = geom.positions[p[:, 1]] - geom.positions[p[:, 0]]
    if period is not None:
        d -= period * np.round(d / period)
    dist = np.linalg.norm(d, axis=1)
    np.testing.assert_allclose(dist, 2 * radius, rtol=1e-12)
    np.testing.assert_allclose(c.t_i, d / dist[:, None], atol=1e-12)
    assert np.array_equal(c.t_j, -c.t_i)
    np.testing.assert_allclose(np.linalg.norm(c.t_i, axis=1), 1.0, rtol=1e-15)


# ---------------------------------------------------------------- flat torus


def test_torus_38x38_counts_and_degrees():
    g = pb.FlatTorus(rows=38, cols=38)
    assert g.n_balls == 1444 and g.n_contacts == 4332 and g.dim == 2
    assert g.positions.shape == (1444, 2)
    assert np.all(g.degrees() == 6)
    assert len(contact_map(g)) == 4332  # no pair twice


@pytest.mark.parametrize("rows, cols", [(4, 3), (6, 5), (38, 38), (10, 17)])
def test_torus_contacts_are_minimum_image_neighbours(rows, cols):
    g = pb.FlatTorus(rows=rows, cols=cols)
    assert np.allclose(g.period, [2 * cols, SQRT3 * rows])
    check_flat_contacts(g, period=g.period)
    assert np.all(g.degrees() == 6)
    # every minimum-image pair at distance 2 is a contact, and nothing else
    d = g.positions[:, None, :] - g.positions[None, :, :]
    d -= g.period * np.round(d / g.period)
    i, j = np.nonzero(np.abs(np.linalg.norm(d, axis=-1) - 2.0) < 1e-9)
    assert {(a, b) for a, b in zip(i.tolist(), j.tolist()) if a < b} == set(contact_map(g))


def test_torus_radius_scales_positions():
    g = pb.FlatTorus(rows=6, cols=5, radius=0.5)
    check_flat_contacts(g, radius=0.5, period=g.period)
    np.testing.assert_allclose(g.positions, 0.5 * pb.FlatTorus(rows=6, cols=5).positions)


def test_torus_1000x1000_builds():
    g = pb.FlatTorus(rows=1000, cols=1000)
    assert g.n_balls == 10**6 and g.n_contacts == 3 * 10**6
    assert np.all(g.degrees() == 6)


@pytest.mark.parametrize("make, closed", [
    (lambda: pb.FlatTorus(4, 3), True), (lambda: pb.FlatTorus(6, 5), True), (lambda: pb.FCC(4, 4, 4), True),
    (lambda: pb.HalfPlane(3, 3), False), (lambda: pb.FCC(4, 4, 4, periodic=(True, True, False)), False),
    (lambda: pb.HCP(4, 4, 4), False), (lambda: TorusLessOne(), False), (icosahedron_sphere, False),
    (lambda: pb.Sphere.geodesic(2), False), (lambda: chain(4), False)],
    ids=["torus4x3", "torus6x5", "fcc", "half-plane", "fcc-open-z", "hcp", "torus-less-one", "icosahedron",
         "sphere", "chain"])
def test_closed_rows_are_a_torus_lattice_lines(make, closed):
    """Every contact on a closed row of balls along one unit vector: the torus's and the periodic FCC's
    lattice lines close; a boundary, HCP's zig-zag between layers, one contact taken out or a curved
    surface leave some row open."""
    assert make().contacts.closed_rows is closed


@pytest.mark.parametrize("geom", [pb.FlatTorus(4, 3), pb.FlatTorus(4, 4), pb.FlatTorus(6, 5), pb.FCC(3, 3, 3),
                                  pb.FCC(4, 3, 5)], ids=["torus4x3", "torus4x4", "torus6x5", "fcc3", "fcc435"])
def test_a_rigid_torus_has_every_closing_speed_zero_only_at_a_common_velocity(geom):
    """`Geometry.rigid`: on the triangular torus and the periodic FCC the map from velocities to
    closing speeds has only the translations in its kernel, so a frozen state is one common velocity."""
    c, n, d = geom.contacts, geom.n_balls, geom.dim
    a = np.zeros((len(c), d * n))
    for k, ((i, j), (ti, tj)) in enumerate(zip(ints(c.pairs), ints(c.ends))):
        a[k, d * i:d * i + d], a[k, d * j:d * j + d] = c.units[ti], c.units[tj]
    assert geom.rigid and geom.contacts.closed_rows
    assert d * n - np.linalg.matrix_rank(a) == d


# ---------------------------------------------------------------- half-plane


@pytest.mark.parametrize("rows, cols", [(1, 1), (1, 5), (2, 2), (5, 6), (29, 50)])
def test_half_plane_is_the_touching_pairs_of_a_triangular_lattice(rows, cols):
    g = pb.HalfPlane(rows=rows, cols=cols)
    assert g.n_balls == rows * cols
    check_flat_contacts(g)
    assert set(contact_map(g)) == brute_force_pairs(g.positions, 2.0)
    assert g.n_contacts == rows * (cols - 1) + (rows - 1) * (2 * cols - 1)


def test_half_plane_degrees_and_boundary():
    g = pb.HalfPlane(rows=7, cols=9)
    deg = g.degrees().reshape(7, 9)
    assert deg.max() <= 6
    assert np.all(deg[1:-1, 1:-1] == 6)  # interior balls touch six
    assert np.all(deg[0, 1:-1] == 4)  # the boundary row: two neighbours beside, two behind
    dist = g.boundary_distance().reshape(7, 9)
    assert np.all(dist[0] == 0.0)
    np.testing.assert_allclose(dist, SQRT3 * np.arange(7)[:, None] * np.ones(9), rtol=1e-15)
    assert np.all(dist >= 0)
    b = g.boundary_center()
    assert dist.ravel()[b] == 0.0 and b in ((9 - 1) // 2, 9 // 2)


def test_half_plane_from_size_matches_the_paper():
    g = pb.HalfPlane.from_size(100, 50)
    assert (g.rows, g.cols) == (29, 50)
    assert g.boundary_distance().max() + 1 <= 50  # the last row's balls still fit in the depth
    for length, depth in [(10, 5), (60, 30), (200, 100), (300, 150), (400, 200), (500, 250)]:
        h = pb.HalfPlane.from_size(length, depth)
        assert h.cols == length // 2
        assert (h.rows - 1) * SQRT3 + 1 <= depth < h.rows * SQRT3 + 1


# ---------------------------------------------------------------- graph geometries


def test_one_dimensional_chain():
    g = chain(6)
    assert g.dim == 1 and g.n_balls == 6 and g.n_contacts == 5
    assert set(contact_map(g)) == {(k, k + 1) for k in range(5)}
    for ti, tj in contact_map(g).values():
        assert ti == (1.0,) and tj == (-1.0,)


def test_one_dimensional_positions_may_be_a_flat_list():
    g = pb.GraphGeometry.from_positions([0.0, 2.0, 4.0, 10.0])
    assert g.dim == 1 and set(contact_map(g)) == {(0, 1), (1, 2)}


def test_fcc_cluster_interior_ball_touches_twelve():
    g = fcc_cluster(2)
    assert g.dim == 3
    check_flat_contacts(g)
    assert set(contact_map(g)) == brute_force_pairs(g.positions, 2.0)
    big = fcc_cluster(4)
    inner = np.all((big.positions > 1) & (big.positions < 4 * np.sqrt(2) - 1), axis=1)
    assert np.all(big.degrees()[inner] == 12)
    assert g.degrees().max() <= 12


def test_simple_cubic_block():
    g = cubic(3)
    assert g.dim == 3 and g.n_balls == 27 and g.n_contacts == 3 * 3 * 3 * 2
    assert g.degrees().max() == 6 and np.count_nonzero(g.degrees() == 6) == 1
    check_flat_contacts(g)


@st.composite
def noisy_lattice_points(draw):
    """A random subset of a square, triangular or cubic lattice (spacing 2 radius), jittered by ~1e-12."""
    kind = draw(st.sampled_from(["square", "triangular", "cubic"]))
    radius = draw(st.sampled_from([1.0, 0.5, 3.25]))
    k = draw(st.integers(2, 7))
    if kind == "square":
        base = np.array(list(itertools.product(range(k), repeat=2)), float)
    elif kind == "cubic":
        base = np.array(list(itertools.product(range(min(k, 4)), repeat=3)), float)
    else:
        r, c = np.divmod(np.arange(k * k), k)
        base = np.column_stack([c + 0.5 * (r % 2), 0.5 * SQRT3 * r])
    keep = np.array(draw(st.lists(st.booleans(), min_size=len(base), max_size=len(base))))
    p = 2 * radius * base[keep]
    seed = draw(st.integers(0, 2**32 - 1))
    p = p + 1e-12 * np.random.default_rng(seed).standard_normal(p.shape) + draw(st.floats(-100, 100))
    return p, radius


@FAST
@given(noisy_lattice_points())
def test_from_positions_finds_exactly_the_touching_pairs(case):
    p, radius = case
    g = pb.GraphGeometry.from_positions(p, radius=radius)
    assert g.n_balls == len(p) and g.dim == p.shape[1]
    assert set(contact_map(g)) == brute_force_pairs(p, 2 * radius)
    c = g.contacts
    pairs = ints(c.pairs)
    d = p[pairs[:, 1]] - p[pairs[:, 0]]
    np.testing.assert_allclose(c.t_i, d / np.linalg.norm(d, axis=1)[:, None], atol=1e-12)
    assert np.array_equal(c.t_j, -c.t_i)


def test_graph_geometry_uses_node_order_and_given_units():
    g = nx.Graph()
    g.add_node("b", pos=(2.0, 0.0))
    g.add_node("a", pos=(0.0, 0.0))
    g.add_edge("a", "b", units={"a": (0.0, 1.0), "b": (1.0, 0.0)})
    geom = pb.GraphGeometry(g)
    assert geom.n_balls == 2 and geom.n_contacts == 1
    assert contact_map(geom) == {(0, 1): ((1.0, 0.0), (0.0, 1.0))}  # ball 0 is "b", its unit is (1, 0)


# ---------------------------------------------------------------- round trip through networkx


@pytest.mark.parametrize(
    "make",
    [
        lambda: pb.FlatTorus(rows=6, cols=5),
        lambda: pb.FlatTorus(rows=38, cols=38),
        lambda: pb.HalfPlane(rows=5, cols=7),
        lambda: chain(5),
        lambda: fcc_cluster(2),
    ],
    ids=["torus6x5", "torus38x38", "halfplane", "chain", "fcc"],
)
def test_geometry_equals_graph_geometry_of_its_contact_graph(make):
    geom = make()
    graph = geom.contact_graph()
    assert sorted(graph.nodes) == list(range(geom.n_balls))
    for n in graph.nodes:
        assert graph.nodes[n]["pos"] == tuple(geom.positions[n].tolist())
    rebuilt = pb.GraphGeometry(graph)
    assert rebuilt.n_balls == geom.n_balls and rebuilt.dim == geom.dim
    assert rebuilt.n_contacts == geom.n_contacts
    np.testing.assert_array_equal(rebuilt.positions, geom.positions)
    assert contact_map(rebuilt) == contact_map(geom)  # same pairs, same t_i and t_j, bit for bit


@pytest.mark.parametrize("geom", [pb.FlatTorus(rows=6, cols=5), pb.HalfPlane(rows=4, cols=7)], ids=repr)
def test_contact_graph_round_trip_keeps_the_contact_order(geom):
    """The rebuilt geometry lists contacts in the same order and orientation, so the same seed
    gives the same run (Sweep order and UniformRandomPair picks index contacts)."""
    rebuilt = pb.GraphGeometry(geom.contact_graph())
    assert np.array_equal(ints(rebuilt.contacts.pairs), ints(geom.contacts.pairs))
    v = np.random.default_rng(7).normal(size=(geom.n_balls, 2))
    runs = [pb.Simulation(g, v, seed=3) for g in (geom, rebuilt)]
    for sim in runs:
        sim.run(steps=5_000)
    np.testing.assert_array_equal(runs[0].velocities, runs[1].velocities)


def test_contact_graph_numbering_must_be_complete():
    graph = pb.FlatTorus(rows=4, cols=3).contact_graph()
    u, v = next(iter(graph.edges))
    graph.edges[u, v]["contact"] = 10**6
    with pytest.raises(ValueError, match="graph: edge 'contact' attributes must number the edges 0, 1, ..."):
        pb.GraphGeometry(graph)


def test_contact_graph_pair_must_name_the_edge_ends():
    graph = pb.FlatTorus(rows=4, cols=3).contact_graph()
    u, v = next(iter(graph.edges))
    graph.edges[u, v]["pair"] = (u, u)
    with pytest.raises(ValueError, match=r"graph: edge \(0, 1\) has 'pair' \(0, 0\), not its two ends"):
        pb.GraphGeometry(graph)


# ---------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "kwargs, error, match",
    [
        ({"rows": 5, "cols": 6}, ValueError, r"^rows: .*even"),
        ({"rows": 7, "cols": 6}, ValueError, r"^rows: .*even"),
        ({"rows": 2, "cols": 6}, ValueError, r"^rows: .*>= 4"),
        ({"rows": 0, "cols": 6}, ValueError, r"^rows: .*>= 4"),
        ({"rows": 6, "cols": 2}, ValueError, r"^cols: .*>= 3"),
        ({"rows": 6, "cols": -1}, ValueError, r"^cols: .*>= 3"),
        ({"rows": 6.0, "cols": 6}, TypeError, r"^rows: .*integer"),
        ({"rows": 6, "cols": "6"}, TypeError, r"^cols: .*integer"),
        ({"rows": 6, "cols": 6, "radius": 0.0}, ValueError, r"^radius: "),
        ({"rows": 6, "cols": 6, "radius": math.nan}, ValueError, r"^radius: "),
    ],
)
def test_flat_torus_refuses_bad_sizes(kwargs, error, match):
    with pytest.raises(error, match=match):
        pb.FlatTorus(**kwargs)


@pytest.mark.parametrize(
    "rows, cols, match",
    [(0, 5, r"^rows: .*>= 1"), (-3, 5, r"^rows: .*>= 1"), (5, 0, r"^cols: .*>= 1"), (5, -1, r"^cols: .*>= 1")],
)
def test_half_plane_refuses_nonpositive_sizes(rows, cols, match):
    with pytest.raises(ValueError, match=match):
        pb.HalfPlane(rows=rows, cols=cols)


@pytest.mark.parametrize(
    "length, depth, error, match",
    [
        (-100, 50, ValueError, r"^length: "),
        (100, -50, ValueError, r"^depth: "),
        (0, 50, ValueError, r"^length: "),
        (1.5, 50, ValueError, r"^length: .*>= 2"),
        (math.nan, 50, ValueError, r"^length: .*finite"),
        (100, math.inf, ValueError, r"^depth: .*finite"),
        ("100", 50, TypeError, r"^length: "),
    ],
)
def test_half_plane_from_size_refuses_bad_sizes(length, depth, error, match):
    with pytest.raises(error, match=match):
        pb.HalfPlane.from_size(length, depth)


def test_overlapping_balls_are_refused_and_named():
    with pytest.raises(ValueError, match=r"^positions: balls 1 and 2 overlap"):
        pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    with pytest.raises(ValueError, match=r"^positions: balls 0 and 1 overlap"):
        pb.GraphGeometry.from_positions([[5.0, 5.0], [5.0, 5.0]])


@pytest.mark.parametrize(
    "positions, match",
    [([[0.0, math.nan], [2.0, 0.0]], r"^positions: .*NaN"), ([["a", 0.0]], r"^positions: ")],
)
def test_from_positions_refuses_non_finite_or_non_numbers(positions, match):
    with pytest.raises((ValueError, TypeError), match=match):
        pb.GraphGeometry.from_positions(positions)


def test_graph_node_without_pos_is_named():
    g = nx.Graph()
    g.add_node(0, pos=(0.0, 0.0))
    g.add_node("lonely")
    g.add_edge(0, "lonely")
    with pytest.raises(ValueError, match=r"^graph: node 'lonely' has no 'pos'"):
        pb.GraphGeometry(g)


def test_contact_between_coincident_centres_is_refused():
    g = nx.Graph()
    g.add_node(0, pos=(1.0, 1.0))
    g.add_node(1, pos=(1.0, 1.0))
    g.add_edge(0, 1)
    with pytest.raises(ValueError, match=r"balls 0 and 1 have the same centre"):
        pb.GraphGeometry(g)


@pytest.mark.parametrize(
    "units, match",
    [
        ({0: (1.0, 0.0)}, r"^graph: edge \(0, 1\) 'units' must map both ends"),
        ({0: (1.0, 0.0), 1: (2.0, 0.0)}, r"^graph: edge \(0, 1\) 'units' must be unit vectors"),
        ({0: (1.0, 0.0, 0.0), 1: (-1.0, 0.0, 0.0)},
         r"^graph: edge \(0, 1\) 'units' must be unit vectors of 2 components"),
    ],
)
def test_bad_given_units_are_refused(units, match):
    g = nx.Graph()
    g.add_node(0, pos=(0.0, 0.0))
    g.add_node(1, pos=(2.0, 0.0))
    g.add_edge(0, 1, units=units)
    with pytest.raises(ValueError, match=match):
        pb.GraphGeometry(g)


def test_graph_must_be_an_undirected_networkx_graph():
    with pytest.raises(TypeError, match=r"^graph: "):
        pb.GraphGeometry(nx.DiGraph([(0, 1)]))
    with pytest.raises(TypeError, match=r"^graph: "):
        pb.GraphGeometry([(0, 1)])
    with pytest.raises(ValueError, match=r"^graph: has no nodes"):
        pb.GraphGeometry(nx.Graph())
