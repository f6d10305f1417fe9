"""A user's components in specs: ``{"kind": "python", "factory": "module:callable", "args": {...}}``,
and kinds registered by installed packages through entry points."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.cli import main as cli
from pinnedballs.specs import parse_spec
from helpers import write

CHAIN = {
    "geometry": {"kind": "python", "factory": "user_components:chain", "args": {"n": 6}},
    "initial": {"kind": "python", "factory": "user_components:reversed_speeds", "args": {"speed": 0.5}},
    "rule": {"kind": "python", "factory": "user_components:half_elastic"},
    "scheduler": {"kind": "python", "factory": "user_components:sweep"},
    "stop": {"frozen": True, "max_steps": 100_000},
}


def call(capsys, *argv) -> tuple[int, str, str]:
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_python_components_build_and_run(tmp_path, capsys):
    sim = parse_spec(CHAIN).build()
    assert sim.geometry.n_balls == 6 and sim.geometry.n_contacts == 5
    assert isinstance(sim.rule, pb.Restitution) and sim.rule.r == 0.5 and isinstance(sim.scheduler, pb.Sweep)
    assert np.array_equal(sim.velocities[:, 0], 0.5 * np.arange(6, 0, -1))
    # the same components built by hand give the same bits
    import user_components as uc

    g = uc.chain(6)
    by_hand = pb.Simulation(g, uc.reversed_speeds(g, 0.5), rule=pb.Restitution(0.5), scheduler=pb.Sweep())
    by_hand.run_until_frozen(100_000)
    code, _, err = call(capsys, "run", write(tmp_path / "s.json", CHAIN), "--out", tmp_path / "r", "--quiet",
                        "--no-figures")
    assert code == 0, err
    res = pb.load(tmp_path / "r")
    assert res.frozen and np.array_equal(res.velocities, by_hand.velocities) and res.steps == by_hand.steps
    # momentum along the chain is conserved by any restitution (flat space), energy is not
    assert np.allclose(res.momentum, by_hand.momentum(), rtol=0, atol=1e-12)
    assert res.momentum[0] == pytest.approx(0.5 * 21, rel=1e-13) and res.energy < res.initial_energy
    assert res.simulation().steps == res.steps  # rebuilt through the spec, which imports the factory again


@pytest.mark.parametrize("slot,factory,message", [
    ("geometry", "no_such_module_xyz:chain",
     "geometry.factory: cannot import module 'no_such_module_xyz' (No module named 'no_such_module_xyz')"),
    ("rule", "user_components:nothing", "rule.factory: module 'user_components' has no attribute 'nothing'"),
    ("scheduler", "user_components", 'scheduler.factory: must be "module:callable", got \'user_components\''),
])
def test_validate_names_the_field_of_a_missing_factory(tmp_path, capsys, slot, factory, message):
    data = {**CHAIN, slot: {"kind": "python", "factory": factory}}
    code, out, err = call(capsys, "validate", write(tmp_path / "s.json", data))
    assert (code, out) == (2, "") and err == f"pinnedballs: error: {message}\n"


def test_a_factory_returning_the_wrong_thing(tmp_path, capsys):
    data = {**CHAIN, "rule": {"kind": "python", "factory": "user_components:not_a_rule"}}
    code, _, err = call(capsys, "validate", write(tmp_path / "s.json", data))
    assert code == 2 and err == ("pinnedballs: error: rule.factory: user_components:not_a_rule returned int, "
                                 "not a pinnedballs CollisionRule\n")
    data = {**CHAIN, "geometry": {**CHAIN["geometry"], "args": {"n": 6, "colour": "red"}}}
    code, _, err = call(capsys, "validate", write(tmp_path / "s.json", data))
    assert code == 2 and err.startswith("pinnedballs: error: geometry: ") and "colour" in err


def test_entry_points_register_named_kinds(tmp_path, monkeypatch, capsys):
    """An installed distribution (here a bare .dist-info on sys.path) names kinds of its own."""
    dist = tmp_path / "demo_components-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: demo-components\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[pinnedballs.geometries]\nchain = user_components:chain\n\n"
                                           "[pinnedballs.rules]\nhalf_elastic = user_components:half_elastic\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    data = {**CHAIN, "geometry": {"kind": "chain", "n": 4}, "rule": {"kind": "half_elastic"}}
    s = parse_spec(data)
    assert s.geometry.factory == "user_components:chain" and s.geometry.args == {"n": 4}
    sim = s.build()
    assert sim.geometry.n_balls == 4 and sim.rule.r == 0.5
    code, out, _ = call(capsys, "validate", write(tmp_path / "s.json", data))
    assert code == 0 and out.startswith("ok: python user_components:chain: 4 balls, 3 contacts")
    # a kind nobody registered is still an error naming the field
    with pytest.raises(ValueError, match=r"^geometry.kind: unknown kind 'ring'"):
        parse_spec({**data, "geometry": {"kind": "ring"}})
    assert "user_components" in sys.modules
