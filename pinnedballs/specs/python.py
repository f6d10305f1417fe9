"""A user's own components in specs: ``{"kind": "python", "factory": "module:callable", "args": {...}}``.

The callable is imported when the spec is validated and called with ``args`` when it is
built; it returns the component: a `Geometry`, a `CollisionRule`, a `Scheduler`, or for
the initial velocities an array ``(n_balls, dim)`` (it is called as ``factory(geometry, **args)``).
**A spec that names Python code runs that code**: validate only specs you trust.

A spec read back from a results file is validated with the context ``{IMPORT_FACTORIES: False}``:
reading a run needs no user code (its geometry is stored), and runs none; only building a
component (continuing the run) imports its factory.

Installed packages may register named kinds under the entry-point groups
``pinnedballs.geometries``, ``pinnedballs.rules`` and ``pinnedballs.schedulers``
(name: the kind, value: ``module:callable``); a spec then says ``{"kind": NAME, **args}``,
which reads as the ``python`` form with that factory.
"""

from __future__ import annotations

import importlib
import importlib.metadata
from typing import Any, Callable, Literal

import numpy as np
from pydantic import ValidationInfo, field_validator

from .errors import SpecError
from ..geometry.base import Geometry
from ..rules import CollisionRule
from ..schedulers.base import Scheduler
from .base import _Spec, engine_errors

__all__ = ["PythonGeometrySpec", "PythonInitialSpec", "PythonRuleSpec", "PythonSchedulerSpec",
           "ENTRY_POINT_GROUPS", "IMPORT_FACTORIES", "import_factory", "expand_entry_points", "label"]

#: spec slot -> entry-point group whose names are kinds of that slot
ENTRY_POINT_GROUPS = {"geometry": "pinnedballs.geometries", "rule": "pinnedballs.rules",
                      "scheduler": "pinnedballs.schedulers"}


#: the validation context key that, set to False, validates factories without importing them
IMPORT_FACTORIES = "import_factories"


def _split(reference: str) -> tuple[str, str]:
    """``(module, callable)`` of ``"module:callable"``; a ValueError if it is not of that form."""
    module_name, sep, name = reference.partition(":")
    if not sep or not module_name or not name:
        raise ValueError(f'must be "module:callable", got {reference!r}')
    return module_name, name


def import_factory(reference: str) -> Callable:
    """The callable named ``"module:callable"`` (``callable`` may be dotted); a ValueError saying
    what is missing and, for a module that is not found, how to make it importable."""
    module_name, name = _split(reference)
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        if exc.name is not None and f"{module_name}.".startswith(f"{exc.name}."):  # the module itself is missing
            raise ValueError(f"cannot import module {module_name!r} ({exc}); make it importable: put the "
                             f"directory holding it on PYTHONPATH, or run from that directory") from None
        raise ValueError(f"importing module {module_name!r} failed ({exc})") from None
    target: Any = module
    for part in name.split("."):
        if not hasattr(target, part):
            raise ValueError(f"module {module_name!r} has no attribute {name!r}")
        target = getattr(target, part)
    if not callable(target):
        raise ValueError(f"{reference!r} is not callable")
    return target


class _PythonSpec(_Spec):
    kind: Literal["python"] = "python"
    factory: str
    args: dict[str, Any] = {}

    @field_validator("factory")
    @classmethod
    def _importable(cls, value: str, info: ValidationInfo) -> str:
        if (info.context or {}).get(IMPORT_FACTORIES, True):
            import_factory(value)
        else:
            _split(value)
        return value

    def _call(self, slot: str, *positional) -> Any:
        try:
            factory = import_factory(self.factory)
        except ValueError as exc:
            raise SpecError(f"{slot}.factory", str(exc)) from None
        with engine_errors(slot):
            return factory(*positional, **self.args)

    def _check(self, slot: str, made: Any, expected: type) -> Any:
        if not isinstance(made, expected):
            raise SpecError(f"{slot}.factory", f"{self.factory} returned {type(made).__name__}, "
                                               f"not a pinnedballs {expected.__name__}")
        return made


class PythonGeometrySpec(_PythonSpec):
    """A geometry made by the user's ``factory(**args)``."""

    def build(self) -> Geometry:
        return self._check("geometry", self._call("geometry"), Geometry)


class PythonInitialSpec(_PythonSpec):
    """Initial velocities ``(n_balls, dim)`` made by the user's ``factory(geometry, **args)``."""

    def build(self, geometry: Geometry, masses: np.ndarray, seed: np.random.SeedSequence) -> np.ndarray:
        v = self._call("initial", geometry)
        try:
            return np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            raise SpecError("initial.factory", f"{self.factory} returned {type(v).__name__}, "
                                               f"not an array (n_balls, dim)") from None


class PythonRuleSpec(_PythonSpec):
    """A collision rule made by the user's ``factory(**args)``."""

    def build(self) -> CollisionRule:
        return self._check("rule", self._call("rule"), CollisionRule)


class PythonSchedulerSpec(_PythonSpec):
    """A scheduler made by the user's ``factory(**args)``."""

    def build(self) -> Scheduler:
        return self._check("scheduler", self._call("scheduler"), Scheduler)


def label(component) -> str:
    """What a component spec is called in summaries: its factory for a user's own, else its kind."""
    return component.factory if isinstance(component, _PythonSpec) else component.kind


def expand_entry_points(data: Any, builtin: dict[str, set[str]]) -> Any:
    """``data`` (a spec as a dict) with each component whose kind an installed package registers
    (and that is not a built-in kind of ``builtin[slot]``) rewritten in the ``python`` form."""
    if not isinstance(data, dict):
        return data
    out = dict(data)
    for slot, group in ENTRY_POINT_GROUPS.items():
        component = out.get(slot)
        kind = component.get("kind") if isinstance(component, dict) else None
        if not isinstance(kind, str) or kind in builtin.get(slot, set()) | {"python"}:
            continue  # not a registered name: pydantic names what is wrong with it
        found = [ep for ep in importlib.metadata.entry_points(group=group) if ep.name == component["kind"]]
        if found:
            args = {k: v for k, v in component.items() if k != "kind"}
            out[slot] = {"kind": "python", "factory": found[0].value, "args": args}
    return out
