"""Moved: `Simulation`, `FreezeWarning`, `RunState` and `mass_array` are `pinnedballs.geometry.simulation`'s
(the model stands below what runs it). Their names here still work, with a DeprecationWarning."""

from __future__ import annotations

import warnings

from ..geometry import simulation as _moved


def __getattr__(name: str):
    if name in _moved.__all__:
        warnings.warn(f"pinnedballs.run.simulation.{name} moved to pinnedballs.geometry.simulation",
                      DeprecationWarning, stacklevel=2)
        return getattr(_moved, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
