"""What every figure shares: headless figures, atomic PNGs, and the arrow scale of state pictures.

Headless by construction: figures are `matplotlib.figure.Figure` objects drawn
by the Agg canvas, and pyplot is never imported, so no window can open and no
figure outlives its caller. Each drawing function draws into ``ax`` if given (and returns
its figure) or into a new figure, saves a PNG when ``path`` is given, and
returns the `Figure`.
"""

from __future__ import annotations

import io
import textwrap
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..util.atomic import write_bytes_atomic

__all__ = ["Picture", "new_figure", "panels", "root", "save", "render", "arrow_scale", "key_speed", "length_label",
           "length_unit", "DPI", "MOVIE_LONGEST"]

DPI = 100
BALL_COLOUR = "0.8"
BALL_EDGE = "white"  #: a thin line between touching balls, which are drawn at their true size
ARROW_COLOUR = "tab:red"
FIT_COLOUR = "tab:orange"
COMPONENT_NAMES = "xyz"


class Picture(Figure):
    """A matplotlib `Figure` that a notebook shows as a PNG (``_repr_png_``) with no pyplot and no
    ``%matplotlib inline``: what ``sim.plot()`` and ``res.plot()`` return shows itself."""

    def _repr_png_(self) -> bytes:
        image = io.BytesIO()
        self.savefig(image, dpi=DPI, format="png")
        return image.getvalue()


def new_figure(figsize) -> Figure:
    """A figure (a `Picture`) of ``figsize`` inches drawn by Agg: never a window, whatever the backend."""
    fig = Picture(figsize=figsize, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def length_unit(radius: float | None = None) -> str:
    """The unit of flat lengths: ``"ball radii"`` for balls of radius 1 (or unknown), else the
    positions' own units, naming the radius."""
    return "ball radii" if radius is None or radius == 1.0 else f"ball radius {radius:g}"


def length_label(name: str, radius: float | None = None) -> str:
    """An axis label of a length: ``"x (ball radii)"``, see `length_unit`."""
    return f"{name} ({length_unit(radius)})"


def _new_axes(ax, figsize, title):
    """``(figure, ax)``: the given axes (and the figure or subfigure holding them), or one axes on a
    `new_figure` of ``figsize`` inches."""
    if ax is None:
        ax = new_figure(figsize).add_subplot()
    if title:
        ax.set_title(wrapped(title, root(ax.figure)))
    return ax.figure, ax


def wrapped(title: str, fig: Figure) -> str:
    """``title`` broken into lines that fit ``fig``'s width at the default title size (about 10
    characters per inch), so a long title is never cut off at the figure's edges."""
    width = max(30, int(10 * fig.get_figwidth()))
    return "\n".join(textwrap.fill(line, width) for line in title.split("\n"))


def panels(ax, figsize):
    """Where a drawing of several panels goes: a `new_figure` of ``figsize`` inches, or, given the
    matplotlib Axes ``ax``, a subfigure in its place (``ax`` is removed; it must be a subplot)."""
    if ax is None:
        return new_figure(figsize)
    spec = ax.get_subplotspec()
    if spec is None:
        raise ValueError("ax: a drawing of several panels takes the place of a subplot (e.g. from "
                         "plt.subplots); these axes are not one")
    parent = ax.figure
    ax.remove()
    return parent.add_subfigure(spec)


def root(fig) -> Figure:
    """The top-level `Figure` of a figure or of a subfigure in it."""
    while not isinstance(fig, Figure):
        fig = fig.figure
    return fig


def save(fig, path) -> Figure:
    """Write ``fig`` (a figure, or a subfigure: its whole figure) as a PNG at ``path`` (its folder
    created) unless ``path`` is None: drawn in memory and written through a temporary file and a
    rename, so a failed write (a full disk) leaves no partial PNG. Returns the top-level `Figure`."""
    fig = root(fig)
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        image = io.BytesIO()
        fig.savefig(image, dpi=DPI, format="png")
        write_bytes_atomic(path, image.getvalue())
    return fig


def render(fig: Figure) -> np.ndarray:
    """The figure drawn by Agg, ``(height, width, 3)`` uint8."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def _spacing(p: np.ndarray) -> float:
    """Median distance from a centre ``p (n, 2)`` to its nearest neighbour (1 for a single ball)."""
    if len(p) < 2:
        return 1.0
    from scipy.spatial import cKDTree

    d, _ = cKDTree(p).query(p, k=2)
    d = d[:, 1][d[:, 1] > 0]
    return float(np.median(d)) if len(d) else 1.0


def arrow_scale(speeds: np.ndarray, spacing: float, longest: float = 3.0) -> float:
    """Arrow length per unit speed, for ``speeds (n,)`` and ``spacing`` between centres.

    The 95th percentile of the speeds gets one spacing, but no arrow gets more
    than ``longest`` spacings: a spread-out state shows typical arrows half a spacing long,
    and a state with all energy on one ball shows a single arrow three spacings long.
    """
    top = float(speeds.max()) if len(speeds) else 0.0
    reference = max(float(np.quantile(speeds, 0.95)) if len(speeds) else 0.0, top / longest)
    return spacing / reference if reference > 0 else 1.0


#: in a movie (`shared` velocities of every frame) the longest arrow, in spacings: the pooled
#: 95th percentile still gets one spacing, so the spread-out frames stay readable
MOVIE_LONGEST = 10.0


def _shared_scale(speeds: np.ndarray, shared, spacing: float, norm, longest: float = 3.0,
                  movie_longest: float = MOVIE_LONGEST) -> float:
    """`arrow_scale` of this state's ``speeds`` (no arrow beyond ``longest`` spacings), or of every
    frame's when ``shared`` (a movie) is given (none beyond ``movie_longest``); ``norm(v) -> (n,)``
    turns one frame's velocities into speeds."""
    if shared is None:
        return arrow_scale(speeds, spacing, longest)
    return arrow_scale(np.concatenate([norm(np.asarray(v, dtype=np.float64)) for v in shared]), spacing,
                       longest=movie_longest)


def _key(ax, arrows, k: float, spacing: float, width: float, y: float = -0.07, drawn: float = 1.0,
         where: str = "") -> None:
    """The arrow-scale key at the left of ``ax`` (``y`` in axes units): a round speed about one spacing
    long, its tail at 2 % of the axes' ``width`` (in data units). ``drawn``: the picture's length of a
    unit of length where the key applies (``where``)."""
    key = key_speed(spacing / k)
    ax.quiverkey(arrows, X=0.02 + key * drawn * k / width, Y=y, U=key * drawn, label=f"speed {key:g}{where}",
                 labelpos="E", coordinates="axes", fontproperties={"size": "small"})


def key_speed(speed: float) -> float:
    """The round speed (1, 2 or 5 times a power of ten) nearest ``speed`` (> 0) on a log scale:
    the speed of the arrow-scale key, drawn about one spacing long."""
    power = 10.0 ** np.floor(np.log10(speed))
    candidates = np.array([1.0, 2.0, 5.0, 10.0]) * power
    return float(candidates[np.argmin(np.abs(np.log(candidates / speed)))])


