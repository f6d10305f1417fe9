"""Study specs (issue 48): zip x grid x points of dotted-path overrides into a base run spec, each point validated,
its seeds from the study's seed and its own overrides only; bad points refused in one line naming the point and
the field."""

from __future__ import annotations

import hashlib
import json
import re

import pytest
from helpers import call, write

from pinnedballs.specs.errors import SpecError
from pinnedballs.specs.run import parse_spec
from pinnedballs.specs.study import PointError, load_study_spec, parse_study, point_seed, stated

HALF_PLANE = {"geometry": {"kind": "half_plane", "length": 10, "depth": 5},
              "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
              "stop": {"frozen": True, "max_steps": 10**7}}


def study(**parts) -> dict:
    return {"base": HALF_PLANE, "replicas": 3, "seed": 0, **parts}


def sha_seed(seed: int, overrides: dict) -> int:
    """The documented rule, written out again: 63 bits of SHA-256 of "<seed>:<sorted, spaceless JSON>"."""
    text = json.dumps(overrides, sort_keys=True, separators=(",", ":"))
    return int.from_bytes(hashlib.sha256(f"{seed}:{text}".encode()).digest()[:8], "little") >> 1


# ---------------------------------------------------------------- points


def test_zip_grid_and_points_combine_as_a_product_zip_outermost():
    s = parse_study(study(zip={"geometry.length": [10, 20], "geometry.depth": [5, 10]},
                          grid={"initial.energy": [1.0, 4.0], "stop.max_steps": [100, 200]},
                          points=[{}, {"scheduler": {"kind": "sweep"}}]))
    points = s.expand()
    assert len(points) == 2 * 4 * 2
    assert [p.overrides for p in points[:3]] == [
        {"geometry.length": 10, "geometry.depth": 5, "initial.energy": 1.0, "stop.max_steps": 100},
        {"geometry.length": 10, "geometry.depth": 5, "initial.energy": 1.0, "stop.max_steps": 100,
         "scheduler": {"kind": "sweep"}},
        {"geometry.length": 10, "geometry.depth": 5, "initial.energy": 1.0, "stop.max_steps": 200}]
    last = points[-1]
    assert (last.spec.geometry.length, last.spec.geometry.depth, last.spec.initial.energy, last.spec.stop.max_steps,
            last.spec.scheduler.kind) == (20.0, 10.0, 4.0, 200, "sweep")
    assert s.varied == ["geometry.length", "geometry.depth", "initial.energy", "stop.max_steps", "scheduler"]


def test_a_study_without_parts_is_its_base_and_a_path_creates_what_the_base_leaves_out():
    (only,) = parse_study(study()).expand()
    assert only.overrides == {} and only.spec.geometry == parse_spec(HALF_PLANE).geometry
    restitution = {"kind": "restitution", "r": 0.5}
    (p,) = parse_study(study(points=[{"snapshots.every_steps": 50, "rule": restitution}])).expand()
    assert p.spec.snapshots.every_steps == 50 and p.spec.rule.r == 0.5


def test_a_point_is_the_base_with_its_overrides_and_nothing_else():
    """Every field but the overridden ones and the seed is the base's."""
    s = parse_study(study(grid={"initial.energy": [7.0]}))
    (p,) = s.expand()
    base = parse_spec(HALF_PLANE)
    assert p.spec.model_copy(update={"seed": None, "initial": base.initial}) == base
    assert p.spec.initial.energy == 7.0 and base.initial.energy == 100.0


def test_replicas_by_rule_first_that_holds():
    s = parse_study(study(grid={"geometry.length": [10, 20, 30]},
                          replicas=[{"where": {"geometry.length": 20}, "replicas": 5},
                                    {"where": {"geometry.depth": 5.0}, "replicas": 2}]))
    assert [p.replicas for p in s.expand()] == [2, 5, 2]  # where compares the spec: the base's depth included


def test_state_points_nest_the_overrides_beside_the_bases_digest():
    s = parse_study(study(zip={"geometry.length": [10, 20], "geometry.depth": [5, 10]}))
    assert s.expand()[1].state_point(s.digest()) == {"base": s.digest(), "geometry": {"length": 20, "depth": 10}}
    # another base, other jobs; the description and (seeds by point) the base's unused seed are not the base
    other = parse_study(study(base={**HALF_PLANE, "initial": {**HALF_PLANE["initial"], "energy": 50}}))
    noted = parse_study(study(base={**HALF_PLANE, "description": "a note", "seed": 9}))
    assert other.digest() != s.digest() == noted.digest()


# ---------------------------------------------------------------- seeds


def test_a_points_seed_is_the_studys_seed_and_its_own_overrides():
    points = parse_study(study(seed=5, grid={"geometry.length": [10, 20]})).expand()
    assert [p.spec.seed for p in points] == [sha_seed(5, {"geometry.length": 10}), sha_seed(5, {"geometry.length": 20})]
    assert [p.spec.seed for p in points] == [point_seed(5, p.overrides) for p in points]
    assert len({p.spec.seed for p in points}) == 2 and all(0 <= p.spec.seed < 2**63 for p in points)


def test_seeds_do_not_depend_on_order_or_on_the_other_points():
    a = parse_study(study(grid={"geometry.length": [10, 20, 30]})).expand()
    b = parse_study(study(grid={"geometry.length": [30, 10]}, points=[{}])).expand()
    c = parse_study(study(points=[{"geometry.length": 20}, {"geometry.length": 40}, {"geometry.length": 10}])).expand()
    seeds = {json.dumps(p.overrides): p.spec.seed for p in a}
    for p in (*b, *c):
        if json.dumps(p.overrides) in seeds:
            assert p.spec.seed == seeds[json.dumps(p.overrides)]
    assert {json.dumps(p.overrides) for p in b} < set(seeds)


def test_a_pinned_seed_and_seeds_as_spec_keep_the_specs_seed():
    points = parse_study(study(points=[{"seed": 11}, {}])).expand()
    assert points[0].spec.seed == 11 and points[1].spec.seed == sha_seed(0, {})
    kept = parse_study({"base": {**HALF_PLANE, "seed": 4}, "grid": {"geometry.length": [10, 20]}, "replicas": 2,
                        "seeds": "as_spec"}).expand()
    assert [p.spec.seed for p in kept] == [4, 4]


def test_a_study_without_a_seed_draws_one():
    s = parse_study({**study(), "seed": None})
    with pytest.raises(SpecError, match="seed: missing: a study without a seed draws one when it runs"):
        s.expand()
    seeded = s.seeded()
    assert seeded.seed is not None and seeded.expand()[0].spec.seed == point_seed(seeded.seed, {})


# ---------------------------------------------------------------- bad points: one line naming the point and field

BAD = [
    (study(grid={"geometry.lenght": [10]}),
     'point {"geometry.lenght": 10}: geometry.lenght: unknown key; did you mean \'length\'?'),
    (study(zip={"geometry.length": [10, 20], "geometry.depth": [5, "deep"]}),
     'point {"geometry.length": 20, "geometry.depth": "deep"}: geometry.depth: input should be a valid number'),
    (study(points=[{"rule.r": 0.5}]), 'point {"rule.r": 0.5}: rule.kind: missing; one of: elastic, restitution'),
    (study(points=[{"stop.frozen.after": 3}]),
     'point {"stop.frozen.after": 3}: stop.frozen.after: stop.frozen is true, not an object to set a key in'),
    (study(grid={"geometry.length": 10}), "grid.geometry.length: must be a list of at least one value, got 10"),
    (study(zip={"geometry.length": [10, 20], "geometry.depth": [5]}),
     "zip: its lists are varied together and must have one length, got geometry.length 2, geometry.depth 1"),
    (study(grid={"geometry": [HALF_PLANE["geometry"]]}, points=[{"geometry.depth": 6}]),
     "points[0].geometry.depth: also varied by grid (geometry)"),
    (study(grid={"geometry..length": [10]}), "grid: 'geometry..length' is not a dotted path into the run spec"),
    (study(points=[{"seed": 1}, {"seed": 1}]), 'points: the point {"seed": 1} is given twice'),
    (study(grid={"geometry.length": [10, 20]}, replicas=[{"where": {"geometry.length": 20}, "replicas": 2}]),
     'point {"geometry.length": 10}: replicas: no rule holds for this point'),
    (study(grid={"geometry.length": [10]}, replicas=[{"where": {"geometry.length": 99}, "replicas": 2},
                                                     {"replicas": 3}]),
     'replicas[0].where: {"geometry.length": 99} holds for no point of the study'),
    (study(replicas=[{"replica": 2}]), "replicas[0].replica: unknown key; did you mean 'replicas'?"),
    (study(replicas=0), "replicas: input should be greater than or equal to 1, got 0"),
    (study(seeds="as_spec"), "seed: seeds \"as_spec\" runs each point on its run spec's own seed; give the study no"),
    ({"base": HALF_PLANE, "replicas": 2, "seeds": "as_spec"},
     'point {}: seed: missing: seeds "as_spec" runs each point on its run spec\'s seed, and the base states none'),
    (study(base={**HALF_PLANE, "stop": {"frozen": True}}),
     "base.stop.max_steps: required with frozen (a flat torus never freezes)"),
    (study(gird={}), "gird: unknown key; did you mean 'grid'?"),
]


@pytest.mark.parametrize("data,message", BAD, ids=[m[:40] for _, m in BAD])
def test_a_bad_study_is_one_line_naming_the_point_and_field(data, message):
    with pytest.raises(SpecError) as info:
        parse_study(data).expand()
    assert str(info.value).startswith(message) and "\n" not in str(info.value)


def test_a_point_error_names_its_overrides_and_the_run_specs_field():
    with pytest.raises(PointError) as info:
        parse_study(study(grid={"geometry.depth": [5, "x"]})).expand()
    assert info.value.point == {"geometry.depth": "x"} and info.value.field == "geometry.depth"


def test_a_base_file_resolves_against_the_study_file(tmp_path):
    (tmp_path / "specs").mkdir()
    write(tmp_path / "specs" / "base.json", HALF_PLANE)
    path = write(tmp_path / "study.json", {"base": "specs/base.json", "grid": {"geometry.length": [10]},
                                           "replicas": 2, "seed": 1})
    inline = parse_study({**study(seed=1), "grid": {"geometry.length": [10]}, "replicas": 2})
    from_file = load_study_spec(path)
    assert from_file.expand()[0].spec == inline.expand()[0].spec and from_file.digest() == inline.digest()
    write(path, {"base": "specs/missing.json", "replicas": 2})
    with pytest.raises(SpecError, match=re.escape(f"base: {tmp_path / 'specs' / 'missing.json'}: no such spec file")):
        load_study_spec(path)


def test_to_json_repeats_the_study(tmp_path):
    s = parse_study(study(zip={"geometry.length": [10, 20], "geometry.depth": [5, 10]},
                          replicas=[{"where": {"geometry.length": 20}, "replicas": 5}, {"replicas": 2}],
                          description="two sizes"))
    again = load_study_spec(write(tmp_path / "again.json", json.loads(s.to_json())))
    assert [(p.overrides, p.spec, p.replicas) for p in again.expand()] == \
        [(p.overrides, p.spec, p.replicas) for p in s.expand()]
    assert again.digest() == s.digest() and stated(again.base) == stated(s.base)


def test_the_schema_command_prints_the_study_schema():
    code, out, _ = call("schema", "--study")
    schema = json.loads(out)
    assert code == 0 and schema["title"] == "StudySpec" and "RunSpec" in schema["$defs"]
    assert {"$ref": "#/$defs/RunSpec"} in schema["properties"]["base"]["anyOf"]
    assert {"zip", "grid", "points", "replicas", "seed", "seeds"} <= set(schema["properties"])
