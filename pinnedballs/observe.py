"""Observables by name: a registry of functions of a simulation's current state.

Writers and specs select observables by name; each is measured on every snapshot and
stored as one column (``(F,)`` for a number, ``(F, *shape)`` for an array). The built-ins:

* ``steps``, ``collisions``: the counters (always recorded);
* ``energy``: ``sum m |v|^2 / 2``; ``momentum``: ``(dim,)`` ``sum m v`` (meaningful in flat space);
* ``approaching``: the number of live contacts (0: frozen).

Add your own with `register` (``fn(sim) -> number or array``, which must not change ``sim``).
"""

from __future__ import annotations

import re
from typing import Callable

import numpy as np

__all__ = ["OBSERVABLES", "DEFAULT", "ALWAYS", "register", "check_names", "measure"]

#: ``name -> fn(sim)``; use `register` to add to it
OBSERVABLES: dict[str, Callable] = {
    "steps": lambda sim: sim.steps,
    "collisions": lambda sim: sim.collisions,
    "energy": lambda sim: sim.energy(),
    "momentum": lambda sim: np.asarray(sim.momentum(), dtype=np.float64),
    "approaching": lambda sim: sim.approaching(),
}
#: recorded on every snapshot whatever is selected
ALWAYS = ("steps", "collisions")
#: what writers and specs record unless told otherwise
DEFAULT = ("steps", "collisions", "energy", "momentum", "approaching")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def register(name: str, fn: Callable, *, replace: bool = False) -> Callable:
    """Register ``fn(sim) -> number or array`` as the observable ``name``; returns ``fn``."""
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(f"name: must be an identifier (letters, digits, _), got {name!r}")
    if not callable(fn):
        raise TypeError(f"fn: must be callable, got {type(fn).__name__}")
    if name in OBSERVABLES and not replace:
        raise ValueError(f"name: {name!r} is already registered (pass replace=True to replace it)")
    if name in ALWAYS:
        raise ValueError(f"name: {name!r} is a built-in counter and cannot be replaced")
    OBSERVABLES[name] = fn
    return fn


def check_names(names, field: str = "observables") -> tuple[str, ...]:
    """``ALWAYS`` followed by ``names`` (registered, without repeats), or a ValueError naming ``field``."""
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise TypeError(f"{field}: must be a list of observable names, got {names!r}")
    for n in names:
        if n not in OBSERVABLES:
            raise ValueError(f"{field}: unknown observable {n!r} (known: {', '.join(OBSERVABLES)})")
    return tuple(dict.fromkeys((*ALWAYS, *names)))


def measure(sim, names) -> dict[str, np.ndarray]:
    """``{name: value}`` of the observables ``names`` on ``sim``'s current state, as numpy values."""
    return {n: np.asarray(OBSERVABLES[n](sim)) for n in names}
