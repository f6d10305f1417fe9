"""A study's figure: an observable's mean ± standard error over each point's replicas against a parameter, a
series for each value of the other parameters, with each series' fitted power law where there is one
(`pinnedballs.run.study_dir.StudyResult.plot` gathers the numbers; this module only draws them)."""

from __future__ import annotations

import numpy as np

from . import base

__all__ = ["study_figure"]


def study_figure(series: list[dict], *, xlabel: str, ylabel: str, title: str, log: bool, symbol: str = "x", ax=None,
                 path=None):
    """Draw ``series`` and return the figure (saved as a PNG at ``path`` if given).

    Parameters
    ----------
    series : list of dict
        Each with ``label`` (a legend's words; empty for a study's only series), ``x``, ``mean`` and ``se``
        (``(k,)`` each, by ``x``) and ``fit``: None, or a power law (`run.reproduction.fit.fit_exponent`'s keys
        ``prefactor``, ``exponent``, ``exponent_se``) drawn over the range of ``x``.
    xlabel, ylabel, title : str
        The axes' labels (with their units) and the figure's title.
    log : bool
        Log-log axes.
    symbol : str
        The parameter in a fit's legend: ``"N"`` for ``C N^a``.
    ax : matplotlib Axes, optional
        Draw into it (its figure is returned) instead of a new figure.
    """
    fig, ax = base._new_axes(ax, (7.0, 4.8), title)
    handles = []  # each series' points, then its fit
    for k, s in enumerate(series):
        colour = f"C{k % 10}"
        name = s["label"] or "mean ± se over replicas"
        handles.append(ax.errorbar(s["x"], s["mean"], yerr=np.nan_to_num(s["se"]), fmt="o", color=colour,
                                   capsize=3, label=name))
        f = s.get("fit")
        if f is not None:
            x = np.geomspace(min(s["x"]), max(s["x"]), 50)
            handles += ax.plot(x, f["prefactor"] * x ** f["exponent"], color=colour, linestyle="--",
                               label=f"fit: {f['prefactor']:.3g} {symbol}^({f['exponent']:.3f} ± "
                                     f"{f['exponent_se']:.3f})")
    if log:
        from matplotlib.ticker import NullFormatter

        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # minor ticks' labels crowd a decade or two
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.legend(handles=handles, fontsize="small")
    return base.save(fig, path)
