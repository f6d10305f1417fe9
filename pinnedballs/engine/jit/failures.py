"""numba's refusal to compile a user's code, in one line: what it said, where, and whose code it was.

numba's errors run to a hundred lines (each pass of its pipeline, every candidate it tried, in colour). `said`
keeps the first line that says what failed (``No implementation of function Function(setitem) found for
signature setitem(DictType[int64,float64], unicode_type, float64)``), `place` the innermost place it names in
the user's own code. `CompileFailure` is the one-line error naming the component (a rule, a scheduler) whose
code numba could not compile, numba's error its cause; `compiling` turns numba's error into it for a chain's
model, so a run says it before anything is written (`pinnedballs.run.execute`) and a spec names the factory
that made the component (`pinnedballs.specs.run.RunSpec.not_compiled`). numba is imported only to read its
errors.
"""

from __future__ import annotations

import contextlib
import inspect
import re
from collections.abc import Callable, Iterator
from pathlib import Path

from ...util.errors import FieldError, described

__all__ = ["CompileFailure", "said", "place", "places", "compile_failure", "compiling", "numba_errors"]

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_OBJECT = re.compile(r"<(?:built-in )?function ([\w.]+) at 0x[0-9a-f]+>")
#: the places numba names: ``File "PATH", line N`` and ``at PATH (N)``
_PLACE = re.compile(r'File "([^"]+)", line (\d+)|\bat (/\S+\.py) \((\d+)\)')
_PACKAGE = Path(__file__).resolve().parents[2]


def numba_errors() -> tuple[type, ...]:
    """What numba raises when it cannot compile a function (typing, lowering, an unsupported construct)."""
    from numba.core.errors import NumbaError

    return (NumbaError,)


def said(exc: BaseException) -> str:
    """numba's message in one line: its first line that says what failed, without colours or addresses, and the
    signature it names on the next line (``No implementation of function ... found for signature f(int64)``)."""
    lines = [line.strip() for line in _ANSI.sub("", str(exc)).splitlines()]
    for k, line in enumerate(lines):
        if line and not line.startswith(("Failed in", "During:", "-", "File", ">>>")):
            line = _OBJECT.sub(r"\1", line).rstrip(".:")
            after = next((rest for rest in lines[k + 1:] if rest), "")
            if line.endswith("for signature") and after.startswith(">>>"):
                line += " " + after.removeprefix(">>>").strip()
            return line
    return type(exc).__name__


def places(exc: BaseException) -> list[Path]:
    """The source files numba's message names, in its order, resolved (with their lines: ``(path, line)``)."""
    found = []
    for m in _PLACE.finditer(_ANSI.sub("", str(exc))):
        path, line = (m.group(1), m.group(2)) if m.group(1) else (m.group(3), m.group(4))
        found.append((Path(path).resolve(), int(line)))
    return found


def _outside(path: Path) -> bool:
    """Whether ``path`` is neither numba's nor numba-cuda's nor this package's: a user's file."""
    import numba

    inside = (Path(numba.__file__).resolve().parent, _PACKAGE)
    return not any(path.is_relative_to(p) for p in inside) and "numba_cuda" not in path.parts


def place(exc: BaseException, own: Callable | None = None, files: set[Path] | None = None) -> str:
    """``FILE:LINE``: the innermost place numba's message names in ``files`` (a component's own sources), else
    outside numba and this package (the user's code), else where ``own`` (a jitted function) is defined."""
    named = [(p, n) for p, n in places(exc) if (p in files if files else _outside(p))]
    if not named and files:
        named = [(p, n) for p, n in places(exc) if _outside(p)]
    if named:
        return f"{named[-1][0]}:{named[-1][1]}"
    try:
        py = getattr(own, "py_func", own)
        return f"{inspect.getsourcefile(py)}:{py.__code__.co_firstlineno}"
    except (TypeError, AttributeError):
        return "its source unknown"


class CompileFailure(FieldError):
    """numba could not compile ``component``'s code (the chain's rule or scheduler, named by ``field``): a
    `FieldError` on ``field``, ``"rule: Sticky cannot be compiled by numba: <what numba said> (FILE:LINE)"``.
    ``said`` and ``where`` keep numba's words and the place; ``gpu``: the compile for a GPU failed too (the
    rule runs nowhere)."""

    def __init__(self, field: str, component, said: str, where: str, gpu: bool = False):
        self.component, self.said, self.where, self.gpu = component, said, where, gpu
        super().__init__(field, f"{described(component)} cannot be compiled by numba{self.detail}")

    @property
    def detail(self) -> str:
        """What follows "compile" in the line: ``", for a GPU or for the CPU: <what numba said> (FILE:LINE)"``."""
        return f"{', for a GPU or for the CPU' if self.gpu else ''}: {self.said} ({self.where})"

    def __reduce__(self):
        return type(self), (self.field, self.component, self.said, self.where, self.gpu)


def _own_files(component, functions: list[Callable]) -> set[Path]:
    """The user's source files of ``component``: its class's, and those of the jitted ``functions`` it gave
    and of every jitted function they reach, this package's left out."""
    from .cache import reachable_functions

    found = set()
    py_funcs = [getattr(f, "py_func", f) for f in functions if f is not None]
    for source in [type(component), *py_funcs, *(g for f in py_funcs for g in reachable_functions(f))]:
        try:
            path = Path(inspect.getsourcefile(source)).resolve()
        except (TypeError, AttributeError):
            continue
        if _outside(path):
            found.add(path)
    return found


def compile_failure(exc: BaseException, model) -> CompileFailure | None:
    """``exc``, numba's error compiling ``model``'s chain (`engine.chain.Model`), as a `CompileFailure` naming the
    component whose code it could not compile: the rule or the scheduler whose own source files numba's message
    names, else the one of them that is a user's; None when ``exc`` is not numba's or neither is a user's."""
    if not isinstance(exc, numba_errors()):
        return None
    from ..closing import impulse_of

    s = model.selector
    own = {"rule": _own_files(model.rule, [model.collide, impulse_of(model.collide)]),
           "scheduler": _own_files(model.scheduler, [s.select, s.begin, s.changed])}
    named = [field for p, _ in places(exc) for field, files in own.items() if p in files]
    users = [field for field, files in own.items() if files]
    field = named[-1] if named else users[0] if len(users) == 1 else None
    if field is None:
        return None
    fallback = (impulse_of(model.collide) or model.collide) if field == "rule" else s.select
    component = model.rule if field == "rule" else model.scheduler
    return CompileFailure(field, component, said(exc), place(exc, fallback, own[field]))


@contextlib.contextmanager
def compiling(model) -> Iterator[None]:
    """A block that compiles ``model``'s chain: numba's error compiling a user's code in it is raised as the
    `CompileFailure` naming that code (`compile_failure`), numba's error its cause; any other goes on as it is."""
    try:
        yield
    except numba_errors() as exc:
        failure = compile_failure(exc, model)
        if failure is None:
            raise
        raise failure from exc
