"""The one helper that checks arguments: each function returns the value in its plain Python type,
or raises a `FieldError` naming the argument (a `FieldTypeError`, also a ``TypeError``, for a value
of the wrong type). Every class of the package checks its arguments through these, so the same
mistake gets the same words everywhere: ``rows: must be an integer >= 4, got 2``.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import FieldError, FieldTypeError

__all__ = ["integer", "number", "flag", "choice", "seed"]


def _is_int(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


_INT64_MAX = 2**63 - 1


def _shown(bound) -> str:
    return f"{bound:g}" if isinstance(bound, float) else str(bound)


def _range(minimum, maximum) -> str:
    if maximum == _INT64_MAX:
        return f">= {_shown(minimum)} and < 2**63" if minimum is not None else "< 2**63"
    if minimum is not None and maximum is not None:
        return f"in [{_shown(minimum)}, {_shown(maximum)}]"
    return f">= {_shown(minimum)}" if minimum is not None else f"<= {_shown(maximum)}"


def _must(what: str) -> str:
    return f"{what} must" if what else "must"


def integer(name: str, value, minimum: int | None = None, maximum: int | None = None, *, what: str = "") -> int:
    """``value`` as an int in ``[minimum, maximum]`` (either may be None: unbounded). ``what``, if
    given, says what the value is at the start of the message."""
    if not _is_int(value):
        raise FieldTypeError(name, f"{_must(what)} be an integer, got {value!r}")
    if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise FieldError(name, f"{_must(what)} be an integer {_range(minimum, maximum)}, got {value}")
    return int(value)


def number(name: str, value, minimum: float | None = None, maximum: float | None = None, *,
           above: bool = False, what: str = "") -> float:
    """``value`` as a finite float in ``[minimum, maximum]``; ``above``: strictly greater than ``minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number)):
        raise FieldTypeError(name, f"{_must(what)} be a number, got {value!r}")
    x = float(value)
    bounds = f"> {_shown(minimum)}" if above and minimum is not None else \
        _range(minimum, maximum) if minimum is not None or maximum is not None else ""
    if not math.isfinite(x) or (above and minimum is not None and not x > minimum) or (
            not above and minimum is not None and x < minimum) or (maximum is not None and x > maximum):
        kind = "a number" if math.isfinite(x) else "a finite number"
        raise FieldError(name, f"{_must(what)} be {kind} {bounds}".rstrip() + f", got {value}")
    return x


def flag(name: str, value) -> bool:
    """``value`` as a bool (True, False or a numpy bool)."""
    if not isinstance(value, (bool, np.bool_)):
        raise FieldTypeError(name, f"must be True or False, got {value!r}")
    return bool(value)


def choice(name: str, value, options: tuple[str, ...]) -> str:
    """``value`` if it is one of the strings ``options``."""
    if not isinstance(value, str) or value not in options:
        listed = " or ".join(repr(o) for o in options)
        raise FieldError(name, f"must be {listed}, got {value!r}")
    return value


def seed(name: str, value) -> int | np.random.SeedSequence:
    """A seed: a non-negative int or a ``numpy.random.SeedSequence``."""
    if isinstance(value, np.random.SeedSequence):
        return value
    if not _is_int(value):
        raise FieldTypeError(name, f"must be a non-negative int or numpy SeedSequence, got {type(value).__name__}")
    if value < 0:
        raise FieldError(name, f"must be a non-negative integer, got {value}")
    return int(value)
