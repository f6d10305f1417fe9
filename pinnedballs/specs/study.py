"""Study specs: one base run spec over many points, a point a set of overrides by dotted path (hydra's sweeps;
signac's state points). `StudySpec` is the JSON; `StudySpec.expand` gives its `StudyPoint` s, each a validated,
seeded `RunSpec` and its number of replicas; `pinnedballs.run.study.run_study` runs them.

A study by example::

    {"base": "../halfplane_100x50.json",
     "zip": {"geometry.length": [10, 20, 40], "geometry.depth": [5, 10, 20]},
     "grid": {"rule": [{"kind": "elastic"}, {"kind": "restitution", "r": 0.9}]},
     "replicas": [{"where": {"geometry.length": 40}, "replicas": 4}, {"replicas": 8}],
     "seed": 0}

``base``: a run spec, inline or the path of one (relative to the study file). The points: ``zip`` lists varied
together (of one length: the k-th point takes the k-th value of each), ``grid`` a Cartesian product (every
combination of its lists), ``points`` a list of override dicts. They combine as a product, every zip entry with
every grid combination with every ``points`` entry (a part not given counts as one empty entry), in that order
(zip outermost, the grid's last key fastest, ``points`` innermost): the example has 3 x 2 = 6 points, and a study
with none of the three has one, the base itself. An override is a dotted path into the run spec
(``geometry.length``, ``rule.r``, ``initial.energy``, ``stop.max_steps``; ``geometry`` replaces a whole
component) and a JSON value; a path through an object the spec does not state creates it. No path may be set by
two parts, nor a path and one inside it (``geometry`` and ``geometry.length``). A point is validated as a run
spec; a bad path or value is one line naming the point and the field (`PointError`).

``replicas``: one number for every point, or rules tried in order, the first whose ``where`` holds for a point
giving its replicas (``where`` compares the point's run spec, the base's values included; a rule without
``where`` holds for every point). Each rule must hold for some point, and some rule for every point.

Seeds (``seeds``): ``"by_point"`` (the default): a point's run seed is `point_seed` of the study's ``seed`` and
the point's own overrides, the first 63 bits of SHA-256 of ``"<seed>:<canonical JSON of the overrides>"`` (keys
sorted, no spaces: ``100`` and ``100.0`` are spelled differently and seed differently), not of its place in the
study, so adding points changes no row; a point whose overrides set ``seed`` keeps it; the base's own seed is
not used. A study without ``seed`` gets one drawn when it first runs (`StudySpec.seeded`), which its directory
records. ``"as_spec"``: each point keeps its run spec's seed (the base's, or its own ``seed`` override), so that
replica k of every point is seeded alike (the extended reproduction's sizes); the study then has no ``seed``.
Replica k of a point is seeded as an ensemble's replica k (`pinnedballs.run.ensemble.replica_seed`).
"""

from __future__ import annotations

import copy
import hashlib
import itertools
import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import BaseModel, Field, PrivateAttr, ValidationError, ValidationInfo, field_validator, model_validator

from ..util.errors import FieldError, InputError
from ..util.limits import check_memory
from .base import _resolve_path, _Spec, draw_seed
from .errors import SpecError, UserCodeError, _short, first_error
from .run import _JSON_BYTES_PER_CHAR, RunSpec, _check_tree, _join, _parse_int, load_spec, parse_spec

__all__ = ["StudySpec", "ReplicasRule", "StudyPoint", "PointError", "parse_study", "load_study_spec", "point_seed",
           "canonical", "stated", "study_schema", "MAX_POINTS"]

#: the most points a study may have (a grid's product grows fast)
MAX_POINTS = 100_000
_PATH = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*")


class PointError(SpecError):
    """A point of a study is not a valid run spec: ``point`` its overrides, ``field`` the run spec's field.
    The message is one line, ``point {"geometry.lenght": 10}: geometry.lenght: unknown key; ...``."""

    def __init__(self, point: dict, path: str, problem: str):
        self.point, self.field, self.problem = point, path, problem
        InputError.__init__(self, f"point {label(point)}: {_join(path, problem)}")

    def __reduce__(self):
        return type(self), (self.point, self.field, self.problem)


def canonical(value: Any) -> str:
    """The canonical JSON of ``value``: keys sorted, no spaces, not ASCII-escaped (what `point_seed` hashes)."""
    return json.dumps(value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False)


def label(overrides: Any, most: int = 160) -> str:
    """A point's overrides (or any JSON value) as a reader sees them: ``{"geometry.length": 10, "geometry.depth":
    5}`` (cut at ``most`` characters)."""
    text = json.dumps(overrides, ensure_ascii=False, allow_nan=False)
    return text if len(text) <= most else text[:most - 3] + "..."


def point_seed(seed: int, overrides: dict) -> int:
    """A point's run seed: the first 63 bits (little-endian) of SHA-256 of ``"<seed>:<canonical(overrides)>"``.

    Parameters
    ----------
    seed : int
        The study's seed.
    overrides : dict
        The point's overrides (dotted path -> JSON value).

    Returns
    -------
    int
        In [0, 2**63).

    Examples
    --------
    >>> from pinnedballs.specs.study import point_seed
    >>> point_seed(0, {"geometry.length": 10}) == point_seed(0, {"geometry.length": 10})
    True
    >>> point_seed(0, {"geometry.length": 10}) != point_seed(1, {"geometry.length": 10})
    True
    """
    digest = hashlib.sha256(f"{int(seed)}:{canonical(overrides)}".encode()).digest()
    return int.from_bytes(digest[:8], "little") >> 1


class ReplicasRule(_Spec):
    """``{"where": {path: value, ...}, "replicas": N}``: N replicas for the points whose run spec has each value."""

    where: dict[str, Any] = {}
    replicas: Annotated[int, Field(ge=1)]

    @field_validator("where", mode="after")
    @classmethod
    def _paths(cls, where: dict) -> dict:
        for path, value in where.items():
            _check_override(path, value, "")
        return where

    def holds(self, values: dict) -> bool:
        """Whether every ``where`` path of ``values`` (a run spec as JSON) has its value."""
        return all(_lookup(values, path) == (True, value) for path, value in self.where.items())


@dataclass(frozen=True)
class StudyPoint:
    """One point of a study: its ``overrides`` (dotted path -> value, as the study gives them), its ``spec``
    (the base with them, validated and seeded) and its number of ``replicas``."""

    overrides: dict[str, Any]
    spec: RunSpec
    replicas: int

    @property
    def label(self) -> str:
        """The overrides as one reads them (`label`)."""
        return label(self.overrides)

    def state_point(self, base: str) -> dict:
        """The point's signac state point: its overrides nested by path (``{"geometry": {"length": 10}}``) and
        ``"base"``, the base spec's digest (`StudySpec.digest`)."""
        nested: dict = {}
        for path, value in self.overrides.items():
            *parents, key = path.split(".")
            node = nested
            for p in parents:
                node = node.setdefault(p, {})
            node[key] = copy.deepcopy(value)
        return {"base": base, **nested}


class StudySpec(_Spec):
    """A study: a ``base`` run spec over points, ``replicas`` of each, seeded by ``seed``.

    The module's docstring says how the parts combine and how points are seeded.

    Parameters
    ----------
    description : str
        Words for the reader.
    base : RunSpec
        The run spec every point overrides (in JSON, inline or the path of one).
    zip, grid : dict
        Dotted path -> list of values: ``zip``'s varied together, ``grid``'s as a Cartesian product.
    points : list of dict
        Override dicts, one a point.
    replicas : int or list of ReplicasRule
        One number for every point, or rules (``{"where": {...}, "replicas": N}``) tried in order.
    seed : int or None
        The study's seed (`point_seed`); None: drawn when it first runs (`seeded`).
    seeds : {"by_point", "as_spec"}
        How points are seeded.

    Examples
    --------
    >>> from pinnedballs.specs.study import parse_study
    >>> run = {"geometry": {"kind": "half_plane", "rows": 4, "cols": 6},
    ...        "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 0.5},
    ...        "stop": {"frozen": True, "max_steps": 100000}}
    >>> study = parse_study({"base": run, "grid": {"geometry.cols": [6, 8]}, "replicas": 2, "seed": 0})
    >>> [(p.overrides, p.spec.geometry.cols, p.replicas) for p in study.expand()]
    [({'geometry.cols': 6}, 6, 2), ({'geometry.cols': 8}, 8, 2)]
    """

    description: str = ""
    base: RunSpec
    zip: dict[str, Any] = Field(default={}, json_schema_extra={"additionalProperties": {"type": "array"}})
    grid: dict[str, Any] = Field(default={}, json_schema_extra={"additionalProperties": {"type": "array"}})
    points: list[dict[str, Any]] = []
    replicas: Annotated[int, Field(ge=1)] | list[ReplicasRule]
    seed: Annotated[int, Field(ge=0, le=np.iinfo(np.int64).max)] | None = None
    seeds: Literal["by_point", "as_spec"] = "by_point"
    #: where relative paths in the overrides resolve (the study file's directory), from the context's base_dir
    _base_dir: str | None = PrivateAttr(default=None)

    @model_validator(mode="before")
    @classmethod
    def _rules(cls, data: Any) -> Any:
        """``replicas``: a number, or a list of rules, each validated here so that an error names its place."""
        if not isinstance(data, dict) or "replicas" not in data:
            return data
        value = data["replicas"]
        if isinstance(value, list):
            rules = []
            for k, rule in enumerate(value):
                try:
                    rules.append(ReplicasRule.model_validate(rule))
                except ValidationError as exc:
                    e = first_error(exc, ReplicasRule)
                    raise ValueError(_join(f"replicas[{k}]" + (f".{e.path}" if e.path else ""), e.problem)) from None
            if not rules:
                raise ValueError("replicas: give a number, or at least one rule")
            return {**data, "replicas": rules}
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"replicas: must be a number >= 1 or a list of rules ({{\"where\": {{...}}, "
                             f"\"replicas\": N}}), got {_short(value)}")
        return data

    @field_validator("base", mode="before")
    @classmethod
    def _base(cls, value: Any, info: ValidationInfo) -> Any:
        """A path (relative to the study file) read as a run spec; a dict validated as one, with its paths
        relative to the study file."""
        base_dir = (info.context or {}).get("base_dir")
        try:
            if isinstance(value, str):
                return load_spec(_resolve_path(value, info))
            if isinstance(value, dict):
                return parse_spec(value, base_dir=base_dir)
        except UserCodeError:
            raise
        except SpecError as exc:
            raise ValueError(str(exc) if isinstance(value, str) else _join(exc.path, exc.problem)) from None
        return value

    @model_validator(mode="after")
    def _parts(self, info: ValidationInfo) -> StudySpec:
        self._base_dir = (info.context or {}).get("base_dir")
        for part in ("zip", "grid"):
            for path, values in getattr(self, part).items():
                _check_override(path, values, part)
                if not isinstance(values, list) or not values:
                    raise ValueError(f"{part}.{path}: must be a list of at least one value, got {_short(values)}")
        lengths = {path: len(values) for path, values in self.zip.items()}
        if len(set(lengths.values())) > 1:
            raise ValueError(f"zip: its lists are varied together and must have one length, got "
                             f"{', '.join(f'{p} {n}' for p, n in lengths.items())}")
        for k, point in enumerate(self.points):
            for path, value in point.items():
                _check_override(path, value, f"points[{k}]")
        _check_overlaps(self)
        count = math.prod([len(v) for v in self.grid.values()]) * (max(lengths.values(), default=1)) * \
            max(len(self.points), 1)
        if count > MAX_POINTS:
            raise ValueError(f"grid: the study has {count:,} points; a study holds at most {MAX_POINTS:,}")
        if self.seeds == "as_spec" and self.seed is not None:
            raise ValueError("seed: seeds \"as_spec\" runs each point on its run spec's own seed; give the study no "
                             "seed (or seeds \"by_point\")")
        return self

    def _repr_html_(self) -> str:  # notebooks: the base, the points and the replicas as a table
        from ..plot.display import study_spec_html

        return study_spec_html(self)

    @property
    def varied(self) -> list[str]:
        """The paths the points vary, in the order the parts give them (zip, grid, points)."""
        return list(dict.fromkeys([*self.zip, *self.grid, *(p for point in self.points for p in point)]))

    def digest(self) -> str:
        """The base spec's digest: a point's state point holds it, so the points of another base are other jobs.

        Returns
        -------
        str
            16 hex digits of SHA-256 of its canonical JSON: defaults and the description left out, and, with
            seeds "by_point", its seed, which the points do not use.
        """
        exclude = {"description"} | ({"seed", "replica"} if self.seeds == "by_point" else set())
        dumped = {k: v for k, v in stated(self.base).items() if k not in exclude}
        return hashlib.sha256(canonical(dumped).encode()).hexdigest()[:16]

    def seeded(self) -> StudySpec:
        """This study with a seed.

        Returns
        -------
        StudySpec
            Itself with its own seed, or none for seeds "as_spec"; else a copy with one drawn from fresh entropy
            (63 bits).
        """
        if self.seed is not None or self.seeds == "as_spec":
            return self
        drawn = draw_seed()
        return self.model_copy(update={"seed": drawn})  # its private base directory with it

    def overrides(self) -> list[dict[str, Any]]:
        """Every point's overrides, in the study's order (the module's docstring)."""
        zipped = [dict(zip(self.zip, values)) for values in zip(*self.zip.values())] or [{}]
        grid = [dict(zip(self.grid, values)) for values in itertools.product(*self.grid.values())]
        points = self.points or [{}]
        return [{**z, **g, **p} for z in zipped for g in grid for p in points]

    def expand(self) -> list[StudyPoint]:
        """The points: each one's overrides, its run spec (the base with them, validated and seeded) and replicas.

        Returns
        -------
        list of StudyPoint
            In the study's order (the module's docstring).

        Raises
        ------
        PointError
            A point is not a valid run spec, has no seed with seeds "as_spec", or no replicas rule holds for it.
        SpecError
            The study has no seed (seeds "by_point": `seeded` draws one), a point is listed twice, or a replicas
            rule holds for no point.
        """
        if self.seed is None and self.seeds == "by_point":
            raise SpecError("seed", "missing: a study without a seed draws one when it runs (run_study); give one, "
                                    "or expand study.seeded()")
        base = stated(self.base)
        seen: set[str] = set()
        out = []
        for overrides in self.overrides():
            key = canonical(overrides)
            if key in seen:
                raise SpecError("points", f"the point {label(overrides)} is given twice (a point is its overrides)")
            seen.add(key)
            spec = self._point_spec(base, overrides)
            out.append(StudyPoint(overrides, spec, self._replicas(overrides, spec)))
        self._every_rule_holds(out)
        return out

    def point_spec(self, overrides: dict[str, Any]) -> RunSpec:
        """The run spec of the point with ``overrides`` (a point of the study or not).

        Parameters
        ----------
        overrides : dict
            Dotted path -> JSON value.

        Returns
        -------
        RunSpec
            Validated and seeded as the study seeds its points.

        Raises
        ------
        PointError
            If it is not a valid run spec.
        SpecError
            On ``seed``, for a study without one (seeds "by_point").
        """
        for path, value in overrides.items():
            try:
                _check_override(path, value, "")
            except ValueError as exc:
                raise PointError(overrides, *str(exc).split(": ", 1)) from None
        if self.seed is None and self.seeds == "by_point":
            raise SpecError("seed", "missing: give the study a seed, or use study.seeded()")
        return self._point_spec(stated(self.base), overrides)

    def _point_spec(self, base: dict, overrides: dict) -> RunSpec:
        """The run spec of the point with ``overrides`` on ``base`` (`stated`), seeded as the study seeds it."""
        try:
            spec = parse_spec(_overridden(base, overrides), base_dir=self._base_dir)
        except UserCodeError as exc:
            error = UserCodeError(f"point {label(overrides)}: {exc.path}", exc.problem)
            raise error from exc.__cause__
        except SpecError as exc:
            raise PointError(overrides, exc.path, exc.problem) from None
        if "seed" in overrides:
            return spec
        if self.seeds == "as_spec":
            if spec.seed is None:
                raise PointError(overrides, "seed", "missing: seeds \"as_spec\" runs each point on its run spec's "
                                                    "seed, and the base states none")
            return spec
        return spec.model_copy(update={"seed": point_seed(self.seed, overrides)})

    def _replicas(self, overrides: dict, spec: RunSpec) -> int:
        if isinstance(self.replicas, int):
            return self.replicas
        values = spec.model_dump(mode="json")
        for rule in self.replicas:
            if rule.holds(values):
                return rule.replicas
        raise PointError(overrides, "replicas", "no rule holds for this point (end the list with "
                                                "{\"replicas\": N} for the others)")

    def _every_rule_holds(self, points: list[StudyPoint]) -> None:
        if isinstance(self.replicas, int):
            return
        dumped = [p.spec.model_dump(mode="json") for p in points]
        for k, rule in enumerate(self.replicas):
            if not any(rule.holds(values) for values in dumped):
                raise SpecError(f"replicas[{k}].where", f"{label(rule.where)} holds for no point of the study")

    def to_json(self) -> str:
        """The study as JSON: a file that repeats it.

        Returns
        -------
        str
            Indented JSON, its base inline (`stated`: paths absolute).
        """
        given = self.model_dump(mode="json", exclude_defaults=True, exclude={"base"})
        study = {**({"description": given.pop("description")} if "description" in given else {}),
                 "base": stated(self.base), **given}
        return json.dumps(study, indent=2, ensure_ascii=False)


def stated(model: BaseModel) -> dict:
    """``model`` (a spec) as JSON without the fields at their defaults, but for each component's ``kind``: what
    a spec file states, and what re-validates to ``model``."""
    out = {}
    for name, field in type(model).model_fields.items():
        value = getattr(model, name)
        if name != "kind" and not field.is_required() and value == field.get_default(call_default_factory=True):
            continue
        out[name] = stated(value) if isinstance(value, BaseModel) else \
            model.model_dump(mode="json", include={name})[name]
    return out


def _check_override(path: str, value: Any, part: str) -> None:
    """A `ValueError` naming ``part.path`` unless ``path`` is a dotted path of names and ``value`` is JSON."""
    if not isinstance(path, str) or not _PATH.fullmatch(path):
        raise ValueError(f"{part or 'where'}: {_short(path)} is not a dotted path into the run spec (names joined by "
                         f"dots, as geometry.length)")
    try:
        canonical(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{_join_path(part, path)}: must be a JSON value ({exc}), got {_short(value)}") from None


def _join_path(part: str, path: str) -> str:
    return f"{part}.{path}" if part else path


def _check_overlaps(study: StudySpec) -> None:
    """A `ValueError` when a path is set by two parts, or a path and one inside it, in one point."""
    varied = [("zip", p) for p in study.zip] + [("grid", p) for p in study.grid]
    for k, point in enumerate(study.points):
        for i, path in enumerate(point):
            for other in list(point)[:i]:
                if _inside(path, other):
                    raise ValueError(f"points[{k}].{path}: set with {other} in the same point")
    for i, (part, path) in enumerate(varied):
        for other_part, other in varied[:i]:
            if _inside(path, other):
                raise ValueError(f"{part}.{path}: also varied by {other_part} ({other})")
        for k, point in enumerate(study.points):
            for other in point:
                if _inside(path, other):
                    raise ValueError(f"points[{k}].{other}: also varied by {part} ({path})")


def _inside(a: str, b: str) -> bool:
    """Whether paths ``a`` and ``b`` are one, or one lies inside the other."""
    return a == b or a.startswith(b + ".") or b.startswith(a + ".")


def _lookup(values: dict, path: str) -> tuple[bool, Any]:
    """``(True, value)`` at ``path`` in nested dicts, or ``(False, None)`` where it leads nowhere."""
    node: Any = values
    for key in path.split("."):
        if not isinstance(node, dict) or key not in node:
            return False, None
        node = node[key]
    return True, node


def _overridden(base: dict, overrides: dict) -> dict:
    """``base`` (a run spec as JSON) with each override set at its dotted path (objects created on the way)."""
    out = copy.deepcopy(base)
    for path, value in overrides.items():
        *parents, key = path.split(".")
        node = out
        for i, p in enumerate(parents):
            if node.get(p) is None:
                node[p] = {}
            elif not isinstance(node[p], dict):
                where = ".".join(parents[:i + 1])
                raise PointError(overrides, path, f"{where} is {label(node[p], 40)}, not an object to set a key in")
            node = node[p]
        node[key] = copy.deepcopy(value)
    return out


# ---------------------------------------------------------------- reading studies


def parse_study(data: str | bytes | dict, base_dir: str | os.PathLike | None = None, source: str = "") -> StudySpec:
    """Validate a study given as JSON text or a dict; relative paths (the base's, and those in overrides) resolve
    against ``base_dir``. Raises `SpecError` naming the first wrong field (``source`` prefixes the message).
    Its points are validated by `StudySpec.expand`."""
    context = {"base_dir": os.fspath(base_dir) if base_dir is not None else None}
    try:
        if isinstance(data, bytes):
            try:
                data = data.decode("utf-8")
            except UnicodeDecodeError as exc:
                raise SpecError(source, f"not UTF-8 text ({exc})") from None
        if isinstance(data, str):
            try:
                data = json.loads(data, parse_int=_parse_int)
            except json.JSONDecodeError as exc:
                raise SpecError(source, f"not valid JSON: {exc}") from None
            except RecursionError:
                raise SpecError(source, "not a study: JSON nested too deep") from None
        if not isinstance(data, dict):
            raise SpecError(source, f"a study must be a JSON object, got {type(data).__name__}")
        _check_tree(data, source)
        return StudySpec.model_validate(data, context=context)
    except ValidationError as exc:
        error = first_error(exc, StudySpec)
        if isinstance(error, UserCodeError):
            raise error from error.__cause__  # the user's exception
        raise SpecError(_join(source, error.path) if source else error.path, error.problem) from None


def load_study_spec(path: str | os.PathLike) -> StudySpec:
    """Read and validate the study file at ``path``; its relative paths resolve against its directory.

    Parameters
    ----------
    path : str or os.PathLike
        A study file.

    Returns
    -------
    StudySpec
        Its points are validated by `StudySpec.expand`.

    Raises
    ------
    SpecError
        In one line naming the file or the first wrong field (no such file, not JSON, a bad base, part or
        replicas rule).
    """
    path = Path(path)
    try:
        check_memory(_JSON_BYTES_PER_CHAR * path.stat().st_size, str(path), "reading this study file")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SpecError(str(path), "no such study file") from None
    except FieldError as exc:
        raise SpecError(str(path), exc.problem) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise SpecError(str(path), f"cannot read the study file ({exc})") from None
    try:
        return parse_study(text, base_dir=path.resolve().parent)
    except SpecError as exc:
        if exc.path:
            raise
        raise SpecError(str(path), exc.problem) from None


def study_schema() -> dict:
    """The JSON Schema of study specs (`StudySpec`): ``base`` a run spec (its schema in ``$defs``) or a path."""
    schema = StudySpec.model_json_schema()
    schema["properties"]["base"] = {
        "anyOf": [{"$ref": "#/$defs/RunSpec"},
                  {"type": "string", "description": "the path of a run spec file, relative to the study file"}],
        "title": "Base"}
    return schema
