"""An ensemble's directory as `pinnedballs ensemble` and `EnsembleResult.save` write it: ``replicas.csv`` (a
row per replica and snapshot, floats as their shortest round-trip repr, so tables compare bit for bit),
``summary.json`` (the statistics and how the ensemble was made), ``spec.json``, the energy profiles and the
figures (the correlations' histograms over replicas, the mean energy by distance from the boundary);
`ensemble_dir.load_ensemble` reads it back."""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

import numpy as np

from .._version import __version__
from ..util.atomic import write_text_atomic
from . import profiles

__all__ = ["write_outputs", "write_figures", "write_table", "read_table", "json_safe", "remove_old_outputs",
           "TABLE_NAME", "SUMMARY_NAME", "SPEC_NAME", "FIGURES_DIR", "KEY_COLUMNS", "MARGIN_COLUMNS", "ERROR_COLUMN",
           "FINAL", "CORRELATIONS", "CORRELATION_BIN_WIDTH"]

TABLE_NAME, SUMMARY_NAME, SPEC_NAME, FIGURES_DIR = "replicas.csv", "summary.json", "spec.json", "figures"
#: the first columns of every row; observables follow, then `ERROR_COLUMN`
KEY_COLUMNS = ("replica", "seed_entropy", "spawn_key", "at", "steps", "collisions", "frozen", "stop_reason")
#: the closing margin of a row's state, after `KEY_COLUMNS` (`margin_columns`)
MARGIN_COLUMNS = ("smallest_collision", "largest_remnant", "near_collisions", "near_remnants")
ERROR_COLUMN = "error"
#: the ``at`` of a replica's final state (snapshots are ``"steps=N"`` or ``"collisions=N"``)
FINAL = "final"
#: correlation columns drawn as histograms over replicas (bin width 0.02 on [-1, 1])
CORRELATIONS = {"line_of_centres_correlation": "line-of-centres correlation of (u, u') over contacts",
                "xy_correlation": "correlation of the x- and y-components over balls"}
CORRELATION_BIN_WIDTH = 0.02



def _cell(value) -> str:
    """A CSV cell: floats as their shortest round-trip repr (so tables compare bit for bit)."""
    if value is None:
        return ""
    if isinstance(value, (bool, np.bool_)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(value)


def write_table(result, path) -> Path:
    """Write ``result.rows`` as CSV at ``path`` (missing cells empty), atomically."""
    path, text = Path(path), io.StringIO()
    columns = result.columns
    w = csv.writer(text, lineterminator="\n")
    w.writerow(columns)
    for row in result.rows:
        w.writerow([_cell(row.get(c)) for c in columns])
    write_text_atomic(path, text.getvalue())
    return path


def read_table(path) -> list[dict[str, str]]:
    """The rows of a ``replicas.csv`` as dicts of strings (empty cells left out)."""
    with Path(path).open(newline="", encoding="utf-8") as f:
        return [{k: v for k, v in row.items() if v != ""} for row in csv.DictReader(f)]


def json_safe(value):
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _slug(at: str) -> str:
    return at.replace("=", "_")


def write_outputs(result, out_dir, figures: bool = True) -> list[Path]:
    """Write ``replicas.csv``, ``summary.json``, ``spec.json`` and (if ``figures``)
    ``figures/<correlation>_<at>.png`` into ``out_dir`` (created); return the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = [write_table(result, out / TABLE_NAME), *profiles.write_profiles(result.rows, out)]
    summary = {
        "replicas": result.replicas,
        "succeeded": result.replicas - len(result.failures),
        "failed": [{k: row[k] for k in ("replica", "seed_entropy", "spawn_key", ERROR_COLUMN)}
                   for row in result.failures],
        "seed": result.spec.seed,
        "seeds": "replica k: numpy.random.SeedSequence(seed).spawn(replicas)[k] (entropy seed, spawn key [k])",
        "where": result.where,
        "wall_seconds": result.wall_seconds,
        "version": __version__,
        **({} if result.provenance is None else {"provenance": result.provenance}),  # how it was made
        "statistics": result.statistics(),
        "spec": json.loads(result.spec.model_dump_json()),
    }
    path = out / SUMMARY_NAME
    write_text_atomic(path, json.dumps(json_safe(summary), indent=2) + "\n")
    path2 = out / SPEC_NAME
    write_text_atomic(path2, result.spec.to_json() + "\n")
    written += [path, path2]
    if figures:
        written += write_figures(result, out)
    return written


def write_figures(result, out_dir) -> list[Path]:
    """Write ``figures/<correlation>_<at>.png`` (the correlations over replicas at each stage) into
    ``out_dir``, first removing those an earlier ensemble left; return their paths."""
    from ..plot.figures import correlation_histogram

    out = Path(out_dir)
    _remove_figures(out)
    written = []
    for at in result.stages():
        for name, label in CORRELATIONS.items():
            x = result.column(name, at)
            x = x[np.isfinite(x)]
            if not len(x):
                continue
            when = "final state" if at == FINAL else at.replace("=", " = ")
            fig_path = out / FIGURES_DIR / f"{name}_{_slug(at)}.png"
            correlation_histogram(x, CORRELATION_BIN_WIDTH, title=f"{label}\n{len(x)} replicas, {when}",
                                  xlabel=name.replace("_", " "), path=fig_path)
            written.append(fig_path)
    means = profiles.mean_profiles(result.rows, ERROR_COLUMN)  # on a geometry with a boundary: its mean profile
    return written + profiles.write_profile_figures(means, result.spec.geometry.build(), out / FIGURES_DIR, FINAL)


def remove_old_outputs(out: Path) -> None:
    """Before writing with --force: remove what an earlier ensemble wrote here (other files stay)."""
    for name in (TABLE_NAME, SUMMARY_NAME, SPEC_NAME, profiles.PROFILES_NAME):
        (out / name).unlink(missing_ok=True)
    _remove_figures(out)


def _remove_figures(out: Path) -> None:
    profiles.remove_profile_figures(out / FIGURES_DIR)
    for name in CORRELATIONS:
        for png in (out / FIGURES_DIR).glob(f"{name}_*.png"):
            png.unlink()
