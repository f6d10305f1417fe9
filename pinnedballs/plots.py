"""Plots of states and observables: the paper's figures.

Headless by construction: figures are `matplotlib.figure.Figure` objects drawn
by the Agg canvas, and pyplot is never imported, so no window can open and no
figure outlives its caller. Each function draws into ``ax`` if given (and returns
its figure) or into a new figure, saves a PNG when ``path`` is given, and
returns the `Figure`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import EllipseCollection
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from scipy import stats

from . import observables as obs
from .geometry import HalfPlane

__all__ = ["quiver", "arrow_scale", "energy_by_distance", "energy_profiles", "component_histograms",
           "correlation_histogram", "write_figures"]

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
    """Write ``fig`` as a PNG at ``path`` (its folder created) unless ``path`` is None."""
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(path, dpi=DPI, format="png")
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


def arrow_scale(speeds: np.ndarray, spacing: float) -> float:
    """Arrow length per unit speed, for ``speeds (n,)`` and ``spacing`` between centres.

    The 95th percentile of the speeds gets one spacing, but no arrow gets more
    than three: a spread-out state shows typical arrows half a spacing long,
    and a state with all energy on one ball shows a single arrow three spacings long.
    """
    top = float(speeds.max()) if len(speeds) else 0.0
    reference = max(float(np.quantile(speeds, 0.95)) if len(speeds) else 0.0, top / 3.0)
    return spacing / reference if reference > 0 else 1.0


def key_speed(speed: float) -> float:
    """The round speed (1, 2 or 5 times a power of ten) nearest ``speed`` (> 0) on a log scale:
    the speed of the arrow-scale key, drawn about one spacing long."""
    power = 10.0 ** np.floor(np.log10(speed))
    candidates = np.array([1.0, 2.0, 5.0, 10.0]) * power
    return float(candidates[np.argmin(np.abs(np.log(candidates / speed)))])


def quiver(positions, velocities, ax=None, title: str | None = None, path=None) -> Figure:
    """The paper's state pictures: velocities as arrows over grey balls.

    positions: ``(n_balls, 2)`` centres; velocities: ``(n_balls, 2)``. Balls are
    grey dots (``BALL_SIZE`` of the typical spacing across); see `arrow_scale`
    for arrow lengths, and the key below the bottom right corner for the scale. Balls at rest
    get no arrow; the axes reach every arrow's tip.
    """
    p = np.asarray(positions, dtype=np.float64)
    v = np.asarray(velocities, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"positions: must have shape (n_balls, 2), got {p.shape}")
    if v.shape != p.shape:
        raise ValueError(f"velocities: must have shape (n_balls, 2) = {p.shape}, got {v.shape}")
    spacing = _spacing(p)
    speeds = np.linalg.norm(v, axis=1)
    k = arrow_scale(speeds, spacing)
    reach = np.concatenate([p, p + k * v]) if len(p) else np.array([[0.0, 0.0], [1.0, 1.0]])
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
        key = key_speed(spacing / k)
        ax.quiverkey(arrows, X=0.95, Y=-0.07, U=key, label=f"speed {key:g}", labelpos="W",
                     coordinates="axes", fontproperties={"size": "small"})
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    return save(fig, path)


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
FIGURE_PATTERNS = ("state_initial.png", "state_step_*.png", "state_final.png", "energy_by_distance.png",
                   "velocity_histograms.png")


def figure_files(out_dir) -> list[Path]:
    """The files in ``out_dir`` that `write_figures` may have written (to clear a stale run's)."""
    out = Path(out_dir)
    return sorted({p for pattern in FIGURE_PATTERNS for p in out.glob(pattern)})


def write_figures(res, out_dir) -> list[Path]:
    """Write the figures of one run's results into ``out_dir``; return their paths.

    res: what `pinnedballs.load` returns (``positions (n, 2)``, final
    ``velocities (n, dim)``, ``snapshots`` with ``.step``, ``.collisions``,
    ``.velocities``, ``geometry``, ``masses`` or None, and ``initial_velocities`` if it
    has them). Writes, for a 2-D state: ``state_initial.png`` (the initial velocities,
    or a snapshot at step 0), ``state_step_<N>.png`` (every other snapshot),
    ``state_final.png``, ``velocity_histograms.png``; on a
    `HalfPlane` also ``energy_by_distance.png``. Pictures of states need 2-D
    positions and velocities; histograms need 2-D velocities.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    positions = np.asarray(res.positions, dtype=np.float64)
    final = np.asarray(res.velocities, dtype=np.float64)
    planar = final.ndim == 2 and final.shape[1] == 2
    written: list[Path] = []

    def emit(name: str, fig: Figure) -> None:
        path = out / name
        save(fig, path)
        written.append(path)

    if planar and positions.ndim == 2 and positions.shape[1] == 2:
        snapshots = list(() if res.snapshots is None else res.snapshots)
        initial = getattr(res, "initial_velocities", None)
        if initial is not None and not any(int(snap.step) == 0 for snap in snapshots):
            emit("state_initial.png", quiver(positions, initial, title="initial state"))
        for snap in snapshots:
            step = int(snap.step)
            name = "state_initial.png" if step == 0 else f"state_step_{step}.png"
            title = "initial state" if step == 0 else f"after {step:,} steps ({int(snap.collisions):,} collisions)"
            emit(name, quiver(positions, snap.velocities, title=title))
        emit("state_final.png", quiver(positions, final, title="final state"))
    if isinstance(res.geometry, HalfPlane):
        emit("energy_by_distance.png", energy_by_distance(res.geometry.boundary_distance(), final, res.masses,
                                                          title="energy by distance from the boundary, final state"))
    if planar:
        emit("velocity_histograms.png", component_histograms(final, title="velocity components, final state"))
    return written
