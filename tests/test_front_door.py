"""The package's face (`pinnedballs/__init__.py`, SPEC 1): ``import pinnedballs`` loads none of the heavy
dependencies and installs no import hook; every public name resolves on first use and ``dir`` lists them;
the command line still answers at once."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import pinnedballs as pb

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ["numpy", "numba", "scipy", "h5py", "networkx", "pydantic", "matplotlib", "dask", "pandas", "xarray",
         "gmpy2", "gsd", "tqdm", "hypothesis"]


def after_import(code: str = "") -> dict:
    report = ("print(json.dumps({'heavy': sorted({m.split('.')[0] for m in sys.modules} & set(HEAVY)), "
              "'hooks': [type(f).__name__ for f in sys.meta_path if f not in hooks]}))")
    probe = f"import sys, json\nhooks = list(sys.meta_path)\nimport pinnedballs\n{code}\nHEAVY = {HEAVY!r}\n{report}"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True)
    return json.loads(out.stdout.splitlines()[-1])


@pytest.mark.slow
def test_import_loads_nothing_heavy_and_installs_no_hook():
    assert after_import() == {"heavy": [], "hooks": []}


@pytest.mark.slow
def test_a_name_loads_what_it_needs_alone():
    """The errors a user catches need no numerics; a geometry needs numpy and numba, not h5py or dask."""
    assert after_import("pinnedballs.InputError, pinnedballs.FieldError")["heavy"] == []
    heavy = after_import("pinnedballs.HalfPlane")["heavy"]
    assert {"numpy", "numba"} <= set(heavy) and not {"h5py", "dask", "matplotlib", "hypothesis"} & set(heavy)


def stub_names() -> list[str]:
    tree = ast.parse((ROOT / "pinnedballs" / "__init__.pyi").read_text(encoding="utf-8"))
    return [alias.asname for node in tree.body if isinstance(node, ast.ImportFrom) for alias in node.names]


def test_every_public_name_resolves_and_dir_lists_it():
    names = stub_names()
    assert sorted(names) == pb.__all__ and len(names) == len(set(names))
    assert {"Simulation", "HalfPlane", "load", "run_spec", "GPUUnavailable", "__version__"} <= set(names)
    for name in names:
        assert getattr(pb, name) is not None, name
        if name != "__version__":
            assert getattr(pb, name).__name__ == name, name   # the object, not a module
    assert set(pb.__all__) <= set(dir(pb))


def test_an_unknown_name_is_an_attribute_error_naming_it():
    with pytest.raises(AttributeError, match="Simulaton"):
        pb.Simulaton  # noqa: B018


def test_the_stub_imports_each_name_as_itself():
    """``from .m import X as X``: the stub is what type checkers and the API page read as the package's names;
    lazy_loader maps each to its module by the name imported (an alias would load the wrong name)."""
    tree = ast.parse((ROOT / "pinnedballs" / "__init__.pyi").read_text(encoding="utf-8"))
    for node in tree.body:
        assert isinstance(node, ast.ImportFrom) and node.level == 1, ast.dump(node)
        assert all(alias.asname == alias.name for alias in node.names), ast.dump(node)
