"""The orders study: fewest and most collisions over every order of small systems, against the
paper's random order."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from .plan import Ensemble, ExtendedPlan


def order_configurations():
    """``{name: (geometry, velocities (n_balls, dim))}``: small systems, one boundary ball moving inward
    with unit energy, and the rhombus of ``docs/orders.md``."""
    from ....geometry import FCC, GraphGeometry, HalfPlane, HyperbolicPlane

    def inward(g):
        b = g.boundary_center()
        v = np.zeros((g.n_balls, g.dim))
        v[b] = -math.sqrt(2.0) * g.boundary.outward[b]
        return g, v

    rhombus = GraphGeometry.from_positions([[0, 0], [2, 0], [1, 3**0.5], [3, 3**0.5]])
    return {"rhombus (4 balls)": (rhombus, np.array([[1.0, 0.0], [-1.0, 1.0], [0.0, 0.0], [0.0, 0.0]])),
            "half-plane 2x3": inward(HalfPlane(rows=2, cols=3)),
            "open FCC 1x1x2": inward(FCC(1, 1, 2, periodic=False)),
            "{3,7} disk, 1 ring": inward(HyperbolicPlane(7, 1)),
            "half-plane 3x3": inward(HalfPlane(rows=3, cols=3)),
            "half-plane 3x4": inward(HalfPlane(rows=3, cols=4))}


def orders(plan: ExtendedPlan, out: Path, ensemble: Ensemble | None = None) -> dict:
    """`orders.orders_against_random` on each of `order_configurations`."""
    from ....analysis.orders import orders_against_random

    rows = []
    for name, (g, v) in order_configurations().items():
        r = orders_against_random(g, v, replicas=plan.orders_replicas, seed=plan.seed,
                                  max_states=plan.orders_max_states)
        # every random order is an order: the fewest is at most, the most at least, what they reached
        rows.append({"name": name, **r, "fewest_known": min(r["min_collisions"], r["random_min"]),
                     "most_known": max(r["max_collisions"], r["random_max"])})
    return {"rows": rows, "figures": [_orders_figure(rows, out / "extended_orders.png")]}


def _orders_figure(rows: list[dict], path: Path) -> str:
    from ....plot import base as plots

    cols = 3
    fig = plots.new_figure((12.0, 3.4 * math.ceil(len(rows) / cols)))
    axes = fig.subplots(math.ceil(len(rows) / cols), cols, squeeze=False).ravel()
    for ax, r in zip(axes, rows):
        n, runs = np.array(r["random_histogram"]).T
        ax.bar(n, runs / runs.sum(), width=0.8, color="tab:blue", label="random order")
        bound = "" if r["exhaustive"] else " (bound)"
        ax.axvline(r["fewest_known"], color="tab:green", linestyle="--", label=f"fewest{bound}: {r['fewest_known']}")
        ax.axvline(r["most_known"], color="tab:red", linestyle="--", label=f"most{bound}: {r['most_known']}")
        ax.set_title(f"{r['name']}", fontsize="medium")
        ax.set_xlabel("collisions until frozen")
        ax.legend(fontsize="x-small")
    for ax in axes[len(rows):]:
        ax.set_visible(False)
    axes[0].set_ylabel("share of random orders")
    fig.suptitle("collisions until frozen: every order against the paper's random order")
    plots.save(fig, path)
    return path.name
