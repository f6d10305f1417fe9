"""Every field of every spec kind, given a value of the wrong JSON type, is refused with one
`SpecError` naming that field, never a traceback (issue 20, item 5).

The fields are read from the models themselves, so a kind or a field added later is covered
without touching this file; a value is "of the wrong type" when the field's annotation
(unions, lists, literals, constraints stripped) admits no value of its JSON type.
"""

from __future__ import annotations

import copy
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import pytest
from helpers import TORUS, assert_input_error, call, write
from pydantic import BaseModel

from pinnedballs.specs import RunSpec, SpecError, parse_spec
from pinnedballs.specs.errors import _models_of

#: a value of each JSON type: array, object, string, float, integer, boolean, null
VALUES = {"array": ["flat_torus"], "object": {"kind": "flat_torus"}, "string": "text", "float": 1.5,
          "integer": 7, "boolean": True, "null": None}

#: a valid component of each kind (every required field given)
VALID = {
    "geometry": {"flat_torus": {"rows": 4, "cols": 4}, "half_plane": {"rows": 4, "cols": 5},
                 "graph_positions": {"positions": "p.npy"}, "sphere": {"frequency": 2},
                 "hyperbolic_plane": {"layers": 2}, "fcc": {"nx": 2, "ny": 2, "nz": 2},
                 "hcp": {"nx": 2, "ny": 2, "nz": 2}, "python": {"factory": "user_components:chain"}},
    "initial": {"single_ball": {"ball": 0, "direction": [1, 0], "energy": 1.0}, "gaussian": {"energy": 1.0},
                "from_file": {"path": "v.npy"}, "python": {"factory": "user_components:reversed_speeds"}},
    "rule": {"elastic": {}, "restitution": {"r": 0.5}, "python": {"factory": "user_components:half_elastic"}},
    "scheduler": {"uniform_random_pair": {}, "sweep": {}, "random_sweep": {}, "rejection_free": {},
                  "colored_sweep": {}, "python": {"factory": "user_components:sweep"}},
}
#: the other fields of a run spec, each a model (or a plain value) with a valid value
OTHERS = {"stop": {"steps": 10}, "snapshots": {"at_steps": [1]}, "checkpoint": {"every_seconds": 1.0}}


def _json_types(annotation: Any) -> set[str]:
    """The JSON types a field of ``annotation`` accepts (pydantic strict mode: an integer is a float)."""
    if get_origin(annotation) is Annotated:
        return _json_types(get_args(annotation)[0])
    if get_origin(annotation) in (Union, types.UnionType):
        return set().union(*(_json_types(a) for a in get_args(annotation)))
    if get_origin(annotation) is Literal:
        return {{str: "string", bool: "boolean", int: "integer"}[type(v)] for v in get_args(annotation)}
    if get_origin(annotation) is list:
        return {"array"}
    if get_origin(annotation) is dict or (isinstance(annotation, type) and issubclass(annotation, BaseModel)):
        return {"object"}
    return {str: {"string"}, bool: {"boolean"}, int: {"integer"}, float: {"float", "integer"},
            type(None): {"null"}, Any: set(VALUES)}[annotation]


def _cases():
    """``(spec dict, field path, case)`` for every field of every kind and every wrong JSON type."""
    for slot, kinds in VALID.items():
        models = _models_of(RunSpec.model_fields[slot].annotation)[1]
        assert set(models) == set(kinds), f"a {slot} kind without a valid example here: {set(models) ^ set(kinds)}"
        for kind, fields in kinds.items():
            for name, info in models[kind].model_fields.items():
                for json_type, value in VALUES.items():
                    if json_type not in _json_types(info.annotation):
                        component = {"kind": kind, **fields, name: value}
                        yield {**TORUS, slot: component}, f"{slot}.{name}", f"{kind}: {json_type}"
    for name, info in RunSpec.model_fields.items():
        if name in VALID:
            continue
        for json_type, value in VALUES.items():
            if json_type not in _json_types(info.annotation):
                yield {**TORUS, name: value}, name, json_type
        model = _models_of(info.annotation)[0]
        if model is not None and name in OTHERS:
            for field, sub in model.model_fields.items():
                for json_type, value in VALUES.items():
                    if json_type not in _json_types(sub.annotation):
                        yield {**TORUS, name: {**OTHERS[name], field: value}}, f"{name}.{field}", json_type


CASES = list(_cases())


def test_every_kind_and_field_is_covered():
    """The cases reach every field of every model (a field no wrong type exists for is only ``Any``)."""
    paths = {path for _, path, _ in CASES}
    assert {"geometry.kind", "initial.kind", "rule.kind", "scheduler.kind", "geometry.rows", "geometry.periodic",
            "geometry.args", "initial.ball", "stop.steps", "snapshots.every_steps", "checkpoint.every_seconds",
            "observables", "masses", "seed", "description"} <= paths
    assert len(CASES) > 300


@pytest.mark.parametrize("data,path,case", CASES, ids=[f"{p} ({c})" for _, p, c in CASES])
def test_a_wrong_type_is_one_spec_error_naming_the_field(data, path, case):
    with pytest.raises(SpecError) as caught:
        parse_spec(copy.deepcopy(data))
    error = caught.value
    assert error.path == path, (error.path, str(error))
    assert "\n" not in str(error) and str(error).startswith(f"{path}: ")


@pytest.mark.parametrize("slot", list(VALID))
@pytest.mark.parametrize("kind", [["flat_torus"], {"kind": "x"}])
def test_a_kind_that_is_not_a_string_is_one_line_from_the_command_line(tmp_path, slot, kind):
    """The issue's example, in every component slot: exit 2, one line, nothing written."""
    path = write(tmp_path / "s.json", {**TORUS, slot: {"kind": kind}})
    for argv in (["validate", path], ["run", path, "--out", tmp_path / "out"]):
        code, out, err = call(*argv)
        assert_input_error(code, err, f"{slot}.kind: must be a string, one of: ")
        assert out == "" and not (tmp_path / "out").exists()
