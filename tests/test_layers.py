"""The library does not load its command line: ``import pinnedballs`` and every library module
import neither ``cli`` nor the paper's reproduction."""

from __future__ import annotations

import pytest

import json
import pkgutil
import subprocess
import sys
from pathlib import Path

import pinnedballs

ROOT = Path(__file__).resolve().parents[2]
FRONT_ENDS = {"pinnedballs.cli", "pinnedballs.__main__", "pinnedballs.reproduction"}


def loaded_after(code: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"],
                         env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"}, check=True, capture_output=True,
                         text=True).stdout
    return {m for m in json.loads(out) if m.startswith("pinnedballs")}


@pytest.mark.slow
def test_import_pinnedballs_loads_no_front_end():
    loaded = loaded_after("import pinnedballs")
    assert not {m for m in loaded if m in FRONT_ENDS or m.startswith(("pinnedballs.reproduction.", "pinnedballs.cli."))}
    assert {"pinnedballs.run.writers", "pinnedballs.engine.driver", "pinnedballs.engine.triggers"} <= loaded


@pytest.mark.slow
def test_no_library_module_imports_the_command_line():
    library = sorted(m.name for m in pkgutil.walk_packages(pinnedballs.__path__, "pinnedballs.")
                     if m.name not in FRONT_ENDS and not m.name.startswith(("pinnedballs.reproduction", "pinnedballs.cli")))
    assert "pinnedballs.specs.run" in library and "pinnedballs.run.ensemble" in library
    loaded = loaded_after("\n".join(f"import {m}" for m in library))
    assert not {m for m in loaded if m.startswith("pinnedballs.cli")}
