"""The library does not load its command line: ``import pinnedballs`` and every library module
import neither ``cli`` nor the paper's reproduction; and its rooms stand in floors, every import running down."""

from __future__ import annotations

import ast
import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import pytest

import pinnedballs

ROOT = Path(__file__).resolve().parents[2]
FRONT_ENDS = {"pinnedballs.run.cli", "pinnedballs.__main__", "pinnedballs.run.reproduction"}


def loaded_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"],
                         env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}, check=True, capture_output=True,
                         text=True).stdout
    return {m for m in json.loads(out) if m.startswith("pinnedballs")}


@pytest.mark.slow
def test_import_pinnedballs_loads_its_face_alone_and_a_name_loads_no_front_end():
    assert loaded_after("import pinnedballs") == {"pinnedballs"}
    loaded = loaded_after("import pinnedballs as pb\npb.ResultsWriter, pb.Simulation, pb.run_spec")
    assert not {m for m in loaded
                if m in FRONT_ENDS or m.startswith(("pinnedballs.run.reproduction.", "pinnedballs.run.cli."))}
    assert {"pinnedballs.run.writers", "pinnedballs.engine.driver", "pinnedballs.engine.triggers"} <= loaded


@pytest.mark.slow
def test_no_library_module_imports_the_command_line():
    library = sorted(m.name for m in pkgutil.walk_packages(pinnedballs.__path__, "pinnedballs.")
                     if m.name not in FRONT_ENDS
                     and not m.name.startswith(("pinnedballs.run.reproduction", "pinnedballs.run.cli")))
    assert "pinnedballs.specs.run" in library and "pinnedballs.run.ensemble" in library
    loaded = loaded_after("\n".join(f"import {m}" for m in library))
    assert not {m for m in loaded if m.startswith("pinnedballs.run.cli")}


def _room_imports() -> dict[str, set[str]]:
    """``{room: rooms it imports}``: a room is a top-level module or subpackage of pinnedballs (the
    package's ``__init__`` one of its own); every import counts, those inside functions too."""
    package = Path(pinnedballs.__file__).parent
    names = {p.stem for p in package.iterdir() if p.suffix == ".py" or (p / "__init__.py").exists()}
    rooms: dict[str, set[str]] = {}
    for path in package.rglob("*.py"):
        parts = path.relative_to(package).with_suffix("").parts
        room, here = parts[0], ("pinnedballs", *parts[:-1])
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                base = ".".join([*here[:len(here) - node.level + 1], node.module or ""] if node.level
                                else [node.module])
                targets = [f"{base.strip('.')}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                continue
            for target in targets:
                top = target.split(".")
                if top[0] == "pinnedballs":
                    to = top[1] if len(top) > 1 and top[1] in names else "__init__"
                    if to != room:
                        rooms.setdefault(room, set()).add(to)
    return rooms


def test_every_import_runs_down_the_house():
    """The rooms (engine, geometry, plot, run, ...) stand in floors: no room imports one that imports it,
    even through others or inside a function, so none reaches up (the geometry's pictures are handed to
    it by `plot.display`, and the `Simulation` stands below the specs, results and analysis that use it)."""
    rooms = _room_imports()
    assert {"geometry", "plot", "results", "run"} <= set(rooms) and "engine" in rooms["geometry"]
    for room in rooms:
        seen, todo = set(), list(rooms.get(room, ()))
        while todo:
            other = todo.pop()
            if other not in seen:
                seen.add(other)
                todo.extend(rooms.get(other, ()))
        assert room not in seen, \
            f"{room} reaches itself through {sorted(seen & {r for r in rooms if room in rooms[r]})}"
