"""Plots of states and observables: the paper's figures.

Headless by construction: figures are `matplotlib.figure.Figure` objects drawn
by the Agg canvas, and pyplot is never imported, so no window can open and no
figure outlives its caller. Each function draws into ``ax`` if given (and returns
its figure) or into a new figure, saves a PNG when ``path`` is given, and
returns the `Figure`.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection
from matplotlib.patches import Circle
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from scipy import stats

from . import observables as obs

__all__ = ["quiver", "arrow_scale", "sphere_views", "poincare_disk", "chain", "components_by_ball",
           "energy_by_distance", "energy_profiles", "component_histograms", "correlation_histogram",
           "write_figures", "state_picture"]

DPI = 100
BALL_COLOUR = "0.75"
BALL_SIZE = 0.6  #: drawn diameter of a ball, in spacings between centres
ARROW_COLOUR = "tab:red"
FIT_COLOUR = "tab:orange"
COMPONENT_NAMES = "xyz"


def new_figure(figsize) -> Figure:
    """A figure of ``figsize`` inches drawn by Agg: never a window, whatever the backend."""
    fig = Figure(figsize=figsize, dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _new_axes(ax, figsize, title):
    """``(figure, ax)``: the given axes, or one axes on a `new_figure` of ``figsize`` inches."""
    if ax is None:
        ax = new_figure(figsize).add_subplot()
    if title:
        ax.set_title(title)
    return ax.figure, ax


def save(fig: Figure, path) -> Figure:
    """Write ``fig`` as a PNG at ``path`` (its folder created) unless ``path`` is None: drawn in
    memory and written through a temporary file and a rename, so a failed write (a full disk)
    leaves no partial PNG."""
    if path is not None:
        from .io import write_bytes_atomic

        Path(path).parent.mkdir(parents=True, exist_ok=True)
        image = io.BytesIO()
        fig.savefig(image, dpi=DPI, format="png")
        write_bytes_atomic(path, image.getvalue())
    return fig


# ---------------------------------------------------------------- states

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


def _shared_scale(speeds: np.ndarray, shared, spacing: float, norm) -> float:
    """`arrow_scale` of this state's ``speeds``, or of every frame's when ``shared`` (a movie) is given;
    ``norm(v) -> (n,)`` turns one frame's velocities into speeds."""
    if shared is None:
        return arrow_scale(speeds, spacing)
    return arrow_scale(np.concatenate([norm(np.asarray(v, dtype=np.float64)) for v in shared]), spacing,
                       longest=MOVIE_LONGEST)


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


def quiver(positions, velocities, ax=None, title: str | None = None, path=None, shared=None) -> Figure:
    """The paper's state pictures: velocities as arrows over grey balls.

    positions: ``(n_balls, 2)`` centres; velocities: ``(n_balls, 2)``. Balls are
    grey dots (``BALL_SIZE`` of the typical spacing across); see `arrow_scale`
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
    k = _shared_scale(speeds, shared, spacing, lambda u: np.linalg.norm(u, axis=1))
    tips = [p + k * np.asarray(u, dtype=np.float64) for u in (shared if shared is not None else [v])]
    reach = np.concatenate([p, *tips]) if len(p) else np.array([[0.0, 0.0], [1.0, 1.0]])
    lo, hi = reach.min(axis=0) - spacing, reach.max(axis=0) + spacing
    width, height = hi - lo
    lines = 1 + (title or "").count("\n")  # room for every line of the title, and the key below
    fig, ax = _new_axes(ax, (8.0, float(np.clip(8.0 * height / width, 2.5, 10.0)) + 0.6 + 0.25 * lines), title)
    ax.add_collection(EllipseCollection(
        BALL_SIZE * spacing, BALL_SIZE * spacing, 0.0, units="xy", offsets=p, offset_transform=ax.transData,
        facecolors=BALL_COLOUR, edgecolors="none"))
    moving = speeds > 0
    if moving.any():
        arrows = ax.quiver(p[moving, 0], p[moving, 1], v[moving, 0], v[moving, 1], color=ARROW_COLOUR,
                           angles="xy", scale_units="xy", scale=1.0 / k, units="xy", width=0.1 * spacing,
                           headwidth=3.5, headlength=4.0, headaxislength=3.5, minlength=0.0)
        _key(ax, arrows, k, spacing, width)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    return save(fig, path)


def _tangent_arrows(ax, p: np.ndarray, v: np.ndarray, k: float, spacing: float):
    """Arrows ``v (n, 2)`` at ``p (n, 2)``, ``k`` long per unit speed; the `Quiver`, or None if all rest."""
    moving = np.linalg.norm(v, axis=1) > 0
    if moving.any():
        return ax.quiver(p[moving, 0], p[moving, 1], v[moving, 0], v[moving, 1], color=ARROW_COLOUR, angles="xy",
                  scale_units="xy", scale=1.0 / k, units="xy", width=0.1 * spacing, headwidth=3.5, headlength=4.0,
                  headaxislength=3.5, minlength=0.0)
    return None


def sphere_views(positions, velocities, title: str | None = None, path=None, shared=None) -> Figure:
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
    fig = new_figure((11.0, 5.8))
    spacing = _spacing(x)
    k = _shared_scale(np.linalg.norm(V, axis=1), shared, spacing, lambda u: np.linalg.norm(u, axis=1))
    for ax, sign, name in zip(fig.subplots(1, 2), (1.0, -1.0), ("northern hemisphere (from +z)",
                                                                  "southern hemisphere (from -z)")):
        on = sign * x[:, 2] >= 0
        flip = np.array([sign, 1.0])
        p, v = x[on, :2] * flip, V[on, :2] * flip
        ax.add_patch(Circle((0, 0), 1.0, fill=False, color="0.5", linewidth=0.8))
        # a ball seen at a slant: its width along the rim kept, its depth towards the centre foreshortened by |z|
        size = np.full(len(p), BALL_SIZE * spacing)
        along_rim = np.degrees(np.arctan2(p[:, 1], p[:, 0])) + 90
        ax.add_collection(EllipseCollection(size, size * np.maximum(np.abs(x[on, 2]), 0.2), along_rim, units="xy",
                                            offsets=p, offset_transform=ax.transData, facecolors=BALL_COLOUR,
                                            edgecolors="none"))
        arrows = _tangent_arrows(ax, p, v, k, spacing)
        if arrows is not None:
            _key(ax, arrows, k, spacing, 2.5, y=0.04)
        ax.set_xlim(-1.25, 1.25)
        ax.set_ylim(-1.25, 1.25)
        ax.set_aspect("equal")
        ax.set_title(name)
        ax.set_xlabel("x" if sign > 0 else "-x")
        ax.set_ylabel("y")
    if title:
        fig.suptitle(title)
    return save(fig, path)


def poincare_disk(positions, velocities, title: str | None = None, path=None, shared=None) -> Figure:
    """A state of the hyperbolic plane drawn in the Poincare disk.

    positions: ``(n_balls, 3)`` on the hyperboloid; velocities: ``(n_balls, 3)`` in embedding
    coordinates. Balls sit at ``p = (x1, x2) / (1 + x0)``; balls and arrows are drawn at their
    hyperbolic sizes carried to the disk by the same map (conformal: directions are true,
    lengths shrink by ``(1 - |p|^2) / 2`` towards the rim). Arrow lengths follow `arrow_scale`
    in hyperbolic units, with the spacing of the ball nearest the centre (one scale for every
    frame's velocities ``shared`` in a movie); the key gives the speed of an arrow at the centre.
    """
    x = np.asarray(positions, dtype=np.float64)
    V = np.asarray(velocities, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or V.shape != x.shape:
        raise ValueError(f"positions, velocities: must both have shape (n_balls, 3), got {x.shape} and {V.shape}")
    one = 1.0 + x[:, :1]
    p = x[:, 1:] / one
    dp = (V[:, 1:] * one - x[:, 1:] * V[:, :1]) / one**2
    shrink = (1.0 - np.einsum("nk,nk->n", p, p)) / 2.0
    def minkowski_speeds(u):
        return np.sqrt(np.maximum(np.einsum("nk,nk->n", u[:, 1:], u[:, 1:]) - u[:, 0] ** 2, 0.0))

    speeds = minkowski_speeds(V)
    centre = int(np.argmin(x[:, 0]))
    cosh = x[centre, 0] * x[:, 0] - x[:, 1:] @ x[centre, 1:]
    cosh[centre] = np.inf
    spacing = float(np.arccosh(cosh.min())) if len(x) > 1 else 1.0
    k = _shared_scale(speeds, shared, spacing, minkowski_speeds)
    fig, ax = _new_axes(None, (8.0, 8.0), title)
    ax.add_patch(Circle((0, 0), 1.0, fill=False, color="0.5", linewidth=0.8))
    size = BALL_SIZE * spacing * shrink
    ax.add_collection(EllipseCollection(size, size, np.zeros(len(p)), units="xy", offsets=p,
                                        offset_transform=ax.transData, facecolors=BALL_COLOUR, edgecolors="none"))
    moving = speeds > 0
    if moving.any():
        arrows = ax.quiver(p[moving, 0], p[moving, 1], dp[moving, 0], dp[moving, 1], color=ARROW_COLOUR,
                           angles="xy", scale_units="xy", scale=1.0 / k, units="dots", width=2.0, headwidth=3.5,
                           headlength=4.0, headaxislength=3.5, minlength=0.0)
        _key(ax, arrows, k, spacing, 2.1, y=0.03, drawn=0.5, where=" at the centre")  # the disk halves lengths there
    ax.set_xlim(-1.05, 1.05)
    ax.set_ylim(-1.05, 1.05)
    ax.set_aspect("equal")
    ax.set_xlabel("Poincare disk x")
    ax.set_ylabel("Poincare disk y")
    return save(fig, path)


def components_by_ball(x, velocities, xlabel: str = "ball", title: str | None = None, path=None,
                       shared=None) -> Figure:
    """Each velocity component as a stem at its ball's ``x (n_balls,)``: the state picture of a 1-D
    chain (``x`` its positions) and of any geometry no other picture fits (``x`` the ball index).

    velocities: ``(n_balls, dim)``, one panel per component (at most three drawn); the vertical
    axis is the same for all panels and, with ``shared`` (every frame of a movie), for all frames.
    """
    x = np.asarray(x, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    if v.ndim != 2 or x.shape != (len(v),):
        raise ValueError(f"x, velocities: must have shapes (n_balls,) and (n_balls, dim), got {x.shape} and {v.shape}")
    panels = min(v.shape[1], 3)
    top = max(float(np.abs(np.asarray(u)).max(initial=0.0)) for u in (shared if shared is not None else [v]))
    top = 1.1 * top if top > 0 else 1.0
    fig = new_figure((8.0, 1.2 + 2.2 * panels))
    axes = fig.subplots(panels, 1, sharex=True, squeeze=False)[:, 0]
    for k, ax in enumerate(axes):
        ax.axhline(0.0, color=BALL_COLOUR, linewidth=4, zorder=0)
        ax.scatter(x, np.zeros_like(x), s=12, color="0.5", zorder=1)
        moving = v[:, k] != 0
        if moving.any():
            ax.vlines(x[moving], 0.0, v[moving, k], color=ARROW_COLOUR, linewidth=2)
            ax.scatter(x[moving], v[moving, k], s=10, color=ARROW_COLOUR)
        ax.set_ylim(-top, top)
        name = COMPONENT_NAMES[k] if v.shape[1] <= 3 else str(k)
        ax.set_ylabel(f"{name}-component of velocity" if v.shape[1] > 1 else "velocity")
    axes[-1].set_xlabel(xlabel if v.shape[1] <= 3 else f"{xlabel} (components 0-2 of {v.shape[1]} drawn)")
    if len(x) and np.all(np.diff(x) == 1):
        axes[-1].xaxis.set_major_locator(MaxNLocator(integer=True))
    if title:
        fig.suptitle(title)
    return save(fig, path)


def chain(positions, velocities, title: str | None = None, path=None, shared=None) -> Figure:
    """A state of a 1-D chain: ``positions (n_balls, 1)``, each velocity ``(n_balls, 1)`` a stem at its ball."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 1:
        raise ValueError(f"positions: must have shape (n_balls, 1), got {p.shape}")
    return components_by_ball(p[:, 0], velocities, xlabel="position x", title=title, path=path, shared=shared)


# ---------------------------------------------------------------- energy against distance from the boundary

def energy_by_distance(distances, velocities, masses=None, bin_width: float | None = None, ax=None,
                       title: str | None = None, path=None) -> Figure:
    """Bar plot of the energy profile (the paper's Figure 3): fraction of the energy per row.

    distances: ``(n_balls,)`` from the boundary; velocities: ``(n_balls, dim)``.
    The bars are the only patches of the axes and sum to 1. See `observables.energy_profile`.
    """
    centres, fraction = obs.energy_profile(distances, velocities, masses, bin_width)
    fig, ax = _new_axes(ax, (8.0, 4.5), title)
    width = bin_width if bin_width is not None else (np.diff(centres).min() if len(centres) > 1 else 1.0)
    ax.bar(centres, fraction, width=0.8 * width, color="tab:blue")
    if len(fraction) and np.isfinite(fraction[0]):
        where = "boundary row" if bin_width is None else "first bin"
        ax.text(0.98, 0.95, f"{where}: {fraction[0]:.1%} of the energy", transform=ax.transAxes,
                ha="right", va="top")
    ax.set_xlabel("distance from the boundary")
    ax.set_ylabel("fraction of the energy")
    ax.set_ylim(0, 1.05 * max(np.nanmax(fraction) if np.isfinite(fraction).any() else 1.0, 1e-12))
    return save(fig, path)


def energy_profiles(profiles: dict, ax=None, title: str | None = None, logy: bool = False,
                    path=None) -> Figure:
    """One line of energy fraction against distance per system (the paper's Figure 4).

    profiles: ``{label: (centres (n_rows,), fraction (n_rows,))}`` from
    `observables.energy_profile`, drawn in the given order. ``logy`` uses a log
    scale for the fractions (rows without energy then leave gaps).
    """
    fig, ax = _new_axes(ax, (8.0, 4.5), title)
    for label, (centres, fraction) in profiles.items():
        centres, fraction = np.asarray(centres, dtype=float), np.asarray(fraction, dtype=float)
        if centres.shape != fraction.shape or centres.ndim != 1:
            raise ValueError(f"profiles[{label!r}]: centres and fraction must be (n_rows,) arrays of one length, "
                             f"got {centres.shape} and {fraction.shape}")
        ax.plot(centres, fraction, marker=".", label=str(label))
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel("distance from the boundary")
    ax.set_ylabel("fraction of the energy")
    if profiles:
        ax.legend(title="system")
    return save(fig, path)


# ---------------------------------------------------------------- distributions

def _bars(ax, counts: np.ndarray, edges: np.ndarray) -> None:
    ax.bar(edges[:-1], counts, width=np.diff(edges), align="edge", color="tab:blue")
    ax.set_xlim(edges[0], edges[-1])
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # counts of balls or runs
    ax.set_ylabel("count")


def _normal_panel(ax, values: np.ndarray, hist: obs.Histogram, bin_width: float) -> None:
    """Bars of ``hist`` in the values' own units; the fitted normal only where the
    Anderson-Darling test (5 %) does not reject it, and the test's verdict either way."""
    edges = hist.edges * hist.scale
    _bars(ax, hist.counts, edges)
    mean, sd = hist.mean * hist.scale, hist.std * hist.scale
    if len(values) < 8 or not sd > 0:
        return
    test = obs.normality_tests(values)
    a2, critical = test["ad_statistic"], test["ad_critical_5pct"]
    fits = a2 <= critical
    if fits:
        x = np.linspace(edges[0], edges[-1], 801)
        ax.plot(x, len(values) * bin_width * hist.scale * stats.norm.pdf(x, mean, sd), color=FIT_COLOUR)
    verdict = "not rejected (orange: the fitted normal)" if fits else "rejected: no normal curve drawn"
    ax.text(0.02, 0.97, f"mean {mean:.3g}, sd {sd:.3g}\nAnderson-Darling A\u00b2 = {a2:.3g} "
            f"{'<=' if fits else '>'} {critical:.3g}\nnormality at 5 %: {verdict}",
            transform=ax.transAxes, ha="left", va="top", fontsize="small",
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none"})
    ax.set_ylim(0, 1.4 * max(hist.counts.max(), 1))  # room for the text above the bars


def component_histograms(velocities, bin_width: float = 0.025, span=(-1.0, 1.0), title: str | None = None,
                         path=None) -> Figure:
    """Histograms of each velocity component, in the velocities' own units (the paper's Figure 6).

    velocities: ``(n_balls, dim)``; one panel per component. The bins are the paper's:
    ``bin_width`` (0.025) of the largest absolute component, over ``span`` times it, the
    same bins for every panel. Each panel gives the mean, the sd and the Anderson-Darling
    test of normality (fitted parameters, 5 %); the fitted normal (``n * bin * pdf``, the
    histogram's area) is drawn only where the test does not reject it. See
    `observables.component_histogram` and `observables.normality_tests`.
    """
    v = np.asarray(velocities, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] < 1:
        raise ValueError(f"velocities: must have shape (n_balls, dim), got {v.shape}")
    dim = v.shape[1]
    scale = float(np.abs(v).max()) if v.size else 0.0
    fig = Figure(figsize=(5.0 * dim, 4.2), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    for k, ax in enumerate(fig.subplots(1, dim, squeeze=False)[0]):
        hist = obs.component_histogram(v[:, k], bin_width, span, scale=scale)
        name = COMPONENT_NAMES[k] if dim <= 3 else str(k)
        _normal_panel(ax, v[:, k], hist, bin_width)
        ax.set_xlabel(f"{name}-component of velocity (bins of {bin_width * hist.scale:.3g})")
        ax.set_title(f"{name}-component")
    if title:
        fig.suptitle(title)
    return save(fig, path)


def correlation_histogram(values, bin_width: float = 0.02, span=(-1.0, 1.0), ax=None, title: str | None = None,
                          xlabel: str = "correlation", path=None) -> Figure:
    """Histogram of correlations over independent runs (the paper's Figures 7 and 8).

    values: ``(n_runs,)`` correlations in ``[-1, 1]``, not rescaled, in bins of
    ``bin_width`` over ``span``. The axis is scaled to the data (a few bins beyond the
    extreme values); a dashed line marks the mean, and a band the mean plus or minus
    its standard error (``sd / sqrt(n_runs)``).
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"values: must have shape (n_runs,), got {x.shape}")
    hist = obs.component_histogram(x, bin_width, span, normalise=False)
    fig, ax = _new_axes(ax, (7.0, 4.0), title)
    _bars(ax, hist.counts, hist.edges)
    ax.set_xlabel(xlabel)
    finite = x[np.isfinite(x)]
    if len(finite):
        lo = max(span[0], finite.min() - 3 * bin_width)
        hi = min(span[1], finite.max() + 3 * bin_width)
        ax.set_xlim(lo, hi)
        mean = float(finite.mean())
        se = float(finite.std(ddof=1) / np.sqrt(len(finite))) if len(finite) > 1 else float("nan")
        ax.axvline(mean, color="k", linestyle="--", linewidth=1,
                   label=f"mean {mean:.4f} \u00b1 {se:.4f} (s.e.) over {len(finite)} runs")
        if np.isfinite(se):
            ax.fill_betweenx([0, 1], mean - se, mean + se, transform=ax.get_xaxis_transform(),
                             color="0.5", alpha=0.3, linewidth=0)
        ax.legend(loc="upper right", fontsize="small")
    return save(fig, path)


# ---------------------------------------------------------------- one run

#: the names `write_figures` gives its files
FIGURE_PATTERNS = ("state_initial.png", "state_step_*.png", "state_collisions_*.png", "state_final.png", "energy_by_distance.png",
                   "energy_by_height.png", "velocity_histograms.png")


def figure_files(out_dir) -> list[Path]:
    """The files in ``out_dir`` that `write_figures` may have written (to clear a stale run's)."""
    out = Path(out_dir)
    return sorted({p for pattern in FIGURE_PATTERNS for p in out.glob(pattern)})


def state_picture(geometry, positions: np.ndarray):
    """``draw(velocities (n, dim), title, shared=None) -> Figure`` for this geometry's states.

    Asked of the geometry's capabilities and positions: flat 2-D (quiver), a curved surface
    whose centres lie on the unit sphere (`sphere_views`) or the hyperboloid (`poincare_disk`),
    flat 3-D (the bottom layer's ``(v_x, v_y)`` as a quiver of a slice), a 1-D chain (`chain`),
    and anything else the components against the ball index (`components_by_ball`).
    ``shared``: every frame's velocities of a movie, drawn on one scale.
    """
    n, k = positions.shape
    if geometry.dim == 2 and k == 2 and not geometry.curved:
        return lambda v, title, shared=None: quiver(positions, v, title=title, shared=shared)
    if geometry.curved and k == 3 and geometry.dim == 2:
        square = positions**2
        scale = 1e-9 * max(1.0, float(square.sum(axis=1).max()))
        draw = None
        if np.all(np.abs(square.sum(axis=1) - 1) <= scale):
            draw = sphere_views
        elif np.all(np.abs(square[:, 1:].sum(axis=1) - square[:, 0] + 1) <= scale) and np.all(positions[:, 0] > 0):
            draw = poincare_disk
        if draw is not None:
            frames = geometry.frames()

            def embed(v):
                return np.einsum("nd,ndk->nk", np.asarray(v, dtype=np.float64), frames)

            return lambda v, title, shared=None: draw(positions, embed(v), title=title,
                                                      shared=None if shared is None else [embed(u) for u in shared])
    if geometry.dim == 3 and k == 3 and not geometry.curved:
        layer = np.flatnonzero(positions[:, 2] <= positions[:, 2].min() + 1e-9)
        if len(layer) >= 3:
            where = f"the bottom layer (z = {positions[layer[0], 2]:g}), arrows (v_x, v_y)"
            return lambda v, title, shared=None: quiver(
                positions[layer, :2], np.asarray(v)[layer, :2], title=f"{title}: {where}",
                shared=None if shared is None else [np.asarray(u)[layer, :2] for u in shared])
    if geometry.dim == 1 and k == 1:
        return lambda v, title, shared=None: chain(positions, v, title=title, shared=shared)
    return lambda v, title, shared=None: components_by_ball(np.arange(n, dtype=np.float64), v, title=title,
                                                            shared=shared)


def snapshot_counter(res) -> str:
    """``"collisions"`` if the run's spec placed its snapshots by collisions, else ``"steps"``."""
    snapshots = getattr(getattr(res, "spec", None), "snapshots", None)
    return getattr(snapshots, "counter", "steps")


def snapshot_name(snap, counter: str) -> tuple[str, str]:
    """``(file name, title)`` of the state picture of ``snap``, named after the count ``counter`` the
    spec asked for: ``state_collisions_22579.png``, "after 22,579 collisions (89,335 steps)"."""
    step, collisions = int(snap.step), int(snap.collisions)
    if step == 0:
        return "state_initial.png", "initial state"
    if counter == "collisions":
        return f"state_collisions_{collisions}.png", f"after {collisions:,} collisions ({step:,} steps)"
    return f"state_step_{step}.png", f"after {step:,} steps ({collisions:,} collisions)"


def write_figures(res, out_dir) -> list[Path]:
    """Write the figures of one run's results into ``out_dir``; return their paths.

    res: what `pinnedballs.load` returns (``positions (n, k)``, final
    ``velocities (n, dim)``, ``snapshots`` with ``.step``, ``.collisions``,
    ``.velocities``, ``geometry``, ``masses`` or None, and ``initial_velocities`` if it
    has them). Writes ``state_initial.png`` (the initial velocities, or a snapshot at
    step 0), ``state_step_<N>.png`` or ``state_collisions_<C>.png`` (every other snapshot, named
    after the counter the spec placed them by) and ``state_final.png`` in the geometry's view
    (see `state_picture`: the plane, both hemispheres of a sphere, the Poincare disk, a slice of
    a 3-D packing, a 1-D chain); ``energy_by_distance.png`` on any geometry with a ``boundary``;
    ``energy_by_height.png`` in flat 3-D; ``velocity_histograms.png`` (one panel per component, up to 3).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    positions = np.asarray(res.positions, dtype=np.float64)
    final = np.asarray(res.velocities, dtype=np.float64)
    geometry = res.geometry
    written: list[Path] = []

    def emit(name: str, fig: Figure) -> None:
        path = out / name
        save(fig, path)
        written.append(path)

    draw = state_picture(geometry, positions) if positions.ndim == 2 else None
    if draw is not None:
        snapshots = list(() if res.snapshots is None else res.snapshots)
        initial = getattr(res, "initial_velocities", None)
        if initial is not None and not any(int(snap.step) == 0 for snap in snapshots):
            emit("state_initial.png", draw(np.asarray(initial, dtype=np.float64), "initial state"))
        counter = snapshot_counter(res)
        for snap in snapshots:
            name, title = snapshot_name(snap, counter)
            emit(name, draw(np.asarray(snap.velocities, dtype=np.float64), title))
        emit("state_final.png", draw(final, "final state"))
    if geometry.boundary is not None:
        emit("energy_by_distance.png", energy_by_distance(geometry.boundary.distance, final, res.masses,
                                                          title="energy by distance from the boundary, final state"))
    if geometry.dim == 3 and positions.shape[1] == 3 and not geometry.curved:
        fig = energy_by_distance(positions[:, 2] - positions[:, 2].min(), final, res.masses,
                                 title="energy by height (z), final state")
        fig.axes[0].set_xlabel("height z above the lowest layer")
        for text in fig.axes[0].texts:
            text.set_text(text.get_text().replace("boundary row", "lowest layer"))
        emit("energy_by_height.png", fig)
    if final.ndim == 2 and 1 <= final.shape[1] <= 3:
        emit("velocity_histograms.png", component_histograms(final, title="velocity components, final state"))
    return written
