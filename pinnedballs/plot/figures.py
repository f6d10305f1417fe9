"""Figures of observables: energy against distance from the boundary, histograms of velocity
components with a test of normality, and correlations over runs (the paper's Figures 3, 4, 6-8)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator
from scipy import stats

from ..analysis import observables as obs
from .base import COMPONENT_NAMES, FIT_COLOUR, _new_axes, length_label, panels, save

__all__ = ["energy_by_distance", "energy_bars", "energy_profiles", "component_histograms", "correlation_histogram"]


# ---------------------------------------------------------------- energy against distance from the boundary

def energy_by_distance(distances, velocities, masses=None, bin_width: float | None = None, ax=None,
                       title: str | None = None, path=None, xlabel: str | None = None,
                       first: str = "boundary row", radius: float | None = None) -> Figure:
    """Bar plot of the energy profile (the paper's Figure 3): fraction of the energy per row.

    distances: ``(n_balls,)`` from the boundary; velocities: ``(n_balls, dim)``.
    The bars are the only patches of the axes and sum to 1; the share of the ``first`` row is
    written in a band above the tallest bar. See `observables.energy_profile`. The x axis is
    ``xlabel``, else "distance from the boundary" in the unit of the balls' ``radius`` ("ball radii"
    for radius 1, "ball radius 0.5" for 0.5), or with no unit where ``radius`` is not given.
    """
    if xlabel is None:
        xlabel = "distance from the boundary" if radius is None else length_label("distance from the boundary",
                                                                                   radius)
    centres, fraction = obs.energy_profile(distances, velocities, masses, bin_width)
    return energy_bars(centres, fraction, ax=ax, title=title, path=path, xlabel=xlabel,
                       first=first if bin_width is None else "first bin", width=bin_width)


def energy_bars(centres, fraction, ax=None, title: str | None = None, path=None,
                xlabel: str = "distance from the boundary", first: str = "boundary row",
                width: float | None = None) -> Figure:
    """The bars of an energy profile ``fraction (n,)`` at distances ``centres (n,)`` (`energy_by_distance`'s,
    or an ensemble's mean), ``width`` apart (default: the least gap), the share of the ``first`` written
    in a band above the tallest bar."""
    centres, fraction = np.asarray(centres, dtype=np.float64), np.asarray(fraction, dtype=np.float64)
    fig, ax = _new_axes(ax, (8.0, 4.5), title)
    width = width if width is not None else (np.diff(centres).min() if len(centres) > 1 else 1.0)
    ax.bar(centres, fraction, width=0.8 * width, color="tab:blue")
    if len(fraction) and np.isfinite(fraction[0]):
        ax.text(0.98, 0.97, f"{first}: {fraction[0]:.1%} of the energy", transform=ax.transAxes,
                ha="right", va="top")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("fraction of the energy")
    # the tallest bar reaches 4/5 of the height: the text above never covers a bar
    ax.set_ylim(0, 1.25 * max(np.nanmax(fraction) if np.isfinite(fraction).any() else 1.0, 1e-12))
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
    Anderson-Darling test (5 %) does not reject it, the test's verdict either way, and how
    many values lie beyond the bars."""
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
    beyond = len(values) - int(hist.counts.sum())
    outside = f"\n{beyond} of {len(values)} beyond the range drawn" if beyond else ""
    ax.text(0.02, 0.97, f"mean {mean:.3g}, sd {sd:.3g}\nAnderson-Darling A\u00b2 = {a2:.3g} "
            f"{'<=' if fits else '>'} {critical:.3g}\nnormality at 5 %: {verdict}{outside}",
            transform=ax.transAxes, ha="left", va="top", fontsize="small",
            bbox={"facecolor": "white", "alpha": 0.8, "edgecolor": "none"})
    ax.set_ylim(0, 1.4 * max(hist.counts.max(), 1))  # room for the text above the bars


def component_histograms(velocities, bin_width: float = 0.025, span=(-1.0, 1.0), title: str | None = None,
                         path=None, quantile: float | None = None, ax=None) -> Figure:
    """Histograms of each velocity component, in the velocities' own units (the paper's Figure 6).

    velocities: ``(n_balls, dim)``; one panel per component. The bins are the paper's:
    ``bin_width`` (0.025) of the largest absolute component, over ``span`` times it, the
    same bins for every panel; with ``quantile`` (e.g. 0.99), of that quantile of the absolute
    components instead, so that one outlier does not set the range (the panels say how many
    values lie beyond it). Each panel gives the mean, the sd and the Anderson-Darling
    test of normality (fitted parameters, 5 %, on every value); the fitted normal (``n * bin * pdf``,
    the histogram's area) is drawn only where the test does not reject it. See
    `observables.component_histogram` and `observables.normality_tests`. ``ax``: the Axes whose place
    the panels take (None: a new figure).
    """
    v = np.asarray(velocities, dtype=np.float64)
    if v.ndim != 2 or v.shape[1] < 1:
        raise ValueError(f"velocities: must have shape (n_balls, dim), got {v.shape}")
    dim = v.shape[1]
    scale = float(np.abs(v).max()) if v.size else 0.0
    if quantile is not None and v.size and np.quantile(np.abs(v), quantile) > 0:
        scale = float(np.quantile(np.abs(v), quantile))
    fig = panels(ax, (5.0 * dim, 4.2))
    for k, ax in enumerate(fig.subplots(1, dim, squeeze=False)[0]):
        hist = obs.component_histogram(v[:, k], bin_width, span, scale=scale)
        name = COMPONENT_NAMES[k] if dim <= 3 else str(k)
        _normal_panel(ax, v[:, k], hist, bin_width)
        ax.set_xlabel(f"v_{name} (velocity units; bins of {bin_width * hist.scale:.3g})")
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
