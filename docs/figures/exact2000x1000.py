"""docs/extended.md's exact counts at 2000x1000: per replica, their means, and the local exponents from 1000x500.

Reads the runs of one folder (issue 33; each a ``pinnedballs run`` of the scaling study's spec, seed 0,
``"replica": k``): ``rK`` counted exactly (certified arithmetic), ``float_rK`` in float arithmetic (the
paper's criterion) and ``ne1e-06_rK`` ... as N_e. Keeps what
it read in ``exact2000x1000_runs.json`` beside this script (the runs' directories are gigabytes) and prints
docs/extended.md's rows as markdown. Without a folder, it prints from that JSON.

    python docs/figures/exact2000x1000.py results/exact2000
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

KEPT = Path(__file__).resolve().parent / "exact2000x1000_runs.json"
#: the half-plane 2000x1000's balls
BALLS = 577_000
#: 1000x500 (144,500 balls), 8 replicas of the same study (`reproduce --extended`, 2026-11-25,
#: docs/extended.md): mean and standard error of each counting
AT_1000x500 = {"balls": 144_500, "exact": (197_271_470, 1_093_268), "float": (189_988_635, 1_082_144),
               "N_1e-06": (150_827_720, 687_933), "N_1e-09": (182_521_610, 1_083_560),
               "N_1e-12": (186_844_458, 1_080_738)}
COUNTINGS = ("exact", "float", "N_1e-06", "N_1e-09", "N_1e-12")


def read(folder: Path) -> dict[str, dict[int, dict]]:
    """``{counting: {replica: {steps, collisions}}}`` of the frozen runs in ``folder``."""
    import pinnedballs as pb

    runs: dict[str, dict[int, dict]] = {name: {} for name in COUNTINGS}
    for k in range(16):
        for name, directory in (("exact", f"r{k}"), ("float", f"float_r{k}"),
                                *((f"N_{e}", f"ne{e}_r{k}") for e in ("1e-06", "1e-09", "1e-12"))):
            if (folder / directory / "results.h5").exists():
                res = pb.load(folder / directory)
                if res.complete and res.frozen:
                    runs[name][k] = {"steps": int(res.steps), "collisions": int(res.collisions)}
    return runs


def mean_se(values: list[int]) -> tuple[float, float]:
    a = np.array(values, dtype=float)
    return float(a.mean()), float(a.std(ddof=1) / math.sqrt(len(a))) if len(a) > 1 else math.nan


def exponent(small: tuple[float, float], large: tuple[float, float]) -> tuple[float, float]:
    """The local exponent between 1000x500 and 2000x1000 and its standard error (relative errors in quadrature)."""
    span = math.log(BALLS / AT_1000x500["balls"])
    return (math.log(large[0] / small[0]) / span,
            math.hypot(small[1] / small[0], large[1] / large[0]) / span)


def report(runs: dict[str, dict[int, dict]]) -> None:
    replicas = sorted(runs["exact"])
    print("| replica | exact | steps | float | float misses | N_1e-6 | N_1e-9 | N_1e-12 |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for k in replicas:
        exact = runs["exact"][k]["collisions"]
        cells = [f"{runs[n][k]['collisions']:,}" if k in runs[n] else "-" for n in ("float", "N_1e-06", "N_1e-09",
                                                                                    "N_1e-12")]
        miss = f"{(exact - runs['float'][k]['collisions']) / exact:.2%}" if k in runs["float"] else "-"
        print(f"| {k} | {exact:,} | {runs['exact'][k]['steps']:,} | {cells[0]} | {miss} | " + " | ".join(cells[1:])
              + " |")
    print()
    print("| counting | replicas | mean ± se at 2000x1000 | local exponent 1000x500 -> 2000x1000 | z from 2 |")
    print("|---|---:|---:|---:|---:|")
    for name in COUNTINGS:
        counts = [r["collisions"] for r in runs[name].values()]
        if len(counts) < 2:
            continue
        m, se = mean_se(counts)
        a, a_se = exponent(AT_1000x500[name], (m, se))
        print(f"| {name} | {len(counts)} | {m:,.0f} ± {se:,.0f} | {a:.3f} ± {a_se:.3f} | {(a - 2) / a_se:+.1f} |")


def main(argv: list[str]) -> None:
    if argv:
        runs = read(Path(argv[0]))
        KEPT.write_text(json.dumps(runs, indent=1) + "\n")
    else:
        runs = {name: {int(k): v for k, v in by.items()} for name, by in json.loads(KEPT.read_text()).items()}
    report(runs)


if __name__ == "__main__":
    main(sys.argv[1:])
