"""A user's components in specs: ``{"kind": "python", "factory": "module:callable", "args": {...}}``,
and kinds registered by installed packages through entry points."""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import write

import pinnedballs as pb
from pinnedballs.run.cli import main as cli
from pinnedballs.specs import parse_spec

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
     "geometry.factory: cannot import module 'no_such_module_xyz' (No module named 'no_such_module_xyz'); make it "
     "importable: put the directory holding it on PYTHONPATH, or run from that directory"),
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
    assert code == 2 and err == ("pinnedballs: error: rule.factory user_components:not_a_rule returned int, "
                                 "not a pinnedballs CollisionRule\n")
    data = {**CHAIN, "geometry": {**CHAIN["geometry"], "args": {"n": 6, "colour": "red"}}}
    code, _, err = call(capsys, "validate", write(tmp_path / "s.json", data))
    assert code == 2 and err == ("pinnedballs: error: geometry.factory user_components:chain raised TypeError: "
                                 "chain() got an unexpected keyword argument 'colour'\n")


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


# ---------------------------------------------------------------- runs of a user's module (issue 20, item 1)

#: a user's module, written beside a spec under a name no other test uses
MODULE = '''
import numpy as np
import pinnedballs as pb

def chain(n):
    return pb.GraphGeometry.from_positions(np.column_stack([2.0 * np.arange(n), np.zeros(n)]))

def reversed_speeds(geometry, speed):
    n = geometry.n_balls
    return np.column_stack([speed * (n - np.arange(n)), np.zeros(n)])

def half_elastic():
    return pb.Restitution(0.5)

def sweep():
    return pb.Sweep()
'''


def user_run(directory, name: str, stop: dict) -> dict:
    """Write the module ``name`` into ``directory``; a spec naming its four components."""
    directory.mkdir(parents=True, exist_ok=True)
    (directory / f"{name}.py").write_text(MODULE)
    return {"geometry": {"kind": "python", "factory": f"{name}:chain", "args": {"n": 6}},
            "initial": {"kind": "python", "factory": f"{name}:reversed_speeds", "args": {"speed": 0.5}},
            "rule": {"kind": "python", "factory": f"{name}:half_elastic"},
            "scheduler": {"kind": "python", "factory": f"{name}:sweep"},
            "stop": stop, "snapshots": {"every_steps": 2}, "seed": 0}


def forget(name: str) -> None:
    """As in a new Python session: the module is not imported."""
    sys.modules.pop(name, None)
    importlib.invalidate_caches()


def test_a_run_of_a_users_module_reads_without_it_and_continues_with_it(tmp_path, monkeypatch, capsys):
    name = "pb_user_module_reading"
    code_dir = tmp_path / "code"
    data = user_run(code_dir, name, {"steps": 10})
    sys.path.insert(0, str(code_dir))
    try:
        code, _, err = call(capsys, "run", write(tmp_path / "s.json", data), "--out", tmp_path / "r", "--quiet")
    finally:
        sys.path.remove(str(code_dir))
    assert code == 0, err
    forget(name)
    with pytest.raises(ImportError):
        importlib.import_module(name)  # not importable any more
    res = pb.load(tmp_path / "r")
    assert (res.steps, len(res.snapshots), res.geometry.n_balls, res.geometry.n_contacts) == (10, 5, 6, 5)
    assert res.kinds == {"geometry": f"{name}:chain", "initial": f"{name}:reversed_speeds",
                         "rule": f"{name}:half_elastic", "scheduler": f"{name}:sweep"}
    code, out, err = call(capsys, "info", tmp_path / "r")
    assert (code, err) == (0, "")
    assert f"geometry:    {name}:chain: 6 balls, 5 contacts, dim 2\n" in out
    assert f"run:         {name}:reversed_speeds, {name}:half_elastic, {name}:sweep, seed 0\n" in out
    code, out, err = call(capsys, "plot", tmp_path / "r")
    assert (code, err) == (0, "") and (tmp_path / "r" / "state_final.png").exists()
    # continuing the run needs the module: the message names it and how to make it importable
    with pytest.raises(pb.InputError) as caught:
        res.simulation()
    assert str(caught.value) == (
        f"{tmp_path / 'r'}: continuing this run needs the code its spec names: rule.factory: cannot import module "
        f"'{name}' (No module named '{name}'); make it importable: put the directory holding it on PYTHONPATH, "
        f"or run from that directory")
    # importable again: reading still runs none of it, continuing goes on to the bits of an unbroken run
    monkeypatch.syspath_prepend(str(code_dir))
    res = pb.load(tmp_path / "r")
    call(capsys, "info", tmp_path / "r")
    assert name not in sys.modules
    sim = res.simulation()
    sim.run(steps=8)
    unbroken = parse_spec(user_run(code_dir, name, {"steps": 18})).build()
    unbroken.run(steps=18)
    assert sim.get_state().identical(unbroken.get_state())


@pytest.mark.parametrize("where", ["beside the spec", "in the working directory"])
def test_the_command_line_finds_a_users_module(tmp_path, monkeypatch, capsys, where):
    name = f"pb_user_module_{where.split()[-1]}"
    data = user_run(tmp_path / "code", name, {"steps": 10})
    (tmp_path / "specs").mkdir()
    spec_path = write((tmp_path / "code" if where == "beside the spec" else tmp_path / "specs") / "s.json", data)
    monkeypatch.chdir(tmp_path / "specs" if where == "beside the spec" else tmp_path / "code")
    code, out, err = call(capsys, "run", spec_path, "--out", tmp_path / "r", "--quiet", "--no-figures")
    assert (code, err) == (0, "") and pb.load(tmp_path / "r").steps == 10
    code, out, err = call(capsys, "validate", spec_path)
    assert (code, err) == (0, "") and out.startswith(f"ok: python {name}:chain: 6 balls")
    assert str(tmp_path / "code") not in sys.path  # the command put it on the path for its own run only
    forget(name)


@pytest.mark.slow
@pytest.mark.parametrize("where", ["beside the spec", "in the working directory"])
def test_the_console_command_finds_a_users_module(tmp_path, where):
    """The installed ``pinnedballs`` script, not ``python -m``: its sys.path starts in the venv's bin."""
    name = "pb_user_module_script"
    data = user_run(tmp_path / "code", name, {"steps": 10})
    (tmp_path / "specs").mkdir()
    spec_path = write((tmp_path / "code" if where == "beside the spec" else tmp_path / "specs") / "s.json", data)
    cwd = tmp_path / "specs" if where == "beside the spec" else tmp_path / "code"
    script = Path(sys.executable).parent / "pinnedballs"
    done = subprocess.run([str(script), "validate", str(spec_path)], cwd=cwd, capture_output=True, text=True,
                          env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"}, timeout=120)
    assert (done.returncode, done.stderr) == (0, "") and done.stdout.startswith(f"ok: python {name}:chain")
