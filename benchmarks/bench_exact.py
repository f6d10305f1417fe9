"""What exact counts cost: CPU seconds to frozen in float, certified and exact arithmetic (issue 27, item 2).

On the paper's half-plane (one boundary ball sent inward with energy 100) at each size and seed,
each arithmetic runs in its own process, after a warm-up run that loads (or compiles) its loops:
CPU seconds to frozen, the ratio to the float chain, the collisions and steps, the process's peak
memory, for the exact policy the width it reached (limbs of 64 bits) and how often it widened,
for both the share of picks the float filter could not decide (decided in fixed point),
for the certified policy its error bound (G on the whole error vector, the largest on one ball),
and for both the margin of their decisions in units of the float criterion's threshold
(`pinnedballs.rules.threshold`, 4 ulp of the speed scale): the smallest closing speed counted as a
collision, the largest nonzero one set aside (negative: exact arithmetic sets aside no positive
one), and the picks set aside whose closing speed is exactly 0. A run that cannot finish says
why: a certified decision it cannot prove (the step and contact), or a time limit.

    python benchmarks/bench_exact.py                                   # 100x50 ... 1000x500, seed 1
    python benchmarks/bench_exact.py --sizes 500x250 --arithmetics float certified:384 certified:512
    python benchmarks/bench_exact.py --sizes 1000x500 --arithmetics certified certified:768/256   # late_precision
    python benchmarks/bench_exact.py --limit 1800                      # CPU seconds before giving up
    python benchmarks/bench_exact.py --json runs.json                  # every row also as JSON (for
                                                                       # docs/figures/make_exactness_figure.py)
    python benchmarks/bench_exact.py --tree /tmp/old --rounds 3        # another copy of the package (a
                                                                       # directory holding pinnedballs/), in turns,
                                                                       # and the medians of 3 rounds

The children import the package from the directory they run in (this checkout, or each ``--tree``: a
``PYTHONPATH`` would not do, as ``python -c`` puts its working directory first). The CPU's model, L2 cache
and vector extensions are printed first.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, resource, sys, time
import numpy as np
import pinnedballs as pb
from pinnedballs.rules import threshold

length, depth, seed, spec, limit = (float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4],
                                    float(sys.argv[5]))
spec, _, resolution = spec.partition("@")
arithmetic, _, bits = spec.partition(":")
bits, _, late = bits.partition("/")
options = {"precision": int(bits)} if bits else {}
if late:
    options["late_precision"] = int(late)
if resolution:
    options["resolution"] = float(resolution)

def half_plane(length, depth):
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    b = g.boundary_center()
    v[b] = -np.sqrt(200.0) * g.boundary.outward[b]
    return g, v

g, v = half_plane(20, 10)
try:  # load (or compile) the loops
    pb.Simulation(g, v, seed=seed, arithmetic=arithmetic, **options).run_until_frozen(10**7)
except ValueError:
    pass
g, v = half_plane(length, depth)
sim = pb.Simulation(g, v, seed=seed, arithmetic=arithmetic, **options)
out = {"balls": g.n_balls, "contacts": g.n_contacts, "outcome": "frozen"}
start = time.process_time()
try:
    while not sim.run_until_frozen(max_steps=50 * g.n_contacts * 64):
        if time.process_time() - start > limit:
            out["outcome"] = f"stopped after {limit:.0f} s CPU at step {sim.steps:,}"
            break
except ValueError as exc:
    out["outcome"] = str(exc)
out["seconds"] = time.process_time() - start
out["collisions"], out["steps"] = sim.collisions, sim.steps
out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
chain = sim.engine.state.field_chain
if chain is not None:
    out["limbs"], out["widenings"] = chain.P, chain.widenings
    out["narrowed"] = getattr(chain, "narrowed", None)
    out["inside"] = getattr(chain, "inside", 0) / max(sim.steps, 1)  # picks decided in fixed point
    T = threshold(v, np.ones(g.n_balls))
    smallest, largest, zeros = chain.margin
    out["margin"] = [smallest / T, largest / T, int(zeros)]
if sim.error_bound is not None:
    out["bound"] = list(sim.error_bound)
m = sim.closing_margin() if arithmetic == "float" else None
if m is not None:  # a float run: how near its criterion its picks came
    out["float_margin"] = [m.smallest_collision, m.largest_remnant, m.near_collisions, m.near_remnants]
print(json.dumps(out))
"""


def measure(size: str, seed: int, spec: str, limit: float, tree: Path = ROOT) -> dict:
    """One run in its own process, importing the package held in ``tree``."""
    length, depth = size.split("x")
    done = subprocess.run([sys.executable, "-c", _CHILD, length, depth, str(seed), spec, str(limit)],
                          capture_output=True, text=True, cwd=tree)
    if done.returncode != 0:
        return {"outcome": "failed: "
                           f"{done.stderr.strip().splitlines()[-1] if done.stderr.strip() else done.returncode}"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def row(size: str, spec: str, r: dict, floats: dict | None) -> str:
    if "seconds" not in r:
        return f"{size:>9} {spec:>14}  {r['outcome']}"
    ratio = f"{r['seconds'] / floats['seconds']:7.2f}x" if floats and "seconds" in floats else "      -"
    text = (f"{size:>9} {spec:>14} {r['seconds']:9.3f} s {ratio} {r['collisions']:>13,} {r['steps']:>15,} "
            f"{r['peak_mb']:8.0f} MB")
    if "limbs" in r:
        text += f"  P={r['limbs']}" + (f" ({r['widenings']} widenings)" if r["widenings"] else "")
        text += f" (narrowed at step {r['narrowed']:,})" if r.get("narrowed") else ""
        text += f"  in fixed point {100 * r['inside']:.2f} % of picks" if "inside" in r else ""
    if "bound" in r:
        text += f"  G={r['bound'][0]:.2e} largest={r['bound'][1]:.2e}"
    if "margin" in r:
        smallest, largest, zeros = r["margin"]
        text += f"  margin: smallest collision {smallest:.3g} T, largest set aside {largest:.3g} T, {zeros:,} zeros"
    if "float_margin" in r:
        smallest, largest, near, rest = r["float_margin"]
        text += (f"  margin: smallest collision {smallest if smallest is not None else float('nan'):.3g} T, largest "
                 f"remnant {largest if largest is not None else 0:.3g} T, {near:,} collisions near T")
    if r["outcome"] != "frozen":
        text += f"\n{'':>26}{r['outcome']}"
    return text


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["100x50", "200x100", "500x250", "1000x500"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[1])
    parser.add_argument("--arithmetics", nargs="+", default=["float", "certified", "exact"],
                        help="float, exact, certified, certified:BITS, certified:BITS/LATE (late_precision "
                             "LATE), or float@E (the float criterion with resolution E: the counts N_e)")
    parser.add_argument("--limit", type=float, default=1800.0, help="CPU seconds a run may take (default 30 min)")
    parser.add_argument("--json", type=Path, help="also write every row to this file, as JSON")
    parser.add_argument("--tree", type=Path, action="append", default=[],
                        help="another copy of the package (a directory holding pinnedballs/), in turns with this one")
    parser.add_argument("--rounds", type=int, default=1,
                        help="run everything this many times, the trees in turns, and print the medians")
    args = parser.parse_args()
    trees = [ROOT, *(t.resolve() for t in args.tree)]
    for tree in trees:
        if not (tree / "pinnedballs" / "__init__.py").is_file():
            parser.error(f"--tree {tree}: holds no pinnedballs/__init__.py")
    sys.path.insert(0, str(ROOT))
    from pinnedballs.util.provenance import cpu_line
    print(cpu_line())
    rows = []
    print(f"{'size':>9} {'arithmetic':>14} {'CPU':>11} {'/float':>8} {'collisions':>13} {'steps':>15} {'peak':>11}")
    for size in args.sizes:
        for seed in args.seeds:
            for _ in range(args.rounds):
                for tree in trees:
                    floats = None
                    for spec in args.arithmetics:
                        r = measure(size, seed, spec, args.limit, tree)
                        floats = r if spec == "float" else floats  # the ratios are to the default criterion's run
                        name = f"{size}/{seed}" if len(args.seeds) > 1 else size
                        print(row(name, spec, r, floats) + (f"  [{tree}]" if len(trees) > 1 else ""), flush=True)
                        rows.append({"size": size, "seed": seed, "arithmetic": spec, "tree": str(tree), **r})
                    if args.json is not None:
                        args.json.write_text(json.dumps(rows, indent=1))
    if args.rounds > 1:
        print_medians(rows)


def print_medians(rows: list[dict]) -> None:
    """The median CPU seconds of each size, seed, tree and arithmetic over the rounds, and its spread."""
    print("\nmedians over the rounds (min-max):")
    runs: dict[tuple, list[float]] = {}
    for r in rows:
        if "seconds" in r:
            runs.setdefault((r["size"], r["seed"], r["tree"], r["arithmetic"]), []).append(r["seconds"])
    for (size, seed, tree, spec), seconds in runs.items():
        median, spread = statistics.median(seconds), f"{min(seconds):.3f}-{max(seconds):.3f}, {len(seconds)} runs"
        print(f"{size:>9}/{seed} {spec:>14} {median:9.3f} s  ({spread})  [{tree}]")


if __name__ == "__main__":
    main()
