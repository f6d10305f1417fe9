"""What a lattice costs in memory beyond its tables (issue 34, item 11), counted by tracemalloc, never timed.

A triangular lattice's tables are built a chunk of balls at a time (`lattices._CHUNK`), so their
temporaries do not grow with the lattice; its `LatticeContacts` know `flat` and `closed_rows` from the
construction, so neither a `Simulation` nor a torus's ``run_until_frozen`` builds ``(E, 2)`` float64 or
int64 tables; the contact checks' scratch is uint32 (`checks._first_repeat`). Before: 155 MB of
temporaries for the 30 MB of a 1000x1000 torus's tables, 100 MB more to build its simulation
(`Contacts.flat`), 440 MB for its first ``run_until_frozen`` (`Contacts.closed_rows`).
"""

from __future__ import annotations

import tracemalloc
import warnings

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.geometry.base import Contacts
from pinnedballs.geometry.lattices import _CHUNK, LatticeContacts

MB = 1 << 20


def _traced(make):
    """``(result, peak bytes above the start)`` of ``make()`` under tracemalloc."""
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        result = make()
        return result, tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()


def _tables(c: Contacts) -> int:
    return c.pairs.nbytes + c.ends.nbytes + c.units.nbytes


@pytest.mark.parametrize("make", [lambda s: pb.FlatTorus(2 * s, 300), lambda s: pb.HalfPlane(2 * s, 300)],
                         ids=["torus", "half-plane"])
def test_building_a_lattice_takes_a_chunk_of_temporaries_whatever_its_size(make):
    """Beyond its positions and tables, what one chunk of balls takes (about 9 MB), at 4 chunks as at 8."""
    def built(size):
        geom = make(size)
        _ = geom.contacts
        return geom

    extras = []
    for size in (2 * _CHUNK // 300, 4 * _CHUNK // 300):
        geom, peak = _traced(lambda size=size: built(size))
        extras.append(peak - _tables(geom.contacts) - geom.positions.nbytes)
    assert max(extras) < 12 * MB and abs(extras[1] - extras[0]) < MB, [x / MB for x in extras]
    # (whole-lattice temporaries: 4 times the tables, 18 and 37 MB here)


@pytest.mark.parametrize("geom", [pb.FlatTorus(4, 3), pb.FlatTorus(6, 5), pb.FlatTorus(12, 9), pb.HalfPlane(1, 1),
                                  pb.HalfPlane(1, 4), pb.HalfPlane(5, 1), pb.HalfPlane(7, 6),
                                  pb.HalfPlane(7, 6, orientation="across")],
                         ids=lambda g: repr(g))
def test_lattice_contacts_know_what_the_tables_say(geom):
    """`LatticeContacts.flat` and `closed_rows` are `Contacts`'s, computed from every contact."""
    c = geom.contacts
    assert isinstance(c, LatticeContacts)
    assert c.flat == Contacts.flat.func(c) and c.closed_rows == Contacts.closed_rows.func(c)
    assert c.closed_rows == isinstance(geom, pb.FlatTorus)


def test_a_simulation_on_a_lattice_builds_no_table_of_unit_vectors():
    """Its velocities, masses and the checks' uint32 scratch (4 bytes a contact and 12 a ball): no (E, 2)
    float64 table of t_i or t_j (16 bytes a contact each), no int64 scratch."""
    pb.Simulation(pb.FlatTorus(4, 4), np.ones((16, 2)), seed=0)  # the checks' kernels loaded outside the count
    geom = pb.FlatTorus(600, 600)
    n, e = geom.n_balls, geom.n_contacts
    v = np.zeros((n, 2))
    v[0, 0] = 1.0
    _, peak = _traced(lambda: pb.Simulation(geom, v, seed=0))
    assert peak < 16 * n + 8 * n + 12 * n + 4 * e + 2 * MB, peak / MB


def test_a_torus_says_it_never_freezes_without_reading_its_tables():
    """`closed_rows`, asked by ``run_until_frozen`` on a torus, from the construction."""
    geom = pb.FlatTorus(600, 600)
    v = np.zeros((geom.n_balls, 2))
    v[0, 0] = 1.0
    sim = pb.Simulation(geom, v, seed=0)
    sim.run(steps=10)  # the loop and the row pattern made outside the count, and the freeze scan below
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pb.Simulation(pb.FlatTorus(4, 4), np.ones((16, 2)), seed=0).run_until_frozen(max_steps=10)
        _, peak = _traced(lambda: sim.run_until_frozen(max_steps=10))
    assert peak < MB, peak / MB
