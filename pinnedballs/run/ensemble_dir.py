"""An ensemble directory read back: `load_ensemble` gives the `EnsembleResult` that
``pinnedballs ensemble`` (or `ensemble_files.write_outputs`) wrote, and `describe` the few lines
``pinnedballs info`` prints of it.

The directory holds ``replicas.csv`` (a row per replica and snapshot, and one for each final
state), ``summary.json`` (how it ran) and ``spec.json``, and on a geometry with a boundary ``profiles.csv``
(each row's energy profile, `run.profiles`, put back in the rows). A directory without them, or a file
that does not parse, or a table cut short (a row with fewer cells than its header, a replica without a
row), is an `InputError` naming the file (and the row and column of a bad cell).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from ..specs.run import stored_spec
from ..util import provenance
from ..util.errors import InputError
from .ensemble import ERROR_COLUMN, FINAL, KEY_COLUMNS, SPEC_NAME, SUMMARY_NAME, TABLE_NAME, EnsembleResult
from .ensemble_files import read_table
from .profiles import PROFILE, read_profiles

__all__ = ["load_ensemble", "is_ensemble_dir", "describe"]

#: columns that hold integers (the others hold numbers, except the texts below)
_INTEGERS = ("replica", "seed_entropy", "steps", "collisions", "frozen", "near_collisions", "near_remnants")
_TEXTS = ("spawn_key", "at", "stop_reason", ERROR_COLUMN)


def is_ensemble_dir(path: str | os.PathLike) -> bool:
    """True when ``path`` is a directory holding an ensemble's ``replicas.csv`` and ``summary.json``."""
    p = Path(path)
    return p.is_dir() and (p / TABLE_NAME).is_file() and (p / SUMMARY_NAME).is_file()


def _cell(name: str, text: str, where: str):
    if name in _TEXTS:
        return text
    try:
        return int(text) if name in _INTEGERS else float(text)
    except ValueError:
        kind = "an integer" if name in _INTEGERS else "a number"
        raise InputError(f"{where}: column {name}: must be {kind}, got {text[:40]!r}") from None


def _json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{path}: missing (not an ensemble directory, or an incomplete one)") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{path}: not readable JSON ({' '.join(str(exc).split())})") from None
    if not isinstance(data, dict):
        raise InputError(f"{path}: must hold a JSON object")
    return data


def load_ensemble(path: str | os.PathLike) -> EnsembleResult:
    """The `EnsembleResult` in an ensemble directory (``pinnedballs ensemble``'s, `EnsembleResult.save`'s).

    Parameters
    ----------
    path : str or os.PathLike
        The directory.

    Returns
    -------
    EnsembleResult
        Its rows (numbers as numbers, each row's energy profile put back), its spec, the number of replicas
        and how it ran.

    Raises
    ------
    InputError
        Naming the file (and the row and column of a bad cell) where it is not one: no such directory, a
        file missing or that does not parse, a table cut short.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.specs.run import parse_spec
    >>> spec = parse_spec({"geometry": {"kind": "half_plane", "rows": 4, "cols": 6}, "seed": 1,
    ...                    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1],
    ...                                "energy": 0.5},
    ...                    "stop": {"frozen": True, "max_steps": 100000}})
    >>> ens = pb.run_ensemble(spec, replicas=3, workers=1)
    >>> [p.name for p in ens.save("ensemble", figures=False)]
    ['replicas.csv', 'profiles.csv', 'summary.json', 'spec.json']
    >>> back = pb.load_ensemble("ensemble")
    >>> back.column("collisions").tolist(), back.rows == ens.rows
    ([46.0, 52.0, 60.0], True)
    """
    out = Path(path)
    if not out.is_dir():
        raise InputError(f"{out}: no such directory")
    if not (out / TABLE_NAME).is_file():
        raise InputError(f"{out}: not an ensemble directory (no {TABLE_NAME})")
    summary = _json(out / SUMMARY_NAME)
    try:
        spec = stored_spec((out / SPEC_NAME).read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{out / SPEC_NAME}: missing (not an ensemble directory, or an incomplete one)") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{out / SPEC_NAME}: not a valid run spec ({' '.join(str(exc).split())[:200]})") from None
    try:
        raw = read_table(out / TABLE_NAME)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"{out / TABLE_NAME}: not a readable table ({' '.join(str(exc).split())})") from None
    replicas = summary.get("replicas")
    if not isinstance(replicas, int) or isinstance(replicas, bool) or replicas < 1:
        raise InputError(f"{out / SUMMARY_NAME}: replicas: must be a count >= 1, got {replicas!r}")
    table = out / TABLE_NAME
    for n, row in enumerate(raw):
        if None in row.values():  # csv's cell for each column past the row's last
            raise InputError(f"{table}: row {n + 2}: has fewer cells than the header has columns (cut short, or "
                             f"damaged)")
    rows = [{k: _cell(k, v, f"{table}: row {n + 2}") for k, v in row.items() if k is not None}
            for n, row in enumerate(raw)]
    for n, row in enumerate(rows):
        if "replica" not in row or not (ERROR_COLUMN in row or all(k in row for k in KEY_COLUMNS[:5])):
            raise InputError(f"{table}: row {n + 2}: must have the columns {', '.join(KEY_COLUMNS[:5])}")
        if not 0 <= row["replica"] < replicas:
            raise InputError(f"{table}: row {n + 2}: replica {row['replica']} is not one of the {replicas} "
                             f"replicas {SUMMARY_NAME} counts")
        if ERROR_COLUMN not in row:
            row.setdefault("stop_reason", "")  # a snapshot's row: written as an empty cell
    _check_every_replica(table, rows, replicas)
    try:
        shares = read_profiles(out)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(" ".join(str(exc).split())) from None
    for row in rows:
        if (row["replica"], row.get("at")) in shares:
            row[PROFILE] = shares[row["replica"], row["at"]]
    wall = summary.get("wall_seconds")
    return EnsembleResult(spec, replicas, rows, str(summary.get("where", "")),
                          float(wall) if isinstance(wall, (int, float)) and not isinstance(wall, bool) else math.nan,
                          _provenance(out / SUMMARY_NAME, summary))


def _provenance(path: Path, summary: dict) -> dict | None:
    """The ``provenance`` ``summary.json`` (at ``path``) holds, checked (`util.provenance.problem`); None where it
    holds none (written before ensembles kept it)."""
    if "provenance" not in summary:
        return None
    said = provenance.problem(summary["provenance"])
    if said is not None:
        raise InputError(f"{path}: provenance: {said}")
    return summary["provenance"]


def _check_every_replica(table: Path, rows: list[dict], replicas: int) -> None:
    """An `InputError` naming ``table`` unless it holds rows of each of the ``replicas`` (every replica writes at
    least one: its final state, or its error): a table cut short is never read as a whole ensemble."""
    missing = sorted(set(range(replicas)) - {row["replica"] for row in rows})
    if not missing:
        return
    which = f"replica {missing[0]}" if len(missing) == 1 else \
        f"{len(missing)} replicas ({', '.join(map(str, missing[:3]))}{', ...' if len(missing) > 3 else ''})"
    held = "holds no rows" if not rows else f"holds no row of {which}"
    raise InputError(f"{table}: {held}, but {SUMMARY_NAME} counts {replicas} replicas (cut short, or damaged)")


def describe(result: EnsembleResult, path: Path) -> list[str]:
    """The lines ``pinnedballs info`` prints of an ensemble directory."""
    final = [r for r in result.rows if not r.get(ERROR_COLUMN) and r.get("at") == FINAL]
    stages = result.stages()
    lines = [f"ensemble:    {path}",
             f"replicas:    {result.replicas} ({result.replicas - len(result.failures)} done, "
             f"{len(result.failures)} failed), seeds spawned from {result.spec.seed}",
             f"geometry:    {result.spec.geometry.kind}; {result.spec.rule.kind}, {result.spec.scheduler.kind}",
             f"ran:         {result.where}" + (f" in {result.wall_seconds:.3g} s" if math.isfinite(result.wall_seconds)
                                                else ""),
             f"stages:      {len(stages)}: " + ", ".join(stages[:4]) + (", ..." if len(stages) > 4 else "")]
    for name in ("steps", "collisions"):
        x = np.array([r[name] for r in final], dtype=np.float64)
        if len(x):
            lines.append(f"{name + ':':<12} mean {x.mean():,.6g}, min {x.min():,.0f}, max {x.max():,.0f} "
                         "(final states)")
    if final:
        frozen = sum(int(r["frozen"]) for r in final)
        lines.append(f"frozen:      {frozen} of {len(final)} final states")
    kept = [r for r in final if "near_collisions" in r]
    if kept:
        lines.append(_margins(kept, len(result.thin())))
    return lines + provenance.lines([] if result.provenance is None else [result.provenance])


def _margins(final: list[dict], thin: int) -> str:
    """One line on the replicas' closing margins (`engine.margin`): how many are thin, the smallest
    collision and the largest remnant over them all, in thresholds."""
    low = [r["smallest_collision"] for r in final if "smallest_collision" in r]
    high = [r["largest_remnant"] for r in final if "largest_remnant" in r]
    smallest = f"smallest collision {min(low):.3g} thresholds" if low else "no collision"
    largest = f"largest remnant {max(high):.3g} thresholds" if high else "no remnant set aside"
    return f"margin:      thin in {thin} of {len(final)} final states; {smallest}, {largest} (over all replicas)"
