"""A geometry given as a graph or as centres (`pinnedballs.geometry.graph`): its normals snapped to a
number field for exact arithmetic, and an edge of the wrong length refused where the graph is given."""

from __future__ import annotations

import networkx as nx
import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.engine.field.numbers import recognise
from pinnedballs.geometry.graph import SNAP_ULPS


def hexagonal(m: int, n: int) -> nx.Graph:
    """networkx's honeycomb: edges of length 1 between centres computed in floats (a few ulps off)."""
    return nx.hexagonal_lattice_graph(m, n, with_positions=True)


def gaussian(geom, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(geom.n_balls, geom.dim))


def frozen(geom, v, arithmetic: str) -> tuple[int, int]:
    sim = pb.Simulation(geom, v, arithmetic=arithmetic, seed=3)
    assert sim.run_until_frozen(max_steps=10**6)
    return sim.steps, sim.collisions


def test_a_honeycomb_from_networkx_is_refused_exactly_with_advice_that_works():
    """Its normals are (-0.5000000000000006, ...): no exact arithmetic runs them; the refusal names snap."""
    geom = pb.GraphGeometry(hexagonal(10, 10), radius=0.5)
    for arithmetic in ("exact", "certified"):
        with pytest.raises(pb.FieldError) as info:
            pb.Simulation(geom, gaussian(geom), arithmetic=arithmetic, seed=0)
        assert str(info.value) == (
            f"arithmetic: {arithmetic} arithmetic needs every contact normal in a known number field (q*sqrt(d) "
            "components), and GraphGeometry's are not: unit vector 36 (-0.5000000000000006, 0.8660254037844384): "
            "-0.5000000000000006 is not q*sqrt(d) for a small rational q and squarefree d; if they are within "
            "rounding of one, snap them there (GraphGeometry(graph, snap=True), "
            "GraphGeometry.from_positions(positions, snap=True))")
    snapped = pb.GraphGeometry(hexagonal(10, 10), radius=0.5, snap=True)
    pb.Simulation(snapped, gaussian(snapped), arithmetic="certified", seed=0)  # the advice taken: it runs


def test_snapping_moves_the_normals_within_rounding_and_nothing_else():
    """The centres, the contacts (pairs, ends) and the boundary stay; each normal moves by at most the
    tolerance, to floats that lie in Q(sqrt 3) (the triangular lattice's field) and keep t_j = -t_i."""
    graph = hexagonal(10, 10)
    raw, snapped = pb.GraphGeometry(graph, radius=0.5), pb.GraphGeometry(graph, radius=0.5, snap=True)
    far = np.abs(raw.positions).max()
    tolerance = SNAP_ULPS * np.finfo(float).eps * (1 + far / 1.0)
    assert np.array_equal(snapped.positions, raw.positions) and snapped.boundary is raw.boundary is None
    assert np.array_equal(snapped.contacts.pairs, raw.contacts.pairs)
    assert np.array_equal(snapped.contacts.ends, raw.contacts.ends)
    moved = np.abs(snapped.contacts.units - raw.contacts.units)
    assert 0 < moved.max() <= tolerance
    assert snapped.contacts.flat and recognise(snapped.contacts.units)[0].basis == (1, 3)
    assert set(np.abs(snapped.contacts.units).ravel().tolist()) == {0.0, 0.5, 1.0, float(np.sqrt(3) / 2)}


def test_from_positions_snaps_the_same_contacts():
    graph = hexagonal(4, 4)
    by_graph = pb.GraphGeometry(graph, radius=0.5, snap=True)
    by_centres = pb.GraphGeometry.from_positions(by_graph.positions, radius=0.5, snap=True)
    pairs = {frozenset(p) for p in by_centres.contacts.pairs.tolist()}
    assert pairs == {frozenset(p) for p in by_graph.contacts.pairs.tolist()}
    assert recognise(by_centres.contacts.units)[0].basis == (1, 3)


def test_a_snapped_honeycomb_counts_exactly_and_as_floats_where_the_margin_is_wide():
    """The exact count is the certified count; on a small honeycomb whose float picks stay far from the
    threshold (not thin), the float count is the same."""
    geom = pb.GraphGeometry(hexagonal(4, 4), radius=0.5, snap=True)
    v = gaussian(geom)
    sim = pb.Simulation(geom, v, seed=3)
    assert sim.run_until_frozen(max_steps=10**6) and not sim.closing_margin().thin
    exact = frozen(geom, v, "exact")
    assert exact == frozen(geom, v, "certified") == (sim.steps, sim.collisions)
    assert exact[1] > 100


def test_a_normal_in_no_field_is_refused_when_snapped():
    p = [[0.0, 0.0], [2 * np.cos(1.0), 2 * np.sin(1.0)]]
    with pytest.raises(pb.FieldError, match=r"^snap: unit vector 0 \(0\.5403023058681398, 0\.8414709848078965\): "
                                            r"0\.5403023058681398 is not within [0-9.e-]+ of q\*sqrt\(d\) for a small "
                                            r"rational q and squarefree d \(within [0-9.e-]+: give snap a larger "
                                            r"tolerance if the centres are rounded more\)$"):
        pb.GraphGeometry.from_positions(p, snap=True)
    for bad in (0.0, 0.7, -1e-9, "yes"):
        with pytest.raises(pb.FieldError, match=r"^snap: must be True, False or a tolerance in \(0, 0\.5\)"):
            pb.GraphGeometry.from_positions(p, snap=bad)


def test_a_tolerance_snaps_centres_rounded_more():
    """Centres written to 7 digits: (0.6, 0.8000001) is (3/5, 4/5) within 1e-6, not within rounding."""
    p = [[0.0, 0.0], [1.2, 1.6000002]]
    with pytest.raises(pb.FieldError, match=r"^snap: "):
        pb.GraphGeometry.from_positions(p, snap=True)
    geom = pb.GraphGeometry.from_positions(p, snap=1e-6)
    assert geom.contacts.t_i.tolist() == [[0.6, 0.8]] and geom.contacts.t_j.tolist() == [[-0.6, -0.8]]


def test_an_edge_of_the_wrong_length_is_refused_where_the_graph_is_given_with_the_radius_that_fits():
    with pytest.raises(pb.FieldError) as info:
        pb.GraphGeometry(hexagonal(2, 2))
    assert str(info.value) == ("graph: edge ((0, 0), (0, 1)) joins balls 1 apart, but touching balls of radius 1 are "
                               "2 apart (relative tolerance 1e-06); every edge is 1 long: "
                               "GraphGeometry(graph, radius=0.5)")
    graph = nx.Graph()
    graph.add_nodes_from([(0, {"pos": (0.0, 0.0)}), (1, {"pos": (2.0, 0.0)}), (2, {"pos": (5.0, 0.0)})])
    graph.add_edges_from([(0, 1), (1, 2)])
    with pytest.raises(pb.FieldError) as info:
        pb.GraphGeometry(graph)
    assert str(info.value) == ("graph: edge (1, 2) joins balls 3 apart, but touching balls of radius 1 are 2 apart "
                               "(relative tolerance 1e-06); its edges have lengths from 2 to 3: "
                               "GraphGeometry.from_positions(positions, radius=...) takes as contacts the pairs "
                               "that touch")
