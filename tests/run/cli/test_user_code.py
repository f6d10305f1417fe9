"""A user's code that fails (issue 26, items 1 and 2): a factory named by a spec that raises, exits,
returns the wrong thing, is interrupted or never returns, in every slot and every subcommand that
runs it, gives one line naming the slot, the factory and what the code did, exit status 2 (130
when interrupted), and writes nothing; ``--traceback`` shows the user's own traceback."""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import TORUS, call, spec, write

import pinnedballs as pb
from pinnedballs.specs import parse_spec

ROOT = Path(__file__).resolve().parents[3]

#: a user's module: factories that fail in every way, usable in any slot (initial gets the geometry first)
FAILING = '''
import sys, time
import numpy as np
import pinnedballs as pb

def boom(*args, **kwargs):
    raise RuntimeError("boom in the factory")

def missing_key(*args, **kwargs):
    return {}["x"]

def exit_0(*args, **kwargs):
    sys.exit(0)

def exit_3(*args, **kwargs):
    sys.exit(3)

def exit_none(*args, **kwargs):
    sys.exit()

def exit_text(*args, **kwargs):
    sys.exit("bye")

def ctrl_c(*args, **kwargs):
    raise KeyboardInterrupt

def text(*args, **kwargs):
    return "a torus, please"

def hang(*args, **kwargs):
    open(kwargs["mark"], "w").close()  # it has started
    while True:
        pass

class BrokenSweep(pb.Sweep):
    def selector(self, geometry):
        raise RuntimeError("selector broke")

def broken_sweep():
    return BrokenSweep()
'''

#: what each factory did, as the line says it
DID = {
    "boom": "raised RuntimeError: boom in the factory",
    "missing_key": "raised KeyError: 'x'",
    "exit_0": "called sys.exit(0)",
    "exit_3": "called sys.exit(3)",
    "exit_none": "called sys.exit()",
    "exit_text": "called sys.exit('bye')",
}

#: what a slot's factory that returns a string is told
WRONG_TYPE = {"geometry": "returned str, not a pinnedballs Geometry",
              "initial": "returned str, not an array (n_balls, dim) = (16, 2)",
              "rule": "returned str, not a pinnedballs CollisionRule",
              "scheduler": "returned str, not a pinnedballs Scheduler"}

COMMANDS = {
    "run": lambda s, out: ["run", s, "--out", out, "--quiet", "--no-figures"],
    "validate": lambda s, out: ["validate", s],
    "ensemble": lambda s, out: ["ensemble", s, "--replicas", "2", "--workers", "1", "--out", out, "--quiet"],
}

_count = [0]


def user_module(directory: Path, source: str = FAILING) -> str:
    """Write ``source`` as a module beside the specs, under a name no other test has imported."""
    _count[0] += 1
    name = f"pb_failing_{os.getpid()}_{_count[0]}"
    (directory / f"{name}.py").write_text(source)
    importlib.invalidate_caches()
    return name


def with_factory(slot: str, factory: str, **args) -> dict:
    """The small torus spec with its ``slot`` made by ``factory``."""
    return spec(TORUS, **{slot: {"kind": "python", "factory": factory, **({"args": args} if args else {})}})


def assert_one_line(code: int, err: str, line: str, status: int = 2) -> None:
    assert (code, err) == (status, f"pinnedballs: {line}\n")


@pytest.mark.parametrize("slot", ["geometry", "initial", "rule", "scheduler"])
@pytest.mark.parametrize("factory", [*DID, "text"])
def test_a_failing_factory_gives_one_line_naming_slot_factory_and_exception(tmp_path, slot, factory):
    name = user_module(tmp_path)
    spec_path = write(tmp_path / "s.json", with_factory(slot, f"{name}:{factory}"))
    did = WRONG_TYPE[slot] if factory == "text" else DID[factory]
    code, out, err = call(*COMMANDS["run"](spec_path, tmp_path / "out"))
    assert_one_line(code, err, f"error: {slot}.factory {name}:{factory} {did}")
    assert out == "" and not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["validate", "ensemble"])
@pytest.mark.parametrize("factory", ["boom", "missing_key", "exit_3", "exit_0"])
def test_every_command_that_runs_a_factory_says_the_same(tmp_path, command, factory):
    name = user_module(tmp_path)
    spec_path = write(tmp_path / "s.json", with_factory("geometry", f"{name}:{factory}"))
    code, out, err = call(*COMMANDS[command](spec_path, tmp_path / "out"))
    assert_one_line(code, err, f"error: geometry.factory {name}:{factory} {DID[factory]}")
    assert out == "" and not (tmp_path / "out").exists()


@pytest.mark.parametrize("slot", ["geometry", "initial", "rule", "scheduler"])
def test_a_ctrl_c_inside_a_factory_is_an_interrupt(tmp_path, slot):
    name = user_module(tmp_path)
    spec_path = write(tmp_path / "s.json", with_factory(slot, f"{name}:ctrl_c"))
    out = tmp_path / "out"
    code, _, err = call(*COMMANDS["run"](spec_path, out))
    assert_one_line(code, err, f"interrupted before the run wrote anything in {out}", status=130)
    assert not out.exists()
    code, _, err = call(*COMMANDS["validate"](spec_path, out))
    assert_one_line(code, err, "interrupted", status=130)


def test_a_component_that_fails_in_its_own_code_names_its_slot_and_method(tmp_path):
    name = user_module(tmp_path)
    spec_path = write(tmp_path / "s.json", with_factory("scheduler", f"{name}:broken_sweep"))
    code, _, err = call(*COMMANDS["run"](spec_path, tmp_path / "out"))
    assert_one_line(code, err, f"error: scheduler.factory {name}:broken_sweep made a BrokenSweep whose selector() "
                               f"raised RuntimeError: selector broke")
    assert not (tmp_path / "out").exists()


#: a user's scheduler whose every pick is out of range: the run is refused at its first pick
BEYOND = '''
import numpy as np
import pinnedballs as pb
from numba import njit

@njit
def pick_beyond(state, rng, n_contacts):
    return np.int64(n_contacts + 5), rng

class BeyondPick(pb.Scheduler):
    def kernel(self):
        return pick_beyond

def beyond_pick():
    return BeyondPick()
'''


@pytest.mark.parametrize("before, flag", [(None, None), ([], None), (["notes.txt"], "--force"), (None, "--resume")],
                         ids=["no directory", "an empty one", "--force, a file of the user's", "--resume, none"])
def test_a_run_refused_at_its_first_pick_leaves_the_directory_as_it_was(tmp_path, before, flag):
    """Issue 34, item 7: exit 2, one line, and no output: before, the run's directory stayed, holding
    results.h5 ("interrupted" at step 0), its data and spec.json (and the directories made for it)."""
    name = f"pb_beyond_{os.getpid()}"  # one module for every case: its pick compiles once
    (tmp_path / f"{name}.py").write_text(BEYOND)
    importlib.invalidate_caches()
    spec_path = write(tmp_path / "s.json", with_factory("scheduler", f"{name}:beyond_pick"))
    out = tmp_path / "made" / "out"  # a parent made for it is removed too
    if before is not None:
        out.mkdir(parents=True)
        for file in before:
            (out / file).write_text("mine")
    code, stdout, err = call(*COMMANDS["run"](spec_path, out), *([flag] if flag else []))
    if flag == "--resume":  # what it says as it starts
        said, _, err = err.partition("\n")
        assert said == f"pinnedballs: --resume: {out} holds no run yet (no such directory): starting it"
    assert_one_line(code, err, "error: scheduler: BeyondPick.kernel()'s pick 'pick_beyond' picked contact 53, "
                               "but there are 48 contacts (0 to 47)")
    assert stdout == ""
    if before is None:
        assert not (tmp_path / "made").exists()
    else:
        assert sorted(p.name for p in out.iterdir()) == before and all(
            (out / file).read_text() == "mine" for file in before)


@pytest.mark.parametrize("body, did", [
    ("raise RuntimeError('broken at import')", "raised RuntimeError: broken at import"),
    ("import sys\nsys.exit(4)", "called sys.exit(4)"),
])
def test_a_module_that_fails_as_it_is_imported(tmp_path, body, did):
    name = user_module(tmp_path, body + "\ndef chain():\n    pass\n")
    spec_path = write(tmp_path / "s.json", with_factory("geometry", f"{name}:chain"))
    for command in ("validate", "run"):
        code, out, err = call(*COMMANDS[command](spec_path, tmp_path / "out"))
        assert_one_line(code, err, f"error: geometry.factory {name}:chain could not be imported: module {name!r} {did}")
    assert not (tmp_path / "out").exists()


def test_traceback_shows_the_users_own_code(tmp_path):
    name = user_module(tmp_path)
    spec_path = write(tmp_path / "s.json", with_factory("rule", f"{name}:boom"))
    for command in ("run", "validate", "ensemble"):
        code, out, err = call(*COMMANDS[command](spec_path, tmp_path / "out"), "--traceback")
        line = f"pinnedballs: error: rule.factory {name}:boom raised RuntimeError: boom in the factory"
        assert code == 2 and err.startswith("Traceback (most recent call last):\n") and err.endswith(f"\n{line}\n")
        assert f'{name}.py", line 7, in boom\n    raise RuntimeError("boom in the factory")\n' in err
        assert "RuntimeError: boom in the factory\n\nThe above exception was the direct cause" in err
    assert not (tmp_path / "out").exists()


def test_python_sees_the_same_error_with_the_users_exception_as_its_cause(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(tmp_path))
    name = user_module(tmp_path)
    with pytest.raises(pb.SpecError, match=rf"^initial.factory {name}:missing_key raised KeyError: 'x'$") as caught:
        parse_spec(with_factory("initial", f"{name}:missing_key")).build()
    assert caught.value.field == "initial.factory" and isinstance(caught.value.__cause__, KeyError)


def test_an_entry_point_kind_that_fails_names_its_factory(tmp_path, monkeypatch):
    name = user_module(tmp_path)
    dist = tmp_path / "failing_components-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: failing-components\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text(f"[pinnedballs.rules]\nboom = {name}:boom\n\n"
                                           f"[pinnedballs.schedulers]\nquits = {name}:exit_3\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    for slot, kind, factory in (("rule", "boom", "boom"), ("scheduler", "quits", "exit_3")):
        spec_path = write(tmp_path / "s.json", spec(TORUS, **{slot: {"kind": kind}}))
        for command in ("run", "validate"):
            code, _, err = call(*COMMANDS[command](spec_path, tmp_path / "out"))
            assert_one_line(code, err, f"error: {slot}.factory {name}:{factory} {DID[factory]}")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- a factory that never returns


def start(argv: list, cwd: Path, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "pinnedballs", *map(str, argv)], cwd=cwd, stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT), **(env or {})})


HANGS = [("geometry", signal.SIGINT, "run"), ("initial", signal.SIGTERM, "run"), ("rule", signal.SIGTERM, "run"),
         ("scheduler", signal.SIGINT, "run"), ("geometry", signal.SIGTERM, "validate"),
         ("entry point", signal.SIGTERM, "run"), ("import", signal.SIGINT, "run"),
         ("import", signal.SIGTERM, "validate")]


@pytest.mark.slow
@pytest.mark.parametrize("where, signum, command", HANGS, ids=[f"{w}-{g.name}-{c}" for w, g, c in HANGS])
def test_a_factory_that_never_returns_stops_at_once_on_a_signal(tmp_path, where, signum, command):
    """In any slot, as an entry-point kind, or as its module is imported (spec validation)."""
    mark = tmp_path / "started"
    env = {}
    if where == "import":
        name = user_module(tmp_path, f"open({str(mark)!r}, 'w').close()\nwhile True:\n    pass\n")
        data = with_factory("geometry", f"{name}:anything")
    elif where == "entry point":
        name = user_module(tmp_path)
        dist = tmp_path / "hanging_components-1.0.dist-info"
        dist.mkdir()
        (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: hanging-components\nVersion: 1.0\n")
        (dist / "entry_points.txt").write_text(f"[pinnedballs.schedulers]\nforever = {name}:hang\n")
        data = spec(TORUS, scheduler={"kind": "forever", "mark": str(mark)})
        env = {"PYTHONPATH": f"{ROOT}{os.pathsep}{tmp_path}"}
    else:
        data = with_factory(where, f"{user_module(tmp_path)}:hang", mark=str(mark))
    spec_path = write(tmp_path / "s.json", data)
    out = tmp_path / "out"
    child = start(COMMANDS[command](spec_path, out), cwd=tmp_path, env=env)
    deadline = time.monotonic() + 120
    while not mark.exists():
        assert child.poll() is None and time.monotonic() < deadline, child.communicate()
        time.sleep(0.02)
    child.send_signal(signum)
    sent = time.monotonic()
    _, err = child.communicate(timeout=60)
    assert time.monotonic() - sent < 10, "the command went on after the signal"
    line = f"interrupted before the run wrote anything in {out}" if command == "run" else "interrupted"
    assert (child.returncode, err) == (130, f"pinnedballs: {line}\n")
    assert not out.exists()


# ---------------------------------------------------------------- a rule numba cannot compile

#: a user's rule numba cannot compile: a dict whose keys are of two types (issue 49, item 5)
KEYED = '''
import numpy as np
from numba import njit
import pinnedballs as pb
from pinnedballs.rules import closing_speed, remnant_threshold

@njit(inline="always")
def collide_keyed(v, units, i, j, a, b, masses, params, dim, flat, write):
    weights = {1: 2.0, "two": 3.0}
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    return w > remnant_threshold(params) and weights[1] > 0.0

class Keyed(pb.CollisionRule):
    def kernel(self, equal_masses):
        return collide_keyed, np.array([0.0])

def keyed():
    return Keyed()
'''
#: the first words of what numba says of it
NUMBA_SAID = "No implementation of function Function(<built-in function setitem>) found for signature setitem("


def keyed_rule(tmp_path: Path, **changes) -> tuple[Path, str]:
    """A spec whose rule is `KEYED`'s, and the start of the one line that refuses it, and its end (the place)."""
    name = user_module(tmp_path, KEYED)
    line = 1 + KEYED.splitlines().index('    weights = {1: 2.0, "two": 3.0}')
    spec_path = write(tmp_path / "s.json", spec(with_factory("rule", f"{name}:keyed"), **changes))
    return spec_path, f"pinnedballs: error: rule.factory {name}:keyed made a Keyed that numba cannot compile", \
        f" ({(tmp_path / f'{name}.py').resolve()}:{line})\n"


@pytest.mark.slow
def test_a_rule_numba_cannot_compile_is_one_line_and_writes_nothing(tmp_path):
    """Before: exit 1, 122 lines of numba's, and an empty run directory left (a run --force replaced, gone)."""
    spec_path, said, where = keyed_rule(tmp_path)
    out = tmp_path / "made" / "out"
    code, stdout, err = call(*COMMANDS["run"](spec_path, out))
    assert (code, stdout, err.count("\n")) == (2, "", 1) and err.startswith(f"{said}: {NUMBA_SAID}"), err
    assert err.endswith(where) and not (tmp_path / "made").exists()
    done = tmp_path / "done"
    assert call(*COMMANDS["run"](write(tmp_path / "torus.json", TORUS), done))[0] == 0
    before = (done / "results.h5").read_bytes()
    code, _, err = call(*COMMANDS["run"](spec_path, done), "--force", "--traceback")
    assert code == 2 and err.endswith(f"{where}") and f"\n{said}: {NUMBA_SAID}" in err
    assert "Failed in nopython mode pipeline" in err and err.count("\n") > 20  # numba's own words, whole
    assert (done / "results.h5").read_bytes() == before and pb.load(done).status == "done"  # the run replaced stays


@pytest.mark.slow
@pytest.mark.cuda
def test_a_rule_numba_cannot_compile_for_a_gpu_nor_the_cpu_says_so(tmp_path):
    """``--device cuda`` (the simulator checks the rule as a GPU does): before, "numba-cuda cannot compile it ...;
    device='cpu' runs it", which it does not."""
    spec_path, said, where = keyed_rule(tmp_path, scheduler={"kind": "uniform_random_pair", "stream": "counter"})
    code, _, err = call(*COMMANDS["run"](spec_path, tmp_path / "out"), "--device", "cuda")
    assert (code, err.count("\n")) == (2, 1) and err.startswith(f"{said}, for a GPU or for the CPU: {NUMBA_SAID}")
    assert err.endswith(where) and "device='cpu' runs it" not in err and not (tmp_path / "out").exists()
