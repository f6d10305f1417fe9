"""An ensemble's energy profile: on a geometry with a boundary, each replica's share of the energy in
each row by distance from it (`analysis.observables.energy_profile`, the paper's Figure 3), kept in its
rows under `PROFILE` (a list of floats, apart from the table's columns: a study's or a table's columns
stay the observables') and beside the table in ``profiles.csv`` (a row per replica and stage: its
shares, boundary row first), and the mean over the replicas drawn as a single run's figure is
(``figures/energy_by_distance_<at>.png``).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..analysis import observables as obs
from ..util.atomic import remove, write_text_atomic

__all__ = ["PROFILE", "PROFILES_NAME", "FIGURE_NAME", "energy_shares", "write_profiles", "read_profiles",
           "mean_profiles", "write_profile_figures", "remove_profile_figures"]

#: the key of a row's profile
PROFILE = "energy_profile"
#: the file beside an ensemble's table
PROFILES_NAME = "profiles.csv"
#: the name of the figures of the mean profile, ``<FIGURE_NAME>_<at>.png``
FIGURE_NAME = "energy_by_distance"


def energy_shares(geometry, velocities: np.ndarray, masses=None) -> list[float]:
    """The share of the energy in each row of ``geometry`` (which has a ``boundary``), the boundary row
    first (`observables.energy_profile`; NaN where the energy is 0)."""
    _, fraction = obs.energy_profile(geometry.boundary.distance, velocities, masses)
    return fraction.tolist()


def write_profiles(rows: list[dict], out_dir) -> list[Path]:
    """``out_dir/profiles.csv`` (``replica``, ``at``, then ``row_0``, ``row_1``, ...) of the ``rows`` that have a
    profile, written atomically, and ``[its path]``; none written (and one an earlier ensemble left removed)
    where no row has one: ``[]``."""
    path = Path(out_dir) / PROFILES_NAME
    profiled = [row for row in rows if PROFILE in row]
    if not profiled:
        remove(path)
        return []
    text = io.StringIO()
    w = csv.writer(text, lineterminator="\n")
    w.writerow(["replica", "at", *(f"row_{k}" for k in range(max(len(r[PROFILE]) for r in profiled)))])
    for row in profiled:
        w.writerow([row["replica"], row["at"], *map(repr, row[PROFILE])])
    write_text_atomic(path, text.getvalue())
    return [path]


def read_profiles(out_dir) -> dict[tuple[int, str], list[float]]:
    """``{(replica, at): shares}`` of ``out_dir/profiles.csv`` (empty when there is none); a ValueError saying
    which row is not one."""
    path = Path(out_dir) / PROFILES_NAME
    if not path.is_file():
        return {}
    out = {}
    with path.open(newline="", encoding="utf-8") as f:
        for n, cells in enumerate(csv.reader(f)):
            if n == 0:
                continue
            try:
                out[int(cells[0]), cells[1]] = [float(c) for c in cells[2:] if c != ""]
            except (IndexError, ValueError):
                raise ValueError(f"{path}: row {n + 1}: must be a replica, a stage and numbers") from None
    return out


def mean_profiles(rows: list[dict], error: str) -> dict[str, tuple[np.ndarray, int]]:
    """``{at: (mean shares (n_rows,), replicas)}`` over the rows without an ``error`` whose profile is finite."""
    by_stage: dict[str, list] = {}
    for row in rows:
        shares = row.get(PROFILE)
        if shares is not None and not row.get(error) and np.isfinite(shares).all():
            by_stage.setdefault(row["at"], []).append(np.asarray(shares, dtype=np.float64))
    return {at: (np.mean(np.stack(p), axis=0), len(p)) for at, p in by_stage.items()
            if len({len(x) for x in p}) == 1}


def write_profile_figures(means: dict[str, tuple[np.ndarray, int]], geometry, figures_dir, final: str) -> list[Path]:
    """``figures_dir/energy_by_distance_<at>.png`` (``=`` as ``_``) of each stage's mean profile (`mean_profiles`)
    on ``geometry``, as a run's ``energy_by_distance.png`` is drawn; ``final``: the label of the final state."""
    from ..plot.base import length_unit
    from ..plot.figures import energy_bars

    if not means or geometry.boundary is None:
        return []
    _, centres = obs.boundary_rows(geometry.boundary.distance)
    unit = "lengths on the surface" if geometry.curved else length_unit(geometry.radius)
    written = []
    for at, (mean, n) in means.items():
        if len(mean) != len(centres):
            continue
        when = "final state" if at == final else at.replace("=", " = ")
        path = Path(figures_dir) / f"{FIGURE_NAME}_{at.replace('=', '_')}.png"
        energy_bars(centres, mean, title=f"mean energy by distance from the boundary\n{n} replicas, {when}",
                    xlabel=f"distance from the boundary ({unit})", path=path)
        written.append(path)
    return written


def remove_profile_figures(figures_dir) -> None:
    """Remove the mean profiles' figures an earlier ensemble left in ``figures_dir``."""
    for png in Path(figures_dir).glob(f"{FIGURE_NAME}_*.png"):
        png.unlink()
