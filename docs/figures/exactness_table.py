"""The tables of docs/collisions.md and docs/extended.md's exact scaling: counts by size and by counting.

Reads the JSON rows of `benchmarks/bench_exact.py --json` (several seeds per size; arithmetics such
as ``float``, ``certified``, ``float@1e-9``) and prints, as markdown:

1. per size: the mean collisions until frozen (± its standard error over the seeds) of each
   counting: exact (``certified`` or ``exact``: the same counts), the float run, and N_e;
2. the local exponents between consecutive sizes of each counting, ± their standard errors
   (`pinnedballs.run.reproduction.extended.scaling_study.local_exponents`).

    python docs/figures/exactness_table.py docs/figures/exactness_runs.json
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from pinnedballs.run.reproduction.extended.scaling_study import local_exponents


def counting(arithmetic: str) -> str:
    """The column a run counts in: ``exact`` (exact or certified arithmetic), ``float``, or ``N_e``."""
    if arithmetic.startswith(("exact", "certified")):
        return "exact"
    return f"N_{arithmetic.partition('@')[2]}" if "@" in arithmetic else "float"


def by_size(rows: list[dict]) -> dict[str, dict[str, dict]]:
    """``{counting: {size: {balls, collisions_mean, collisions_se, replicas}}}`` over frozen runs."""
    runs = defaultdict(lambda: defaultdict(list))
    balls, seen = {}, set()
    for r in rows:
        key = (counting(r["arithmetic"]), r["size"], r["seed"])  # exact and certified: one run's count
        if r.get("outcome") == "frozen" and key not in seen:
            seen.add(key)
            runs[key[0]][r["size"]].append(r["collisions"])
            balls[r["size"]] = r["balls"]
    out = {}
    for name, sizes in runs.items():
        out[name] = {}
        for size, counts in sorted(sizes.items(), key=lambda kv: balls[kv[0]]):
            c = np.array(counts, dtype=float)
            se = c.std(ddof=1) / np.sqrt(len(c)) if len(c) > 1 else float("nan")
            out[name][size] = {"balls": balls[size], "collisions_mean": c.mean(), "collisions_se": se,
                               "replicas": len(c)}
    return out


def main(path: Path) -> None:
    table = by_size(json.loads(path.read_text()))
    names = ["exact", "float"] + sorted((n for n in table if n.startswith("N_")), key=lambda n: -float(n[2:]))
    names = [n for n in names if n in table]
    sizes = sorted({s for n in names for s in table[n]}, key=lambda s: table[names[0]].get(s, {"balls": 0})["balls"])
    print("| half-plane | balls | replicas | " + " | ".join(names) + " |")
    print("|---|---:|---:|" + "---:|" * len(names))
    for s in sizes:
        first = next(table[n][s] for n in names if s in table[n])
        cells = [f"{table[n][s]['collisions_mean']:,.0f} ± {table[n][s]['collisions_se']:,.0f}"
                 if s in table[n] else "-" for n in names]
        print(f"| {s} | {first['balls']:,} | {first['replicas']} | " + " | ".join(cells) + " |")
    print()
    print("| between | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    slopes = {}
    for n in names:
        rows = list(table[n].values())
        if len(rows) > 1:
            slopes[n] = local_exponents(rows, "collisions")
    for k, (a, b) in enumerate(zip(sizes, sizes[1:])):
        cells = []
        for n in names:
            f = slopes.get(n)
            cells.append(f"{f['local_exponents'][k]:.3f} ± {f['local_exponents_se'][k]:.3f}"
                         if f and k < len(f["local_exponents"]) else "-")
        print(f"| {a} and {b} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parent / "exactness_runs.json")
