"""What a run directory whose index (``results.h5``) is lost still holds: its segments and static
data, described for ``pinnedballs info`` so a user can tell which run they were before putting the
index back. Reads only, and trusts nothing it reads (the digests that vouched for these files were
in the lost index)."""

from __future__ import annotations

import os
import re
from pathlib import Path

import h5py
import numpy as np

from .format import DATA_DIR, RESULTS_NAME, STATIC_NAME

__all__ = ["lost_index"]

_SEGMENT = re.compile(r"frames_(\d+)\.h5")


def lost_index(run_dir: str | os.PathLike) -> list[str] | None:
    """Lines describing the segments in ``run_dir/results.data/`` when ``run_dir`` (or the index path
    ``run_dir/results.h5``) has no index but holds segments; None when it is not such a directory."""
    run_dir = Path(run_dir)
    if run_dir.name == RESULTS_NAME and not run_dir.is_dir():  # the index's own path was given
        run_dir = run_dir.parent
    data = run_dir / DATA_DIR
    if (run_dir / RESULTS_NAME).exists() or not data.is_dir():
        return None
    segments = sorted((p for p in data.iterdir() if _SEGMENT.fullmatch(p.name) and p.is_file()),
                      key=lambda p: int(_SEGMENT.fullmatch(p.name).group(1)))
    if not segments:
        return None
    frames, steps, collisions, unreadable = 0, [], [], []
    for p in segments:
        try:
            with h5py.File(p, "r") as f:
                frames += len(f["velocities"])
                steps += np.asarray(f["observables/steps"][()]).tolist()
                collisions += np.asarray(f["observables/collisions"][()]).tolist()
        except (OSError, KeyError, TypeError, ValueError):
            unreadable.append(p.name)
    lines = [f"results:     {run_dir / RESULTS_NAME} is missing: the run's index is lost",
             f"segments:    {len(segments)} in {data} ({segments[0].name} to {segments[-1].name}): "
             f"{frames:,} snapshot(s)" + (f", steps {min(steps):,} to {max(steps):,}, collisions {min(collisions):,} "
                                          f"to {max(collisions):,}" if steps else "")
             + (f"; unreadable: {', '.join(unreadable)}" if unreadable else ""),
             f"geometry:    {_static(data / STATIC_NAME)}"]
    spec = run_dir / "spec.json"
    lines.append(f"recover:     put {RESULTS_NAME} back from a backup (nothing can rebuild it: it holds the last "
                 f"state); " + (f"the run's spec is {spec}" if spec.is_file() else "no spec.json beside it"))
    return lines


def _static(path: Path) -> str:
    """The balls, contacts and velocity components of the static file at ``path``, or why not."""
    try:
        with h5py.File(path, "r") as f:
            n, (e, d) = len(f["geometry/positions"]), f["geometry/t_i"].shape
    except (OSError, KeyError, TypeError, ValueError):
        return f"{path.name} is missing or unreadable"
    return f"{n:,} balls, {e:,} contacts, dim {d} ({path.name})"
