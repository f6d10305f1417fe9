"""Plots: PNGs of the right size, and the drawn data equal to the observables."""

import os
import subprocess
import sys
import types

import matplotlib.image
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection
from matplotlib.quiver import Quiver

import pinnedballs as pb
from pinnedballs.analysis import observables as obs
from pinnedballs.plot import base as plot_base
from pinnedballs.plot import figures, states
from pinnedballs.plot import run as plot_run


def read_png(path, fig):
    """The image at ``path``, checked to be a PNG of the figure's size in pixels."""
    assert path.stat().st_size > 0
    image = matplotlib.image.imread(path)
    width, height = fig.get_size_inches() * fig.dpi
    assert image.shape[:2] == (round(height), round(width))
    return image


def one_ball_state(geom):
    v = np.zeros((geom.n_balls, 2))
    v[1] = [0.0, 10.0]
    return v


def normal_state(n, seed=0):
    return np.random.default_rng(seed).normal(size=(n, 2))


# ---------------------------------------------------------------- states

def test_quiver_draws_balls_and_one_arrow_per_moving_ball(tmp_path):
    half = pb.HalfPlane(rows=5, cols=8)
    fig = states.quiver(half.positions, one_ball_state(half), title="initial", path=tmp_path / "q.png")
    image = read_png(tmp_path / "q.png", fig)
    assert image[..., :3].std() > 0                          # not a blank page
    ax = fig.axes[0]
    balls = [c for c in ax.collections if isinstance(c, EllipseCollection)]
    arrows = [c for c in ax.collections if isinstance(c, Quiver)]
    assert len(balls) == 1 and len(balls[0].get_offsets()) == half.n_balls
    assert len(arrows) == 1 and arrows[0].N == 1
    assert ax.get_title() == "initial"
    assert isinstance(fig.canvas, FigureCanvasAgg)


def test_quiver_axes_reach_the_arrow_tips():
    half = pb.HalfPlane(rows=3, cols=4)
    v = np.zeros((half.n_balls, 2))
    v[1] = [0.0, -1.0]                                        # points out of the lattice, below row 0
    ax = states.quiver(half.positions, v).axes[0]
    tip = half.positions[1, 1] - 3 * 2.0                      # a lone arrow is three spacings long
    assert ax.get_ylim()[0] < tip


def test_arrow_scale_keeps_arrows_visible():
    spacing = 2.0
    one = np.zeros(1000)
    one[7] = 14.0
    assert 14.0 * plot_base.arrow_scale(one, spacing) == pytest.approx(3 * spacing)   # a lone arrow: 3 spacings
    spread = np.linalg.norm(normal_state(1000), axis=1)
    k = plot_base.arrow_scale(spread, spacing)
    assert np.quantile(spread, 0.95) * k == pytest.approx(spacing)
    assert 0.3 * spacing < np.median(spread) * k < spacing   # typical arrows: a fair part of a spacing
    assert spread.max() * k <= 3 * spacing


def test_quiver_of_a_state_at_rest_has_no_arrows():
    torus = pb.FlatTorus(rows=4, cols=3)
    ax = states.quiver(torus.positions, np.zeros((12, 2))).axes[0]
    assert not any(isinstance(c, Quiver) for c in ax.collections)


def test_quiver_rejects_bad_shapes():
    with pytest.raises(ValueError, match="^positions:"):
        states.quiver(np.zeros((4, 3)), np.zeros((4, 2)))
    with pytest.raises(ValueError, match="^velocities:"):
        states.quiver(np.zeros((4, 2)), np.zeros((5, 2)))


# ---------------------------------------------------------------- energy against distance

def test_energy_by_distance_bars_are_the_profile_and_sum_to_one(tmp_path):
    half = pb.HalfPlane(rows=6, cols=5)
    d, v = half.boundary_distance(), normal_state(half.n_balls, seed=1)
    fig = figures.energy_by_distance(d, v, path=tmp_path / "bars.png")
    read_png(tmp_path / "bars.png", fig)
    bars = fig.axes[0].patches
    centres, fraction = obs.energy_profile(d, v)
    assert len(bars) == half.rows
    heights = [b.get_height() for b in bars]
    assert sum(heights) == pytest.approx(1.0)
    np.testing.assert_allclose(heights, fraction)
    np.testing.assert_allclose([b.get_x() + b.get_width() / 2 for b in bars], centres, atol=1e-12)


def test_energy_profiles_draw_one_line_per_system(tmp_path):
    profiles = {}
    for rows, cols in [(3, 5), (6, 10), (9, 15)]:
        half = pb.HalfPlane(rows=rows, cols=cols)
        profiles[f"{2 * cols} x {rows}"] = obs.energy_profile(half.boundary_distance(),
                                                              normal_state(half.n_balls, rows))
    fig = figures.energy_profiles(profiles, title="sizes", logy=True, path=tmp_path / "profiles.png")
    read_png(tmp_path / "profiles.png", fig)
    ax = fig.axes[0]
    assert [line.get_label() for line in ax.lines] == list(profiles)
    for line, (centres, fraction) in zip(ax.lines, profiles.values()):
        np.testing.assert_array_equal(line.get_xdata(), centres)
        np.testing.assert_array_equal(line.get_ydata(), fraction)
    assert ax.get_yscale() == "log"


# ---------------------------------------------------------------- distributions

def test_component_histograms_with_fitted_normal(tmp_path):
    """Bars in the velocities' own units (the paper's bins: 1/80 of the largest |component|),
    and a normal curve holding the histogram's area where Anderson-Darling accepts it."""
    v = normal_state(2000, seed=2) * [1.0, 2.0]
    fig = figures.component_histograms(v, path=tmp_path / "hist.png")
    read_png(tmp_path / "hist.png", fig)
    assert len(fig.axes) == 2
    scale = np.abs(v).max()                                   # one set of bins for both panels
    for k, ax in enumerate(fig.axes):
        heights = np.array([b.get_height() for b in ax.patches])
        assert len(heights) == 80 and heights.sum() == 2000
        assert [b.get_width() for b in ax.patches] == pytest.approx([0.025 * scale] * 80)
        (line,) = ax.lines
        x, y = line.get_xdata(), line.get_ydata()
        area = np.sum((y[1:] + y[:-1]) / 2 * np.diff(x))
        assert area == pytest.approx(0.025 * scale * heights.sum(), rel=0.01)  # curve and bars: same area
        assert x[np.argmax(y)] == pytest.approx(v[:, k].mean(), abs=0.01 * scale)
        (note,) = ax.texts
        assert f"sd {v[:, k].std():.3g}" in note.get_text() and "not rejected" in note.get_text()
        assert f"bins of {0.025 * scale:.3g}" in ax.get_xlabel()


def test_component_histograms_draw_no_normal_curve_the_test_rejects():
    """A component that is visibly not normal (uniform, n = 2000: Anderson-Darling A^2 ~ 20)
    gets the test's verdict and no fitted curve that would pass it off as normal."""
    v = np.random.default_rng(4).uniform(-1, 1, size=(2000, 2))
    fig = figures.component_histograms(v)
    for ax in fig.axes:
        assert len(ax.lines) == 0
        assert "rejected: no normal curve drawn" in ax.texts[0].get_text()


def test_correlation_histogram_counts_runs(tmp_path):
    values = np.random.default_rng(3).normal(0.0, 0.05, size=240)
    fig = figures.correlation_histogram(values, title="line of centres", path=tmp_path / "corr.png")
    read_png(tmp_path / "corr.png", fig)
    ax = fig.axes[0]
    heights = np.array([b.get_height() for b in ax.patches])
    assert len(heights) == 100 and heights.sum() == 240       # bin width 0.02 on [-1, 1]
    (mean_line,) = ax.lines
    assert mean_line.get_xdata()[0] == pytest.approx(values.mean())
    lo, hi = ax.get_xlim()                                    # scaled to the data, not [-1, 1]
    assert lo == pytest.approx(values.min() - 0.06) and hi == pytest.approx(values.max() + 0.06)
    se = values.std(ddof=1) / np.sqrt(240)
    assert f"{values.mean():.4f} \u00b1 {se:.4f} (s.e.) over 240 runs" in ax.get_legend().texts[0].get_text()
    (band,) = ax.collections                                  # mean +- standard error
    xs = band.get_paths()[0].vertices[:, 0]
    assert xs.min() == pytest.approx(values.mean() - se) and xs.max() == pytest.approx(values.mean() + se)
    assert all(float(tick).is_integer() for tick in ax.get_yticks())   # counts of runs


@pytest.mark.slow
def test_plots_never_import_pyplot():
    code = ("import sys, numpy as np; from pinnedballs.plot import states; "
            "states.quiver(np.zeros((2, 2)) + [[0, 0], [2, 0]], np.ones((2, 2))); "
            "print('matplotlib.pyplot' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "MPLBACKEND": "TkAgg"})   # a GUI backend, were pyplot used
    assert out.stdout.strip() == "False"


# ---------------------------------------------------------------- one run

def results(geometry, velocities, snapshots, masses=None):
    """A stand-in for what `pinnedballs.load` returns."""
    return types.SimpleNamespace(positions=geometry.positions, velocities=velocities, geometry=geometry,
                                 masses=masses, snapshots=snapshots)


def snapshot(step, collisions, velocities):
    return types.SimpleNamespace(steps=step, collisions=collisions, velocities=velocities)


def test_write_figures_for_a_half_plane_run(tmp_path):
    half = pb.HalfPlane(rows=4, cols=6)
    v0, v1 = one_ball_state(half), normal_state(half.n_balls, seed=4)
    res = results(half, v1, [snapshot(0, 0, v0), snapshot(250, 40, v1)], masses=np.ones(half.n_balls))
    paths = plot_run.write_figures(res, tmp_path / "figs")
    names = [p.name for p in paths]
    assert names == ["state_initial.png", "state_step_250.png", "state_final.png",  # one snapshot: its picture
                     "energy_by_distance.png", "velocity_histograms.png"]
    res.snapshots.append(snapshot(500, 90, v0))
    names = [p.name for p in plot_run.write_figures(res, tmp_path / "two")]
    assert names == ["state_initial.png", "state_snapshots.png", "state_final.png",  # more: a contact sheet
                     "energy_by_distance.png", "velocity_histograms.png"]
    every = [p.name for p in plot_run.write_figures(res, tmp_path / "every", every_snapshot=True)]
    assert every == ["state_initial.png", "state_snapshots.png", "state_step_250.png", "state_step_500.png",
                     "state_final.png", "energy_by_distance.png", "velocity_histograms.png"]
    for p in paths:
        assert p.parent == tmp_path / "figs"
        assert matplotlib.image.imread(p).shape[2] in (3, 4)


def test_write_figures_for_a_torus_run_has_no_energy_bars(tmp_path):
    torus = pb.FlatTorus(rows=4, cols=4)
    v = normal_state(16)
    paths = plot_run.write_figures(results(torus, v, (snapshot(10, 3, v),)), tmp_path)
    assert [p.name for p in paths] == ["state_step_10.png", "state_final.png", "velocity_histograms.png"]


def test_write_figures_for_a_one_dimensional_chain_draws_each_velocity_at_its_ball(tmp_path):
    """Changed by issue 11: every dimension gets figures; a 1-D chain gets stems at its positions."""
    geom = pb.GraphGeometry.from_positions(np.array([0.0, 2.0, 4.0]))
    v0, v1 = np.array([[3.0], [0.0], [-1.0]]), np.array([[-1.0], [0.0], [3.0]])
    paths = plot_run.write_figures(results(geom, v1, [snapshot(0, 0, v0)]), tmp_path)
    assert [p.name for p in paths] == ["state_initial.png", "state_final.png", "velocity_histograms.png"]
    fig = states.chain(geom.positions, v0)
    ax = fig.axes[0]
    stems = ax.collections[-2].get_segments()               # one vertical segment per moving ball
    assert [(s[0][0], s[0][1], s[1][1]) for s in stems] == [(0.0, 0.0, 3.0), (4.0, 0.0, -1.0)]
    assert ax.get_ylim() == pytest.approx((-3.3, 3.3))


def test_a_user_graph_in_four_dimensions_gets_its_components_by_ball(tmp_path):
    geom = pb.GraphGeometry.from_positions(np.sqrt(2.0) * np.eye(4)[[0, 1]], radius=1.0)   # two balls touching in 4-D
    v = np.arange(8.0).reshape(2, 4) - 3.0
    paths = plot_run.write_figures(results(geom, v, []), tmp_path)
    assert [p.name for p in paths] == ["state_final.png"]   # no histograms of 4 components
    fig = states.components_by_ball(np.arange(2.0), v)
    assert len(fig.axes) == 3                                # the first three components, and it says so
    assert fig.axes[-1].get_xlabel() == "ball (components 0-2 of 4 drawn)"


def test_snapshots_the_spec_placed_by_collisions_are_named_after_the_collisions(tmp_path):
    half = pb.HalfPlane(rows=4, cols=6)
    v = normal_state(half.n_balls, seed=4)
    res = results(half, v, [snapshot(89335, 22579, v)])
    res.spec = types.SimpleNamespace(snapshots=types.SimpleNamespace(counter="collisions"))
    names = [p.name for p in plot_run.write_figures(res, tmp_path)]
    assert names[0] == "state_collisions_22579.png"
    assert plot_run.snapshot_name(snapshot(89335, 22579, v), "collisions")[1] == \
        "after 22,579 collisions (89,335 steps)"
    assert plot_run.snapshot_name(snapshot(89335, 22579, v), "steps")[0] == "state_step_89335.png"
    assert set(plot_run.figure_files(tmp_path)) == set(tmp_path / n for n in names)


def test_sphere_and_disk_views_carry_an_arrow_scale_key():
    sphere, h = pb.Sphere.geodesic(2), pb.HyperbolicPlane(q=7, layers=2)
    for geom, draw in ((sphere, states.sphere_views), (h, states.poincare_disk)):
        v = normal_state(geom.n_balls, seed=1)
        fig = draw(geom.positions, np.einsum("nd,ndk->nk", v, geom.frames()))
        keys = [a for ax in fig.axes for a in ax.artists if type(a).__name__ == "QuiverKey"]
        assert len(keys) == len(fig.axes) and all(k.text.get_text().startswith("speed ") for k in keys)
    # the disk's key is half as long as the speed it names: the disk halves lengths at its centre
    key = keys[0]
    assert key.U == pytest.approx(0.5 * float(key.text.get_text().split()[1]))


def test_a_shared_arrow_scale_is_the_same_for_every_frame():
    half = pb.HalfPlane(rows=4, cols=6)
    frames = [one_ball_state(half), normal_state(half.n_balls, seed=1), 0.1 * normal_state(half.n_balls, seed=2)]
    scales = {states.quiver(half.positions, v, shared=frames).axes[0].collections[1].scale for v in frames}
    sizes = {tuple(states.quiver(half.positions, v, shared=frames).get_size_inches()) for v in frames}
    assert len(scales) == 1 and len(sizes) == 1
    alone = {states.quiver(half.positions, v).axes[0].collections[1].scale for v in frames}
    assert len(alone) == 3


def test_write_figures_for_a_sphere_shows_both_hemispheres(tmp_path):
    sphere = pb.Sphere.geodesic(3)
    v = normal_state(sphere.n_balls, seed=2)
    paths = plot_run.write_figures(results(sphere, v, [snapshot(0, 0, v)]), tmp_path)
    assert [p.name for p in paths] == ["state_initial.png", "state_final.png", "velocity_histograms.png"]
    fig = states.sphere_views(sphere.positions, np.einsum("nd,ndk->nk", v, sphere.frames()))
    north, south = fig.axes
    # every ball is drawn once, on the hemisphere facing the viewer (the equator on both), one arrow per ball
    on_equator = int((sphere.positions[:, 2] == 0).sum())
    drawn = [len(ax.collections[0].get_offsets()) for ax in (north, south)]
    assert sum(drawn) == sphere.n_balls + on_equator
    assert [len(ax.collections[1].get_offsets()) for ax in (north, south)] == drawn


def test_write_figures_for_the_hyperbolic_plane_uses_the_poincare_disk_and_the_boundary(tmp_path):
    h = pb.HyperbolicPlane(q=7, layers=3)
    v = normal_state(h.n_balls, seed=3)
    paths = plot_run.write_figures(results(h, v, []), tmp_path)
    assert [p.name for p in paths] == ["state_final.png", "energy_by_distance.png", "velocity_histograms.png"]
    # the same surface as a plain GraphGeometry (no boundary) is still drawn in the disk, from its positions
    twin = pb.GraphGeometry(h.contact_graph())
    drawn = plot_run.write_figures(results(twin, v, []), tmp_path / "twin")
    assert [p.name for p in drawn] == ["state_final.png", "velocity_histograms.png"]
    assert np.array_equal(matplotlib.image.imread(drawn[0]), matplotlib.image.imread(paths[0]))
    fig = states.poincare_disk(h.positions, np.einsum("nd,ndk->nk", v, h.frames()))
    offsets = fig.axes[0].collections[0].get_offsets()
    np.testing.assert_allclose(offsets, h.poincare(), atol=1e-12)
    assert np.hypot(*np.asarray(offsets).T).max() < 1


def test_write_figures_for_a_3d_half_space(tmp_path):
    g = pb.FCC(3, 3, 2, periodic=(True, True, False))
    v = normal_state(g.n_balls, seed=6)
    v = np.column_stack([v, v[::-1, 0]])
    paths = plot_run.write_figures(results(g, v, []), tmp_path)
    assert [p.name for p in paths] == ["state_final.png", "energy_by_distance.png", "energy_by_height.png",
                                       "velocity_histograms.png"]
    slice_fig = states.quiver(g.positions[g.positions[:, 2] == 0, :2], v[g.positions[:, 2] == 0, :2])
    assert len(slice_fig.axes[0].collections[0].get_offsets()) == 2 * 3 * 3  # the bottom layer
    heights = figures.energy_by_distance(g.positions[:, 2], v)
    _, fraction = obs.energy_profile(g.positions[:, 2], v)
    np.testing.assert_allclose([b.get_height() for b in heights.axes[0].patches], fraction, rtol=1e-15)


def test_write_figures_draws_the_initial_state_from_the_results_without_a_step_0_snapshot(tmp_path, monkeypatch):
    half = pb.HalfPlane(rows=4, cols=6)
    v0, v1 = one_ball_state(half), normal_state(half.n_balls, seed=5)
    res = results(half, v1, [snapshot(250, 40, v1)])
    res.initial_velocities = v0
    drawn = []
    quiver = states.quiver
    monkeypatch.setitem(states.DRAWINGS, "plane", lambda p, v, **kw: drawn.append(v) or quiver(p, v, **kw))
    names = [p.name for p in plot_run.write_figures(res, tmp_path)]
    assert names[:3] == ["state_initial.png", "state_step_250.png", "state_final.png"]
    assert drawn[0] is v0 and drawn[1] is v1 and drawn[2] is v1


def test_the_disk_holds_every_arrow_tip_and_its_key_lies_under_the_disk():
    """A lone arrow at the centre stays inside the disk, the axes reach every tip (none clipped),
    and the key lies in a strip under the disk, not across it."""
    h = pb.HyperbolicPlane(q=7, layers=3)
    v = np.zeros((h.n_balls, 2))
    v[0] = [5.0, 0.0]
    fig = states.poincare_disk(h.positions, np.einsum("nd,ndk->nk", v, h.frames()))
    ax = fig.axes[0]
    (arrows,) = [c for c in ax.collections if isinstance(c, Quiver)]
    tip = arrows.get_offsets()[0] + np.array([arrows.U[0], arrows.V[0]]) / arrows.scale
    assert 0.5 < np.hypot(*tip) < 1.0                                     # inside the disk, and long enough to see
    v[h.boundary_center()] = [-5.0, 0.0]                                  # and one at the rim, pointing out
    fig = states.poincare_disk(h.positions, np.einsum("nd,ndk->nk", v, h.frames()))
    ax = fig.axes[0]
    (arrows,) = [c for c in ax.collections if isinstance(c, Quiver)]
    tips = arrows.get_offsets() + np.column_stack([arrows.U, arrows.V]) / arrows.scale
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert (tips[:, 0] > x0).all() and (tips[:, 0] < x1).all() and (tips[:, 1] > y0).all() and (tips[:, 1] < y1).all()
    (key,) = [a for a in ax.artists if type(a).__name__ == "QuiverKey"]
    assert y0 + key.Y * (y1 - y0) < -1.0


def test_the_share_of_the_first_row_never_covers_a_bar():
    """The tallest bar at the far side, under where the text sits: the text stays above every bar."""
    half = pb.HalfPlane(rows=6, cols=5)
    v = np.zeros((half.n_balls, 2))
    far = half.boundary_distance() == half.boundary_distance().max()
    v[far] = [3.0, 0.0]
    v[half.boundary_center()] = [0.0, 1.0]
    fig = figures.energy_by_distance(half.boundary_distance(), v, xlabel="distance from the boundary (ball radii)")
    fig.canvas.draw()
    ax = fig.axes[0]
    (text,) = ax.texts
    box = text.get_window_extent()
    assert not any(box.overlaps(bar.get_window_extent()) for bar in ax.patches)
    assert text.get_text().startswith("boundary row: ") and ax.get_xlabel().endswith("(ball radii)")


def test_velocity_histograms_of_a_run_are_not_stretched_by_one_outlier(tmp_path):
    torus = pb.FlatTorus(rows=20, cols=20)
    v = normal_state(torus.n_balls, seed=8)
    v[17] = [40.0, -40.0]                                     # one ball far out
    paths = plot_run.write_figures(results(torus, v, []), tmp_path)
    assert [p.name for p in paths][-1] == "velocity_histograms.png"
    fig = figures.component_histograms(v, quantile=plot_run.ROBUST_RANGE)
    scale = np.quantile(np.abs(v), 0.99)
    for ax in fig.axes:
        assert ax.get_xlim() == pytest.approx((-scale, scale))
    heights = [sum(b.get_height() for b in ax.patches) for ax in fig.axes]
    beyond = [(np.abs(v[:, k]) > scale).sum() for k in range(2)]
    assert [400 - h for h in heights] == beyond and min(beyond) >= 1
    assert all(f"{b} of 400 beyond the range drawn" in ax.texts[0].get_text() for b, ax in zip(beyond, fig.axes))
    paper = figures.component_histograms(v)                  # the paper's range: the largest component
    assert paper.axes[0].get_xlim() == pytest.approx((-40.0, 40.0))


def test_a_long_title_is_wrapped_inside_the_figure(tmp_path):
    """The reproduction's long titles were cut off at both edges: drawn, every line of the title
    lies inside the figure."""
    from pinnedballs.plot.figures import energy_by_distance

    title = ("paper orientation (1,425 balls, rows perpendicular to the boundary): frozen after 46,451 collisions "
             "(266,938 steps)")
    fig = energy_by_distance(np.arange(6.0), np.ones((6, 2)), title=title, path=tmp_path / "e.png")
    (ax,) = fig.axes
    text = ax.title
    assert "\n" in text.get_text() and text.get_text().replace("\n", " ") == title
    box = text.get_window_extent(renderer=fig.canvas.get_renderer())
    assert 0 <= box.x0 and box.x1 <= fig.bbox.width


def test_the_energy_profile_names_its_unit_only_from_the_radius():
    """Its axis said "ball radii" for balls of radius 0.5 (issue 49): the unit comes from ``radius``,
    and without one none is claimed."""
    half = pb.HalfPlane(4, 6, radius=0.5)
    v = np.random.default_rng(0).standard_normal((half.n_balls, 2))
    label = {r: figures.energy_by_distance(half.boundary.distance, v, radius=r).axes[0].get_xlabel()
             for r in (None, 0.5, 1.0)}
    assert label == {None: "distance from the boundary", 0.5: "distance from the boundary (ball radius 0.5)",
                     1.0: "distance from the boundary (ball radii)"}
