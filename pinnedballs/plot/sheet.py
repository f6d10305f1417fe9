"""A contact sheet: every snapshot of a run as a small picture in one grid, on one arrow scale.

One PNG shows how a run evolved where one PNG per snapshot would bury the reader (a run with a
snapshot every 100 collisions has a hundred). Each state is drawn by its geometry's state picture
(`states.state_picture`), all with the arrow scale of every state together, rendered and placed
as a tile titled with its counts.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from .base import panels, render, save

__all__ = ["contact_sheet", "MAX_TILES"]

#: at most this many snapshots get a tile (evenly spaced, the first and the last always among them)
MAX_TILES = 48
_COLUMNS = 6
_SHEET_INCHES = 15.6  #: the width of a full row of tiles; a sheet of fewer columns has larger tiles, up to
_LARGEST_TILE = 6.0


def _chosen(n: int) -> np.ndarray:
    """The snapshots that get a tile: all of them, or `MAX_TILES` evenly spaced from the first to the last."""
    if n <= MAX_TILES:
        return np.arange(n)
    return np.unique(np.round(np.linspace(0, n - 1, MAX_TILES)).astype(int))


def contact_sheet(draw, states: list[tuple[str, np.ndarray]], title: str | None = None, path=None, ax=None) -> Figure:
    """One tile per state of ``states`` ``[(label, velocities (n, dim)), ...]`` drawn with ``draw``
    (`states.state_picture` of the geometry) on their shared arrow scale; the tiles in order,
    left to right and top to bottom. More than `MAX_TILES` states: evenly spaced ones, and the
    title says how many. ``ax``: the Axes whose place the sheet takes (None: a new figure)."""
    chosen = _chosen(len(states))
    shared = [v for _, v in states]
    columns = min(_COLUMNS, int(np.ceil(np.sqrt(len(chosen)))))
    rows = -(-len(chosen) // columns)
    images = [render(draw(states[i][1], None, shared=shared)) for i in chosen]
    height, width = images[0].shape[:2]
    tile = min(_LARGEST_TILE, _SHEET_INCHES / columns)
    fig = panels(ax, (tile * columns, (tile * height / width + 0.3) * rows + 0.5))
    axes = fig.subplots(rows, columns, squeeze=False)
    for ax, i, image in zip(axes.ravel(), chosen, images):
        ax.imshow(image, interpolation="antialiased")
        ax.set_title(states[i][0], fontsize="small")
    for ax in axes.ravel():
        ax.set_axis_off()
    note = f" ({len(chosen)} of {len(states)}, evenly spaced)" if len(chosen) < len(states) else ""
    fig.suptitle(f"{title or 'snapshots'}{note}")
    return save(fig, path)
