"""Movies of a run's snapshots: one frame per state, in the geometry's own view, on one arrow scale.

`animate` draws the initial state, every snapshot and the final state with the state picture
of `states.state_picture` (the plane, both hemispheres of a sphere, the Poincare
disk, a slice of a 3-D packing, a 1-D chain), all frames sharing one arrow scale and one
figure size, and writes a GIF (Pillow) or an MP4 (ffmpeg from imageio-ffmpeg, the optional
extra ``movies``). The movie is written to a temporary file and renamed: a failure leaves no
partial movie.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..engine.errors import FieldError, FieldTypeError
from ..results.rundir import unwritable
from .base import render
from .states import state_picture

__all__ = ["animate", "movie_frames", "Movie", "MOVIE_NAME", "FORMATS", "INLINE_BYTES"]

#: the movie's name in the run directory when no ``out`` is given
MOVIE_NAME = "movie.gif"
#: the movie formats, by file suffix
FORMATS = (".gif", ".mp4")
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


def movie_frames(res) -> list[tuple[str, np.ndarray]]:
    """``[(title, velocities (n, dim)), ...]``: the initial state, each snapshot and the final state of
    ``res`` (what `pinnedballs.load` returns), each state once, titled with its steps and collisions."""
    frames: list[tuple[int, int, np.ndarray]] = []
    snapshots = list(res.snapshots or ())
    initial = getattr(res, "initial_velocities", None)
    if initial is not None and not any(int(s.steps) == 0 for s in snapshots):
        frames.append((0, 0, np.asarray(initial, dtype=np.float64)))
    frames += [(int(s.steps), int(s.collisions), np.asarray(s.velocities, dtype=np.float64)) for s in snapshots]
    if not frames or frames[-1][0] != int(res.steps):
        frames.append((int(res.steps), int(res.collisions), np.asarray(res.velocities, dtype=np.float64)))
    last = len(frames) - 1
    return [(f"step {s:,}, {c:,} collisions" + (" (final)" if k == last else ""), v)
            for k, (s, c, v) in enumerate(frames)]


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


def animate(res, out=None, fps: float = 4) -> Path:
    """Write a movie of the run ``res`` (its `Results`, from `pinnedballs.load`) to ``out`` (default ``<run dir>/movie.gif``; ``.gif`` or ``.mp4``) at ``fps`` frames per second;
    returns its path (a `Movie`: a notebook shows it). Frames: see `movie_frames`; the state picture:
    `states.state_picture`, with one arrow scale (`base.MOVIE_LONGEST`) and one size for all frames.
    """
    out, fps = _check(res.run_dir / MOVIE_NAME if out is None else out, fps)
    frames = movie_frames(res)
    draw = state_picture(res.geometry)
    shared = [v for _, v in frames]
    images = [render(draw(v, title, shared=shared)) for title, v in frames]
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.{os.getpid()}.tmp{out.suffix}"  # beside out: the rename is atomic
    try:
        (_write_mp4 if out.suffix.lower() == ".mp4" else _write_gif)(images, Path(tmp), fps)
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Movie(out)


def _write_gif(images: list[np.ndarray], path: Path, fps: float) -> None:
    from PIL import Image

    pictures = [Image.fromarray(im) for im in images]
    pictures[0].save(path, format="GIF", save_all=True, append_images=pictures[1:], duration=round(1000 / fps),
                     loop=0, optimize=False)


def _write_mp4(images: list[np.ndarray], path: Path, fps: float) -> None:
    import imageio_ffmpeg

    h, w = images[0].shape[:2]
    even = [np.pad(im, ((0, h % 2), (0, w % 2), (0, 0)), constant_values=255) for im in images]  # yuv420p
    writer = imageio_ffmpeg.write_frames(str(path), (w + w % 2, h + h % 2), fps=fps, codec="libx264",
                                         pix_fmt_out="yuv420p", macro_block_size=1, ffmpeg_log_level="error",
                                         output_params=["-f", "mp4"])
    writer.send(None)
    for im in even:
        writer.send(np.ascontiguousarray(im))
    writer.close()
