"""Movies of a run's snapshots: one frame per state, one size and one arrow scale, no partial file."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import read_only_dir
from matplotlib.quiver import Quiver
from PIL import Image

import pinnedballs as pb
from pinnedballs.plot import animation
from pinnedballs.plot import run as plot_run
from pinnedballs.run.cli import main as cli


def record(tmp_path, geometry, every=300, steps=1_500, name="run"):
    """A Python run of ``steps`` steps recorded into ``tmp_path/name`` with a snapshot ``every`` steps."""
    v = np.zeros((geometry.n_balls, geometry.dim))
    v[0, 0] = 10.0
    sim = pb.Simulation(geometry, v, seed=3)
    sim.run(steps=steps, writers=[pb.ResultsWriter(tmp_path / name, snapshots={"every_steps": every})])
    return pb.load(tmp_path / name)


@pytest.fixture
def drawn(monkeypatch):
    """The figures `animate` turns into frames, in order."""
    figures = []
    rgb = animation.render
    monkeypatch.setattr(animation, "render", lambda fig: figures.append(fig) or rgb(fig))
    return figures


def gif_frames(path) -> list[np.ndarray]:
    im = Image.open(path)
    frames = []
    for k in range(im.n_frames):
        im.seek(k)
        frames.append(np.asarray(im.convert("RGB")))
    return frames


def test_a_gif_has_one_frame_per_state_of_one_size_on_one_arrow_scale(tmp_path, drawn):
    res = record(tmp_path, pb.HalfPlane(rows=5, cols=8))
    path = res.animate()
    assert path == tmp_path / "run" / "movie.gif"
    frames = gif_frames(path)
    # the initial state, the snapshots at 300, 600, ..., 1500 (the last one is the final state)
    assert len(frames) == len(drawn) == 6
    width, height = drawn[0].canvas.get_width_height()
    assert {f.shape for f in frames} == {(height, width, 3)}
    scales = [[c.scale for c in fig.axes[0].collections if isinstance(c, Quiver)] for fig in drawn]
    assert all(len(s) == 1 for s in scales) and len({s[0] for s in scales}) == 1
    titles = [fig.axes[0].get_title() for fig in drawn]
    assert titles[0] == "step 0, 0 collisions"
    assert titles[1] == f"step 300, {res.snapshots[0].collisions:,} collisions"
    assert titles[-1] == f"step 1,500, {res.collisions:,} collisions (final)"
    assert not np.array_equal(frames[0], frames[-1])


def test_a_movie_of_a_sphere_shows_both_hemispheres_in_every_frame(tmp_path, drawn):
    res = record(tmp_path, pb.Sphere.geodesic(2), every=500, steps=1_000)
    frames = gif_frames(pb.load(tmp_path / "run").animate(tmp_path / "sphere.gif", fps=2))
    assert len(frames) == 3
    assert all(len(fig.axes) == 2 for fig in drawn)
    scales = {c.scale for fig in drawn for ax in fig.axes for c in ax.collections if isinstance(c, Quiver)}
    assert len(scales) == 1
    assert res.snapshots[-1].steps == res.steps == 1_000


def test_a_movie_of_a_chain_keeps_one_vertical_scale(tmp_path, drawn):
    res = record(tmp_path, pb.GraphGeometry.from_positions(np.arange(6.0) * 2), every=2, steps=6)
    res.animate(tmp_path / "chain.gif")
    assert len({fig.axes[0].get_ylim() for fig in drawn}) == 1
    assert drawn[0].axes[0].get_ylim() == pytest.approx((-11.0, 11.0))


def test_an_mp4_has_one_frame_per_state(tmp_path):
    import imageio_ffmpeg

    res = record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=500)
    path = res.animate(tmp_path / "movie.mp4", fps=5)
    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    assert len(list(reader)) == 4
    assert meta["fps"] == 5


def test_mp4_without_ffmpeg_is_refused_with_what_to_install(tmp_path, monkeypatch, capsys):
    record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=500)
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)    # as if not installed
    with pytest.raises(ValueError, match=r'^out: writing MP4 needs ffmpeg: python3 -m pip install "\.\[movies\]"'):
        pb.load(tmp_path / "run").animate(tmp_path / "movie.mp4")
    assert cli.main(["animate", str(tmp_path / "run"), "--out", str(tmp_path / "movie.mp4")]) == 2
    err = capsys.readouterr().err
    assert err == ("pinnedballs: error: animate: --out: writing MP4 needs ffmpeg: python3 -m pip install \".[movies]\" "
                   "in the pinnedballs checkout (imageio-ffmpeg), or write a .gif\n")
    assert not (tmp_path / "movie.mp4").exists()


FPS = "animate: --fps: must be a number of frames per second in [0.01, 100], got"


@pytest.mark.parametrize("argv, message", [
    (["--out", "movie.avi"], "animate: --out: must end in .gif or .mp4, got 'movie.avi'"),
    (["--fps", "0"], f"{FPS} 0.0"),
    (["--fps", "0.001"], f"{FPS} 0.001"),  # a GIF frame lasts at most 655.35 s
    (["--fps", "-4"], f"{FPS} -4.0"),
    (["--fps", "nan"], f"{FPS} nan"),
    (["--fps", "1e300"], f"{FPS} 1e+300"),
    (["--fps", "inf"], f"{FPS} inf"),
])
def test_bad_animate_arguments_exit_2_with_one_line(tmp_path, capsys, argv, message):
    record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=500)
    before = sorted(p.name for p in (tmp_path / "run").iterdir())
    assert cli.main(["animate", str(tmp_path / "run"), *argv]) == 2
    assert capsys.readouterr().err == f"pinnedballs: error: {message}\n"
    assert sorted(p.name for p in (tmp_path / "run").iterdir()) == before


def test_an_out_that_cannot_be_written_exits_2_with_one_line_naming_out(tmp_path, capsys):
    """Issue 26, item 6: refused before a frame is drawn, and nothing written."""
    record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=500)
    run = tmp_path / "run"
    (tmp_path / "file").write_text("not a directory")
    (tmp_path / "x.gif").mkdir()
    cases = {tmp_path / "file" / "movie.gif": f"{tmp_path / 'file'} exists and is not a directory",
             tmp_path / "file" / "a" / "movie.gif": f"{tmp_path / 'file'} is not a directory",
             Path("/dev/null/movie.gif"): "/dev/null exists and is not a directory"}
    for out, why in cases.items():
        assert cli.main(["animate", str(run), "--out", str(out)]) == 2
        assert capsys.readouterr().err == f"pinnedballs: error: animate: --out: {out}: cannot be written, {why}\n"
    assert cli.main(["animate", str(run), "--out", str(tmp_path / "x.gif")]) == 2
    assert capsys.readouterr().err == (f"pinnedballs: error: animate: --out: {tmp_path / 'x.gif'} is a directory; give "
                                       f"the movie's file name (e.g. {tmp_path / 'x.gif' / 'movie.gif'})\n")
    assert list((tmp_path / "x.gif").iterdir()) == [] and (tmp_path / "file").read_text() == "not a directory"
    with read_only_dir(tmp_path / "ro") as ro:
        for out in (ro / "movie.gif", ro / "sub" / "movie.gif"):
            assert cli.main(["animate", str(run), "--out", str(out)]) == 2
            err = capsys.readouterr().err
            assert err.startswith(f"pinnedballs: error: animate: --out: {out}: cannot be written, "
                                  f"{ro} is not writable (")
            assert err.count("\n") == 1
        assert list(ro.iterdir()) == []


def test_a_read_only_run_directory_names_out(tmp_path, capsys):
    """The movie goes into the run directory by default: a read-only one is refused naming --out."""
    def fill(where):
        record(where, pb.FlatTorus(rows=4, cols=6), every=500)

    with read_only_dir(tmp_path / "ro", fill) as ro:
        before = sorted(p.name for p in (ro / "run").iterdir())
        assert cli.main(["animate", str(ro / "run")]) == 2
        err = capsys.readouterr().err
        assert err.startswith(f"pinnedballs: error: animate: --out: {ro / 'run' / 'movie.gif'}: cannot be written, "
                              f"{ro / 'run'} is not writable (") and err.count("\n") == 1
        assert sorted(p.name for p in (ro / "run").iterdir()) == before


def test_a_failed_movie_leaves_no_file_and_an_old_movie_intact(tmp_path, monkeypatch):
    res = record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=500)
    old = res.animate()
    before = old.read_bytes()

    def broken(images, path, fps):
        path.write_bytes(b"GIF89a half a movie")
        raise OSError("disk full")

    monkeypatch.setattr(animation, "_write_gif", broken)
    with pytest.raises(OSError, match="disk full"):
        res.animate()
    assert old.read_bytes() == before
    assert sorted(p.name for p in old.parent.iterdir() if "movie" in p.name) == ["movie.gif"]


def test_the_cli_prints_the_movie_it_wrote(tmp_path, capsys):
    record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=500)
    assert cli.main(["animate", str(tmp_path / "run"), "--fps", "10"]) == 0
    out = capsys.readouterr().out
    assert out == f"{tmp_path / 'run' / 'movie.gif'}\n"
    assert Image.open(tmp_path / "run" / "movie.gif").info["duration"] == 100
    assert plot_run.figure_files(tmp_path / "run") == []   # a movie is not one of the run's figures


# ---------------------------------------------------------------- bounded: 10,000 snapshots (issue 26, item 5)


def test_a_long_run_makes_a_movie_of_at_most_max_frames_evenly_spaced_and_says_so(tmp_path, drawn, capsys):
    """41 states (the initial one and 40 snapshots) into 9 frames: every 5th state, the first and the last
    among them, in Python (a UserWarning) and from the command line (one line on stderr)."""
    res = record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=25, steps=1_000)
    with pytest.warns(UserWarning, match=r"^animate: 9 of the run's 41 states drawn, evenly spaced \(the first and "
                                         r"the last among them\); max_frames=9 allows 9$"):
        frames = gif_frames(res.animate(tmp_path / "short.gif", max_frames=9))
    assert len(frames) == len(drawn) == 9
    titles = [fig.axes[0].get_title() for fig in drawn]
    assert titles[0] == "step 0, 0 collisions"
    assert titles[-1].startswith("step 1,000,") and titles[-1].endswith("(final)")
    assert [int(t.split()[1].rstrip(",").replace(",", "")) for t in titles] == list(range(0, 1_001, 125))
    assert cli.main(["animate", str(tmp_path / "run"), "--max-frames", "9"]) == 0
    assert capsys.readouterr().err == ("pinnedballs: animate: 9 of the run's 41 states drawn, evenly spaced (the first "
                                       "and the last among them); --max-frames 9 allows 9\n")
    assert cli.main(["animate", str(tmp_path / "run"), "--max-frames", "1"]) == 2
    assert capsys.readouterr().err == "pinnedballs: error: animate: --max-frames: must be an integer >= 2, got 1\n"


def test_evenly_keeps_the_first_and_the_last():
    assert animation.evenly(10_001, 300)[:3] == [0, 33, 67] and animation.evenly(10_001, 300)[-1] == 10_000
    assert len(animation.evenly(10_001, 300)) == 300
    assert animation.evenly(5, 300) == [0, 1, 2, 3, 4]
    assert animation.evenly(7, 2) == [0, 6]


def test_frames_are_drawn_and_written_one_at_a_time(tmp_path, monkeypatch):
    """The writer is handed a generator: each frame is drawn when the writer asks for it, so a movie
    holds one picture at a time, not all of them (4 GB for 10,000 snapshots before)."""
    res = record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=100)
    events, rgb, write = [], animation.render, animation._write_gif
    monkeypatch.setattr(animation, "render", lambda fig: events.append("drawn") or rgb(fig))

    def writing(images, path, fps):
        def told():
            for im in images:
                events.append("written")
                yield im
        write(told(), path, fps)

    monkeypatch.setattr(animation, "_write_gif", writing)
    res.animate(tmp_path / "m.gif")
    assert events == ["drawn", "written"] * 16


def test_a_large_system_gets_fewer_frames_within_the_movie_memory(monkeypatch, tmp_path):
    res = record(tmp_path, pb.FlatTorus(rows=4, cols=6), every=100)
    assert animation.frames_allowed(res, 300) == 300
    monkeypatch.setattr(animation, "MOVIE_BYTES", 24 * 2 * 8 * 10)  # ten frames' velocities of 24 balls
    assert animation.frames_allowed(res, 300) == 10
