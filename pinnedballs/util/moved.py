"""Module paths that moved, still importable: ``import pinnedballs.engine.loops`` gives the module now at
``pinnedballs.engine.sequential.loops`` (the same object), with one DeprecationWarning naming the new path.

The package's rooms were reordered in 2026-11 (the engine by concern, package-wide helpers in `util`, the
paper's reproduction beside the other runs); code written against the old paths keeps working. `install`
puts the finder on ``sys.meta_path`` (the package's ``__init__`` does); it answers only for `MOVED`'s names,
names no file has any more.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

__all__ = ["MOVED", "new_name", "install"]

#: old module (or package: its submodules too) -> where it is now
MOVED = {
    "pinnedballs.engine.errors": "pinnedballs.util.errors",
    "pinnedballs.engine.checks": "pinnedballs.util.checks",
    "pinnedballs.engine.atomic": "pinnedballs.util.atomic",
    "pinnedballs.engine.limits": "pinnedballs.util.limits",
    "pinnedballs.engine.progress": "pinnedballs.util.progress",
    "pinnedballs.engine.bars": "pinnedballs.util.bars",
    "pinnedballs.engine.sigint": "pinnedballs.util.sigint",
    "pinnedballs.engine.compiling": "pinnedballs.util.compiling",
    "pinnedballs.engine.random": "pinnedballs.engine.streams.xoshiro",
    "pinnedballs.engine.jump": "pinnedballs.engine.streams.jump",
    "pinnedballs.engine.philox": "pinnedballs.engine.streams.philox",
    "pinnedballs.engine.jitcache": "pinnedballs.engine.jit.cache",
    "pinnedballs.engine.intrinsics": "pinnedballs.engine.jit.intrinsics",
    "pinnedballs.engine.loops": "pinnedballs.engine.sequential.loops",
    "pinnedballs.engine.parallel": "pinnedballs.engine.threads.regions",
    "pinnedballs.engine.reservations": "pinnedballs.engine.threads.reservations",
    "pinnedballs.engine.arithmetic": "pinnedballs.engine.field.arithmetic",
    "pinnedballs.engine.fields": "pinnedballs.engine.field.numbers",
    "pinnedballs.engine.exact": "pinnedballs.engine.field.rational",
    "pinnedballs.engine.fixed": "pinnedballs.engine.field.fixed",
    "pinnedballs.engine.fixed_kernels": "pinnedballs.engine.field.fixed_kernels",
    "pinnedballs.engine.fixed_state": "pinnedballs.engine.field.fixed_state",
    "pinnedballs.engine.limbs": "pinnedballs.engine.field.limbs",
    "pinnedballs.reproduction": "pinnedballs.run.reproduction",
}


def new_name(name: str) -> str | None:
    """Where the module ``name`` is now, or None when it did not move."""
    for old, new in MOVED.items():
        if name == old or name.startswith(old + "."):
            return new + name[len(old):]
    return None


class _Moved(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds a moved module under its old name: the module itself, imported by its new one."""

    def find_spec(self, name, path=None, target=None):
        new = new_name(name)
        return None if new is None else importlib.util.spec_from_loader(name, self)

    def create_module(self, spec):
        new = new_name(spec.name)
        # stacklevel 2: the import statement (warnings skips the import machinery's own frames)
        warnings.warn(f"{spec.name} moved to {new}; import it from there", DeprecationWarning, stacklevel=2)
        return importlib.import_module(new)

    def exec_module(self, module):
        pass  # imported already, under its own name


def install() -> None:
    """Put the finder on ``sys.meta_path`` once, first: the submodules of a moved package must be found by it (as
    the moved ones), not by the path finder in the package's directory (as a second copy under the old name).
    It answers only for `MOVED`'s names, which no file has any more."""
    if not any(isinstance(f, _Moved) for f in sys.meta_path):
        sys.meta_path.insert(0, _Moved())
