"""State pictures: the velocities over the balls, in each geometry's own view (`Geometry.view`).

`state_picture(geometry)` gives the drawing function of a geometry's view: arrows in the plane
(`quiver`), both hemispheres of a sphere (`sphere_views`), the Poincare disk (`poincare_disk`),
a 3-D packing layer by layer (`pinnedballs.plot.layers.layers`), a 1-D chain (`chain`), or each
component against the ball index (`components_by_ball`). Balls are drawn at their true size
(touching balls touch), with a thin white line between them. A state of more than
`field.FIELD_BALLS` (5,000) balls is drawn in the plane, on the sphere and in the disk as a field
instead: the mean speed in small cells, as a heat map (`field`), since arrows would be moire.

Every drawing takes ``ax``: a matplotlib Axes to draw into (a drawing of several panels, such as
both hemispheres or the layers of a packing, takes that Axes' place in its figure), or None for a
new figure; it returns the `Figure` drawn in, saved as a PNG when ``path`` is given.
"""

from __future__ import annotations

import numpy as np
from matplotlib.collections import EllipseCollection
from matplotlib.figure import Figure
from matplotlib.patches import Circle
from matplotlib.ticker import MaxNLocator

from .base import (
    ARROW_COLOUR,
    BALL_COLOUR,
    BALL_EDGE,
    COMPONENT_NAMES,
    _key,
    _new_axes,
    _shared_scale,
    _spacing,
    length_label,
    panels,
    save,
)
from .field import colour_bar, draws_field, speed_field, speed_norm
from .layers import layers

#: a lone arrow in the Poincare disk is at most this many spacings long (3 would run off the disk)
DISK_LONGEST = 1.5

__all__ = ["quiver", "sphere_views", "poincare_disk", "layers", "chain", "components_by_ball", "state_picture",
           "DRAWINGS"]


def quiver(positions, velocities, ax=None, title: str | None = None, path=None, shared=None,
           radius: float | None = None) -> Figure:
    """The paper's state pictures: velocities as arrows over grey balls.

    positions: ``(n_balls, 2)`` centres; velocities: ``(n_balls, 2)``. Balls are grey discs
    of ``radius`` (None: half the typical spacing, so neighbours touch); see `arrow_scale`
    for arrow lengths, and the key below the bottom left corner for the scale. Balls at rest
    get no arrow; the axes reach every arrow's tip. ``shared``: the velocities ``[(n_balls, 2), ...]``
    of every frame of a movie, which get one arrow scale and one extent (the same figure size).
    """
    p = np.asarray(positions, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"positions: must have shape (n_balls, 2), got {p.shape}")
    if v.shape != p.shape:
        raise ValueError(f"velocities: must have shape (n_balls, 2) = {p.shape}, got {v.shape}")
    spacing = _spacing(p)
    speeds = np.linalg.norm(v, axis=1)
    if draws_field(len(p)):
        return _plane_field(p, speeds, spacing, ax, title, path, shared, radius)
    k = _shared_scale(speeds, shared, spacing, lambda u: np.linalg.norm(u, axis=1))
    tips = [p + k * np.asarray(u, dtype=np.float64) for u in (shared if shared is not None else [v])]
    reach = np.concatenate([p, *tips]) if len(p) else np.array([[0.0, 0.0], [1.0, 1.0]])
    lo, hi = reach.min(axis=0) - spacing, reach.max(axis=0) + spacing
    width, height = hi - lo
    lines = 1 + (title or "").count("\n")  # room for every line of the title, and the key below
    fig, ax = _new_axes(ax, (8.0, float(np.clip(8.0 * height / width, 2.5, 10.0)) + 0.6 + 0.25 * lines), title)
    diameter = 2.0 * radius if radius is not None else spacing
    ax.add_collection(EllipseCollection(
        diameter, diameter, 0.0, units="xy", offsets=p, offset_transform=ax.transData,
        facecolors=BALL_COLOUR, edgecolors=BALL_EDGE, linewidths=0.5))
    moving = speeds > 0
    if moving.any():
        arrows = ax.quiver(p[moving, 0], p[moving, 1], v[moving, 0], v[moving, 1], color=ARROW_COLOUR,
                           angles="xy", scale_units="xy", scale=1.0 / k, units="xy", width=0.1 * spacing,
                           headwidth=3.5, headlength=4.0, headaxislength=3.5, minlength=0.0)
        _key(ax, arrows, k, spacing, width)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel(length_label("x", radius))
    ax.set_ylabel(length_label("y", radius))
    return save(fig, path)


def _plane_field(p: np.ndarray, speeds: np.ndarray, spacing: float, ax, title, path, shared, radius) -> Figure:
    """`quiver`'s picture of a large state: the field of the speeds over the plane (`field`)."""
    norm = speed_norm([speeds] if shared is None else [np.linalg.norm(np.asarray(u, float), axis=1) for u in shared])
    lo, hi = p.min(axis=0) - spacing, p.max(axis=0) + spacing
    width, height = hi - lo
    fig, ax = _new_axes(ax, (8.0, float(np.clip(7.0 * height / width, 2.5, 10.0)) + 0.6), title)
    colour_bar(ax.figure, speed_field(ax, p, speeds, norm), ax)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel(length_label("x", radius))
    ax.set_ylabel(length_label("y", radius))
    return save(fig, path)


def _tangent_arrows(ax, p: np.ndarray, v: np.ndarray, k: float, spacing: float):
    """Arrows ``v (n, 2)`` at ``p (n, 2)``, ``k`` long per unit speed; the `Quiver`, or None if all rest."""
    moving = np.linalg.norm(v, axis=1) > 0
    if moving.any():
        return ax.quiver(p[moving, 0], p[moving, 1], v[moving, 0], v[moving, 1], color=ARROW_COLOUR, angles="xy",
                  scale_units="xy", scale=1.0 / k, units="xy", width=0.1 * spacing, headwidth=3.5, headlength=4.0,
                  headaxislength=3.5, minlength=0.0)
    return None


def sphere_views(positions, velocities, title: str | None = None, path=None, shared=None, ax=None) -> Figure:
    """Orthographic views of both hemispheres of the unit sphere, velocities as tangent arrows.

    positions: ``(n_balls, 3)`` on the unit sphere; velocities: ``(n_balls, 3)`` in embedding
    coordinates (``einsum("nd,ndk->nk", v, geom.frames())``). Left: the northern hemisphere seen
    from above (+z); right: the southern seen from below (x mirrored, so both are seen from outside).
    Balls are foreshortened towards the rim (at least to a fifth, to stay visible); arrows show
    each velocity's part in the picture plane, on the common scale of `arrow_scale` (of every
    frame's velocities ``shared`` in a movie), with its key under each view.
    """
    x = np.asarray(positions, dtype=np.float64)
    V = np.asarray(velocities, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or V.shape != x.shape:
        raise ValueError(f"positions, velocities: must both have shape (n_balls, 3), got {x.shape} and {V.shape}")
    fig = panels(ax, (11.0, 5.8))
    spacing = _spacing(x)
    k = _shared_scale(np.linalg.norm(V, axis=1), shared, spacing, lambda u: np.linalg.norm(u, axis=1))
    frames = [V] if shared is None else [np.asarray(u, dtype=np.float64) for u in shared]
    field = draws_field(len(x))
    reach = 1.1 if field else max(1.25, *(float(np.abs(x[:, :2] + k * u[:, :2]).max()) + 0.05 for u in frames))
    norm = speed_norm([np.linalg.norm(u, axis=1) for u in frames]) if field else None
    axes = fig.subplots(1, 2)
    for ax, sign, name in zip(axes, (1.0, -1.0), ("northern hemisphere (from +z)", "southern hemisphere (from -z)")):
        on = sign * x[:, 2] >= 0
        flip = np.array([sign, 1.0])
        p, v = x[on, :2] * flip, V[on, :2] * flip
        ax.add_patch(Circle((0, 0), 1.0, fill=False, color="0.5", linewidth=0.8))
        if field:  # each ball's whole speed, where the view shows its centre
            image = speed_field(ax, p, np.linalg.norm(V[on], axis=1), norm, (-1, 1, -1, 1))
            _hemisphere_axes(ax, reach, sign, name)
            continue
        # a ball seen at a slant: its width along the rim kept, its depth towards the centre foreshortened by |z|
        size = np.full(len(p), spacing)  # neighbours touch
        along_rim = np.degrees(np.arctan2(p[:, 1], p[:, 0])) + 90
        ax.add_collection(EllipseCollection(size, size * np.maximum(np.abs(x[on, 2]), 0.2), along_rim, units="xy",
                                            offsets=p, offset_transform=ax.transData, facecolors=BALL_COLOUR,
                                            edgecolors=BALL_EDGE, linewidths=0.5))
        arrows = _tangent_arrows(ax, p, v, k, spacing)
        if arrows is not None:
            _key(ax, arrows, k, spacing, 2 * reach, y=0.04)
        _hemisphere_axes(ax, reach, sign, name)
    if field:
        colour_bar(fig, image, list(axes))
    if title:
        fig.suptitle(title)
    return save(fig, path)


def _hemisphere_axes(ax, reach: float, sign: float, name: str) -> None:
    ax.set_xlim(-reach, reach)
    ax.set_ylim(-reach, reach)
    ax.set_aspect("equal")
    ax.set_title(name)
    ax.set_xlabel(("x" if sign > 0 else "-x") + " (unit sphere)")
    ax.set_ylabel("y (unit sphere)")


def poincare_disk(positions, velocities, title: str | None = None, path=None, shared=None, ax=None) -> Figure:
    """A state of the hyperbolic plane drawn in the Poincare disk.

    positions: ``(n_balls, 3)`` on the hyperboloid; velocities: ``(n_balls, 3)`` in embedding
    coordinates. Balls sit at ``p = (x1, x2) / (1 + x0)``; balls and arrows are drawn at their
    hyperbolic sizes carried to the disk by the same map (conformal: directions are true,
    lengths shrink by ``(1 - |p|^2) / 2`` towards the rim). Arrow lengths follow `arrow_scale`
    in hyperbolic units, with the spacing of the ball nearest the centre, a lone arrow at most
    `DISK_LONGEST` spacings long (one scale for every frame's velocities ``shared`` in a movie);
    the axes reach every arrow's tip, and the key, in a strip under the disk, gives the speed of
    an arrow at the centre.
    """
    x = np.asarray(positions, dtype=np.float64)
    V = np.asarray(velocities, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or V.shape != x.shape:
        raise ValueError(f"positions, velocities: must both have shape (n_balls, 3), got {x.shape} and {V.shape}")
    p = x[:, 1:] / (1.0 + x[:, :1])
    dp = _disk_velocities(x, V)
    shrink = (1.0 - np.einsum("nk,nk->n", p, p)) / 2.0
    def minkowski_speeds(u):
        return np.sqrt(np.maximum(np.einsum("nk,nk->n", u[:, 1:], u[:, 1:]) - u[:, 0] ** 2, 0.0))

    speeds = minkowski_speeds(V)
    centre = int(np.argmin(x[:, 0]))
    cosh = x[centre, 0] * x[:, 0] - x[:, 1:] @ x[centre, 1:]
    cosh[centre] = np.inf
    spacing = float(np.arccosh(cosh.min())) if len(x) > 1 else 1.0
    if draws_field(len(x)):
        return _disk_field(p, speeds, title, path, shared, ax, minkowski_speeds)
    k = _shared_scale(speeds, shared, spacing, minkowski_speeds, longest=DISK_LONGEST,
                      movie_longest=DISK_LONGEST)
    tips = [p + k * dp] if shared is None else [p + k * _disk_velocities(x, np.asarray(u, float)) for u in shared]
    lo = np.minimum(np.concatenate([*tips, [[-1.0, -1.0]]]).min(axis=0) - 0.05, -1.05)
    hi = np.maximum(np.concatenate([*tips, [[1.0, 1.0]]]).max(axis=0) + 0.05, 1.05)
    lo[1] -= 0.15  # a strip under the disk for the key
    fig, ax = _new_axes(ax, (8.0, float(np.clip(8.0 * (hi[1] - lo[1]) / (hi[0] - lo[0]), 6.0, 10.0))), title)
    ax.add_patch(Circle((0, 0), 1.0, fill=False, color="0.5", linewidth=0.8))
    size = spacing * shrink  # the contact length: neighbours touch
    ax.add_collection(EllipseCollection(size, size, np.zeros(len(p)), units="xy", offsets=p,
                                        offset_transform=ax.transData, facecolors=BALL_COLOUR, edgecolors=BALL_EDGE,
                                        linewidths=0.5))
    moving = speeds > 0
    if moving.any():
        arrows = ax.quiver(p[moving, 0], p[moving, 1], dp[moving, 0], dp[moving, 1], color=ARROW_COLOUR,
                           angles="xy", scale_units="xy", scale=1.0 / k, units="dots", width=2.0, headwidth=3.5,
                           headlength=4.0, headaxislength=3.5, minlength=0.0)
        width, strip = hi[0] - lo[0], 0.08 / (hi[1] - lo[1])  # the key in the middle of the strip
        _key(ax, arrows, k, spacing, width, y=strip, drawn=0.5, where=" at the centre")  # the disk halves lengths there
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x in the Poincare disk (radius 1)")
    ax.set_ylabel("y in the Poincare disk (radius 1)")
    return save(fig, path)


def _disk_field(p: np.ndarray, speeds: np.ndarray, title, path, shared, ax, norm_of) -> Figure:
    """`poincare_disk`'s picture of a large state: the field of the hyperbolic speeds over the disk,
    in cells sized by the spacing of the balls (most of them near the rim, where the disk shrinks them)."""
    norm = speed_norm([speeds] if shared is None else [norm_of(np.asarray(u, float)) for u in shared])
    fig, ax = _new_axes(ax, (8.0, 7.0), title)
    ax.add_patch(Circle((0, 0), 1.0, fill=False, color="0.5", linewidth=0.8))
    colour_bar(ax.figure, speed_field(ax, p, speeds, norm, (-1, 1, -1, 1)), ax)
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_aspect("equal")
    ax.set_xlabel("x in the Poincare disk (radius 1)")
    ax.set_ylabel("y in the Poincare disk (radius 1)")
    return save(fig, path)


def _disk_velocities(x: np.ndarray, V: np.ndarray) -> np.ndarray:
    """``(n, 2)``: velocities ``V (n, 3)`` on the hyperboloid at ``x (n, 3)`` carried to the Poincare disk."""
    one = 1.0 + x[:, :1]
    return (V[:, 1:] * one - x[:, 1:] * V[:, :1]) / one**2


def components_by_ball(x, velocities, xlabel: str = "ball", title: str | None = None, path=None,
                       shared=None, ax=None) -> Figure:
    """Each velocity component as a stem at its ball's ``x (n_balls,)``: the state picture of a 1-D
    chain (``x`` its positions) and of any geometry no other picture fits (``x`` the ball index).

    velocities: ``(n_balls, dim)``, one panel per component (at most three drawn); the vertical
    axis is the same for all panels and, with ``shared`` (every frame of a movie), for all frames.
    """
    x = np.asarray(x, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    if v.ndim != 2 or x.shape != (len(v),):
        raise ValueError(f"x, velocities: must have shapes (n_balls,) and (n_balls, dim), got {x.shape} and {v.shape}")
    count = min(v.shape[1], 3)
    top = max(float(np.abs(np.asarray(u)).max(initial=0.0)) for u in (shared if shared is not None else [v]))
    top = 1.1 * top if top > 0 else 1.0
    fig = panels(ax, (8.0, 1.2 + 2.2 * count))
    axes = fig.subplots(count, 1, sharex=True, squeeze=False)[:, 0]
    for k, ax in enumerate(axes):
        ax.axhline(0.0, color=BALL_COLOUR, linewidth=4, zorder=0)
        ax.scatter(x, np.zeros_like(x), s=12, color="0.5", zorder=1)
        moving = v[:, k] != 0
        if moving.any():
            ax.vlines(x[moving], 0.0, v[moving, k], color=ARROW_COLOUR, linewidth=2)
            ax.scatter(x[moving], v[moving, k], s=10, color=ARROW_COLOUR)
        ax.set_ylim(-top, top)
        name = COMPONENT_NAMES[k] if v.shape[1] <= 3 else str(k)
        ax.set_ylabel(f"v_{name} (velocity units)" if v.shape[1] > 1 else "velocity (velocity units)")
    axes[-1].set_xlabel(xlabel if v.shape[1] <= 3 else f"{xlabel} (components 0-2 of {v.shape[1]} drawn)")
    if len(x) and np.all(np.diff(x) == 1):
        axes[-1].xaxis.set_major_locator(MaxNLocator(integer=True))
    if title:
        fig.suptitle(title)
    return save(fig, path)


def chain(positions, velocities, title: str | None = None, path=None, shared=None, ax=None) -> Figure:
    """A state of a 1-D chain: ``positions (n_balls, 1)``, each velocity ``(n_balls, 1)`` a stem at its ball."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 1:
        raise ValueError(f"positions: must have shape (n_balls, 1), got {p.shape}")
    return components_by_ball(p[:, 0], velocities, xlabel="position x (ball radii)", title=title, path=path,
                              shared=shared, ax=ax)


def _embedded(draw, frames: np.ndarray):
    """``draw`` of velocities given in the balls' frames, carried to embedding coordinates first."""
    def embed(v):
        return np.einsum("nd,ndk->nk", np.asarray(v, dtype=np.float64), frames)

    def embedded(positions, v, title=None, path=None, shared=None, ax=None):
        return draw(positions, embed(v), title=title, path=path,
                    shared=None if shared is None else [embed(u) for u in shared], ax=ax)
    return embedded


def _by_ball(positions, v, title=None, path=None, shared=None, ax=None) -> Figure:
    return components_by_ball(np.arange(len(positions), dtype=np.float64), v, title=title, path=path, shared=shared,
                              ax=ax)


#: the drawing of each view (`pinnedballs.geometry.VIEWS`): ``draw(positions, velocities, title, path, shared)``
DRAWINGS = {"plane": quiver, "sphere": sphere_views, "poincare": poincare_disk, "layers": layers, "chain": chain,
            "components": _by_ball}


def state_picture(geometry):
    """``draw(velocities (n, dim), title=None, shared=None, ax=None) -> Figure`` for this geometry's states,
    in its `view` (velocities in the balls' frames on a curved surface are carried to the embedding first).
    ``shared``: every frame's velocities of a movie, drawn on one scale; ``ax``: draw into these axes
    (a view of several panels takes their place), else a new figure.

    ``pb.Simulation.plot`` and ``pb.Results.plot`` draw with it; so do ``pinnedballs plot`` and movies."""
    draw = DRAWINGS[geometry.view]
    if geometry.view in ("sphere", "poincare"):
        draw = _embedded(draw, geometry.frames())
    positions = np.asarray(geometry.positions, dtype=np.float64)
    if geometry.view in ("plane", "layers"):  # flat: balls of the geometry's radius
        radius = float(geometry.radius)
        return lambda v, title=None, shared=None, ax=None: draw(positions, v, title=title, shared=shared, ax=ax,
                                                                radius=radius)
    return lambda v, title=None, shared=None, ax=None: draw(positions, v, title=title, shared=shared, ax=ax)
