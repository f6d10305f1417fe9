"""The file names of a run's figures, without drawing anything (no matplotlib): what a new run in a
directory clears before it starts, so that an old run's pictures never pass for the new one's."""

from __future__ import annotations

from pathlib import Path

__all__ = ["FIGURE_PATTERNS", "figure_files"]

#: the names `pinnedballs.plot.run.write_figures` gives its files
FIGURE_PATTERNS = ("state_initial.png", "state_snapshots.png", "state_step_*.png", "state_collisions_*.png",
                   "state_final.png", "energy_by_distance.png", "energy_by_height.png", "velocity_histograms.png")


def figure_files(out_dir) -> list[Path]:
    """The files in ``out_dir`` that `write_figures` may have written (to clear a stale run's)."""
    out = Path(out_dir)
    return sorted({p for pattern in FIGURE_PATTERNS for p in out.glob(pattern)})
