"""Building blocks of every spec: the base model, path, count and number types, file loading,
and turning the engine's errors into `SpecError` on a spec field."""

from __future__ import annotations

import contextlib
import os
from typing import Annotated, Iterator

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationInfo

from ..errors import SpecError



class _Spec(BaseModel):
    """Base of every spec: strict types, no unknown keys, no NaN, immutable."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)


def _resolve_path(value: str, info: ValidationInfo) -> str:
    """Make a path absolute against ``context["base_dir"]`` (else the working directory)."""
    if not value:
        raise ValueError("must be a file path, got an empty string")
    base = (info.context or {}).get("base_dir") or os.getcwd()
    return os.path.abspath(os.path.join(os.fspath(base), os.path.expanduser(value)))


FilePath = Annotated[str, AfterValidator(_resolve_path)]
Count = Annotated[int, Field(ge=0, le=np.iinfo(np.int64).max)]
Positive = Annotated[float, Field(gt=0)]


def _load_npy(path: str, field: str) -> np.ndarray:
    """The array in the ``.npy`` file at ``path``; a `SpecError` on ``field`` if unreadable."""
    try:
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise SpecError(field, f"file not found: {path}") from None
    except (OSError, ValueError, EOFError) as exc:
        raise SpecError(field, f"cannot read {path} as a .npy array ({exc})") from None
    if not isinstance(array, np.ndarray) or array.dtype.kind not in "iuf":
        raise SpecError(field, f"{path} must hold a numeric array, got {getattr(array, 'dtype', type(array))}")
    return array.astype(np.float64)


@contextlib.contextmanager
def engine_errors(path: str, fields: dict[str, str] | None = None) -> Iterator[None]:
    """Turn a `FieldValueError`/`FieldTypeError` from the engine into a `SpecError`.

    ``fields`` maps the engine's argument names (the error's ``field``) to spec field
    paths; other errors are reported under ``path``.
    """
    try:
        yield
    except SpecError:
        raise
    except (ValueError, TypeError) as exc:
        field = getattr(exc, "field", None)
        if field is not None and fields and field in fields:
            raise SpecError(fields[field], exc.problem) from None
        raise SpecError(path, str(exc)) from None


def _fields(path: str, *names: str) -> dict[str, str]:
    return {name: f"{path}.{name}" for name in names}


def _in_file(exc: SpecError, path: str) -> SpecError:
    """``exc`` with the data file named, if its message does not name it yet."""
    return exc if path in exc.problem else SpecError(exc.path, f"{exc.problem} (in {path})")


def _only_one(model: BaseModel, names: tuple[str, ...], what: str) -> list[str]:
    given = [n for n in names if getattr(model, n) not in (None, False)]
    if len(given) != 1:
        raise ValueError(f": give exactly one of {what} (got {', '.join(given) or 'none'})")
    return given

