"""What a user writes cannot corrupt memory or run with wrong numbers (issue 25, item 1).

A geometry built the way docs/extending.md shows (`Contacts.build(pairs, ends, units)`), one thing wrong
at a time: each gets one `FieldError` naming the table and the first offending contact, when the
`Simulation` is built; a scheduler's pick out of range stops the run with an error naming it. Where the
interpreter could die (an index out of range reaches the compiled loop unchecked), the case runs in a
subprocess and the test asserts its exit status and its one line. The compiled checks are held against
a plain-Python twin on damaged tables.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import networkx as nx
import numpy as np
import pytest
from helpers import FAST, ints
from hypothesis import given
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs.geometry import checks
from pinnedballs.schedulers.base import PickOutOfRange

ROOT = Path(__file__).resolve().parents[2]

#: four balls in a row on the x-axis, each touching the next: pairs, ends, units as a user writes them
CHAIN = dict(positions=[[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [6.0, 0.0]], pairs=[[0, 1], [1, 2], [2, 3]],
             ends=[[0, 1], [0, 1], [0, 1]], units=[[1.0, 0.0], [-1.0, -0.0]])


class UserGeometry(pb.Geometry):
    """A user's geometry: `Contacts.build` on the given tables (``direct``: the `Contacts` made by hand)."""

    def __init__(self, positions, pairs, ends, units, direct=False):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.tables, self.direct = (pairs, ends, units), direct

    def _build_contacts(self) -> pb.Contacts:
        if self.direct:
            pairs, ends, units = (np.asarray(x) for x in self.tables)
            return pb.Contacts(pairs=pairs, ends=ends, units=units.astype(np.float64))
        return pb.Contacts.build(*self.tables)


def chain_with(**changes) -> UserGeometry:
    return UserGeometry(**{**CHAIN, **changes})


def simulate(geometry, scheduler=None) -> pb.Simulation:
    return pb.Simulation(geometry, np.ones((geometry.n_balls, geometry.dim)), scheduler=scheduler, seed=0)


def test_the_sound_chain_runs():
    sim = simulate(chain_with())
    sim.run(steps=100)
    assert sim.steps == 100


# ---------------------------------------------------------------- the table, where a crash was possible

CHILD = """
import sys
import numpy as np
import pinnedballs as pb
from numba import njit

class UserGeometry(pb.Geometry):
    def __init__(self, positions, pairs, ends, units, direct):
        self.positions = np.asarray(positions, dtype=np.float64)
        self.tables, self.direct = (pairs, ends, units), direct
    def _build_contacts(self):
        if self.direct:
            pairs, ends, units = (np.asarray(x) for x in self.tables)
            return pb.Contacts(pairs=pairs, ends=ends, units=units.astype(np.float64))
        return pb.Contacts.build(*self.tables)

@njit
def pick_given(state, rng, n_contacts):
    return np.int64(PICK), rng

class UserPick(pb.Scheduler):
    def kernel(self):
        return pick_given

try:
    g = UserGeometry(POSITIONS, PAIRS, ENDS, UNITS, DIRECT)
    pick = PICK
    sim = pb.Simulation(g, np.ones((len(g.positions), 2)), scheduler=UserPick() if pick is not None else None, seed=0)
    sim.run(steps=1000)
except ValueError as error:
    print(error)
    sys.exit(2)
print("ran")
"""


def run_child(pick=None, direct=False, **changes) -> subprocess.CompletedProcess:
    t = {**CHAIN, **changes}
    code = CHILD.replace("PICK", repr(pick)).replace("DIRECT", repr(direct))
    for name in ("positions", "pairs", "ends", "units"):
        code = code.replace(name.upper(), repr(t[name]))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                          env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"})


CRASHES = {
    "far out of range": (dict(pairs=[[0, 1], [1, 10**6], [2, 3]]),
                         "pairs: contact 1 has balls (1, 1000000), but there are 4 balls (0 to 3)"),
    "negative": (dict(pairs=[[0, 1], [-1, 2], [2, 3]]),
                 "pairs: contact 1 has balls (-1, 2): ball indices are whole numbers from 0 (below 2**32)"),
    "negative, Contacts made by hand": (dict(pairs=[[0, 1], [-1, 2], [2, 3]], direct=True),
                                        "pairs: contact 1 has balls (-1, 2), but there are 4 balls (0 to 3)"),
    "just out of range": (dict(pairs=[[0, 1], [1, 2], [2, 4]]),
                          "pairs: contact 2 has balls (2, 4), but there are 4 balls (0 to 3)"),
    "an end out of range, Contacts made by hand": (dict(ends=[[0, 1], [0, 9], [0, 1]], direct=True),
                                                   "ends: contact 1 has ends (0, 9), but units has 2 rows (0 to 1)"),
    "a pick out of range": (dict(pick=3), "scheduler: UserPick.kernel()'s pick 'pick_given' picked contact 3, but "
                                          "there are 3 contacts (0 to 2)"),
    "a negative pick": (dict(pick=-1), "scheduler: UserPick.kernel()'s pick 'pick_given' picked contact -1, but "
                                       "there are 3 contacts (0 to 2)"),
}


@pytest.mark.slow
@pytest.mark.parametrize("case", list(CRASHES))
def test_what_could_crash_the_interpreter_is_one_line_instead(case):
    changes, line = CRASHES[case]
    out = run_child(**changes)
    assert (out.returncode, out.stdout.strip()) == (2, line), out.stderr[-2000:]


@pytest.mark.slow
def test_the_child_runs_the_sound_chain():
    """The subprocess harness itself: the sound chain runs (exit 0), so exit 2 above is the error's."""
    out = run_child()
    assert (out.returncode, out.stdout.strip()) == (0, "ran"), out.stderr[-2000:]


# ---------------------------------------------------------------- the rest of the table, in process

ERRORS = {
    "units of length 2": (dict(units=[[2.0, 0.0], [-1.0, 0.0]]),
                          "units: contact 0 (balls (0, 1)): t_i = (2, 0) has length 2, not 1 (tolerance 1e-12)"),
    "NaN in a unit vector": (dict(units=[[1.0, 0.0], [math.nan, 0.0]]),
                             "units: contact 0 (balls (0, 1)): t_j = (nan, 0) is not finite"),
    "a ball touching itself": (dict(pairs=[[0, 1], [1, 1], [2, 3]]), "pairs: contact 1 joins ball 1 to itself"),
    "a contact listed twice": (dict(pairs=[[0, 1], [1, 2], [2, 3], [2, 1]], ends=[[0, 1]] * 4),
                               "pairs: contact 3 repeats contact 1: balls (2, 1)"),
    "a normal pointing away": (dict(units=[[-1.0, 0.0], [1.0, 0.0]]),
                               "units: contact 0 (balls (0, 1)): t_i = (-1, 0) points away from ball 1: "
                               "t_i . (x_j - x_i) <= 0"),
    "balls not touching": (dict(positions=[[0.0, 0.0], [2.0, 0.0], [4.0, 0.0], [6.5, 0.0]]),
                           "pairs: contact 2 joins balls (2, 3) 2.5 apart, but touching balls of radius 1 are 2 "
                           "apart (relative tolerance 1e-06)"),
    "an end out of range": (dict(ends=[[0, 1], [0, 2], [0, 1]]),
                            "ends: contact 1 has ends (0, 2), but units has 2 rows (0 to 1)"),
    "a ball index that is not whole": (dict(pairs=[[0, 1], [1, 2.5], [2, 3]]),
                                       "pairs: contact 1 has (1.0, 2.5): ball indices must be whole numbers"),
    "pairs of three balls": (dict(pairs=[[0, 1, 2]], ends=[[0, 1]]), "pairs: must have shape (n_contacts, 2), "
                                                                     "got (1, 3)"),
}


@pytest.mark.parametrize("case", list(ERRORS))
def test_each_bad_table_is_one_error_naming_it_and_the_contact(case):
    changes, line = ERRORS[case]
    with pytest.raises(pb.FieldError) as info:
        simulate(chain_with(**changes))
    assert str(info.value) == line
    assert info.value.field == line.split(":")[0]


def test_a_negative_index_in_an_integer_array_does_not_wrap():
    """numpy would wrap -1 to 4294967295 when narrowing to uint32: the raw tables are checked first."""
    with pytest.raises(pb.FieldError, match=r"^pairs: contact 1 has balls \(-1, 2\): ball indices are whole numbers"):
        simulate(chain_with(pairs=np.array([[0, 1], [-1, 2], [2, 3]], dtype=np.int64)))
    with pytest.raises(pb.FieldError, match=r"^ends: contact 2 has ends \(-1, 1\), but units has 2 rows"):
        simulate(chain_with(ends=np.array([[0, 1], [0, 1], [-1, 1]], dtype=np.int64)))


def test_the_first_offending_contact_is_named():
    """Contact 2 points away and contact 1 has a NaN: contact 1 is named (the lowest index)."""
    g = UserGeometry(CHAIN["positions"], CHAIN["pairs"], [[0, 1], [2, 3], [4, 5]],
                     [[1.0, 0.0], [-1.0, 0.0], [math.nan, 0.0], [-1.0, 0.0], [-1.0, 0.0], [1.0, 0.0]])
    with pytest.raises(pb.FieldError, match=r"^units: contact 1 \(balls \(1, 2\)\): t_i = \(nan, 0\) is not finite$"):
        simulate(g)


def test_a_repeat_before_another_fault_is_named_first():
    g = chain_with(pairs=[[0, 1], [1, 0], [2, 2]])
    with pytest.raises(pb.FieldError, match=r"^pairs: contact 1 repeats contact 0: balls \(1, 0\)$"):
        simulate(g)


def test_a_graph_edge_of_the_wrong_length():
    g = nx.Graph()
    g.add_node(0, pos=(0.0, 0.0))
    g.add_node(1, pos=(3.0, 0.0))
    g.add_edge(0, 1)
    with pytest.raises(pb.FieldError, match=r"^graph: edge \(0, 1\) joins balls 3 apart, but touching balls of "
                                            r"radius 1 are 2 apart \(relative tolerance 1e-06\); every edge is 3 "
                                            r"long: GraphGeometry\(graph, radius=1\.5\)$"):
        pb.GraphGeometry(g)  # refused where it is given (tests/geometry/test_graph.py), before any simulation
    simulate(pb.GraphGeometry(g, radius=1.5))  # touching at radius 1.5
    simulate(pb.GraphGeometry(g, rtol=0.6))     # or within a tolerance the user states


def test_a_torus_graph_keeps_its_contacts_across_the_boundary_but_not_a_flipped_one():
    """Edges with "units" across the periodic boundary (their segment runs through the box) are taken as
    stated; a flipped unit vector on an edge whose segment is the contact is caught."""
    graph = pb.FlatTorus(4, 3).contact_graph()
    simulate(pb.GraphGeometry(graph))
    u, v, data = next((u, v, d) for u, v, d in graph.edges(data=True) if d["pair"] == (0, 1))
    data["units"] = {n: tuple(-x for x in t) for n, t in data["units"].items()}
    with pytest.raises(pb.FieldError, match=r"^units: contact 0 \(balls \(0, 1\)\): t_i = \(-1, -0\) points away "
                                            r"from ball 1: t_i \. \(x_j - x_i\) <= 0$"):
        simulate(pb.GraphGeometry(graph))


@pytest.mark.parametrize("make", [lambda: pb.Sphere.geodesic(2), lambda: pb.HyperbolicPlane(7, 2)],
                         ids=["sphere", "hyperbolic"])
def test_on_a_curved_surface_a_tangent_pointing_away_is_caught_in_its_frame(make):
    """The geometry's own metric measures the direction (Euclidean on the sphere, Minkowski on the
    hyperboloid: with the Euclidean one, 817 of the {3,7} disk's contacts would look reversed)."""
    geom = make()
    graph = geom.contact_graph()
    simulate(pb.GraphGeometry(graph))
    u, v, data = next((u, v, d) for u, v, d in graph.edges(data=True) if d["contact"] == 3)
    i = data["pair"][0]
    data["units"][i] = tuple(-x for x in data["units"][i])
    with pytest.raises(pb.FieldError, match=r"^units: contact 3 \(balls \(\d+, \d+\)\): t_i = \(.*\) points away from "
                                            r"ball \d+ \(in its tangent frame\): t_i \. \(x_j - x_i\) <= 0$"):
        simulate(pb.GraphGeometry(graph))


def test_a_curved_graph_without_a_metric_is_not_measured():
    """Frames alone do not say sphere or hyperboloid: without the graph's "metric", directions are left alone."""
    graph = pb.HyperbolicPlane(7, 2).contact_graph()
    del graph.graph["metric"]
    for _, _, data in graph.edges(data=True):
        data["units"] = {n: tuple(-x for x in t) for n, t in data["units"].items()}
    simulate(pb.GraphGeometry(graph))


def test_bad_metric_attribute_is_refused():
    graph = pb.Sphere.geodesic(1).contact_graph()
    graph.graph["metric"] = (1.0, 2.0, 1.0)
    with pytest.raises(pb.FieldError, match=r"^graph: its 'metric' attribute must be 3 signs \(1 or -1\), got "):
        pb.GraphGeometry(graph)


def test_the_verdict_is_kept_on_the_contacts(monkeypatch):
    """A second simulation on the same geometry does not check again; another geometry does."""
    geom = pb.HalfPlane(4, 5)
    simulate(geom)

    def refuse(*args):
        raise AssertionError("checked again")

    monkeypatch.setattr(checks, "_first_fault", refuse)
    simulate(geom)
    with pytest.raises(AssertionError, match="checked again"):
        simulate(pb.HalfPlane(4, 5))


# ---------------------------------------------------------------- a user's pick is checked, the project's are not


class UserSweep(pb.Scheduler):
    def kernel(self):
        return pick_sweep_of_a_user


from numba import njit  # noqa: E402  (the user's pick, at module level as numba needs)


@njit
def pick_sweep_of_a_user(state, rng, n_contacts):
    k = state[0]
    state[0] = k + 1 if k + 1 < n_contacts else 0
    return np.uint64(k), rng


def test_a_users_pick_is_wrapped_and_the_projects_are_not():
    geom = pb.HalfPlane(3, 3)
    own = pb.Sweep().selector(geom).select.py_func.__closure__[0].cell_contents
    users = UserSweep().selector(geom).select.py_func.__closure__[0].cell_contents
    assert own is pb.Sweep().kernel()
    assert users is not pick_sweep_of_a_user and users.py_func.__name__ == "checked"


def test_a_users_pick_in_range_runs_as_the_projects():
    """The wrapper changes nothing but the check: the user's sweep gives Sweep's bits."""
    geom = pb.HalfPlane(3, 4)
    v = np.random.default_rng(1).normal(size=(geom.n_balls, 2))
    runs = [pb.Simulation(geom, v, scheduler=s, seed=2) for s in (pb.Sweep(), UserSweep())]
    for sim in runs:
        sim.run(steps=777)
    assert np.array_equal(runs[0].velocities, runs[1].velocities) and runs[0].collisions == runs[1].collisions


def test_pick_out_of_range_pickles():
    import pickle

    error = pickle.loads(pickle.dumps(PickOutOfRange("X's pick", 5, 4)))
    assert isinstance(error, pb.FieldError) and str(error) == ("scheduler: X's pick picked contact 5, but there are "
                                                               "4 contacts (0 to 3)")


# ---------------------------------------------------------------- the compiled checks against a plain-Python twin


def twin_verdict(pairs, ends, units, positions, contact=2.0, rtol=1e-6):
    """Plain Python, flat space without periodic images: ``(table, contact)`` of the first fault, or None."""
    n, seen = len(positions), {}
    for e, ((i, j), (a, b)) in enumerate(zip(pairs, ends)):
        if not (0 <= i < n and 0 <= j < n):
            return "pairs", e
        if not (0 <= a < len(units) and 0 <= b < len(units)):
            return "ends", e
        if i == j:
            return "pairs", e
        key = (min(i, j), max(i, j))
        if key in seen:
            return "pairs", e
        seen[key] = e
        for row in (a, b):
            if not abs(math.sqrt(sum(x * x for x in units[row])) - 1.0) <= 1e-12:
                return "units", e
        d = [positions[j][c] - positions[i][c] for c in range(len(positions[0]))]
        if not abs(math.sqrt(sum(x * x for x in d)) - contact) <= rtol * contact:
            return "pairs", e
        if not sum(t * x for t, x in zip(units[a], d)) > 0 or not sum(-t * x for t, x in zip(units[b], d)) > 0:
            return "units", e
    return None


@st.composite
def damaged_chains(draw):
    """A chain of 3..12 balls on the x-axis with one to three of its entries damaged."""
    n = draw(st.integers(3, 12))
    positions = [[2.0 * k, 0.0] for k in range(n)]
    pairs = [[k, k + 1] for k in range(n - 1)]
    units = [[1.0, 0.0], [-1.0, 0.0], [0.6, 0.8], [2.0, 0.0], [math.nan, 0.0], [-1.0, 0.0]]
    ends = [[0, 1] for _ in pairs]
    for _ in range(draw(st.integers(1, 3))):
        e = draw(st.integers(0, len(pairs) - 1))
        what = draw(st.sampled_from(["ball", "end", "swap", "repeat"]))
        if what == "ball":
            pairs[e][draw(st.integers(0, 1))] = draw(st.integers(0, n + 2))
        elif what == "end":
            ends[e][draw(st.integers(0, 1))] = draw(st.integers(0, len(units)))
        elif what == "swap":
            pairs[e] = pairs[e][::-1]
        else:
            pairs.append(list(pairs[e]))
            ends.append([0, 1])
    return positions, pairs, ends, units


@FAST
@given(damaged_chains())
def test_compiled_checks_agree_with_the_twin(case):
    positions, pairs, ends, units = case
    expected = twin_verdict(pairs, ends, units, positions)
    g = UserGeometry(positions, pairs, ends, units, direct=True)
    if expected is None:
        checks.check_contacts(g)
        return
    with pytest.raises(pb.FieldError) as info:
        checks.check_contacts(g)
    assert (info.value.field, int(str(info.value).split("contact ")[1].split()[0])) == expected, str(info.value)


def test_big_lattices_pass_and_their_tables_are_untouched():
    """The checks read the tables and write nothing (the compiled loop reads them next)."""
    for geom in (pb.FCC(4, 4, 4, periodic=(True, False, True)), pb.HCP(3, 3, 3), pb.FlatTorus(8, 6),
                 pb.HalfPlane(6, 7, orientation="across")):
        c = geom.contacts
        before = (ints(c.pairs).copy(), ints(c.ends).copy(), c.units.copy())
        checks.check_contacts(geom)
        assert np.array_equal(before[0], ints(c.pairs)) and np.array_equal(before[1], ints(c.ends))
        assert np.array_equal(before[2], c.units)


def test_raw_tables_name_the_table_before_narrowing():
    with pytest.raises(pb.FieldError, match=r"^pairs: contact 0 has balls \(4294967296, 1\): ball indices"):
        pb.Contacts.build([[2**32, 1]], [[0, 1]], [[1.0, 0.0], [-1.0, 0.0]])
    with pytest.raises(pb.FieldError, match=r"^ends: must have one row per contact: 2 pairs but 1 ends$"):
        pb.Contacts.build([[0, 1], [1, 2]], [[0, 1]], [[1.0, 0.0], [-1.0, 0.0]])
    with pytest.raises(pb.FieldError, match=r"^units: must have shape \(n_units, dim\), got \(2,\)$"):
        pb.Contacts.build([[0, 1]], [[0, 1]], [1.0, 0.0])
    with pytest.raises(pb.FieldTypeError, match=r"^ends: must be rows of units \(integers\), got dtype <U1$"):
        pb.Contacts.build([[0, 1]], [["a", "b"]], [[1.0, 0.0], [-1.0, 0.0]])
