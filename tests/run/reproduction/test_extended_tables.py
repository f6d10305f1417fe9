"""The extended reproduction's scaling and torus-law studies run from study specs (issue 48) and give the tables
of the studies before them to the digit: every number, every replica's row (tests/data/make_extended_tables.py
recorded them with the code of commit 7dac6a9); and the full plan's study specs are examples/studies/'s files."""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import pytest

from pinnedballs.run.reproduction import EXTENDED_FULL, EXTENDED_QUICK
from pinnedballs.run.reproduction import extended as ext
from pinnedballs.specs.run import stored_spec
from pinnedballs.specs.study import load_study_spec

ROOT = Path(__file__).resolve().parents[3]
DATA = ROOT / "tests" / "data"
sys.path.insert(0, str(DATA))
from make_extended_tables import PLAN, tables  # noqa: E402

RECORDED = json.loads((DATA / "extended_tables.json").read_text())


def before(name: str) -> str:
    """The description each ensemble's spec had before: its own size's (a study's base now says it once)."""
    if name.startswith("torus"):
        return f"torus {name.split('_')[2]}: ball 0 moving, all others at rest"
    return f"scaling: half-plane {name.split('_')[1]}: the boundary-centre ball moving inward, until frozen"


@pytest.mark.slow
def test_the_tiny_plans_tables_are_the_same_to_the_digit(tmp_path):
    now = tables(tmp_path)
    assert now["scaling"] == RECORDED["scaling"] and now["torus_law"] == RECORDED["torus_law"]
    assert set(now["files"]) == set(RECORDED["files"])
    for name, recorded in RECORDED["files"].items():
        assert now["files"][name]["replicas.csv"] == recorded["replicas.csv"], name  # every replica's row
        spec = stored_spec((tmp_path / name / "spec.json").read_text(encoding="utf-8"))
        text = spec.model_copy(update={"description": before(name)}).to_json() + "\n"
        assert hashlib.sha256(text.encode()).hexdigest() == recorded["spec.json"], name  # all but the description


def test_the_studies_are_the_plans_sizes_on_its_seed():
    for plan in (PLAN, EXTENDED_FULL, EXTENDED_QUICK):
        points = ext.scaling_study_spec(plan).expand()
        assert [(p.spec.geometry.length, p.spec.geometry.depth, p.replicas) for p in points] == \
            [(float(a), float(b), r) for a, b, r in plan.scaling]
        assert {p.spec.seed for p in points} == {plan.seed} and {p.spec.scheduler.stream for p in points} == {"xoshiro"}
        torus = ext.torus_law_study_spec(plan).expand()
        assert [(p.spec.geometry.rows, p.spec.stop.steps, p.replicas) for p in torus] == \
            [(s, plan.torus_times[-1] * s * s, plan.torus_replicas) for s in plan.torus_sides]
        assert [p.spec.snapshots.at_steps for p in torus] == [[t * s * s for t in plan.torus_times[:-1]]
                                                              for s in plan.torus_sides]


def test_the_full_plans_studies_are_the_example_files():
    for name, study in (("extended_scaling.json", ext.scaling_study_spec(EXTENDED_FULL)),
                        ("extended_torus_law.json", ext.torus_law_study_spec(EXTENDED_FULL))):
        example = load_study_spec(ROOT / "examples" / "studies" / name)
        assert [(p.overrides, p.spec, p.replicas) for p in example.expand()] == \
            [(p.overrides, p.spec, p.replicas) for p in study.expand()], name
