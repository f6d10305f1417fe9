"""What the tests share: small geometries and states, physics checks in numpy, small run specs,
calling the command line in-process, and running a spec to compare runs bit for bit.

(The plain-Python twin of the engine is `reference.py`; a user's own components, named by specs,
are in `user_components.py`.)
"""

from __future__ import annotations

import contextlib
import copy
import io
import itertools
import json
from pathlib import Path

import networkx as nx
import numpy as np
from hypothesis import settings

import pinnedballs as pb
from pinnedballs.results.load import load
from pinnedballs.run.cli.main import main
from pinnedballs.run.execute import execute
from pinnedballs.specs.run import parse_spec

ROOT = Path(__file__).resolve().parent.parent


def pick_loops(collide, pick, dim: int, flat: bool):
    """The engine's compiled `Loops` for a rule's ``collide`` and a scheduler's ``pick``."""
    from pinnedballs.engine.sequential.loops import loops, pick_selector

    s = pick_selector(pick)
    return loops(collide, s.select, s.begin, s.changed, s.skips, dim, flat)


# ================================================================ small systems and physics checks

#: hypothesis settings for the engine tests: reproducible in CI, no per-example deadline
#: (the first example of a new (rule, scheduler) pair pays numba's compile time).
FAST = settings(max_examples=60, deadline=None, derandomize=True)
SLOWER = settings(max_examples=30, deadline=None, derandomize=True)


# ---------------------------------------------------------------- which compiled loops the tests use

#: The engine compiles one loop per (scheduler, kind of collision, dim, flat), on first use,
#: for stepping (``run(steps=)``) and again for limited runs (a collision target or the freeze).
#: Each costs seconds on a cold cache, so the engine tests keep to these covering sets:
#: stepping gets the full product in flat 2-D (torus, half-plane) and, in 1-D, flat 3-D and
#: curved 3-D, a Latin square (every scheduler and every kind once), so that every pair of
#: factors meets. Kinds: "exchange" (elastic, equal masses), "equal" (restitution < 1, equal
#: masses), "masses" (unequal masses).
KINDS = ("exchange", "equal", "masses")
_ALL = frozenset(KINDS)

#: ``LOOPS[(dim, flat)][scheduler]`` = kinds the tests may step with
LOOPS = {
    (2, True): {"uniform": _ALL, "sweep": _ALL, "random_sweep": _ALL},
    (1, True): {"uniform": {"equal"}, "sweep": {"masses"}, "random_sweep": {"exchange"}},
    (3, True): {"uniform": {"exchange"}, "sweep": {"equal"}, "random_sweep": {"masses"}},
    (3, False): {"uniform": {"masses"}, "sweep": {"exchange"}, "random_sweep": {"equal"}},
}

#: the same for limited runs (``run(collisions=)``, ``run_until_frozen``); also a covering set
LIMITED = {
    (2, True): {"uniform": {"exchange", "masses"}, "sweep": {"exchange"}, "random_sweep": {"equal"}},
    (1, True): LOOPS[(1, True)],
    (3, True): LOOPS[(3, True)],
}


def rule_kind(r: float, unequal: bool) -> str:
    return "masses" if unequal else ("exchange" if r == 1.0 else "equal")


def schedulers_for(dim: int, flat: bool, kind: str, limited: bool = False) -> list[str]:
    """Scheduler names whose compiled loop for this case the tests already use."""
    table = (LIMITED if limited else LOOPS)[(dim, flat)]
    return [name for name, kinds in table.items() if kind in kinds]


SCHEDULER_CLASSES = {"uniform": pb.UniformRandomPair, "sweep": pb.Sweep, "random_sweep": pb.RandomSweep}


# ---------------------------------------------------------------- geometries


def chain(n: int) -> pb.GraphGeometry:
    """``n`` balls on a line, centres 2 apart: a 1-D Newton's cradle (dim 1)."""
    return pb.GraphGeometry.from_positions(2.0 * np.arange(n))


def chain_along(n: int, direction) -> pb.GraphGeometry:
    """``n`` balls on a line along the 2-D unit vector ``direction``, centres 2 apart (dim 2)."""
    return pb.GraphGeometry.from_positions(2.0 * np.arange(n)[:, None] * np.asarray(direction, float))


SQRT3 = float(np.sqrt(3.0))


def triangle() -> pb.GraphGeometry:
    """Three mutually touching balls A (0, 0), B (2, 0), C (1, sqrt 3): contacts AB = 0, AC = 1, BC = 2."""
    return pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0], [1.0, SQRT3]])


def rhombus() -> pb.GraphGeometry:
    """The paper's 4-ball rhombus: two triangles sharing the short diagonal BC.

    Balls A (0, 0), B (2, 0), C (1, sqrt 3), D (3, sqrt 3); contacts AB, AC, BC, BD, CD = 0..4.
    """
    return pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0], [1.0, SQRT3], [3.0, SQRT3]])


#: A moves right into B, B moves up and left: 2 to 6 collisions depending on the order
RHOMBUS_V = np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, 0.0], [0.0, 0.0]])


def fcc_cluster(k: int = 2) -> pb.GraphGeometry:
    """Face-centred cubic cluster (dim 3): points of ``Z^3`` with even coordinate sum, scaled to touch."""
    pts = [p for p in itertools.product(range(k + 1), repeat=3) if sum(p) % 2 == 0]
    return pb.GraphGeometry.from_positions(np.sqrt(2.0) * np.array(pts, dtype=float))


def cubic(k: int = 3) -> pb.GraphGeometry:
    """Simple cubic ``k x k x k`` block, centres 2 apart (dim 3)."""
    return pb.GraphGeometry.from_positions(2.0 * np.array(list(itertools.product(range(k), repeat=3)), float))


def matching(n_pairs: int, dim: int = 1) -> pb.GraphGeometry:
    """``n_pairs`` separate touching pairs along the first axis: contacts share no ball."""
    x = np.empty(2 * n_pairs)
    x[0::2] = 6.0 * np.arange(n_pairs)
    x[1::2] = x[0::2] + 2.0
    p = np.zeros((2 * n_pairs, dim))
    p[:, 0] = x
    return pb.GraphGeometry.from_positions(p)


def two_balls(t_i, t_j) -> pb.GraphGeometry:
    """One contact with the given unit vectors at each end (any dimension, need not be antiparallel).

    When ``t_j`` is not ``-t_i`` the two balls sit as on a curved surface: each node carries a frame
    (the identity) and the graph no metric, so the contact checks leave the directions alone."""
    t_i, t_j = np.asarray(t_i, float), np.asarray(t_j, float)
    curved = not np.array_equal(t_j, -t_i)
    g = nx.Graph()
    for n, pos in enumerate((np.zeros_like(t_i), 2.0 * t_i)):
        g.add_node(n, pos=tuple(pos), **({"frame": np.eye(len(t_i)).tolist()} if curved else {}))
    g.add_edge(0, 1, units={0: tuple(t_i), 1: tuple(t_j)})
    return pb.GraphGeometry(g)


def stated_units(g: nx.Graph) -> nx.Graph:
    """``g`` with each edge's ``"units"`` the straight line between its nodes' ``"pos"``: contacts stated
    as data, of any length (balls at random places are not balls of one radius touching), which
    `GraphGeometry` takes as they are."""
    for u, v, data in g.edges(data=True):
        d = np.asarray(g.nodes[v]["pos"], float) - np.asarray(g.nodes[u]["pos"], float)
        t = d / np.linalg.norm(d)
        data["units"] = {u: tuple(t), v: tuple(-t)}
    return g


def icosahedron_sphere() -> pb.GraphGeometry:
    """12 balls on a sphere at the vertices of an icosahedron, touching along its 30 edges.

    Curved: ``t_i`` is the unit tangent at ``i`` of the great circle towards ``j`` (dim 3,
    ``t_j != -t_i``). Velocities should be tangent (see `tangent_velocities`).
    """
    phi = (1 + 5**0.5) / 2
    pts = []
    for a, b in itertools.product([-1.0, 1.0], repeat=2):
        pts += [(0.0, a, b * phi), (a, b * phi, 0.0), (b * phi, 0.0, a)]
    p = np.array(pts)
    p /= np.linalg.norm(p, axis=1)[:, None]
    g = nx.Graph()
    for k, x in enumerate(p):
        g.add_node(k, pos=tuple(x))
    d = np.linalg.norm(p[:, None] - p[None], axis=-1)
    edge = d[d > 1e-9].min()
    for i, j in zip(*np.nonzero(np.abs(d - edge) < 1e-9)):
        if i < j:
            ti = p[j] - (p[j] @ p[i]) * p[i]
            tj = p[i] - (p[i] @ p[j]) * p[j]
            g.add_edge(int(i), int(j), units={int(i): tuple(ti / np.linalg.norm(ti)),
                                              int(j): tuple(tj / np.linalg.norm(tj))})
    return pb.GraphGeometry(g)


class TorusLessOne(pb.Geometry):
    """A flat torus with its first contact taken out: one row of balls no longer closes
    (`Contacts.closed_rows` is False), the rest is the torus."""

    def __init__(self, rows: int = 4, cols: int = 4):
        self._torus = pb.FlatTorus(rows, cols)
        self.positions, self.radius = self._torus.positions, self._torus.radius

    @property
    def box(self) -> np.ndarray:
        return self._torus.box

    def _build_contacts(self) -> pb.Contacts:
        c = self._torus.contacts
        return pb.Contacts.build(c.pairs[1:], c.ends[1:], c.units)


def tangent_velocities(geom: pb.Geometry, seed: int) -> np.ndarray:
    """Random velocities tangent to the unit sphere at each ball (for `icosahedron_sphere`)."""
    v = np.random.default_rng(seed).standard_normal((geom.n_balls, 3))
    n = geom.positions / np.linalg.norm(geom.positions, axis=1)[:, None]
    return v - np.sum(v * n, axis=1)[:, None] * n


# ---------------------------------------------------------------- numpy physics


def ints(a) -> np.ndarray:
    """Index arrays as signed int64 (contact tables may be unsigned)."""
    return np.asarray(a).astype(np.int64)


def closing_speeds(geom: pb.Geometry, v: np.ndarray) -> np.ndarray:
    """``(n_contacts,)`` closing speeds ``v_i . t_i + v_j . t_j`` computed with numpy."""
    c = geom.contacts
    p = ints(c.pairs)
    return np.einsum("kc,kc->k", v[p[:, 0]], c.t_i) + np.einsum("kc,kc->k", v[p[:, 1]], c.t_j)


def energy(v: np.ndarray, masses=None) -> float:
    m = np.ones(len(v)) if masses is None else np.broadcast_to(np.asarray(masses, float), (len(v),))
    return float(0.5 * np.sum(m * np.einsum("ij,ij->i", v, v)))


def momentum(v: np.ndarray, masses=None) -> np.ndarray:
    m = np.ones(len(v)) if masses is None else np.broadcast_to(np.asarray(masses, float), (len(v),))
    return m @ v


def random_state(geom: pb.Geometry, seed: int, unequal_masses: bool = False):
    """Standard-normal velocities, and masses in [0.5, 2] (or None)."""
    rng = np.random.default_rng(seed)
    v = rng.standard_normal((geom.n_balls, geom.dim))
    m = rng.uniform(0.5, 2.0, geom.n_balls) if unequal_masses else None
    return v, m


# ================================================================ small run specs

TORUS = {
    "geometry": {"kind": "flat_torus", "rows": 4, "cols": 4},
    "initial": {"kind": "single_ball", "ball": 0, "direction": [1, 0], "energy": 100},
    "rule": {"kind": "elastic"},
    "scheduler": {"kind": "uniform_random_pair"},
    "stop": {"steps": 1000},
    "snapshots": {"at_steps": [0, 250, 1000]},
    "seed": 1,
}

HALF_PLANE = {
    "geometry": {"kind": "half_plane", "rows": 6, "cols": 10},
    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
    "stop": {"frozen": True, "max_steps": 10**7},
    "seed": 3,
}


def thin_spec(where: Path) -> dict:
    """A run until frozen whose closing margin is thin: two balls on a line (files in ``where``) closing at
    64 * 2^-53, about 11.3 thresholds of the default criterion; one collision, then frozen."""
    np.save(where / "pair.npy", np.array([[0.0], [2.0]]))
    np.save(where / "pair_v.npy", np.array([[1.0], [1.0 - 64 * 2.0**-53]]))
    return {"geometry": {"kind": "graph_positions", "positions": str(where / "pair.npy")},
            "initial": {"kind": "from_file", "path": str(where / "pair_v.npy")},
            "stop": {"frozen": True, "max_steps": 10}, "seed": 0}


def thin_torus() -> tuple:
    """``(geometry, velocities)``: a 4 x 4 torus moving as one but for ball 0, 64 * 2^-53 faster along x: its
    collisions close within a few thresholds (a thin margin) in every run, and it never freezes."""
    g = pb.FlatTorus(4, 4)
    v = np.tile([1.0, 0.5], (g.n_balls, 1))
    v[0, 0] += 64 * 2.0**-53
    return g, v


#: the first words of what a thin run says (`engine.margin.ClosingMargin.warning`)
THIN = "the closing margin is thin (smallest collision 11.3 thresholds"


def spec(base: dict = TORUS, **changes) -> dict:
    """A deep copy of ``base`` with dotted keys changed (``geometry__rows=6``); ``...`` deletes a key."""
    d = copy.deepcopy(base)
    for dotted, value in changes.items():
        *parents, key = dotted.split("__")
        node = d
        for p in parents:
            node = node[p]
        if value is ...:
            node.pop(key, None)
        else:
            node[key] = value
    return d


def write(path: Path, data: dict) -> Path:
    """Write ``data`` as JSON to ``path``; return ``path``."""
    path.write_text(json.dumps(data))
    return path


# ================================================================ the command line, in-process

def call(*argv) -> tuple[int, str, str]:
    """``(exit status, stdout, stderr)`` of ``pinnedballs ARGV`` run in this process."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def assert_input_error(code: int, err: str, *words: str) -> None:
    assert code == 2
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("pinnedballs: error: ")
    for w in words:
        assert w in lines[0], (w, lines[0])



# ================================================================ directories that cannot be written

def _succeeds(*argv: str) -> bool:
    import subprocess

    return subprocess.run(argv, capture_output=True).returncode == 0


@contextlib.contextmanager
def read_only_dir(where: Path, fill=None):
    """A directory ``where`` on which nothing can be created: a read-only tmpfs if mounting works,
    else an immutable directory (root ignores permissions). ``fill(where)``, if given, writes into
    it first."""
    import os

    where.mkdir()
    if _succeeds("mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(where)):
        try:
            if fill is not None:
                fill(where)
            assert _succeeds("mount", "-o", "remount,ro", str(where))
            yield where
        finally:
            _succeeds("umount", str(where))
        return
    if fill is not None:
        fill(where)
    if _succeeds("chattr", "+i", str(where)):
        try:
            yield where
        finally:
            _succeeds("chattr", "-i", str(where))
    else:
        assert os.getuid() != 0, "as root, a read-only directory needs mount or chattr"
        where.chmod(0o555)
        yield where


# ================================================================ comparing runs bit for bit

def reference(tmp_path: Path, data: dict):
    """The uninterrupted run, in one go with the default chunks."""
    execute(parse_spec(data), tmp_path / "reference", figures=False, progress=False)
    return load(tmp_path / "reference")


def assert_identical(a, b) -> None:
    assert a.complete and b.complete
    assert np.array_equal(a.velocities, b.velocities)
    assert (a.steps, a.collisions, a.stop_reason) == (b.steps, b.collisions, b.stop_reason)
    assert np.array_equal(a.rng_state, b.rng_state) and np.array_equal(a.scheduler_state, b.scheduler_state)
    assert [s[:2] for s in a.snapshots] == [s[:2] for s in b.snapshots]
    assert all(np.array_equal(x.velocities, y.velocities) for x, y in zip(a.snapshots, b.snapshots))
    for name in a.observables:
        assert np.array_equal(a.observables[name], b.observables[name])
    assert a.latest.identical(b.latest)  # the closing margin too, bit for bit
    assert a.closing_margin == b.closing_margin


def frames_of(path) -> list:
    """Every frame of the GSD trajectory at ``path``, read with ``gsd.hoomd``."""
    import gsd.hoomd

    with gsd.hoomd.open(str(path), "r") as t:
        return list(t)


def resume(spec_path: Path, out: Path) -> int:
    return main(["run", str(spec_path), "--out", str(out), "--resume", "--quiet", "--no-figures"])




@contextlib.contextmanager
def pickled_by_value(module):
    """Send ``module``'s functions to Dask workers by value (the workers cannot import a test module)."""
    import pytest

    cloudpickle = pytest.importorskip("cloudpickle")
    cloudpickle.register_pickle_by_value(module)
    try:
        yield
    finally:
        cloudpickle.unregister_pickle_by_value(module)
