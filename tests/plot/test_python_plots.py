"""Plots from Python (issue 24, items 2 and 3): ``sim.plot``, ``geom.plot`` and ``res.plot`` return the
figures ``pinnedballs plot`` draws, into given axes or new figures; a large state is a field of
speeds, not arrows; a movie shows itself in a notebook."""

from __future__ import annotations

import base64
import io
import re
import shutil

import numpy as np
import pytest
from helpers import HALF_PLANE, call, spec, write
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.quiver import Quiver
from PIL import Image

import pinnedballs as pb
from pinnedballs.analysis import observables as obs
from pinnedballs.plot import field
from pinnedballs.plot.base import new_figure
from pinnedballs.plot.names import figure_files
from pinnedballs.run.execute import write_figures


def quivers(ax) -> list[Quiver]:
    return [c for c in ax.collections if isinstance(c, Quiver)]


def images(ax) -> list[AxesImage]:
    return [i for i in ax.get_images()]


def one_ball(geom, speed: float = 10.0) -> np.ndarray:
    v = np.zeros((geom.n_balls, geom.dim))
    v[1, 0] = speed
    return v


def test_sim_plot_draws_the_state_as_arrows_into_a_new_figure_or_given_axes():
    torus = pb.FlatTorus(6, 6)
    v = np.random.default_rng(2).standard_normal((36, 2))
    sim = pb.Simulation(torus, v, seed=1)
    sim.run(steps=500)
    fig = sim.plot()
    assert isinstance(fig, Figure) and len(fig.axes) == 1
    (q,) = quivers(fig.axes[0])
    assert np.array_equal(np.column_stack([q.U, q.V]), sim.velocities)       # every ball moves: 36 arrows
    assert fig.axes[0].get_title() == f"after 500 steps, {sim.collisions:,} collisions"
    png = fig._repr_png_()                                                   # a notebook shows it without pyplot
    assert png.startswith(b"\x89PNG") and Image.open(io.BytesIO(png)).size == tuple(
        round(x) for x in fig.get_size_inches() * fig.dpi)
    mine = new_figure((8, 4))
    left, right = mine.subplots(1, 2)
    assert sim.plot(ax=right, title="mine") is mine and right.get_title() == "mine" and quivers(right)
    assert not quivers(left)


def test_a_view_of_several_panels_takes_the_place_of_the_axes_given():
    sphere = pb.Sphere.geodesic(2)
    sim = pb.Simulation(sphere, np.random.default_rng(0).standard_normal((sphere.n_balls, 2)), seed=0)
    fig = new_figure((12, 5))
    left, right = fig.subplots(1, 2)
    assert sim.plot(ax=right) is fig
    assert right not in fig.axes and left in fig.axes
    (sub,) = fig.subfigs
    assert [a.get_title() for a in sub.axes] == ["northern hemisphere (from +z)", "southern hemisphere (from -z)"]
    with pytest.raises(ValueError, match="ax: a drawing of several panels takes the place of a subplot"):
        sim.plot(ax=fig.add_axes((0, 0, 0.1, 0.1)))


def test_a_geometry_plots_its_balls_at_rest():
    fig = pb.HalfPlane(6, 10).plot(title="the rectangle")
    ax = fig.axes[0]
    assert ax.get_title() == "the rectangle" and not quivers(ax)
    assert len(ax.collections[0].get_offsets()) == 60


@pytest.mark.parametrize("rows, cols", [(50, 100), (60, 100)], ids=["5000 balls: arrows", "6000 balls: a field"])
def test_a_state_of_more_than_5000_balls_is_a_field_of_speeds(rows, cols):
    torus = pb.FlatTorus(rows, cols)
    assert field.FIELD_BALLS == 5_000
    ax = pb.Simulation(torus, one_ball(torus), seed=0).plot().axes[0]
    if torus.n_balls <= field.FIELD_BALLS:
        assert len(quivers(ax)) == 1 and not images(ax)
        return
    assert not quivers(ax)
    rest, speed = images(ax)
    moving = speed.get_array()
    values = moving.compressed() if np.ma.isMaskedArray(moving) else moving[np.isfinite(moving)]
    assert len(values) == 1                                         # the one cell with the moving ball
    per_cell = 10.0 / values[0]                                     # its mean: 10 over the balls in its cell
    assert per_cell == pytest.approx(round(per_cell), abs=1e-9) and 1 <= round(per_cell) <= 4
    assert speed.norm.vmax == 10.0 and speed.norm.vmin == 10.0 * 10.0**-field.DECADES
    occupied = rest.get_array()
    cells = np.isfinite(occupied).sum() if not np.ma.isMaskedArray(occupied) else occupied.count()
    assert cells >= torus.n_balls / 4                               # every cell of the torus holds a ball
    assert ax.figure.axes[-1].get_ylabel().startswith("mean speed in a cell (log scale")


@pytest.fixture(scope="module")
def half_plane_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("plots")
    data = spec(HALF_PLANE, snapshots={"at_collisions": [0, 40, 80, 120]})
    assert call("run", write(base / "s.json", data), "--out", base / "r", "--quiet", "--no-figures")[0] == 0
    return pb.load(base / "r")


def test_res_plot_all_gives_the_figures_pinnedballs_plot_writes(half_plane_run, tmp_path):
    res = half_plane_run
    figures = res.plot("all")
    copy = tmp_path / "copy"  # the run directory is shared by the tests: write into a copy
    shutil.copytree(res.run_dir, copy)
    written = write_figures(copy)
    assert sorted(figures) == sorted(p.stem for p in written) == sorted(p.stem for p in figure_files(copy))
    assert sorted(figures) == ["energy_by_distance", "state_final", "state_initial", "state_snapshots",
                               "velocity_histograms"]
    assert all(isinstance(f, Figure) for f in figures.values())


def test_res_plot_draws_each_figure_with_its_data(half_plane_run):
    res = half_plane_run
    energy = res.plot("energy")
    centres, fraction = obs.energy_profile(res.geometry.boundary.distance, res.velocities)
    heights = [p.get_height() for p in energy.axes[0].patches]
    assert np.allclose(heights, fraction) and sum(heights) == pytest.approx(1.0)
    assert len(res.plot("histograms").axes) == 2
    final = res.plot("final").axes[0]
    assert final.get_title() == "final state"
    last = res.plot("snapshot", snapshot=-1).axes[0]
    (q,) = quivers(last)
    moving = np.linalg.norm(res.snapshots[-1].velocities, axis=1) > 0
    assert np.array_equal(np.column_stack([q.U, q.V]), res.snapshots[-1].velocities[moving])
    assert last.get_title().startswith("after 120 collisions")
    fig = new_figure((6, 4))
    ax = fig.subplots()
    assert res.plot("energy", ax=ax) is fig and ax.patches
    with pytest.raises(ValueError) as caught:
        res.plot("height")
    assert str(caught.value) == ("what: 'height' is not a figure of this run; it has: final, initial, snapshots, "
                                 "energy, histograms, snapshot, all")


def test_an_animation_shows_itself_in_a_notebook(half_plane_run, tmp_path):
    movie = half_plane_run.animate(tmp_path / "m.gif", fps=2)
    assert movie == tmp_path / "m.gif" and movie.exists()
    html = movie._repr_html_()
    data = re.search(r'src="data:image/gif;base64,([^"]+)"', html).group(1)
    assert base64.b64decode(data) == movie.read_bytes()


def test_sim_plot_draws_the_figures_of_a_run_of_its_current_state():
    """``sim.plot("energy")`` raised AttributeError: 'str' object has no attribute 'set_title' (issue 49):
    the kinds `Results.plot` has that a live state has, drawn as a run draws them; the others named."""
    half = pb.HalfPlane(5, 8, radius=0.5)
    sim = pb.Simulation(half, np.random.default_rng(0).standard_normal((half.n_balls, 2)), seed=0)
    sim.run(steps=300)
    ax = sim.plot("energy").axes[0]
    _, fraction = obs.energy_profile(half.boundary.distance, sim.velocities)
    assert np.allclose([bar.get_height() for bar in ax.patches], fraction, rtol=0, atol=1e-15)
    assert ax.get_title() == f"energy by distance from the boundary, after 300 steps, {sim.collisions:,} collisions"
    assert ax.get_xlabel() == "distance from the boundary (ball radius 0.5)"
    assert len(sim.plot("histograms").axes) >= 2 and quivers(sim.plot("state").axes[0])
    with pytest.raises(ValueError, match=r"^what: 'height' is not a figure of this simulation; it has: state, "
                                         r"energy, histograms$"):
        sim.plot("height")  # flat 2-D
    with pytest.raises(ValueError, match=r"a simulation keeps no snapshots: record it with a ResultsWriter, then "
                                         r"pb\.load\(DIR\)\.plot\(\)$"):
        sim.plot("snapshots")
    with pytest.raises(TypeError, match=r"^what: must name a figure of this simulation \(state, energy, "
                                        r"histograms\), got 3$"):
        sim.plot(3)
    mine = new_figure((4, 4))
    assert sim.plot(mine.add_subplot()) is mine and quivers(mine.axes[0])  # the axes first, as before
    cube = pb.FCC(2, 2, 2, periodic=(True, True, False))
    sim3 = pb.Simulation(cube, np.random.default_rng(1).standard_normal((cube.n_balls, 3)), seed=0)
    assert sim3.plot("height").axes[0].get_title().startswith("energy by height (z), after 0 steps")
