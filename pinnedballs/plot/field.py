"""Large states drawn as a field: the mean speed over the balls of each small cell, as a heat map.

Above `FIELD_BALLS` balls, arrows and discs at true size are a few pixels each: a 200 x 200 torus
(40,000 balls) drawn with arrows is moire, not a picture. The state pictures of the plane, the
sphere and the Poincare disk (`states`) then draw a field instead: the balls' centres (as the
view shows them) are binned into square cells 1.5 spacings wide (at most `CELLS` across),
and each cell is coloured by the mean speed of its balls on a log scale (from the largest speed down
to `DECADES` decades below it); cells whose balls are all at rest are the grey of resting balls,
cells without balls are left blank. A mean over whole cells, not a sample per pixel, so the
lattice does not alias into stripes.
"""

from __future__ import annotations

import numpy as np
from matplotlib.colors import LogNorm

from .base import BALL_COLOUR

__all__ = ["FIELD_BALLS", "CELLS", "DECADES", "SPEED_COLOURS", "draws_field", "speed_norm", "speed_field", "colour_bar"]

#: a state of more balls than this is drawn as a field, not as arrows over discs
FIELD_BALLS = 5_000
#: at most this many cells across the picture
CELLS = 400
#: the colour scale spans this many decades of speed below the largest
DECADES = 4
SPEED_COLOURS = "viridis"


def draws_field(n_balls: int) -> bool:
    """True when a state of ``n_balls`` is drawn as a field (more than `FIELD_BALLS`)."""
    return n_balls > FIELD_BALLS


def speed_norm(speeds: list[np.ndarray]) -> LogNorm:
    """The log colour scale of one picture (or of every frame of a movie): ``speeds`` ``[(n,), ...]``."""
    top = max((float(np.max(s)) for s in speeds if len(s)), default=0.0)
    top = top if top > 0 else 1.0
    return LogNorm(top * 10.0 ** -DECADES, top, clip=True)


def _widest_spacing(p: np.ndarray) -> float:
    """The 95th percentile of the distance from a point ``p (n, 2)`` to its nearest neighbour: a cell
    this wide holds a ball even where a projection spreads the balls most (the middle of a hemisphere)."""
    if len(p) < 2:
        return 1.0
    from scipy.spatial import cKDTree

    d = cKDTree(p).query(p, k=2)[0][:, 1]
    d = d[d > 0]
    return float(np.quantile(d, 0.95)) if len(d) else 1.0


def speed_field(ax, points: np.ndarray, speeds: np.ndarray, norm: LogNorm, extent=None):
    """Draw the field of ``speeds (n,)`` at ``points (n, 2)`` (the picture's coordinates) on ``ax``, in
    cells 1.5 times the widest spacing of the points; ``extent``: ``(x0, x1, y0, y1)`` of the cells
    (default: the points' bounding box). Returns the image, for a colour bar."""
    p = np.asarray(points, dtype=np.float64)
    if extent is None:
        lo, hi = p.min(axis=0), p.max(axis=0)
    else:
        lo, hi = np.array(extent[0::2], dtype=float), np.array(extent[1::2], dtype=float)
    size = max(1.5 * _widest_spacing(p), float((hi - lo).max()) / CELLS, 1e-12)
    shape = np.maximum(np.ceil((hi - lo) / size).astype(int), 1)
    cell = np.minimum(((p - lo) / size).astype(int), shape - 1)
    flat = cell[:, 1] * shape[0] + cell[:, 0]
    count = np.bincount(flat, minlength=shape.prod()).reshape(shape[1], shape[0])
    total = np.bincount(flat, weights=speeds, minlength=shape.prod()).reshape(shape[1], shape[0])
    mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    box = (lo[0], lo[0] + shape[0] * size, lo[1], lo[1] + shape[1] * size)
    rest = np.where(count > 0, 1.0, np.nan)  # occupied cells, under the colours: grey where all rest
    ax.imshow(rest, extent=box, origin="lower", cmap=_grey(), interpolation="nearest", vmin=0, vmax=1)
    moving = np.where(mean > 0, mean, np.nan)
    image = ax.imshow(moving, extent=box, origin="lower", cmap=SPEED_COLOURS, norm=norm, interpolation="nearest")
    return image


def _grey():
    from matplotlib.colors import ListedColormap

    return ListedColormap([BALL_COLOUR]).with_extremes(bad=(0.0, 0.0, 0.0, 0.0))


def colour_bar(fig, image, ax) -> None:
    """The colour bar of a field beside ``ax`` (which may be a list of axes)."""
    bar = fig.colorbar(image, ax=ax, shrink=0.85, aspect=30)
    bar.set_label(f"mean speed in a cell (log scale; grey: at rest; {DECADES} decades)")
