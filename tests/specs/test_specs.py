"""Run specs: what a valid spec builds, and the exact message of each invalid one."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, spec, write

import pinnedballs as pb
from pinnedballs.specs import SpecError, describe, load_spec, parse_spec

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


# ---------------------------------------------------------------- what valid specs build


def test_build_is_the_python_api_bit_for_bit():
    sim = parse_spec(TORUS).build()
    v = np.zeros((16, 2))
    v[0] = [np.sqrt(200.0), 0.0]
    direct = pb.Simulation(pb.FlatTorus(4, 4), v, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=1)
    sim.run(steps=5000)
    direct.run(steps=5000)
    assert np.array_equal(sim.velocities, direct.velocities)
    assert (sim.steps, sim.collisions) == (direct.steps, direct.collisions)
    assert np.array_equal(sim.get_state().rng_state, direct.get_state().rng_state)


@pytest.mark.parametrize("name", ["halfplane_100x50.json", "torus.json"])
def test_examples_validate_and_build(name):
    s = load_spec(EXAMPLES / name)
    sim = s.build()
    assert sim.energy() == pytest.approx(100.0, rel=1e-15)
    assert np.count_nonzero(np.linalg.norm(sim.velocities, axis=1)) == 1


def test_paper_half_plane_example():
    s = load_spec(EXAMPLES / "halfplane_100x50.json")
    g = s.build().geometry
    assert (g.rows, g.cols) == (29, 50)  # HalfPlane.from_size(100, 50)
    sim = s.build()
    ball = g.boundary_center()
    assert np.flatnonzero(sim.velocities.any(axis=1)).tolist() == [ball]
    assert sim.velocities[ball, 0] == 0 and sim.velocities[ball, 1] == pytest.approx(np.sqrt(200.0), rel=1e-15)


def test_single_ball_energy_counts_the_mass():
    s = parse_spec(spec(masses=4.0, initial__direction=[3, 4]))
    sim = s.build()
    assert sim.energy() == pytest.approx(100.0, rel=1e-15)
    assert np.allclose(sim.velocities[0], np.sqrt(2 * 100 / 4.0) * np.array([0.6, 0.8]), rtol=1e-15)


def test_single_ball_velocity_given():
    sim = parse_spec(spec(initial={"kind": "single_ball", "ball": 5, "velocity": [1.5, -2]})).build()
    expected = np.zeros((16, 2))
    expected[5] = [1.5, -2.0]
    assert np.array_equal(sim.velocities, expected)


@pytest.mark.parametrize("geometry", [{"kind": "hyperbolic_plane", "q": 7, "layers": 3},
                                      {"kind": "half_plane", "rows": 4, "cols": 5},
                                      {"kind": "fcc", "nx": 2, "ny": 2, "nz": 2, "periodic": False}])
def test_single_ball_inward_is_minus_the_boundary_outward(geometry):
    d = spec(geometry=geometry, initial={"kind": "single_ball", "ball": "boundary_center", "direction": "inward",
                                         "energy": 50})
    sim = parse_spec(d).build()
    g = sim.geometry
    ball = g.boundary_center()
    expected = np.zeros((g.n_balls, g.dim))
    expected[ball] = -np.sqrt(2 * 50.0) * g.boundary.outward[ball]
    assert np.allclose(sim.velocities, expected, rtol=1e-15, atol=0)
    assert sim.energy() == pytest.approx(50.0, rel=1e-14)


def test_single_ball_inward_moves_the_hyperbolic_rim_ball():
    d = spec(geometry={"kind": "hyperbolic_plane", "q": 7, "layers": 3},
             initial={"kind": "single_ball", "ball": "boundary_center", "direction": "inward", "energy": 100})
    sim = parse_spec(d).build()
    assert sim.run_until_frozen(max_steps=10**8)
    assert sim.collisions > 0 and sim.energy() == pytest.approx(100.0, rel=1e-12)


def test_gaussian_energy_momentum_and_seed():
    d = spec(initial={"kind": "gaussian", "energy": 7.5, "zero_momentum": True}, geometry__rows=8)
    a, b = parse_spec(d).build(), parse_spec(d).build()
    other = parse_spec({**d, "seed": 2}).build()
    assert np.array_equal(a.velocities, b.velocities)
    assert not np.array_equal(a.velocities, other.velocities)
    assert a.energy() == pytest.approx(7.5, rel=1e-12)
    assert np.abs(a.momentum()).max() < 1e-12
    plain = parse_spec(spec(d, initial__zero_momentum=False)).build()
    assert np.abs(plain.momentum()).max() > 1e-3


def test_gaussian_stream_is_not_the_simulation_stream():
    """Initial draws come from their own stream, so they are not the simulation's random numbers."""
    sim = parse_spec(spec(initial={"kind": "gaussian", "energy": 1.0})).build()
    words = np.random.SeedSequence(1).generate_state(4, np.uint64)
    assert np.array_equal(sim.get_state().rng_state, words)
    same_stream = np.random.default_rng(np.random.SeedSequence(1)).standard_normal((16, 2))
    assert not np.allclose(sim.velocities / np.linalg.norm(sim.velocities), same_stream / np.linalg.norm(same_stream))


def test_relative_paths_resolve_against_the_spec_file(tmp_path, monkeypatch):
    data = tmp_path / "data"
    data.mkdir()
    v = np.arange(32, dtype=float).reshape(16, 2) / 10
    np.save(data / "v0.npy", v)
    np.save(data / "m.npy", np.linspace(1, 2, 16))
    path = write(data / "spec.json", spec(initial={"kind": "from_file", "path": "v0.npy"}, masses="m.npy"))
    monkeypatch.chdir(tmp_path)  # not the spec's directory
    s = load_spec(path)
    assert s.initial.path == str(data / "v0.npy")
    sim = s.build()
    assert np.array_equal(sim.velocities, v)
    assert np.array_equal(sim.masses, np.linspace(1, 2, 16))


def test_graph_positions_match_the_lattice(tmp_path):
    lattice = pb.HalfPlane(4, 5)
    np.save(tmp_path / "p.npy", lattice.positions)
    s = parse_spec(spec(geometry={"kind": "graph_positions", "positions": "p.npy"}, stop={"steps": 10},
                        snapshots=...), base_dir=tmp_path)
    g = s.build().geometry
    assert isinstance(g, pb.GraphGeometry) and g.n_contacts == lattice.n_contacts
    ours = {tuple(sorted(p)) for p in g.contacts.pairs.tolist()}
    theirs = {tuple(sorted(p)) for p in lattice.contacts.pairs.tolist()}
    assert ours == theirs


def test_half_plane_from_size_equals_rows_and_cols():
    a = parse_spec(spec(HALF_PLANE, geometry={"kind": "half_plane", "length": 20, "depth": 10})).build().geometry
    b = pb.HalfPlane.from_size(20, 10)
    assert (a.rows, a.cols) == (b.rows, b.cols)


def test_defaults_and_round_trip():
    s = parse_spec(spec(rule=..., scheduler=..., seed=..., snapshots=...))
    assert (s.rule.kind, s.scheduler.kind, s.seed, s.snapshots, s.checkpoint.every_seconds) == \
        ("elastic", "uniform_random_pair", None, None, 60.0)  # no seed: one is drawn when it runs
    again = parse_spec(s.to_json())
    assert again == s
    seeded = s.seeded()
    assert isinstance(seeded.seed, int) and 0 <= seeded.seed < 2**63 and parse_spec(seeded.to_json()) == seeded
    assert seeded.seeded() is seeded and s.seeded().seed != seeded.seed  # fresh entropy each time


def test_snapshot_lists_are_sorted_and_unique():
    s = parse_spec(spec(snapshots={"at_steps": [500, 0, 500, 10]}))
    assert s.snapshots.at_steps == [0, 10, 500]
    assert [s.snapshots.target(n) for n in range(4)] == [0, 10, 500, None]
    every = parse_spec(spec(snapshots={"every_collisions": 7}, stop={"collisions": 100})).snapshots
    assert (every.counter, every.target(0), every.target(2)) == ("collisions", 7, 21)


@pytest.mark.parametrize("kind,extra", [("restitution", {"r": 0.5}), ("elastic", {})])
@pytest.mark.parametrize("scheduler", ["uniform_random_pair", "sweep", "random_sweep"])
def test_rules_and_schedulers_build(kind, extra, scheduler):
    sim = parse_spec(spec(rule={"kind": kind, **extra}, scheduler={"kind": scheduler})).build()
    expected = {"restitution": pb.Restitution(0.5), "elastic": pb.Elastic()}[kind]
    assert sim.rule == expected
    assert type(sim.scheduler).__name__ == {"uniform_random_pair": "UniformRandomPair", "sweep": "Sweep",
                                            "random_sweep": "RandomSweep"}[scheduler]


def test_schema_names_every_kind():
    text = json.dumps(pb.RunSpec.model_json_schema())
    for kind in ("flat_torus", "half_plane", "graph_positions", "single_ball", "gaussian", "from_file",
                 "elastic", "restitution", "uniform_random_pair", "sweep", "random_sweep"):
        assert f'"{kind}"' in text


def test_describe_is_one_line():
    s = parse_spec(TORUS)
    line = describe(s, s.build())
    assert "\n" not in line
    assert line.startswith("flat_torus 4x4: 16 balls, 48 contacts, dim 2; single_ball, energy 100;")
    assert "stop at 1,000 steps; 3 snapshots; seed 1" in line


@pytest.mark.parametrize("snapshots, trajectory, said", [
    ({"at_steps": [500]}, None, "1 snapshot;"),
    (..., None, "no snapshots;"),
    ({"every_steps": 100}, {"every_steps": 250}, "10 snapshots, trajectory.gsd: 4 frames;"),
])
def test_describe_counts_snapshots_in_words(snapshots, trajectory, said):
    s = parse_spec(spec(TORUS, snapshots=snapshots, trajectory=trajectory if trajectory else ...))
    assert said in describe(s, s.build())


def test_the_resolution_is_the_simulations_and_round_trips():
    """``"resolution"``: the collision criterion ``e`` of the simulation a spec builds (None: the default
    4 * 2^-53), written out with the spec; the same picks at a coarser e set aside more of them."""
    default, coarse = parse_spec(HALF_PLANE), parse_spec(spec(HALF_PLANE, resolution=1e-3))
    assert default.resolution is None and default.build().resolution == 4 * 2.0**-53
    sim = coarse.build()
    assert sim.resolution == 1e-3 and sim.threshold == pytest.approx(1e-3 * np.sqrt(200.0), rel=1e-15)
    assert parse_spec(coarse.to_json()) == coarse and json.loads(coarse.to_json())["resolution"] == 1e-3
    assert describe(coarse, sim).endswith("; seed 3; resolution 0.001")
    fine = default.build()
    fine.run_until_frozen(max_steps=10**6)
    sim.run_until_frozen(max_steps=10**6)
    assert sim.closing_margin().smallest_collision > 1 and sim.collisions < fine.collisions


def test_late_precision_is_the_simulations_and_round_trips():
    """``"late_precision"``: certified arithmetic's bits behind the first wave (`Simulation`'s), written
    out with the spec; the run's counts are those at ``precision`` throughout."""
    late = parse_spec(spec(HALF_PLANE, arithmetic="certified", precision=256, late_precision=128))
    assert parse_spec(late.to_json()) == late and json.loads(late.to_json())["late_precision"] == 128
    sim, whole = late.build(), parse_spec(spec(HALF_PLANE, arithmetic="certified", precision=256)).build()
    assert (sim.engine.state.field_chain.P, sim.engine.state.field_chain.late_P) == (4, 2)
    assert whole.engine.state.field_chain.late_P is None
    for s in (sim, whole):
        s.run_until_frozen(max_steps=10**6)
    assert (sim.steps, sim.collisions) == (whole.steps, whole.collisions) and sim.collisions > 10


RESOLUTION_RANGE = ("must be a number in (0, 1): a pick collides when its closing speed exceeds resolution * V "
                    "(V the system's speed scale), got ")


@pytest.mark.parametrize("text, problem", [
    ("0", RESOLUTION_RANGE + "0"), ("1", RESOLUTION_RANGE + "1"), ("1.5", RESOLUTION_RANGE + "1.5"),
    ("-1e-9", RESOLUTION_RANGE + "-1e-09"), ('"1e-9"', "must be a number, got '1e-9'"),
    ("true", "must be a number, got True"), ("[1e-9]", "must be a number, got [1e-09]"),
    ("NaN", "must be a finite number, got nan"), ("1e400", "must be a finite number, got inf"),
])
def test_a_bad_resolution_is_one_line_naming_the_field(tmp_path, text, problem):
    path = tmp_path / "s.json"
    path.write_text(json.dumps(TORUS)[:-1] + f', "resolution": {text}}}')
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert str(info.value) == f"resolution: {problem}"


def test_describe_says_every_so_many_collisions_when_it_cannot_count():
    s = parse_spec(spec(HALF_PLANE, snapshots={"every_collisions": 100}))
    assert "stop at frozen (max 10,000,000 steps); a snapshot every 100 collisions; seed 3" in describe(s, s.build())


# ---------------------------------------------------------------- what invalid specs say

BAD = [
    (spec(geometry__rows=5), "geometry.rows", "must be even for a flat torus, got 5"),
    (spec(geometry__rows="4"), "geometry.rows", "input should be a valid integer, got '4'"),
    (spec(geometry__rows=4.0), "geometry.rows", "input should be a valid integer"),
    (spec(geometry__cols=2), "geometry.cols", "must be an integer >= 3, got 2"),
    (spec(geometry__kind="flat_toru"), "geometry.kind", "unknown kind 'flat_toru'; did you mean 'flat_torus'?"),
    (spec(geometry__kind=...), "geometry.kind", "missing; one of: flat_torus, half_plane, graph_positions"),
    (spec(geometry__rowz=4), "geometry.rowz",
     "unknown key; did you mean 'rows'? (valid keys: kind, rows, cols, radius)"),
    (spec(geometry__radius=-1), "geometry.radius", "input should be greater than 0, got -1"),
    (spec(HALF_PLANE, geometry={"kind": "half_plane", "rows": 3}), "geometry",
     "give rows and cols, or length and depth (got rows)"),
    (spec(HALF_PLANE, geometry={"kind": "half_plane", "length": 1, "depth": 9}), "geometry.length", "must be >= 2"),
    (spec(scheduler__kind="swep"), "scheduler.kind", "unknown kind 'swep'; did you mean 'sweep'?"),
    (spec(rule={"kind": "restitution", "r": 1.5}), "rule.r",
     "coefficient of restitution must be a number in [0, 1], got 1.5"),
    (spec(rule={"kind": "restitution"}), "rule.r", "missing (required)"),
    (spec(rule={"kind": "elastic", "r": 1}), "rule.r", "unknown key (valid keys: kind)"),
    (spec(stop__steps=-1), "stop.steps", "input should be greater than or equal to 0, got -1"),
    (spec(stop__collisions=3), "stop", "give exactly one of steps, collisions or frozen (got steps, collisions)"),
    (spec(stop={}), "stop", "give exactly one of steps, collisions or frozen (got none)"),
    (spec(stop={"frozen": True}, snapshots=...), "stop.max_steps", "required with frozen"),
    (spec(stop={"steps": 5, "max_steps": 9}, snapshots=...), "stop.max_steps", "only allowed with frozen"),
    (spec(snapshots__at_steps=[0, 5000]), "snapshots.at_steps", "5000 is beyond the stop at 1000"),
    (spec(snapshots__at_steps=[1, "x"]), "snapshots.at_steps[1]", "input should be a valid integer, got 'x'"),
    (spec(snapshots={"at_steps": [1], "every_steps": 5}), "snapshots",
     "give exactly one of at_steps, at_collisions, every_steps or every_collisions"),
    (spec(snapshots={"every_steps": 0}), "snapshots.every_steps", "input should be greater than or equal to 1"),
    (spec(checkpoint={"every_second": 1}), "checkpoint.every_second", "did you mean 'every_seconds'?"),
    (spec(checkpoint={"every_seconds": -1}), "checkpoint.every_seconds", "greater than or equal to 0"),
    (spec(seed=-3), "seed", "input should be greater than or equal to 0, got -3"),
    (spec(seed=True), "seed", "input should be a valid integer, got True"),
    (spec(masses=-1), "masses", "input should be greater than 0, got -1"),
    (spec(masses=[1, 2]), "masses", "must be a number > 0 or the path of a .npy file, got [1, 2]"),
    (spec(seeds=1), "seeds", "unknown key; did you mean 'seed'?"),
    (spec(initial__ball="centre"), "initial.ball", 'must be a ball index (an integer >= 0) or "boundary_center"'),
    (spec(initial__ball=16), "initial.ball", "must be < n_balls = 16, got 16"),
    (spec(initial__ball="boundary_center"), "initial.ball", '"boundary_center" needs a geometry with a boundary'),
    (spec(initial__direction=[1, 0, 0]), "initial.direction", "must have dim = 2 components, got 3"),
    (spec(initial__direction=[0, 0]), "initial.direction", "must not be the zero vector"),
    (spec(initial__energy=...), "initial.energy", "required (give velocity, or direction and energy)"),
    (spec(initial__velocity=[1, 0]), "initial", "give velocity, or direction and energy, not both"),
    (spec(initial__energy=float("inf")), "initial.energy", "input should be a finite number"),
    (spec(initial={"kind": "gaussian"}), "initial.energy", "missing (required)"),
    (spec(initial={"kind": "from_file"}), "initial.path", "missing (required)"),
    (spec(initial={"kind": "from_file", "path": "nope.npy"}), "initial.path", "file not found: "),
    (spec(geometry={"kind": "graph_positions", "positions": "nope.npy"}), "geometry.positions", "file not found"),
    (spec(masses="nope.npy"), "masses", "file not found"),
    (spec(description=3), "description", "input should be a valid string"),
    (spec(initial__direction="inward"), "initial.direction",
     '"inward" needs a geometry with a boundary, got FlatTorus'),
    (spec(initial__direction="outward"), "initial.direction", "input should be"),
    (spec(HALF_PLANE, arithmetic="certified", precision=256, late_precision=512), "late_precision",
     "must be at most precision (256 bits), got 512"),
    (spec(late_precision=128), "late_precision",
     "is certified arithmetic's precision behind the first wave; this run's is 'float'"),
]


@pytest.mark.parametrize("data,path,words", BAD, ids=[f"{p}-{i}" for i, (_, p, _) in enumerate(BAD)])
def test_bad_spec_names_the_field(data, path, words, tmp_path):
    with pytest.raises(SpecError) as info:
        parse_spec(data, base_dir=tmp_path).build()
    assert info.value.path == path
    assert words in info.value.problem
    assert str(info.value).startswith(f"{path}: ")
    assert "\n" not in str(info.value)


BAD_FILES = [
    ("v.npy", lambda: np.full((16, 2), 0.5) + np.where(np.arange(32).reshape(16, 2) == 7, np.nan, 0),
     "initial", "initial.path", "ball 3 has a NaN or infinite component (1 ball(s) in all)"),
    ("v.npy", lambda: np.zeros((16, 3)), "initial", "initial.path",
     "must have shape (n_balls, dim) = (16, 2), got (16, 3)"),
    ("v.npy", lambda: b"not an array", "initial", "initial.path", "as a .npy array"),
    ("m.npy", lambda: np.ones(3), "masses", "masses", "must have shape (n_balls,) = (16,), got (3,)"),
    ("m.npy", lambda: -np.ones(16), "masses", "masses", "m.npy: must all be finite and > 0"),
    ("p.npy", lambda: np.array([[0.0, 0.0], [1.0, 0.0]]), "geometry", "geometry.positions",
     "balls 0 and 1 overlap (centres 1 apart, contact distance 2); 1 overlapping pair(s) in all (in "),
    ("p.npy", lambda: np.array([[0.0, 0.0], [5.0, 0.0]]), "geometry", "geometry", "has no contacts"),
]


@pytest.mark.parametrize("name,make,slot,path,words", BAD_FILES,
                         ids=[f"{p}-{i}" for i, (*_, p, _) in enumerate(BAD_FILES)])
def test_bad_data_file_names_the_field(name, make, slot, path, words, tmp_path):
    content = make()
    if isinstance(content, bytes):
        (tmp_path / name).write_bytes(content)
    else:
        np.save(tmp_path / name, content)
    value = {"initial": {"kind": "from_file", "path": name}, "masses": name,
             "geometry": {"kind": "graph_positions", "positions": name}}[slot]
    with pytest.raises(SpecError) as info:
        parse_spec(spec(**{slot: value}), base_dir=tmp_path).build()
    assert info.value.path == path
    assert words in info.value.problem
    assert str(tmp_path / name) in info.value.problem  # the file is named


@pytest.mark.parametrize("text,words", [
    ("{", "not valid JSON: Expecting property name"),
    ("[1, 2]", "a spec must be a JSON object, got list"),
    ('{"geometry": {"kind": "flat_torus", "rows": 4, "cols": 4, "radius": NaN}}', "input should be a finite number"),
])
def test_bad_spec_file(tmp_path, text, words):
    path = tmp_path / "s.json"
    path.write_text(text)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert words in str(info.value)


def test_missing_spec_file(tmp_path):
    with pytest.raises(SpecError, match=r"nope\.json: no such spec file"):
        load_spec(tmp_path / "nope.json")


def test_engine_errors_carry_their_field():
    """The engine names the argument as data; a spec maps it to its field without reading the message."""
    from pinnedballs.util.errors import FieldValueError

    with pytest.raises(FieldValueError) as info:
        pb.FlatTorus(5, 4)
    assert (info.value.field, info.value.problem) == ("rows", "must be even for a flat torus, got 5")
    assert str(info.value) == "rows: must be even for a flat torus, got 5" and isinstance(info.value, ValueError)
    with pytest.raises(FieldValueError) as info:
        pb.Simulation(pb.FlatTorus(4, 4), np.zeros((3, 2)))
    assert info.value.field == "velocities"
    with pytest.raises(SpecError) as spec_error:
        parse_spec({"geometry": {"kind": "flat_torus", "rows": 5, "cols": 4},
                    "initial": {"kind": "single_ball", "velocity": [1, 0]}, "stop": {"steps": 1}}).build()
    assert (spec_error.value.path, spec_error.value.problem) == ("geometry.rows",
                                                                 "must be even for a flat torus, got 5")
