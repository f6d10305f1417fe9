"""Hypothesis strategies for pinnedballs' types (needs hypothesis: ``pip install hypothesis``).

`geometries` (any of the others), `lattices` (small built-in lattices and packings), `graphs` (balls
on lattice sites in 1, 2 or 3 dimensions, `GraphGeometry.from_positions`), `velocities`, `masses`,
`rules`, `schedulers` and `run_specs` (small whole runs, as `RunSpec`). Every geometry drawn has at
least one contact, so a `Simulation` can run on it.

Importing this module registers them with hypothesis, so ``st.from_type(pb.Geometry)``,
``st.from_type(pb.CollisionRule)``, ``st.from_type(pb.Scheduler)`` and ``st.from_type(pb.RunSpec)`` draw
from them; installed, the package does it by itself whichever of hypothesis and pinnedballs is
imported first (the ``hypothesis`` entry point, `_pinnedballs_hypothesis`, and the end of
``pinnedballs/__init__.py``).
"""

from __future__ import annotations

import numpy as np
from hypothesis import assume
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ..geometry.base import Geometry
from ..geometry.graph import GraphGeometry
from ..geometry.hyperbolic import HyperbolicPlane
from ..geometry.lattices import ORIENTATIONS, FlatTorus, HalfPlane
from ..geometry.packings import FCC, HCP
from ..geometry.sphere import Sphere
from ..rules import CollisionRule, Elastic, Restitution
from ..schedulers import ColoredSweep, RandomSweep, RejectionFree, Scheduler, Sweep, UniformRandomPair
from ..specs.run import RunSpec, parse_spec
from ..util.errors import FieldError

__all__ = ["geometries", "lattices", "graphs", "velocities", "masses", "rules", "schedulers", "run_specs", "register"]


@st.composite
def _packing(draw) -> Geometry:
    kind = draw(st.sampled_from([FCC, HCP]))
    shape = draw(st.tuples(*[st.integers(1, 3)] * 3))
    periodic = draw(st.tuples(*[st.booleans()] * 3))
    try:
        return kind(*shape, periodic=periodic)
    except FieldError:  # a periodic axis too short to close up
        assume(False)


def lattices() -> st.SearchStrategy[Geometry]:
    """Small built-in lattices: a flat torus, a half-plane (either orientation), an FCC or HCP block."""
    return st.one_of(
        st.builds(FlatTorus, rows=st.sampled_from([4, 6, 8]), cols=st.integers(3, 6)),
        st.builds(HalfPlane, rows=st.integers(1, 5), cols=st.integers(2, 6), orientation=st.sampled_from(ORIENTATIONS)),
        _packing())


def _sites(dim: int) -> np.ndarray:
    """Lattice sites 2 apart (radius 1) in ``dim`` dimensions: a row, a triangular patch, an FCC block."""
    if dim == 1:
        return 2.0 * np.arange(12.0)[:, None]
    if dim == 2:
        return HalfPlane(4, 5).positions
    return FCC(2, 2, 2, periodic=False).positions


def graphs(dim: int) -> st.SearchStrategy[Geometry]:
    """`GraphGeometry.from_positions` of balls of a drawn radius on some sites of a lattice in ``dim``
    (1, 2 or 3) dimensions: contacts wherever two of them touch (at least one)."""
    if dim not in (1, 2, 3):
        raise ValueError(f"dim: must be 1, 2 or 3, got {dim!r}")
    sites = _sites(dim)

    @st.composite
    def draw_graph(draw) -> Geometry:
        keep = np.array(draw(st.lists(st.booleans(), min_size=len(sites), max_size=len(sites))))
        radius = draw(st.sampled_from([1.0, 0.5, 2.5]))
        assume(keep.sum() >= 2)
        g = GraphGeometry.from_positions(radius * sites[keep], radius=radius)
        assume(g.n_contacts >= 1)
        return g

    return draw_graph()


def geometries() -> st.SearchStrategy[Geometry]:
    """Any small geometry: `lattices`, `graphs` in 1 to 3 dimensions, a geodesic sphere, a {3,7} disk."""
    return st.one_of(lattices(), graphs(1), graphs(2), graphs(3),
                     st.builds(Sphere.geodesic, st.integers(1, 3)),
                     st.builds(HyperbolicPlane, st.just(7), st.integers(1, 3)))


def velocities(geometry: Geometry) -> st.SearchStrategy[np.ndarray]:
    """``(n_balls, dim)`` velocities for ``geometry``: components 0 or of magnitude 1e-3 to 1e2."""
    component = st.one_of(st.just(0.0), st.floats(1e-3, 1e2).flatmap(lambda x: st.sampled_from([x, -x])))
    return hnp.arrays(np.float64, (geometry.n_balls, geometry.dim), elements=component)


def masses(n: int) -> st.SearchStrategy[np.ndarray | None]:
    """None (all 1) or ``(n,)`` masses in [0.01, 100]."""
    return st.one_of(st.none(), hnp.arrays(np.float64, (n,), elements=st.floats(0.01, 100.0)))


def rules() -> st.SearchStrategy[CollisionRule]:
    """`Elastic`, or `Restitution` with ``r`` in [0, 1]."""
    return st.one_of(st.builds(Elastic), st.builds(Restitution, st.floats(0.0, 1.0)))


def schedulers() -> st.SearchStrategy[Scheduler]:
    """Any built-in scheduler that runs on any geometry (`Replay` needs an order of its contacts)."""
    return st.one_of(st.builds(UniformRandomPair), st.builds(Sweep), st.builds(RandomSweep), st.builds(RejectionFree),
                     st.builds(ColoredSweep, shuffle=st.booleans()))


_GEOMETRY_SPECS = st.one_of(
    st.fixed_dictionaries({"kind": st.just("flat_torus"), "rows": st.sampled_from([4, 6]), "cols": st.integers(3, 5)}),
    st.fixed_dictionaries({"kind": st.just("half_plane"), "rows": st.integers(1, 4), "cols": st.integers(2, 5),
                           "orientation": st.sampled_from(ORIENTATIONS)}),
    st.fixed_dictionaries({"kind": st.just("sphere"), "frequency": st.integers(1, 2)}),
    st.fixed_dictionaries({"kind": st.just("hyperbolic_plane"), "q": st.just(7), "layers": st.integers(1, 2)}),
    st.fixed_dictionaries({"kind": st.just("fcc"), "nx": st.integers(2, 3), "ny": st.integers(2, 3),
                           "nz": st.integers(1, 2), "periodic": st.just([False, False, False])}))


@st.composite
def run_specs(draw) -> RunSpec:
    """A small whole run as a `RunSpec`: a geometry, Gaussian velocities or one moving ball, a rule, a
    scheduler, a seed, and a stop after up to 10,000 steps or, where it freezes, until frozen."""
    geometry = draw(_GEOMETRY_SPECS)
    initial = draw(st.one_of(
        st.fixed_dictionaries({"kind": st.just("gaussian"), "energy": st.floats(0.1, 100.0)}),
        st.fixed_dictionaries({"kind": st.just("single_ball"), "ball": st.just(0), "energy": st.floats(0.1, 100.0),
                               "direction": st.just([1.0, 0.0] if geometry["kind"] != "fcc" else [1.0, 0.0, 0.0])})))
    rule = draw(st.one_of(st.just({"kind": "elastic"}),
                          st.fixed_dictionaries({"kind": st.just("restitution"), "r": st.floats(0.0, 1.0)})))
    scheduler = {"kind": draw(st.sampled_from(["uniform_random_pair", "sweep", "random_sweep", "rejection_free",
                                               "colored_sweep"]))}
    freezes = geometry["kind"] in ("half_plane", "fcc", "hyperbolic_plane")
    stop = (draw(st.sampled_from([{"steps": draw(st.integers(1, 10_000))}, {"frozen": True, "max_steps": 10**6}]))
            if freezes else {"steps": draw(st.integers(1, 10_000))})
    return parse_spec({"geometry": geometry, "initial": initial, "rule": rule, "scheduler": scheduler, "stop": stop,
                       "seed": draw(st.integers(0, 2**32 - 1))})


def register() -> None:
    """Register the strategies for ``st.from_type`` (done as this module is imported)."""
    st.register_type_strategy(Geometry, geometries())
    st.register_type_strategy(CollisionRule, rules())
    st.register_type_strategy(Scheduler, schedulers())
    st.register_type_strategy(RunSpec, run_specs())


register()
