"""State pictures of 3-D packings: a panel per layer, v_z as a signed colour, (v_x, v_y) as arrows,
and balls drawn at their true size in every flat view."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import EllipseCollection
from matplotlib.quiver import Quiver

import pinnedballs as pb
from pinnedballs.plot import layers as layer_pictures
from pinnedballs.plot import states

HALF_SPACE = pb.FCC(3, 3, 2, periodic=(True, True, False))


def panels(fig) -> list:
    """The axes that draw a layer (the colour bar has no balls)."""
    return [ax for ax in fig.axes if any(isinstance(c, EllipseCollection) for c in ax.collections)]


def balls_of(ax) -> EllipseCollection:
    (balls,) = [c for c in ax.collections if isinstance(c, EllipseCollection)]
    return balls


def arrows_of(ax) -> list[Quiver]:
    return [c for c in ax.collections if isinstance(c, Quiver)]


def kicked(geom, ball: int, velocity) -> np.ndarray:
    v = np.zeros((geom.n_balls, 3))
    v[ball] = velocity
    return v


def colour_of(ax, x: float, y: float) -> np.ndarray:
    """The RGBA face colour of the ball drawn at ``(x, y)`` in the panel ``ax``."""
    ax.figure.canvas.draw()
    balls = balls_of(ax)
    where = np.flatnonzero(np.all(np.isclose(balls.get_offsets(), [x, y]), axis=1))
    assert len(where) == 1
    return balls.get_facecolors()[where[0]]


def test_one_panel_per_layer_each_with_its_own_balls():
    g = HALF_SPACE
    fig = layer_pictures.layers(g.positions, np.zeros((g.n_balls, 3)))
    heights = np.unique(g.positions[:, 2])
    drawn = panels(fig)
    assert len(drawn) == len(heights) == 4
    for ax, z in zip(drawn, heights):
        on = g.positions[:, 2] == z
        assert np.array_equal(balls_of(ax).get_offsets(), g.positions[on, :2])
        assert ax.get_title().startswith(f"layer {list(heights).index(z) + 1} of 4: z = {z:.3g}")


def test_a_kick_up_and_a_kick_down_have_colours_of_opposite_sign():
    g = HALF_SPACE
    ball = g.boundary_center()
    x, y = g.positions[ball, :2]
    up = layer_pictures.layers(g.positions, kicked(g, ball, [0, 0, 10]))
    down = layer_pictures.layers(g.positions, kicked(g, ball, [0, 0, -10]))
    red, blue = colour_of(panels(up)[0], x, y), colour_of(panels(down)[0], x, y)
    assert red[0] > 2 * red[2] and blue[2] > 2 * blue[0]                # red up, blue down
    bottom = list(np.flatnonzero(g.positions[:, 2] == 0))
    assert balls_of(panels(up)[0]).get_array()[bottom.index(ball)] == 10
    other = next(b for b in bottom if b != ball)
    rest = colour_of(panels(up)[0], *g.positions[other, :2])             # a ball at rest: no colour
    assert np.ptp(rest[:3]) < 0.05 and rest[0] > 0.9
    for fig in (up, down):                                               # straight up or down: no arrow
        assert not any(arrows_of(ax) for ax in panels(fig))


def test_a_ball_moving_in_the_top_layer_is_drawn_in_the_top_panel():
    g = HALF_SPACE
    z = g.positions[:, 2]
    ball = int(np.flatnonzero(z == z.max())[3])
    fig = layer_pictures.layers(g.positions, kicked(g, ball, [3.0, 0.0, 5.0]))
    *lower, top = panels(fig)
    (arrow,) = arrows_of(top)
    assert arrow.N == 1 and np.array_equal(arrow.get_offsets()[0], g.positions[ball, :2])
    assert (arrow.U[0], arrow.V[0]) == (3.0, 0.0)
    r, _, b, _ = colour_of(top, *g.positions[ball, :2])
    assert r > 2 * b                                                     # moving up as well: red
    assert not any(arrows_of(ax) for ax in lower)
    assert "(the highest)" in top.get_title()


def test_a_movie_shares_one_colour_scale_and_one_arrow_scale():
    g = HALF_SPACE
    rng = np.random.default_rng(3)
    frames = [kicked(g, 0, [0, 0, 9]), rng.standard_normal((g.n_balls, 3)), 0.1 * rng.standard_normal((g.n_balls, 3))]
    drawn = [layer_pictures.layers(g.positions, v, shared=frames) for v in frames]
    assert {(balls_of(panels(f)[0]).norm.vmin, balls_of(panels(f)[0]).norm.vmax) for f in drawn} == {(-9.0, 9.0)}
    scales = {q.scale for f in drawn[1:] for ax in panels(f) for q in arrows_of(ax)}
    assert len(scales) == 1


def test_a_tall_packing_draws_the_bottom_the_top_and_evenly_spaced_layers_between():
    g = pb.FCC(1, 1, 13, periodic=False)
    fig = layer_pictures.layers(g.positions, np.zeros((g.n_balls, 3)), title="tall")
    drawn = panels(fig)
    assert len(drawn) == layer_pictures.MAX_PANELS == 24
    assert "(the lowest)" in drawn[0].get_title() and "(the highest)" in drawn[-1].get_title()
    assert fig.get_suptitle() == "tall (24 of 26 layers drawn, evenly spaced)"


def test_the_state_picture_of_a_packing_is_its_layers():
    g = HALF_SPACE
    fig = states.state_picture(g)(kicked(g, g.boundary_center(), [0, 0, 1]), "initial state")
    assert len(panels(fig)) == 4 and fig.get_suptitle() == "initial state"
    assert all(np.array_equal(balls_of(ax).get_widths(), np.full(9 * 2, 2.0)) for ax in panels(fig))


@pytest.mark.parametrize("radius", [1.0, 2.5])
def test_balls_are_drawn_at_their_true_size(radius):
    half = pb.HalfPlane(rows=3, cols=4, radius=radius)
    fig = states.state_picture(half)(np.zeros((half.n_balls, 2)), "at rest")
    (ax,) = fig.axes
    assert np.allclose(balls_of(ax).get_widths(), 2 * radius) and np.allclose(balls_of(ax).get_heights(), 2 * radius)
    assert ax.get_xlabel() == ("x (ball radii)" if radius == 1 else f"x (ball radius {radius:g})")
