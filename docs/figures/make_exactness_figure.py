"""The figure of docs/collisions.md's "Where the float criterion fails": exact against float counts by size.

Reads the JSON rows of `benchmarks/bench_exact.py --json` (float and exact or certified runs of the
paper's half-plane, several seeds per size) and draws two panels:

- left, against the number of balls: the smallest genuine closing speed of each run (exact or
  certified arithmetic, in units of the float criterion's threshold T), and the largest remnant the
  float run set aside; the float criterion counts a collision only above T (the line), so every
  point below the line is a genuine collision the float run lost;
- right: how many more collisions exact arithmetic counts than the float run, in percent.

    python benchmarks/bench_exact.py --sizes 100x50 200x100 500x250 --seeds 1 2 3 \
        --arithmetics float certified --json docs/figures/exactness_runs.json
    python docs/figures/make_exactness_figure.py docs/figures/exactness_runs.json
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).resolve().parent


def pairs(rows: list[dict]) -> list[tuple[dict, dict]]:
    """``(float row, exact or certified row)`` of each (size, seed) where both ran to frozen."""
    by = defaultdict(dict)
    for r in rows:
        if r.get("outcome") == "frozen":
            by[(r["size"], r["seed"])][r["arithmetic"].split(":")[0]] = r
    out = []
    for runs in by.values():
        exact = runs.get("exact") or runs.get("certified")
        if "float" in runs and exact is not None:
            out.append((runs["float"], exact))
    return sorted(out, key=lambda p: p[0]["balls"])


def draw(rows: list[dict], out: Path) -> None:
    both = pairs(rows)
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    balls = [e["balls"] for _, e in both]
    left.scatter(balls, [e["margin"][0] for _, e in both], marker="o", color="tab:blue",
                 label="smallest genuine collision (exact)")
    remnants = [(f["balls"], f["float_margin"][1]) for f, _ in both if f.get("float_margin") and f["float_margin"][1]]
    if remnants:
        left.scatter(*zip(*remnants), marker="x", color="tab:red", label="largest remnant set aside (float)")
    left.axhline(1.0, color="black", lw=1)
    left.text(min(balls), 1.5, "float criterion T = 4 ulp of the speed scale", fontsize=8, va="bottom")
    left.set(xscale="log", yscale="log", xlabel="balls N", ylabel="closing speed / T",
             title="Closing speeds at the edge of the float criterion")
    left.legend(fontsize=8, loc="lower left")
    lost = [100.0 * (e["collisions"] - f["collisions"]) / e["collisions"] for f, e in both]
    right.scatter(balls, lost, color="tab:blue")
    right.axhline(0.0, color="black", lw=1)
    right.set(xscale="log", xlabel="balls N", ylabel="(exact - float) / exact, %",
              title="Collisions the float run misses, until frozen")
    sizes = sorted({(e["balls"], e["size"]) for _, e in both})
    for ax in (left, right):
        ax.grid(True, which="major", alpha=0.3)
        ax.set_xticks([n for n, _ in sizes], [f"{n:,}\n{size}" for n, size in sizes])
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.set_xlim(sizes[0][0] / 1.6, sizes[-1][0] * 1.6)
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    source = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE / "exactness_runs.json"
    draw(json.loads(source.read_text()), HERE / "collisions_exact_by_size.png")
