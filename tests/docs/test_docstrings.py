"""The public API's docstrings are numpydoc, and their examples run.

Public: every name of `pb.__all__`, of `pinnedballs.testing` and of the engine's door (`pinnedballs.engine`),
and the public methods of their classes: every one of the classes a user holds (`HELD`); of the others, those
the API page shows, the methods a user's component overrides among them (`Scheduler.kernel`, `Writer.write`).
numpydoc's validator finds on none of them a parameter left undocumented (PR01), one documented that is not
there (PR02), a value returned with no Returns section (RT01) or no docstring at all (GL08); the main names
have an Examples section (`EXAMPLED`); and every public docstring's examples run as doctests, in a temporary
working directory (examples write relative paths).
"""

from __future__ import annotations

import doctest
import importlib
import inspect
import re
from pathlib import Path

import pytest
from numpydoc.validate import validate

import pinnedballs as pb

DOCS = Path(__file__).resolve().parents[2] / "docs"
#: the engine's door: `pinnedballs.engine`'s names
ENGINE_DOOR = ("engines", "register", "unregister", "find", "choose", "check", "Engine", "Refusal", "Refused",
               "Device", "CPU", "CUDA", "as_device")
#: the classes a user holds: every public method is public, whatever the API page shows (with every `Geometry`)
HELD = ("Simulation", "Results", "Geometry", "EnsembleResult", "StudyResult")
#: the numpydoc errors the public API may not have
REFUSED = {"PR01": "parameters not documented", "PR02": "unknown parameters documented",
           "RT01": "no Returns section", "GL08": "no docstring"}
#: the main classes and functions: each has an Examples section
EXAMPLED = ("Simulation", "HalfPlane", "FlatTorus", "GraphGeometry", "Sphere", "HyperbolicPlane", "FCC", "HCP",
            "Elastic", "Restitution", "UniformRandomPair", "Sweep", "RandomSweep", "RejectionFree", "ColoredSweep",
            "Replay", "load", "load_spec", "run_spec", "run_ensemble", "load_ensemble", "run_study", "load_study",
            "explore_orders", "search_max_collisions", "ResultsWriter", "CollisionLog", "Stop", "AtSteps",
            "EverySteps", "AtCollisions", "EveryCollisions", "CPU", "CUDA", "testing.check_engine",
            "testing.check_geometry", "testing.check_rule", "testing.check_scheduler", "engine.engines",
            "engine.choose", "Simulation.run")


def _methods(cls: type, names: dict) -> dict:
    """``{qualified name: function}`` of the public methods ``cls`` has from the package's classes (named by
    the class that defines them: `pb.NAME` where public, else its module's path)."""
    out = {}
    for name in sorted(dir(cls)):
        owner = next((k for k in cls.__mro__ if name in vars(k)), None)
        if name.startswith("_") or owner is None or not owner.__module__.startswith("pinnedballs"):
            continue
        raw = vars(owner)[name]
        func = raw.__func__ if isinstance(raw, (staticmethod, classmethod)) else raw
        if inspect.isfunction(func) and func.__module__.startswith("pinnedballs"):
            prefix = f"pinnedballs.{names[owner]}" if owner in names else f"{owner.__module__}.{owner.__qualname__}"
            out[f"{prefix}.{name}"] = func
    return out


def _properties(cls: type) -> dict:
    """``{qualified name: property}`` of the public properties defined on ``cls`` itself."""
    return {f"{cls.__module__}.{cls.__qualname__}.{name}": raw for name, raw in vars(cls).items()
            if not name.startswith("_") and isinstance(raw, property)}


def public() -> dict:
    """``{qualified name: object}`` of every public callable, each once."""
    import pinnedballs.engine as door
    import pinnedballs.testing as testing

    out, seen = {}, set()
    for prefix, module, names in (("pinnedballs", pb, pb.__all__), ("pinnedballs.testing", testing, testing.__all__),
                                  ("pinnedballs.engine", door, ENGINE_DOOR)):
        for name in names:
            obj = getattr(module, name)
            if callable(obj) and id(obj) not in seen:
                seen.add(id(obj))
                out[f"{prefix}.{name}"] = obj
    named = {getattr(pb, n): n for n in pb.__all__ if inspect.isclass(getattr(pb, n))}
    shown = _members_shown()
    for name, cls in [(n, obj) for n, obj in out.items() if inspect.isclass(obj)]:
        methods = _methods(cls, named)
        if name in shown and not (name.removeprefix("pinnedballs.") in HELD or issubclass(cls, pb.Geometry)):
            methods = {k: f for k, f in methods.items() if k.rpartition(".")[2] in shown[name]}
        out.update((k, f) for k, f in methods.items() if id(f) not in seen and not seen.add(id(f)))
    return out


def _members_shown() -> dict:
    """``{name: members}`` of the API page's entries that show only some members (``members: [a, b]``, or
    ``members: false``: none)."""
    shown, entry = {}, None
    for line in (DOCS / "api.md").read_text(encoding="utf-8").splitlines():
        if line.startswith("::: "):
            entry = line[4:].strip()
        elif entry and (m := re.fullmatch(r"\s+members:\s*(.*)", line)):
            listed = m.group(1).strip()
            shown[entry] = () if listed == "false" else tuple(x.strip() for x in listed.strip("[]").split(","))
        elif not line.startswith(" "):
            entry = None
    return shown


PUBLIC = public()


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_every_public_callable_has_numpydoc_parameters_and_returns(name):
    errors = [f"{code} ({REFUSED[code]}): {message}" for code, message in validate(name)["errors"] if code in REFUSED]
    assert not errors, f"{name}: " + "; ".join(errors)


@pytest.mark.parametrize("name", EXAMPLED)
def test_the_main_names_have_examples(name):
    full = f"pinnedballs.{name}"
    assert full in PUBLIC, f"{full} is not a public callable"
    assert "EX01" not in {code for code, _ in validate(full)["errors"]}, f"{full} has no Examples section"


def _on_the_api_page() -> dict:
    """``{name: object}`` of every entry of docs/api.md (``::: pinnedballs.x.y``): a module or a module's name."""
    out = {}
    for name in re.findall(r"^::: (\S+)", (DOCS / "api.md").read_text(encoding="utf-8"), flags=re.M):
        try:
            out[name] = importlib.import_module(name)
        except ModuleNotFoundError:
            module, _, attr = name.rpartition(".")
            out[name] = getattr(importlib.import_module(module), attr)
    return out


def _doctests() -> dict:
    """``{name: doctest}`` of every public docstring with examples: the callables, their classes'
    properties, and what the API page shows (the modules' own docstrings, and the names for extensions)."""
    finder = doctest.DocTestFinder(recurse=False)
    objects = dict(PUBLIC)
    for obj in list(PUBLIC.values()):
        if inspect.isclass(obj) and obj.__module__.startswith("pinnedballs"):
            objects.update(_properties(obj))
    shown = {id(obj) for obj in objects.values()}
    objects.update((k, v) for k, v in _on_the_api_page().items() if id(v) not in shown)
    tests = {}
    for name, obj in objects.items():
        module = obj if inspect.ismodule(obj) else inspect.getmodule(getattr(obj, "fget", obj))
        for test in finder.find(obj, name, module=module, globs={}):
            if test.examples:
                tests[name] = test
    return tests


DOCTESTS = _doctests()


@pytest.mark.slow  # 73 docstrings' examples: about 3 s with numba's cache warm, minutes on an empty one
@pytest.mark.parametrize("name", sorted(DOCTESTS))
def test_the_examples_run(name, tmp_path, monkeypatch):
    """Each docstring's examples give what they show, in a fresh directory (what they write stays there), the
    observables they register forgotten after them."""
    from pinnedballs.analysis.observables import OBSERVABLES

    monkeypatch.chdir(tmp_path)
    registered = dict(OBSERVABLES)
    test = DOCTESTS[name]
    test.globs = {"__name__": f"doctest_{name.replace('.', '_')}"}
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report = []
    try:
        result = runner.run(test, out=report.append, clear_globs=True)
    finally:
        OBSERVABLES.clear()
        OBSERVABLES.update(registered)
    assert result.failed == 0, "".join(report)
