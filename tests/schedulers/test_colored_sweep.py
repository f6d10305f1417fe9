"""ColoredSweep: colour classes are matchings, a sweep is their replay, threads change no bit.

Bit-level agreement with the plain-Python twin (contact by contact) is in
`test_kernel_vs_reference.py`; here the colouring, a NumPy replay of one parallel
sweep, and runs on 1 and 2 numba threads in separate processes.
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import TORUS, matching, spec

import pinnedballs as pb
from pinnedballs.specs import parse_spec

ROOT = Path(__file__).resolve().parents[2]


def fcc_block(n: int) -> pb.GraphGeometry:
    """Open FCC block: points of Z^3 in [0, 2n)^3 with even coordinate sum, scaled to touch (degree 12 inside)."""
    pts = [p for p in itertools.product(range(2 * n), repeat=3) if sum(p) % 2 == 0]
    return pb.GraphGeometry.from_positions(np.sqrt(2.0) * np.array(pts, dtype=float))


GEOMETRIES = {
    "torus 38x38": (lambda: pb.FlatTorus(38, 38), 7),
    "torus 10x11 (odd cycles)": (lambda: pb.FlatTorus(10, 11), 7),
    "half-plane 29x50": (lambda: pb.HalfPlane(rows=29, cols=50), 7),
    "fcc 4x4x4": (lambda: fcc_block(4), 13),
}


@pytest.mark.parametrize("name", GEOMETRIES)
def test_classes_are_matchings_covering_every_contact_once(name):
    make, bound = GEOMETRIES[name]
    geom = make()
    classes = pb.ColoredSweep.classes(geom)
    pairs = geom.contacts.pairs.astype(np.int64)
    degree = np.bincount(pairs.ravel()).max()
    assert degree <= len(classes) <= bound  # at least the degree; at most the bound of the issue
    every = np.concatenate(classes)
    assert np.array_equal(np.sort(every), np.arange(geom.n_contacts))  # each contact exactly once
    for c in classes:
        balls = pairs[c].ravel()
        assert len(np.unique(balls)) == len(balls)  # no ball twice: a matching
        assert np.all(np.diff(pairs[c].min(axis=1)) > 0)  # sorted by the smaller ball, for locality


def numpy_sweep(geom, v, classes):
    """One sweep replayed class by class with NumPy (equal masses, elastic): the closing speed
    summed component by component, ``v_i -= w t_i``, ``v_j -= w t_j`` where ``w > 0``."""
    v = v.copy()
    c, collisions = geom.contacts, 0
    p = c.pairs.astype(np.int64)
    for k in classes:
        i, j, ti, tj = p[k, 0], p[k, 1], c.t_i[k], c.t_j[k]
        w = v[i, 0] * ti[:, 0] + v[j, 0] * tj[:, 0]
        for d in range(1, geom.dim):
            w = w + (v[i, d] * ti[:, d] + v[j, d] * tj[:, d])
        hit = w > 0
        new_i, new_j = v[i] - w[:, None] * ti, v[j] - w[:, None] * tj
        changed = hit & (np.any(new_i != v[i], axis=1) | np.any(new_j != v[j], axis=1))
        v[i[hit]], v[j[hit]] = new_i[hit], new_j[hit]
        collisions += int(changed.sum())
    return v, collisions


@pytest.mark.parametrize("make", [lambda: pb.FlatTorus(30, 40), lambda: pb.HalfPlane(rows=12, cols=15)],
                         ids=["torus", "half-plane"])
def test_one_sweep_equals_a_numpy_replay_of_the_classes(make):
    geom = make()
    v = np.random.default_rng(8).normal(size=(geom.n_balls, 2))
    sim = pb.Simulation(geom, v, scheduler=pb.ColoredSweep(), seed=0)
    expected, collisions = numpy_sweep(geom, v, pb.ColoredSweep.classes(geom))
    assert sim.run(steps=geom.n_contacts) == geom.n_contacts
    assert np.array_equal(sim.velocities, expected)
    assert sim.collisions == collisions > geom.n_contacts // 10


def test_steps_count_contacts_tried():
    """Separate approaching pairs: each contact collides when tried, so k steps make k collisions."""
    geom = matching(50, dim=2)
    v = np.zeros((100, 2))
    v[0::2, 0], v[1::2, 0] = 1.0, -1.0
    sim = pb.Simulation(geom, v, scheduler=pb.ColoredSweep(shuffle=True), seed=1)
    assert len(pb.ColoredSweep.classes(geom)) == 1
    sim.run(steps=17)
    assert sim.collisions == 17
    sim.run(steps=33)
    assert sim.collisions == 50 and sim.is_frozen()


_CHILD = r"""
import json, sys
import numba, numpy as np
import pinnedballs as pb
geom = pb.FlatTorus(200, 150)
v = np.random.default_rng(5).normal(size=(geom.n_balls, 2))
sim = pb.Simulation(geom, v, scheduler=pb.ColoredSweep(shuffle=sys.argv[1] == "shuffle"), seed=3)
sim.run(steps=10 * geom.n_contacts + 12_345)
sim.run(collisions=sim.collisions + 1000)
from pinnedballs.schedulers import colored_sweep
colored_sweep.TUNED_SEGMENT = 20_011                    # a tuned run: segments on 2 threads and on 1
sim.run(steps=50 * colored_sweep.TUNED_SEGMENT)
print(json.dumps(dict(threads=numba.get_num_threads(), steps=sim.steps, collisions=sim.collisions,
                      v=sim.velocities.view(np.uint64).tolist())))
"""


def run_with_threads(threads: int, shuffle: str) -> dict:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_NUM_THREADS": str(threads)}
    out = subprocess.run([sys.executable, "-c", _CHILD, shuffle], env=env, capture_output=True, text=True,
                         check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.parametrize("shuffle", ["fixed", "shuffle"])
def test_same_bits_on_one_and_two_threads(shuffle):
    """A 30,000-ball torus, 10 sweeps and a bit, then 1,000 more collisions, then a run whose
    segments the thread tuner runs on 2 threads and on 1: the same bits of every velocity with
    NUMBA_NUM_THREADS=1 and 2."""
    one, two = run_with_threads(1, shuffle), run_with_threads(2, shuffle)
    assert (one["threads"], two["threads"]) == (1, 2)
    assert one["collisions"] > 100_000
    assert (one["steps"], one["collisions"]) == (two["steps"], two["collisions"])
    assert one["v"] == two["v"]


def test_shuffle_draws_a_fresh_class_order_each_sweep():
    """With shuffle, 40 sweeps on a 6-class torus give many different first classes; without, never."""
    geom = pb.FlatTorus(8, 8)
    firsts = {True: set(), False: set()}
    for shuffle in (True, False):
        sim = pb.Simulation(geom, np.zeros((geom.n_balls, 2)), scheduler=pb.ColoredSweep(shuffle=shuffle), seed=4)
        for _ in range(40):
            sim.run(steps=1)
            firsts[shuffle].add(_first_class(sim))
            sim.run(steps=geom.n_contacts - 1)
    assert len(firsts[True]) >= 4 and firsts[False] == {0}


def _first_class(sim) -> int:
    """The class now running, from the replayed order of the state (slot 0 after one step)."""
    from pinnedballs.schedulers.colored_sweep import class_order

    state = sim.get_state().scheduler_state
    assert state[0] == 0 and state[1] == 1
    return int(class_order(state, len(pb.ColoredSweep.classes(sim.geometry)), sim.scheduler.shuffle)[0])


def test_state_is_checked():
    geom = pb.FlatTorus(8, 8)
    sim = pb.Simulation(geom, np.zeros((geom.n_balls, 2)), scheduler=pb.ColoredSweep(), seed=4)
    state = sim.get_state()
    for bad, message in [([6, 0, 0, 0, 0, 0], "scheduler_state: class slot 6 is beyond the 6 classes"),
                         ([0, 32, 0, 0, 0, 0], "scheduler_state: offset 32 is beyond the 32 contacts of its class"),
                         ([-1, 3, 0, 0, 0, 0], "scheduler_state: the position in the sweep must be"),
                         ([0, 0], r"scheduler_state: must have shape \(6,\) for ColoredSweep\(shuffle=False\)")]:
        with pytest.raises(ValueError, match=message):
            sim.set_state(state.replace(scheduler_state=np.array(bad, dtype=np.int64)))
    with pytest.raises(TypeError, match="shuffle: must be True or False, got 1"):
        pb.ColoredSweep(shuffle=1)


def test_spec_kind_builds_it():
    assert parse_spec(spec(TORUS, scheduler={"kind": "colored_sweep"})).build().scheduler == pb.ColoredSweep()
    built = parse_spec(spec(TORUS, scheduler={"kind": "colored_sweep", "shuffle": True})).build().scheduler
    assert built == pb.ColoredSweep(shuffle=True) and built != pb.ColoredSweep()
    built = parse_spec(spec(TORUS, scheduler={"kind": "colored_sweep", "threads": 1})).build().scheduler
    assert built == pb.ColoredSweep(threads=1) and built.to_spec() == {"kind": "colored_sweep", "shuffle": False,
                                                                       "threads": 1}
    with pytest.raises(pb.SpecError, match=r"scheduler\.threads"):
        parse_spec(spec(TORUS, scheduler={"kind": "colored_sweep", "threads": 0}))
