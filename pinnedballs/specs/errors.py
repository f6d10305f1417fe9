"""`SpecError`, and pydantic's validation errors as one `SpecError` with a dotted field path and a
suggestion on typos."""

from __future__ import annotations

import difflib
import re
import types
from typing import Annotated, Any, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from ..util.errors import FieldError, InputError

__all__ = ["SpecError", "UserCodeError", "first_error", "failure"]


class SpecError(FieldError):
    """A spec field is wrong: the message is one line, ``"geometry.rows: ..."`` (a `FieldError`, a ValueError).

    Parameters
    ----------
    path : str
        The dotted field path (``"geometry.rows"``), or a file's path; also ``field``.
    problem : str
        What is wrong.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> error = pb.SpecError("geometry.rows", "must be >= 1, got 0")
    >>> str(error), error.path, error.problem
    ('geometry.rows: must be >= 1, got 0', 'geometry.rows', 'must be >= 1, got 0')
    """

    def __init__(self, path: str, problem: str):
        super().__init__(path, problem)

    @property
    def path(self) -> str:
        """The dotted field path (`FieldError.field`)."""
        return self.field


class UserCodeError(SpecError):
    """A user's code that a spec names failed: its factory raised or exited, or the component it made
    failed as the run was set up. The message is one line, ``"geometry.factory shapes:boom raised
    RuntimeError: boom"``; ``__cause__`` is the user's exception, with its traceback."""

    def __init__(self, path: str, problem: str):
        self.field, self.problem = path, problem
        InputError.__init__(self, f"{path} {problem}" if path else problem)


def failure(exc: BaseException) -> str:
    """What a user's code did: ``"raised KeyError: 'x'"``, ``"called sys.exit(3)"``."""
    if isinstance(exc, SystemExit):
        return f"called sys.exit({'' if exc.code is None else repr(exc.code)})"
    text = " ".join(str(exc).split())
    return f"raised {type(exc).__name__}" + (f": {text}" if text else "")


_PRIORITY = {"extra_forbidden": 0, "union_tag_invalid": 1, "union_tag_not_found": 1}


def first_error(exc: ValidationError, root: type[BaseModel]) -> SpecError:
    """The most telling error of a pydantic `ValidationError` of ``root``, as a `SpecError` with a dotted path."""
    e = sorted(exc.errors(), key=lambda e: _PRIORITY.get(e["type"], 2))[0]
    loc = tuple(e["loc"])
    if e["type"] == "extra_forbidden":
        path, model, _ = _walk(loc[:-1], root)
        key, valid = str(loc[-1]), list(model.model_fields) if model else []
        return SpecError(_dot(path, key), f"unknown key{_suggest(key, valid)} (valid keys: {', '.join(valid)})")
    path, _, tags = _walk(loc, root)
    failed = (e.get("ctx") or {}).get("error")
    if isinstance(failed, UserCodeError):  # a factory's module failed as it was imported
        error = UserCodeError(_dot(path, failed.field), failed.problem)
        error.__cause__ = failed.__cause__
        return error
    if e["type"] == "union_tag_not_found":
        return SpecError(_dot(path, "kind"), f"missing; one of: {', '.join(tags)}")
    if e["type"] == "union_tag_invalid":
        given = e["input"].get("kind", "") if isinstance(e.get("input"), dict) else ""
        if not isinstance(given, str):
            return SpecError(_dot(path, "kind"), f"must be a string, one of: {', '.join(tags)}; got {_short(given)}")
        tag = str(e["ctx"]["tag"])
        return SpecError(_dot(path, "kind"), f"unknown kind {tag!r}{_suggest(tag, list(tags))} "
                                             f"(valid kinds: {', '.join(tags)})")
    message = e["msg"]
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
        head, sep, rest = message.partition(": ")
        if sep and re.fullmatch(r"[\w.]*", head):  # a model validator naming its own field
            return SpecError(_dot(path, head), rest)
        return SpecError(path, message)
    if e["type"] == "missing":
        return SpecError(path, "missing (required)")
    return SpecError(path, f"{message[0].lower()}{message[1:]}, got {_short(e.get('input'))}")


def _walk(loc: tuple, root: type[BaseModel]) -> tuple[str, type[BaseModel] | None, dict[str, type[BaseModel]]]:
    """Follow ``loc`` from ``root``: the dotted path (union tags and member labels dropped),
    the model reached, and the ``kind``-tagged models if a union was reached."""
    parts: list[str] = []
    model: type[BaseModel] | None = root
    tags: dict[str, type[BaseModel]] = {}
    for element in loc:
        if isinstance(element, int):
            if parts:
                parts[-1] += f"[{element}]"
        elif model is not None and element in model.model_fields:
            parts.append(element)
            model, tags = _models_of(model.model_fields[element].annotation)
        elif element in tags:
            model, tags = tags[element], {}
    return ".".join(parts), model, tags


def _models_of(annotation: Any) -> tuple[type[BaseModel] | None, dict[str, type[BaseModel]]]:
    """The single model behind ``annotation``, or its ``kind``-tagged members."""
    members = [a for a in _flatten(annotation) if isinstance(a, type) and issubclass(a, BaseModel)]
    tags = {m.model_fields["kind"].default: m for m in members if "kind" in m.model_fields}
    if len(members) == 1 and not tags:
        return members[0], {}
    return None, tags


def _flatten(annotation: Any) -> list[Any]:
    """The members of a (possibly Annotated or Optional) union annotation."""
    if get_origin(annotation) is Annotated:
        return _flatten(get_args(annotation)[0])
    if get_origin(annotation) in (Union, types.UnionType):
        return [m for a in get_args(annotation) for m in _flatten(a)]
    return [annotation]


def _suggest(word: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.5)
    return f"; did you mean {close[0]!r}?" if close else ""


def _dot(path: str, name: str) -> str:
    return f"{path}.{name}" if path and name else path or name


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
