"""A user's own components in specs: ``{"kind": "python", "factory": "module:callable", "args": {...}}``.

The callable is imported when the spec is validated and called with ``args`` when it is
built; it returns the component: a `Geometry`, a `CollisionRule`, a `Scheduler`, or for
the initial velocities an array ``(n_balls, dim)`` (it is called as ``factory(geometry, **args)``).
**A spec that names Python code runs that code**: validate only specs you trust. Code of the user's
that fails (its module as it is imported, the factory, or the component it made as the run is set
up, numba's compile of it included: `not_compiled`) raises `UserCodeError`, one line naming the slot,
the factory and what the code did (``geometry.factory shapes:boom raised RuntimeError: boom``), its
traceback kept as the cause; a ``sys.exit`` there is such a failure too, and a KeyboardInterrupt goes
on as one.

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
import traceback
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import ValidationInfo, field_validator

from .base import _Spec
from .errors import SpecError, UserCodeError, failure

if TYPE_CHECKING:  # the component classes, imported when one is built: a spec is validated without them
    from ..geometry.base import Geometry
    from ..rules import CollisionRule
    from ..schedulers.base import Scheduler

__all__ = ["PythonGeometrySpec", "PythonInitialSpec", "PythonRuleSpec", "PythonSchedulerSpec",
           "ENTRY_POINT_GROUPS", "IMPORT_FACTORIES", "import_factory", "expand_entry_points", "component_failed",
           "not_compiled", "label"]

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
    except (Exception, SystemExit) as exc:  # the module's own code failed as it ran
        raise UserCodeError("", f"{reference} could not be imported: module {module_name!r} {failure(exc)}") from exc
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
        """``factory(*positional, **args)``; a `UserCodeError` naming ``slot`` and the factory if it fails
        (raises anything but KeyboardInterrupt, or exits)."""
        try:
            factory = import_factory(self.factory)
        except UserCodeError as exc:
            raise UserCodeError(f"{slot}.factory", exc.problem) from exc.__cause__
        except ValueError as exc:
            raise SpecError(f"{slot}.factory", str(exc)) from None
        try:
            return factory(*positional, **self.args)
        except (Exception, SystemExit) as exc:
            raise UserCodeError(f"{slot}.factory", f"{self.factory} {failure(exc)}") from exc

    def _check(self, slot: str, made: Any, expected: type) -> Any:
        if not isinstance(made, expected):
            raise UserCodeError(f"{slot}.factory", f"{self.factory} returned {type(made).__name__}, "
                                                   f"not a pinnedballs {expected.__name__}")
        return made


class PythonGeometrySpec(_PythonSpec):
    """A geometry made by the user's ``factory(**args)``."""

    def build(self) -> Geometry:
        from ..geometry.base import Geometry

        return self._check("geometry", self._call("geometry"), Geometry)


class PythonInitialSpec(_PythonSpec):
    """Initial velocities ``(n_balls, dim)`` made by the user's ``factory(geometry, **args)``."""

    def build(self, geometry: Geometry, masses: np.ndarray, seed: np.random.SeedSequence) -> np.ndarray:
        v = self._call("initial", geometry)
        wanted = (geometry.n_balls, geometry.dim)
        try:
            array = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            array = None
        except (Exception, SystemExit) as exc:  # its own __array__ or __float__ failed
            raise UserCodeError("initial.factory", f"{self.factory} returned {type(v).__name__}, which "
                                                   f"{failure(exc)} as it was read as an array") from exc
        if array is None or array.ndim != 2:
            raise UserCodeError("initial.factory", f"{self.factory} returned {type(v).__name__}, not an array "
                                                   f"(n_balls, dim) = {wanted}")
        if array.shape != wanted:
            raise UserCodeError("initial.factory", f"{self.factory} returned an array of shape {array.shape}, "
                                                   f"not (n_balls, dim) = {wanted}")
        return array


class PythonRuleSpec(_PythonSpec):
    """A collision rule made by the user's ``factory(**args)``."""

    def build(self) -> CollisionRule:
        from ..rules import CollisionRule

        return self._check("rule", self._call("rule"), CollisionRule)


class PythonSchedulerSpec(_PythonSpec):
    """A scheduler made by the user's ``factory(**args)``."""

    def build(self) -> Scheduler:
        from ..schedulers.base import Scheduler

        return self._check("scheduler", self._call("scheduler"), Scheduler)


def component_failed(exc: BaseException, components: dict[str, Any], specs: dict[str, Any]) -> UserCodeError | None:
    """``exc``, raised while a run was set up, as a `UserCodeError` naming the slot whose component
    (``components[slot]``, made by a user's factory ``specs[slot]``) was running its own code when it
    failed: the innermost frame whose ``self`` is that component, of a class from outside pinnedballs.
    None if no user's component was running (then the error is not the user's)."""
    slot = method = None
    for frame, _ in traceback.walk_tb(exc.__traceback__):
        owner = frame.f_locals.get("self")
        for name, component in components.items():
            if owner is component and not type(component).__module__.startswith("pinnedballs."):
                slot, method = name, frame.f_code.co_name
    if slot is None:
        return None
    made = type(components[slot]).__name__
    source = specs[slot]
    where = f"{slot}.factory {source.factory}" if isinstance(source, _PythonSpec) else slot
    return UserCodeError(where, f"made a {made} whose {method}() {failure(exc)}")


def not_compiled(failure, specs: dict[str, Any]) -> SpecError:
    """numba's refusal to compile a chain's rule or scheduler (``failure``, an
    `pinnedballs.engine.jit.failures.CompileFailure` on its slot), in a spec's words: a user's component named by
    the factory that made it (``specs[slot]``), as a `UserCodeError`: ``rule.factory mine:sticky made a Sticky that
    numba cannot compile: <what numba said> (FILE:LINE)``; another's on its slot."""
    source = specs.get(failure.field)
    if not isinstance(source, _PythonSpec):
        return SpecError(failure.field, failure.problem)
    made = type(failure.component).__name__
    return UserCodeError(f"{failure.field}.factory", f"{source.factory} made a {made} that numba cannot compile"
                                                     f"{failure.detail}")


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
