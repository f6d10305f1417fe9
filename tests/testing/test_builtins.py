"""The project runs the kit's checks on its own components: every built-in geometry, rule and
scheduler, each check a test (`pinnedballs.testing.parametrize_with_checks`)."""

from __future__ import annotations

import numpy as np

import pinnedballs as pb
from pinnedballs.testing import checks_for, parametrize_with_checks


def _on_sphere(n: int) -> np.ndarray:
    x = np.random.default_rng(0).normal(size=(n, 3))
    return x / np.linalg.norm(x, axis=1, keepdims=True)


GEOMETRIES = [pb.FlatTorus(4, 3), pb.HalfPlane(3, 4), pb.HalfPlane(3, 4, orientation="across"), pb.FCC(2, 2, 2),
              pb.FCC(2, 2, 2, periodic=(True, True, False)), pb.HCP(3, 3, 2, periodic=(True, True, False)),
              pb.Sphere.geodesic(2), pb.Sphere.from_points(_on_sphere(30)),
              pb.HyperbolicPlane(7, 2), pb.GraphGeometry.from_positions(pb.HalfPlane(3, 3).positions),
              pb.GraphGeometry(pb.Sphere.geodesic(1).contact_graph()),
              pb.GraphGeometry(pb.FlatTorus(4, 3).contact_graph())]
RULES = [pb.Elastic(), pb.Restitution(0.5), pb.Restitution(0.0)]
#: a Replay order long enough for every check: 40,000 picks among the 23 contacts of the 3 x 4 half-plane
SCHEDULERS = [pb.UniformRandomPair(), pb.Sweep(), pb.RandomSweep(), pb.RejectionFree(), pb.ColoredSweep(),
              pb.ColoredSweep(shuffle=True), pb.Replay(np.random.default_rng(1).integers(0, 23, 40_000))]


def expected_failures(component) -> dict[str, str]:
    """A torus given as a bare graph cannot know its box: its contacts across the boundary are far apart."""
    if isinstance(component, pb.GraphGeometry) and component.n_contacts == 3 * component.n_balls:
        return {"check_contacts_are_touching_pairs": "a torus's contact graph does not know its periodic box"}
    return {}


@parametrize_with_checks(GEOMETRIES + RULES + SCHEDULERS, expected_failed_checks=expected_failures)
def test_builtin_component(component, check):
    check(component)


def test_every_builtin_gets_every_check_that_applies():
    """The laws, exact forms and specs each built-in claims put their checks in its battery."""
    names = {repr(c): {f.__name__ for f in checks_for(c)} for c in GEOMETRIES + RULES + SCHEDULERS}
    assert "check_scheduler_law" in names["UniformRandomPair()"] and "check_scheduler_law" in names["RejectionFree()"]
    assert "check_scheduler_law" not in names[repr(SCHEDULERS[-1])]  # Replay claims no law
    assert {"check_exact_agrees", "check_restitution_law", "check_energy_conserved_if_elastic"} <= names["Elastic()"]
    assert "check_energy_conserved_if_elastic" not in names["Restitution(0.5)"]
    assert "check_contacts_are_touching_pairs" not in names[repr(GEOMETRIES[6])]  # a sphere: curved
    assert "check_boundary" in names[repr(GEOMETRIES[1])] and "check_boundary" not in names[repr(GEOMETRIES[0])]
    assert "check_geometry_spec_round_trip" not in names[repr(GEOMETRIES[9])]  # a graph has no spec
