"""A run as tidy data: `to_pandas` (one row per snapshot, scalar columns) and `to_xarray` (labelled
arrays, the velocities read lazily through dask). The final state is always the last row: the
state the run stopped in, after the snapshots (or the last snapshot itself, when it is that state).

pandas and xarray are imported here only, when a table is asked for: ``import pinnedballs`` and a
run from the command line never load them.
"""

from __future__ import annotations

import numpy as np

from ..util.extras import need
from .frames import Snapshots

__all__ = ["rows", "to_pandas", "to_xarray", "component_names"]


def component_names(dim: int) -> list[str]:
    """``["x", "y", "z"][:dim]`` up to three components, else ``["0", "1", ...]``."""
    return list("xyz"[:dim]) if dim <= 3 else [str(k) for k in range(dim)]


def _final_is_last_snapshot(res) -> bool:
    s = res.snapshots
    return len(s) > 0 and int(s.steps[-1]) == res.steps and int(s.collisions[-1]) == res.collisions


def _final_values(res) -> dict[str, np.ndarray]:
    """The observables of the final state the results file holds (``/state``); the others are NaN."""
    known = {"steps": res.steps, "collisions": res.collisions, "energy": res.energy, "momentum": res.momentum,
             "approaching": res.approaching}
    out = {}
    for name, column in res.observables.items():
        if name in known:
            out[name] = np.asarray(known[name], dtype=column.dtype).reshape(column.shape[1:])
        else:  # a user's observable, measured on snapshots only
            out[name] = np.full(column.shape[1:], np.nan)
    return out


def rows(res) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """``(columns, final)``: each observable over the snapshots and then the final state (``(F', ...)``,
    ``F' = F`` or ``F + 1``), and ``final (F',) bool``, True on the final state's row only."""
    columns = {name: np.asarray(column) for name, column in res.observables.items()}
    final = np.zeros(len(res.snapshots), dtype=bool)
    if _final_is_last_snapshot(res):
        final[-1] = True
        return columns, final
    extra = _final_values(res)
    columns = {name: np.concatenate([c.astype(np.result_type(c, extra[name])), extra[name][None]])
               for name, c in columns.items()}
    return columns, np.append(final, True)


def _scalar_columns(name: str, values: np.ndarray, dim: int) -> dict[str, np.ndarray]:
    """One column per number: ``momentum`` as ``momentum_x, momentum_y``, other arrays ``name_0, name_1, ...``."""
    if values.ndim == 1:
        return {name: values}
    flat = values.reshape(len(values), -1)
    if name == "momentum" and flat.shape[1] == dim:
        labels = component_names(dim)
    else:
        labels = ["_".join(map(str, k)) for k in np.ndindex(*values.shape[1:])]
    return {f"{name}_{label}": flat[:, k] for k, label in enumerate(labels)}


def to_pandas(res):
    """A `pandas.DataFrame` of the run ``res``: one row per snapshot, then the final state (see the
    module's docstring), indexed by ``snapshot``. Columns: ``steps``, ``collisions``, ``final`` (True on
    the last row), each recorded observable as scalar columns (``energy``, ``momentum_x``,
    ``momentum_y``, ``approaching``, ...), and ``frozen`` when ``approaching`` is recorded. A user's
    observable is NaN on the final row unless a snapshot was taken there."""
    pd = need("pandas", "to_pandas", "pandas")

    columns, final = rows(res)
    dim = res.velocities.shape[1]
    data = {"steps": columns.pop("steps"), "collisions": columns.pop("collisions"), "final": final}
    for name, values in columns.items():
        data.update(_scalar_columns(name, values, dim))
    if "approaching" in data:
        data["frozen"] = data["approaching"] == 0
    return pd.DataFrame(data, index=pd.RangeIndex(len(final), name="snapshot"))


def to_xarray(res):
    """An `xarray.Dataset` of the run ``res``, its velocities read lazily (dask: one chunk per snapshot,
    read from its segment when computed). Dimensions ``snapshot`` (the snapshots, then the final state),
    ``ball``, ``component`` (``x``, ``y``, ...), ``coordinate`` (of the positions). Variables:
    ``velocities (snapshot, ball, component)``; each observable over ``snapshot`` (``momentum`` over
    ``(snapshot, component)``); ``positions (ball, coordinate)``; ``boundary_distance (ball)`` on a
    geometry with a boundary. Coordinates ``steps``, ``collisions`` and ``final`` along ``snapshot``;
    attributes: the results file, status, stop reason, frozen, seed."""
    xr = need("xarray", "to_xarray", "xarray")
    da, delayed = need("dask.array", "to_xarray", "xarray"), need("dask", "to_xarray", "xarray").delayed

    columns, final = rows(res)
    n, dim = res.velocities.shape
    snaps: Snapshots = res.snapshots
    frames = [da.from_delayed(delayed(snaps.velocities, pure=True)(k), (n, dim), np.float64) for k in range(len(snaps))]
    if not _final_is_last_snapshot(res):
        frames.append(da.from_array(np.asarray(res.velocities, dtype=np.float64), chunks=(n, dim)))
    velocities = da.stack(frames) if frames else da.zeros((0, n, dim), chunks=(1, n, dim))
    components = component_names(dim)
    data = {"velocities": (("snapshot", "ball", "component"), velocities),
            "positions": (("ball", "coordinate"), np.asarray(res.positions))}
    for name, values in columns.items():
        if name in ("steps", "collisions"):
            continue
        dims = ("snapshot", "component") if name == "momentum" and values.shape[1:] == (dim,) else \
            ("snapshot", *(f"{name}_dim_{k}" for k in range(values.ndim - 1)))
        data[name] = (dims, values)
    boundary = res.stored.boundary
    if boundary is not None:
        data["boundary_distance"] = (("ball",), np.asarray(boundary.distance))
    coords = {"snapshot": np.arange(len(final)), "ball": np.arange(n), "component": components,
              "coordinate": component_names(res.positions.shape[1]),
              "steps": ("snapshot", columns["steps"]), "collisions": ("snapshot", columns["collisions"]),
              "final": ("snapshot", final)}
    attrs = {"results": str(res.path), "status": res.status, "stop_reason": res.stop_reason,
             "frozen": int(res.frozen), "seed": "" if res.spec is None else res.spec.seed}
    return xr.Dataset(data, coords=coords, attrs=attrs)
