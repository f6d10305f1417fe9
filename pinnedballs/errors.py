"""Errors that name what the user got wrong: a field of a spec, an argument, a file."""

from __future__ import annotations

__all__ = ["InputError", "SpecError", "FieldValueError", "FieldTypeError"]


class InputError(ValueError):
    """Bad input from the user: a spec, a data file or an output directory."""


class SpecError(InputError):
    """A spec field is wrong. ``path`` is the dotted field path (``"geometry.rows"``)."""

    def __init__(self, path: str, problem: str):
        self.path, self.problem = path, problem
        super().__init__(f"{path}: {problem}" if path else problem)


class _FieldError:
    """Mixin: an engine error about one argument, carried as data (``field``, ``problem``)."""

    def __init__(self, field: str, problem: str):
        self.field, self.problem = field, problem
        super().__init__(f"{field}: {problem}")


class FieldValueError(_FieldError, ValueError):
    """A ValueError about the argument ``field`` (the message is ``"field: problem"``)."""


class FieldTypeError(_FieldError, TypeError):
    """A TypeError about the argument ``field`` (the message is ``"field: problem"``)."""
