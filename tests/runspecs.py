"""Small run specs shared by the spec, I/O, CLI and resume tests."""

from __future__ import annotations

import copy
import json
from pathlib import Path

TORUS = {
    "geometry": {"kind": "flat_torus", "rows": 4, "cols": 4},
    "initial": {"kind": "single_ball", "ball": 0, "direction": [1, 0], "energy": 100},
    "rule": {"kind": "elastic"},
    "scheduler": {"kind": "uniform_random_pair"},
    "stop": {"steps": 1000},
    "snapshots": {"at_steps": [0, 250, 1000]},
    "seed": 1,
}

HALF_PLANE = {
    "geometry": {"kind": "half_plane", "rows": 6, "cols": 10},
    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
    "stop": {"frozen": True, "max_steps": 10**7},
    "seed": 3,
}


def spec(base: dict = TORUS, **changes) -> dict:
    """A deep copy of ``base`` with dotted keys changed (``geometry__rows=6``); ``...`` deletes a key."""
    d = copy.deepcopy(base)
    for dotted, value in changes.items():
        *parents, key = dotted.split("__")
        node = d
        for p in parents:
            node = node[p]
        if value is ...:
            node.pop(key, None)
        else:
            node[key] = value
    return d


def write(path: Path, data: dict) -> Path:
    """Write ``data`` as JSON to ``path``; return ``path``."""
    path.write_text(json.dumps(data))
    return path
