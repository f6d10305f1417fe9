"""Errors that name what the user got wrong: a field of a spec, an argument, a file.

The engine raises `FieldError` (a ``ValueError``) or `FieldTypeError` (also a
``TypeError``) with the argument's name in ``field``; a spec maps that name to its
own field path without reading the message (`pinnedballs.specs.base.engine_errors`); a spec
raises `pinnedballs.specs.errors.SpecError`, a `FieldError` whose field is the spec's field path.
"""

from __future__ import annotations

__all__ = ["InputError", "FieldError", "FieldValueError", "FieldTypeError", "InternalError", "check_jitted",
           "described"]


class InputError(ValueError):
    """Bad input from the user: a spec, a data file, an argument or an output directory (a ValueError).

    The base of every error the command line says in one line, exiting with status 2.
    """


class FieldError(InputError):
    """A bad value of one argument or field: the message is ``"field: problem"`` (just ``problem`` when
    ``field`` is empty).

    Parameters
    ----------
    field : str
        The argument or field it names.
    problem : str
        What is wrong.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> try:
    ...     pb.FlatTorus(rows=5, cols=3)
    ... except pb.FieldError as error:
    ...     print(error.field, "|", error.problem)
    rows | must be even for a flat torus, got 5
    """

    def __init__(self, field: str, problem: str):
        self.field, self.problem = field, problem
        super().__init__(f"{field}: {problem}" if field else problem)

    def __reduce__(self):  # picklable across processes (Dask, process pools)
        return type(self), (self.field, self.problem)


#: the same class under the name the run driver's modules use
FieldValueError = FieldError


class FieldTypeError(FieldError, TypeError):
    """A `FieldError` for a value of the wrong type (also a ``TypeError``).

    Parameters
    ----------
    field : str
        The argument or field it names.
    problem : str
        What is wrong.
    """


class InternalError(RuntimeError):
    """pinnedballs itself failed, not its input: an engine that broke the chunk protocol (its loop stopped short
    of its chunk). A run saves its last state marked "failed" with the words (`pinnedballs.run.writers`); the
    command line says them in one line and exits with status 1 (``--traceback`` prints the traceback too)."""


def check_jitted(function, field: str, what: str):
    """``function`` if it is compiled by numba (``@njit``), else a `FieldTypeError` on ``field``.

    The compiled loops call it inside numba: a plain Python function would fail there with a
    TypingError from deep inside the engine. With ``NUMBA_DISABLE_JIT=1`` everything is plain.
    """
    from numba import config
    from numba.core.dispatcher import Dispatcher

    if config.DISABLE_JIT or isinstance(function, Dispatcher):
        return function
    raise FieldTypeError(field, f"{what} must be a numba-compiled function (decorate it with @numba.njit), "
                                f"got {function!r}")


def described(value) -> str:
    """``value`` as a message names it: its own ``repr`` (``Elastic()``), or its class's name where its class
    gives none (``Softening``, not ``<softening.Softening object at 0x7f...>``)."""
    return repr(value) if type(value).__repr__ is not object.__repr__ else type(value).__name__
