"""Speed of the compiled loop against the C yardstick, compile time, and peak memory.

Runs UniformRandomPair + Elastic on a periodic triangular lattice (the paper's
torus, one moving ball with energy 100; on 1000x1000 also Gaussian velocities, equilibrium)
and, in the same run, the plain C loop
``benchmarks/c/reference.sh`` on the same sizes. Each measurement runs in its
own process, so compile time and peak RSS belong to that measurement alone.

    python benchmarks/bench_chain.py                # 38x38 (50M steps), 1000x1000 single and Gaussian (200M)
    python benchmarks/bench_chain.py --quick        # 5M and 20M steps
    python benchmarks/bench_chain.py --markdown     # also print a table for docs/performance.md
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "benchmarks" / "c" / "reference.sh"

_CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
import numpy as np
import pinnedballs as pb
t_import = time.perf_counter() - t0
rows, cols, steps = map(int, sys.argv[1:4])
start = sys.argv[4]
t0 = time.perf_counter()
geom = pb.FlatTorus(rows, cols)
_ = geom.contacts
t_geometry = time.perf_counter() - t0
if start == "gaussian":                         # equilibrium: i.i.d. normal components
    v = np.random.default_rng(1).normal(size=(geom.n_balls, 2))
else:
    v = np.zeros((geom.n_balls, 2))
    v[0, 0] = np.sqrt(200.0)                    # energy 100, as in the paper
sim = pb.Simulation(geom, v, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=1)
t0 = time.perf_counter()
sim.run(steps=1)                                # compiles, or loads numba's disk cache
t_first = time.perf_counter() - t0
t0 = time.perf_counter()
sim.run(steps=steps)
t_run = time.perf_counter() - t0
print(json.dumps(dict(n=geom.n_balls, steps=steps, collisions=sim.collisions, energy=sim.energy(),
                      msteps=steps / t_run / 1e6, run_s=t_run, first_call_s=t_first, import_s=t_import,
                      geometry_s=t_geometry, peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)))
"""


def run_python(rows: int, cols: int, steps: int, cache_dir: str | None = None, start: str = "single") -> dict:
    """One measurement in a fresh process; ``cache_dir`` set means numba starts with an empty cache."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", _CHILD, str(rows), str(cols), str(steps), start],
                         capture_output=True, text=True, check=True, env=env, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_reference(rows: int, cols: int, steps: int, start: str = "single") -> dict:
    out = subprocess.run(["bash", str(REFERENCE), str(rows), str(cols), str(steps), start],
                         capture_output=True, text=True, check=True)
    fields = dict(re.findall(r"(\S+)=(\S+)", out.stdout))
    return dict(msteps=float(fields["Msteps/s"]), collisions=int(fields["collisions"]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps (a smoke run, not the figures)")
    parser.add_argument("--repeats", type=int, default=3, help="best of this many runs of each (default 3)")
    parser.add_argument("--markdown", action="store_true", help="also print a markdown table")
    args = parser.parse_args(argv)
    sizes = [(38, 38, 5_000_000 if args.quick else 50_000_000, "single"),
             (1000, 1000, 20_000_000 if args.quick else 200_000_000, "single"),
             (1000, 1000, 20_000_000 if args.quick else 200_000_000, "gaussian")]

    with tempfile.TemporaryDirectory() as empty_cache:
        cold = run_python(38, 38, 1000, cache_dir=empty_cache)
    print(f"compile (empty numba cache, first call): {cold['first_call_s']:.2f} s; "
          f"import pinnedballs: {cold['import_s']:.2f} s")
    rows = []
    for r, c, steps, start in sizes:
        ours = max((run_python(r, c, steps, start=start) for _ in range(args.repeats)), key=lambda d: d["msteps"])
        ref = max((run_reference(r, c, steps, start) for _ in range(args.repeats)), key=lambda d: d["msteps"])
        ratio = ours["msteps"] / ref["msteps"]
        rows.append((r, c, steps, start, ours, ref, ratio))
        print(f"{r}x{c} torus ({start}), {steps:,} steps: pinnedballs {ours['msteps']:.1f} Msteps/s "
              f"(first call {ours['first_call_s']:.2f} s from cache, geometry {ours['geometry_s']:.2f} s, "
              f"peak RSS {ours['peak_rss_mb']:.0f} MB, {ours['collisions']:,} collisions, "
              f"energy {ours['energy']:.12f}); "
              f"C reference {ref['msteps']:.1f} Msteps/s; ratio {ratio:.2f}", flush=True)
    if args.markdown:
        print("\n| lattice | start | steps | pinnedballs Msteps/s | C Msteps/s | ratio | peak RSS MB | geometry s |")
        print("|---|---|---|---|---|---|---|---|")
        for r, c, steps, start, ours, ref, ratio in rows:
            print(f"| {r}x{c} | {start} | {steps:,} | {ours['msteps']:.1f} | {ref['msteps']:.1f} | {ratio:.2f} | "
                  f"{ours['peak_rss_mb']:.0f} | {ours['geometry_s']:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
