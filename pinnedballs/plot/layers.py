"""The state picture of a 3-D packing: every layer of equal height as a panel seen from above.

In each panel the balls of one layer are drawn at their true size, coloured by ``v_z`` on a
diverging scale (red: up, +z; blue: down; white: no vertical motion), with ``(v_x, v_y)`` as
arrows; all panels (and all frames of a movie) share one colour scale and one arrow scale. So a
kick straight up, a kick down and a kick in the top layer all look different.
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import EllipseCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure

from ..geometry.rows import boundary_rows
from .base import _shared_scale, _spacing, key_speed, length_label, panels, save

__all__ = ["layers", "layer_of", "VZ_COLOURS", "MAX_PANELS"]

#: the diverging colour map of ``v_z``: red up, blue down, white at rest
VZ_COLOURS = "RdBu_r"
#: at most this many layers get a panel (evenly spaced, the bottom and top always among them)
MAX_PANELS = 24
_COLUMNS = 4
_IN_PLANE_ARROWS = "0.1"


def layer_of(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(layer (n,), heights (L,))``: the layer of each ball, 0 the lowest, by equal ``z (n,)``."""
    return boundary_rows(z)


def _shown(n_layers: int) -> np.ndarray:
    """The layers that get a panel: all, or `MAX_PANELS` evenly spaced from the bottom to the top."""
    if n_layers <= MAX_PANELS:
        return np.arange(n_layers)
    return np.unique(np.round(np.linspace(0, n_layers - 1, MAX_PANELS)).astype(int))


def layers(positions, velocities, title: str | None = None, path=None, shared=None, radius: float | None = None,
           ax=None) -> Figure:
    """A state of a 3-D packing, one panel per layer (see the module's docstring).

    positions: ``(n_balls, 3)``; velocities: ``(n_balls, 3)``; ``shared``: the velocities
    ``[(n_balls, 3), ...]`` of every frame of a movie (one colour and arrow scale for all);
    radius: of the balls (None: half the spacing of the bottom layer's centres); ax: the Axes whose
    place the panels take (None: a new figure).
    """
    p = np.asarray(positions, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or v.shape != p.shape:
        raise ValueError(f"positions, velocities: must both have shape (n_balls, 3), got {p.shape} and {v.shape}")
    layer, heights = layer_of(p[:, 2])
    shown = _shown(len(heights))
    frames = [np.asarray(u, dtype=np.float64) for u in shared] if shared is not None else [v]
    spacing = _spacing(p[layer == 0, :2])
    k = _shared_scale(np.linalg.norm(v[:, :2], axis=1), shared, spacing, lambda u: np.linalg.norm(u[:, :2], axis=1))
    top = max(float(np.abs(u[:, 2]).max(initial=0.0)) for u in frames)
    norm = Normalize(-top, top) if top > 0 else Normalize(-1.0, 1.0)
    diameter = 2.0 * radius if radius is not None else spacing
    tips = np.concatenate([p[:, :2], *(p[:, :2] + k * u[:, :2] for u in frames)])
    lo, hi = tips.min(axis=0) - diameter, tips.max(axis=0) + diameter
    columns = min(_COLUMNS, int(np.ceil(np.sqrt(len(shown)))))
    rows = -(-len(shown) // columns)
    panel = 3.6 * float(np.clip((hi[1] - lo[1]) / (hi[0] - lo[0]), 0.4, 2.0))
    fig = panels(ax, (3.6 * columns + 1.2, panel * rows + 1.0))
    axes = fig.subplots(rows, columns, squeeze=False, sharex=True, sharey=True)
    balls, arrows = None, None
    for ax, index in zip(axes.ravel(), shown):
        on = layer == index
        balls, drawn = _layer(ax, p[on], v[on], diameter, norm, k, spacing)
        arrows = arrows or drawn
        where = " (the lowest)" if index == 0 else " (the highest)" if index == len(heights) - 1 else ""
        ax.set_title(f"layer {index + 1} of {len(heights)}: z = {heights[index]:.3g}{where}", fontsize="medium")
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
    for ax in axes.ravel()[len(shown):]:
        ax.set_axis_off()
    for ax in axes[-1]:
        ax.set_xlabel(length_label("x", radius))
    for ax in axes[:, 0]:
        ax.set_ylabel(length_label("y", radius))
    bar = fig.colorbar(balls, ax=axes, shrink=0.8, aspect=30)
    bar.set_label("v_z: red up (+z), blue down (-z), white none")
    note = f" ({len(shown)} of {len(heights)} layers drawn, evenly spaced)" if len(shown) < len(heights) else ""
    fig.suptitle(f"{title or 'state'}{note}")  # also the row of the arrow key, at its left
    if arrows is not None:
        key = key_speed(spacing / k)
        arrows.axes.quiverkey(arrows, X=0.05, Y=0.975, U=key, label=f"speed {key:g} (v_x, v_y)", labelpos="E",
                              coordinates="figure", fontproperties={"size": "small"})
    return save(fig, path)


def _layer(ax, p: np.ndarray, v: np.ndarray, diameter: float, norm: Normalize, k: float, spacing: float):
    """One layer's balls ``p (m, 3)`` coloured by ``v_z`` and arrows of ``(v_x, v_y)``, ``k`` long per unit
    speed; ``(balls, arrows)``: the balls' collection and the `Quiver` (None if no ball moves across)."""
    balls = EllipseCollection(np.full(len(p), diameter), np.full(len(p), diameter), 0.0, units="xy",
                              offsets=p[:, :2], offset_transform=ax.transData, cmap=VZ_COLOURS, norm=norm,
                              edgecolors="0.55", linewidths=0.5)
    balls.set_array(v[:, 2])
    ax.add_collection(balls)
    moving = np.hypot(v[:, 0], v[:, 1]) > 0
    if not moving.any():
        return balls, None
    return balls, ax.quiver(p[moving, 0], p[moving, 1], v[moving, 0], v[moving, 1], color=_IN_PLANE_ARROWS,
                            angles="xy", scale_units="xy", scale=1.0 / k, units="xy", width=0.08 * spacing,
                            headwidth=3.5, headlength=4.0, headaxislength=3.5, minlength=0.0)
