"""The kit's hypothesis strategies draw what they promise, hypothesis finds them through ``st.from_type``
whichever of hypothesis and pinnedballs is imported first, and the kit imports without pytest or
hypothesis (only the parts that need them do not)."""

from __future__ import annotations

import importlib.metadata
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs.specs.run import parse_spec
from pinnedballs.testing import check_contact_tables, check_contacts_are_touching_pairs, check_frames
from pinnedballs.testing import strategies as pst

ROOT = Path(__file__).resolve().parents[2]
DRAWS = settings(max_examples=25, deadline=None, derandomize=True)


@DRAWS
@given(st.from_type(pb.Geometry), st.from_type(pb.CollisionRule), st.from_type(pb.Scheduler), st.from_type(pb.RunSpec))
def test_from_type_draws_each_type(geometry, rule, scheduler, spec):
    assert isinstance(geometry, pb.Geometry) and geometry.n_contacts >= 1
    assert isinstance(rule, pb.CollisionRule) and isinstance(scheduler, pb.Scheduler) and isinstance(spec, pb.RunSpec)


@DRAWS
@given(pst.geometries())
def test_drawn_geometries_are_sound(geometry):
    """Every geometry drawn passes the kit's own geometry checks (contact tables, touching pairs, frames)."""
    check_contact_tables(geometry)
    if not geometry.curved:
        check_contacts_are_touching_pairs(geometry)
    check_frames(geometry)


@DRAWS
@given(st.data())
def test_drawn_runs_never_gain_energy_and_elastic_ones_keep_it(data):
    """A drawn geometry, velocities, masses, rule and scheduler: 300 steps never add energy (beyond 1e-10 of
    it, rounding over 300 collisions), and an elastic rule keeps it to 1e-10."""
    g = data.draw(pst.geometries())
    v = data.draw(pst.velocities(g))
    assert v.shape == (g.n_balls, g.dim) and np.isfinite(v).all()
    masses = data.draw(pst.masses(g.n_balls))
    assert masses is None or (masses.shape == (g.n_balls,) and (masses > 0).all())
    rule, scheduler = data.draw(pst.rules()), data.draw(pst.schedulers())
    sim = pb.Simulation(g, v, rule=rule, scheduler=scheduler, masses=masses, seed=data.draw(st.integers(0, 2**32 - 1)))
    e0 = sim.energy()
    sim.run(steps=300)
    assert sim.energy() <= e0 * (1 + 1e-10) + 1e-300
    if rule.exact_restitution() == 1.0:
        assert sim.energy() == pytest.approx(e0, rel=1e-10, abs=1e-300)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_graphs_have_the_asked_dimension(dim):
    @DRAWS
    @given(pst.graphs(dim))
    def drawn(g):
        assert g.dim == dim and g.positions.shape[1] == dim and g.n_contacts >= 1

    drawn()


def test_graphs_refuse_a_dimension_they_do_not_draw():
    with pytest.raises(ValueError, match=r"^dim: must be 1, 2 or 3, got 4$"):
        pst.graphs(4)


@DRAWS
@given(pst.run_specs())
def test_run_specs_build_run_and_round_trip(spec):
    """A drawn spec builds a simulation that runs, and reads back from its own JSON as itself."""
    assert parse_spec(json.loads(spec.to_json())) == spec
    sim = spec.build()
    sim.run(steps=min(spec.stop.steps or 1000, 1000))
    assert sim.steps > 0


def test_the_entry_point_names_a_module_outside_the_package():
    """hypothesis loads ``_pinnedballs_hypothesis:setup``, a module outside the package (as hypothesis' own
    pytest plugin is), which imports the strategies when hypothesis calls it."""
    found = [ep for ep in importlib.metadata.entry_points(group="hypothesis") if ep.name == "pinnedballs"]
    assert [ep.value for ep in found] == ["_pinnedballs_hypothesis:setup"]


def _python(code: str, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT,
                          env={"PATH": "/usr/bin:/bin", **env})


@pytest.mark.slow
def test_the_entry_point_registers_the_strategies_whichever_is_imported_first():
    """hypothesis calls the entry point as it is imported: the strategies are registered then, and only then
    (``import pinnedballs`` alone registers nothing and loads no hypothesis)."""
    out = _python("import sys, hypothesis\n"
                  "print('pinnedballs.testing.strategies' in sys.modules)\n"
                  "import pinnedballs as pb\n"
                  "from hypothesis import strategies as st\n"
                  "print(isinstance(st.from_type(pb.Geometry).example(), pb.Geometry))")
    assert out.stdout.split() == ["True", "True"], out.stderr[-2000:]
    out = _python("import sys, pinnedballs as pb\n"
                  "print('hypothesis' in sys.modules, 'pinnedballs.testing.strategies' in sys.modules)\n"
                  "import hypothesis\n"
                  "from hypothesis import strategies as st\n"
                  "print(isinstance(st.from_type(pb.Scheduler).example(), pb.Scheduler))")
    assert out.stdout.split() == ["False", "False", "True"], out.stderr[-2000:]


@pytest.mark.slow
def test_the_kit_imports_and_checks_without_pytest_or_hypothesis():
    """With neither installed (both blocked), the checks run; the decorator and the strategies say what
    they need."""
    out = _python("import sys\n"
                  "sys.modules['pytest'] = None\n"
                  "sys.modules['hypothesis'] = None\n"
                  "import pinnedballs as pb\n"
                  "from pinnedballs.testing import check_rule, check_geometry, parametrize_with_checks\n"
                  "check_rule(pb.Elastic()); check_geometry(pb.HalfPlane(3, 4))\n"
                  "print('checked')\n"
                  "for use in (lambda: parametrize_with_checks([pb.Elastic()]),\n"
                  "            lambda: __import__('pinnedballs.testing.strategies')):\n"
                  "    try:\n"
                  "        use()\n"
                  "    except ImportError as error:\n"
                  "        print('needs', error.name)\n")
    assert out.stdout.split("\n")[:3] == ["checked", "needs pytest", "needs hypothesis"], out.stderr[-2000:]
