"""The package's input errors: bad input from the user, and the field or argument it concerns.

The engine raises `FieldError` (a ``ValueError``) or `FieldTypeError` (also a
``TypeError``) with the argument's name in ``field``; a spec maps that name to
its own field path without reading the message (`pinnedballs.spec.engine_errors`).
"""

from __future__ import annotations

__all__ = ["InputError", "FieldError", "FieldTypeError"]


class InputError(ValueError):
    """Bad input from the user: a spec, a data file, an argument or an output directory."""


class FieldError(InputError):
    """A bad value of one argument or field. ``field`` names it, ``problem`` says what is wrong;
    the message is ``"field: problem"`` (just ``problem`` when ``field`` is empty)."""

    def __init__(self, field: str, problem: str):
        self.field, self.problem = field, problem
        super().__init__(f"{field}: {problem}" if field else problem)

    def __reduce__(self):  # picklable across processes (Dask, process pools)
        return type(self), (self.field, self.problem)


class FieldTypeError(FieldError, TypeError):
    """A `FieldError` for a value of the wrong type (also a ``TypeError``)."""
