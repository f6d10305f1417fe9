"""Movies of a run's snapshots: one frame per state, in the geometry's own view, on one arrow scale.

`animate` draws the initial state, every snapshot and the final state with the state picture
of `states.state_picture` (the plane, both hemispheres of a sphere, the Poincare
disk, a slice of a 3-D packing, a 1-D chain), all frames sharing one arrow scale and one
figure size, and writes a GIF (Pillow) or an MP4 (ffmpeg from imageio-ffmpeg, the optional
extra ``movies``). Frames are drawn and written one at a time, at most `MAX_FRAMES` of them (evenly
spaced among the states of a longer run), so a run of 10,000 snapshots makes a movie in bounded time
and memory. The movie is written to a temporary file and renamed: a failure leaves no partial movie.
"""

from __future__ import annotations

import itertools
import os
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from ..util import checks
from ..util.atomic import unwritable
from ..util.errors import FieldError, FieldTypeError
from .base import render
from .states import state_picture

__all__ = ["animate", "movie_frames", "evenly", "frames_allowed", "Movie", "MOVIE_NAME", "FORMATS", "MAX_FRAMES",
           "MOVIE_BYTES", "INLINE_BYTES"]

#: the movie's name in the run directory when no ``out`` is given
MOVIE_NAME = "movie.gif"
#: the movie formats, by file suffix
FORMATS = (".gif", ".mp4")
#: at most this many frames by default (75 s at 4 frames per second): more are chosen evenly among the states
MAX_FRAMES = 300
#: the frames' velocities held at once (one arrow scale for all) stay under this many bytes
MOVIE_BYTES = 512 << 20
MP4_MISSING = ("writing MP4 needs ffmpeg: python3 -m pip install \".[movies]\" in the pinnedballs checkout "
               "(imageio-ffmpeg), or write a .gif")


#: a notebook shows a movie inline up to this size (a larger one is named, not embedded)
INLINE_BYTES = 32 << 20


class Movie(type(Path())):
    """The path of a movie that `animate` wrote; a notebook displaying it shows the movie itself (a GIF
    as an image, an MP4 in a video player), embedded in the page (up to `INLINE_BYTES`)."""

    def _repr_html_(self) -> str:
        import base64
        import html

        size = self.stat().st_size
        if size > INLINE_BYTES:
            return f"<p>{html.escape(str(self))}: {size / 2**20:.0f} MB, too large to show here; open the file</p>"
        data = base64.b64encode(self.read_bytes()).decode("ascii")
        if self.suffix.lower() == ".mp4":
            return f"<video controls loop src=\"data:video/mp4;base64,{data}\" style=\"max-width:100%\"></video>"
        return f"<img src=\"data:image/gif;base64,{data}\" alt=\"{html.escape(self.name)}\" style=\"max-width:100%\">"


def movie_frames(res, max_frames: int | None = None) -> list[tuple[str, np.ndarray]]:
    """``[(title, velocities (n, dim)), ...]``: the initial state, each snapshot and the final state of
    ``res`` (what `pinnedballs.load` returns), each state once, titled with its steps and collisions;
    at most ``max_frames`` of them (None: all), evenly spaced, the first and the last among them.
    Only the states chosen are read."""
    states = _states(res)
    last = len(states) - 1
    return [(f"step {s:,}, {c:,} collisions" + (" (final)" if k == last else ""),
             np.asarray(getattr(v, "velocities", v), dtype=np.float64))
            for k, (s, c, v) in ((k, states[k]) for k in evenly(len(states), max_frames))]


def _states(res) -> list[tuple[int, int, object]]:
    """``[(steps, collisions, state), ...]`` of the movie, a state being an array or a snapshot (not read yet)."""
    snapshots = list(res.snapshots or ())
    states: list[tuple[int, int, object]] = []
    initial = getattr(res, "initial_velocities", None)
    if initial is not None and not any(int(s.steps) == 0 for s in snapshots):
        states.append((0, 0, initial))
    states += [(int(s.steps), int(s.collisions), s) for s in snapshots]
    if not states or states[-1][0] != int(res.steps):
        states.append((int(res.steps), int(res.collisions), res.velocities))
    return states


def evenly(count: int, most: int | None) -> list[int]:
    """At most ``most`` of the indices ``0 .. count - 1`` (None: all), evenly spaced, the first and the last among
    them."""
    if most is None or count <= most:
        return list(range(count))
    if most == 1:
        return [count - 1]
    return sorted({round(k * (count - 1) / (most - 1)) for k in range(most)})


def frames_allowed(res, max_frames: int) -> int:
    """``max_frames``, or fewer when the frames' velocities would take more than `MOVIE_BYTES` (all of
    them are held at once: they share one arrow scale)."""
    row = 8 * max(1, int(np.prod(np.shape(res.velocities))))
    return max(2, min(max_frames, MOVIE_BYTES // row))


#: frames per second a movie may have: a GIF holds each frame's duration in hundredths of a second,
#: from 1 to 65535 (a frame at most 655 s, at least 10 ms), and MP4 players keep to the same
FPS_RANGE = (0.01, 100.0)


def _check(out, fps) -> tuple[Path, float]:
    """``out`` and ``fps`` checked before anything is drawn or written: a `FieldError` naming either."""
    if not isinstance(out, (str, os.PathLike)):
        raise FieldTypeError("out", f"must be a path ending in .gif or .mp4, got {type(out).__name__}")
    out = Path(out)
    if out.suffix.lower() not in FORMATS:
        raise FieldError("out", f"must end in .gif or .mp4, got {out.name!r}")
    low, high = FPS_RANGE
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not low <= fps <= high:
        raise FieldError("fps", f"must be a number of frames per second in [{low:g}, {high:g}], got {fps!r}")
    if out.is_dir():
        raise FieldError("out", f"{out} is a directory; give the movie's file name (e.g. {out / MOVIE_NAME})")
    problem = unwritable(out.parent)
    if problem is not None:
        where = out.parent if problem.startswith(("is ", "exists ")) else ""
        raise FieldError("out", f"{out}: cannot be written, {where}{' ' if where else ''}{problem}")
    if out.suffix.lower() == ".mp4":
        try:
            import imageio_ffmpeg

            imageio_ffmpeg.get_ffmpeg_exe()  # a RuntimeError if it has no ffmpeg for this machine
        except (ImportError, RuntimeError):
            raise FieldError("out", MP4_MISSING) from None
    return out, float(fps)


def animate(res, out=None, fps: float = 4, max_frames: int | None = None) -> Path:
    """Write a movie of the run ``res`` (its `Results`, from `pinnedballs.load`) to ``out`` (default
    ``<run dir>/movie.gif``; ``.gif`` or ``.mp4``) at ``fps`` frames per second; returns its path (a `Movie`: a notebook
    shows it). Frames: see `movie_frames`; the state picture: `states.state_picture`, with one arrow scale
    (`base.MOVIE_LONGEST`) and one size for all frames.

    A movie has at most ``max_frames`` frames (None: `MAX_FRAMES`; fewer for a large system, whose
    frames' velocities would take more than `MOVIE_BYTES`): a run with more states gets that many,
    evenly spaced, the first and the last among them, and a `UserWarning` says so. Frames are drawn
    and written one at a time.
    """
    out, fps = _check(res.run_dir / MOVIE_NAME if out is None else out, fps)
    max_frames = MAX_FRAMES if max_frames is None else checks.integer("max_frames", max_frames, 2)
    allowed = frames_allowed(res, max_frames)
    frames = movie_frames(res, allowed)
    everything = len(_states(res))
    if everything > len(frames):
        warnings.warn(f"animate: {len(frames)} of the run's {everything:,} states drawn, evenly spaced (the first "
                      f"and the last among them); max_frames={max_frames} allows {allowed}", UserWarning, stacklevel=2)
    draw = state_picture(res.geometry)
    shared = [v for _, v in frames]
    images = (render(draw(v, title, shared=shared)) for title, v in frames)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.{os.getpid()}.tmp{out.suffix}"  # beside out: the rename is atomic
    try:
        (_write_mp4 if out.suffix.lower() == ".mp4" else _write_gif)(images, Path(tmp), fps)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Movie(out)


def _write_gif(images: Iterator[np.ndarray], path: Path, fps: float) -> None:
    from PIL import Image

    first = Image.fromarray(next(images))
    first.save(path, format="GIF", save_all=True, append_images=(Image.fromarray(im) for im in images),
               duration=round(1000 / fps), loop=0, optimize=False)


def _write_mp4(images: Iterator[np.ndarray], path: Path, fps: float) -> None:
    import imageio_ffmpeg

    first = next(images)
    h, w = first.shape[:2]
    writer = imageio_ffmpeg.write_frames(str(path), (w + w % 2, h + h % 2), fps=fps, codec="libx264",
                                         pix_fmt_out="yuv420p", macro_block_size=1, ffmpeg_log_level="error",
                                         output_params=["-f", "mp4"])
    writer.send(None)
    for im in itertools.chain([first], images):
        writer.send(np.ascontiguousarray(np.pad(im, ((0, h % 2), (0, w % 2), (0, 0)), constant_values=255)))  # yuv420p
    writer.close()
