"""Building blocks of every spec: the base model, path, count and number types, file loading,
and turning the engine's errors into `SpecError` on a spec field."""

from __future__ import annotations

import contextlib
import math
import os
from collections.abc import Iterator
from typing import Annotated, Any

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationInfo, field_validator

from ..util.errors import FieldError
from ..util.limits import check_memory, format_bytes
from .errors import SpecError


class _Spec(BaseModel):
    """Base of every spec: strict types, no unknown keys, no NaN, immutable."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)

    @field_validator("*", mode="after")
    @classmethod
    def _text(cls, value: Any) -> Any:
        if isinstance(value, str) and not _is_text(value):
            raise ValueError(f"{_NOT_TEXT}: {_short_text(value)}")
        return value


_NOT_TEXT = "not valid UTF-8 text (a lone surrogate, or bytes that are not UTF-8)"


def draw_seed() -> int:
    """A seed for a spec that has none: 63 bits (as a spec holds) from fresh entropy."""
    return int(np.random.SeedSequence().generate_state(1, np.uint64)[0] >> np.uint64(1))


def _is_text(value: str) -> bool:
    """True if ``value`` encodes as UTF-8 (no lone surrogates), so files and HDF5 can hold it."""
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _short_text(value: Any) -> str:
    """``ascii(value)``, cut to 60 characters: shows lone surrogates as escapes."""
    text = ascii(value)
    return text if len(text) <= 60 else text[:57] + "..."


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
    """The array in the ``.npy`` file at ``path`` as float64; a `SpecError` on ``field`` if unreadable.

    The header is checked before any data is read: a numeric dtype, and no more data
    than the file holds or the machine's memory can take (`check_memory`).
    """
    try:
        with open(path, "rb") as f:
            shape, dtype = _npy_header(f, path, field)
            held = os.fstat(f.fileno()).st_size - f.tell()
            needed = math.prod(shape) * dtype.itemsize
            if needed > held:
                raise SpecError(field, f"{path}: the header claims shape {shape} of {dtype} "
                                       f"({format_bytes(needed)}), but the file holds {format_bytes(held)} of data")
            check_memory(needed + 8 * math.prod(shape), field, f"the array in {path}")
        array = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise SpecError(field, f"file not found: {path}") from None
    except (SpecError, FieldError) as exc:
        raise SpecError(field, exc.problem) from None
    except (OSError, ValueError, EOFError, MemoryError) as exc:
        raise SpecError(field, f"cannot read {path} as a .npy array ({' '.join(str(exc).split())})") from None
    return array.astype(np.float64)


def _npy_header(f, path: str, field: str) -> tuple[tuple[int, ...], np.dtype]:
    """``(shape, dtype)`` from the header of the open ``.npy`` file ``f``; the dtype must be numeric."""
    try:
        version = np.lib.format.read_magic(f)
        if version not in ((1, 0), (2, 0)):
            raise ValueError(f".npy format version {version} is not supported for numeric arrays")
        read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read(f)
    except Exception as exc:  # noqa: BLE001 - numpy parses the header with ast and tokenize: any error
        raise ValueError(f"{type(exc).__name__}: {exc}") from None
    if dtype.kind not in "iuf":
        raise SpecError(field, f"{path} must hold a numeric array, got {dtype}")
    return tuple(int(n) for n in shape), dtype


@contextlib.contextmanager
def engine_errors(path: str, fields: dict[str, str] | None = None) -> Iterator[None]:
    """Turn an error from the engine into a `SpecError`.

    ``fields`` maps the engine's argument names (a `FieldError`'s ``field``) to spec
    field paths; other errors are reported under ``path``, whole.
    """
    try:
        yield
    except SpecError:
        raise
    except FieldError as exc:
        if fields and exc.field in fields:
            raise SpecError(fields[exc.field], exc.problem) from None
        raise SpecError(path, str(exc)) from None
    except (ValueError, TypeError) as exc:
        raise SpecError(path, str(exc)) from None
    except MemoryError as exc:
        raise SpecError(path, f"needs more memory than this machine has ({' '.join(str(exc).split())})") from None


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

