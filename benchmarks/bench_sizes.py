"""The paper's chain by size and by thread count (issue 23): ns per step, and 2 threads against 1.

Part 1, one thread: `UniformRandomPair(threads=1)` on half-planes from 60x30 to 4000x2000 at a
Gaussian state (every contact a coin flip), ns per step (CPU time), with the row pattern (what the
engine runs) and without it (the ``(E, 2)`` tables it read before, prefetched): the cost per step
against 60x30's. Part 2, threads: the same chain with ``threads=1``, ``threads=2`` and the default
(tuned) on the largest sizes, wall time, idle and beside busy processes (a Python process spinning on
a core, as another user's job would). Each measurement runs in a fresh process after a warm-up that
loads the loops; the median of ``--repeats``; every thread count must end on the same velocities.

    python benchmarks/bench_sizes.py                              # both parts (about 10 minutes)
    python benchmarks/bench_sizes.py --part sizes --sizes 60x30 4000x2000
    python benchmarks/bench_sizes.py --part threads --sizes 2000x1000 4000x2000 --busy 0 1
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys, time
import numpy as np
import pinnedballs as pb
length, depth, steps = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
threads = None if sys.argv[4] == "tuned" else int(sys.argv[4])
tables = sys.argv[5] == "tables"
half = pb.HalfPlane.from_size(length, depth)
if tables:
    half.__dict__["row_pattern"] = None           # the loops read the (E, 2) tables instead
v = np.random.default_rng(1).normal(size=(half.n_balls, 2))
sim = pb.Simulation(half, v, seed=1, scheduler=pb.UniformRandomPair(threads=threads))
sim.run(steps=min(steps, 4_000_000))              # load the loops, fill the caches
t0, c0 = time.perf_counter(), time.process_time()
sim.run(steps=steps)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(balls=half.n_balls, contacts=half.n_contacts, steps=steps, wall=wall, cpu=cpu,
                      checksum=float(np.abs(sim.velocities).sum()) + sim.collisions)))
"""

_BUSY = "while True:\n    pass\n"

DEFAULT_SIZES = ["60x30", "500x250", "1000x500", "2000x1000", "4000x2000"]


def measure(size: str, steps: int, threads: str, source: str, busy: int) -> dict:
    length, depth = size.split("x")
    spinners = [subprocess.Popen([sys.executable, "-c", _BUSY]) for _ in range(busy)]
    try:
        out = subprocess.run([sys.executable, "-c", _CHILD, length, depth, str(steps), threads, source],
                             capture_output=True, text=True, check=True, cwd=ROOT)
    finally:
        for p in spinners:
            p.kill()
            p.wait()
    return json.loads(out.stdout.strip().splitlines()[-1])


def median_of(repeats: int, *args) -> dict:
    runs = [measure(*args) for _ in range(repeats)]
    if len({r["checksum"] for r in runs}) != 1:
        raise SystemExit(f"repeats differ: {[r['checksum'] for r in runs]}")
    return dict(runs[0], wall=statistics.median(r["wall"] for r in runs), cpu=statistics.median(r["cpu"] for r in runs),
                wall_low=min(r["wall"] for r in runs), wall_high=max(r["wall"] for r in runs))


def part_sizes(sizes: list[str], steps: int, repeats: int) -> None:
    print(f"One thread, Gaussian state, {steps:,} steps, CPU ns per step (median of {repeats})")
    print("| half-plane | balls | contacts | row pattern ns/step | x 60x30 | tables ns/step | x 60x30 |")
    print("|---|---|---|---|---|---|---|")
    first = {}
    for size in sizes:
        cells = []
        for source in ("rows", "tables"):
            r = median_of(repeats, size, steps, "1", source, 0)
            ns = r["cpu"] / steps * 1e9
            first.setdefault(source, ns)
            cells.append(f"{ns:.1f} | {ns / first[source]:.2f}")
        print(f"| {size} | {r['balls']:,} | {r['contacts']:,} | {' | '.join(cells)} |", flush=True)


def part_threads(sizes: list[str], steps: int, repeats: int, busy_counts: list[int]) -> None:
    print(f"Threads, Gaussian state, {steps:,} steps, wall ns per step (median of {repeats}, min-max); "
          f"{os.cpu_count()} cores")
    print("| half-plane | busy processes | 1 thread | 2 threads | tuned | 2 / 1 | tuned / 1 |")
    print("|---|---|---|---|---|---|---|")
    for size in sizes:
        for busy in busy_counts:
            runs = {t: median_of(repeats, size, steps, t, "rows", busy) for t in ("1", "2", "tuned")}
            if len({r["checksum"] for r in runs.values()}) != 1:
                raise SystemExit(f"{size}: the thread counts end on different velocities")
            ns = {t: r["wall"] / steps * 1e9 for t, r in runs.items()}
            print(f"| {size} | {busy} | {ns['1']:.1f} | {ns['2']:.1f} | {ns['tuned']:.1f} | {ns['1'] / ns['2']:.2f} | "
                  f"{ns['1'] / ns['tuned']:.2f} |", flush=True)
    print("the same velocities and counts on every thread count: yes")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=["sizes", "threads", "both"], default="both")
    parser.add_argument("--sizes", nargs="+", default=None, help="half-planes LxD (default: 60x30 ... 4000x2000; "
                                                                 "threads: 2000x1000 4000x2000)")
    parser.add_argument("--steps", type=float, default=2e8, help="steps per measurement")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--busy", type=int, nargs="+", default=[0, 1], help="busy processes beside the thread runs")
    args = parser.parse_args(argv)
    if args.part in ("sizes", "both"):
        part_sizes(args.sizes or DEFAULT_SIZES, int(args.steps), args.repeats)
    if args.part in ("threads", "both"):
        part_threads(args.sizes or ["2000x1000", "4000x2000"], int(args.steps), args.repeats, args.busy)
    return 0


if __name__ == "__main__":
    sys.exit(main())
