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
    python benchmarks/bench_sizes.py --part torus                 # equal collision rates at every size, and C
    python benchmarks/bench_sizes.py --part torus-threads --busy 0 1
    python benchmarks/bench_sizes.py --part split                 # the parallel chain's whole work on one thread

A half-plane from a Gaussian state freezes: the longer the run and the smaller the system, the fewer
of its picks collide (60x30: none in 200M steps after a warm-up of 4M; 4000x2000: 0.46 of them), so
part 1 compares picks that do not collide on small systems with picks that do on large ones. The
tori keep every size at the same share of collisions (about 0.46), which isolates what the size
itself costs; the C yardstick runs the same chain on the same tori.
"""

from __future__ import annotations

import argparse
import concurrent.futures
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
if sys.argv[4] == "split":  # the parallel chain's regions (2), all run by one thread: its whole work
    import numba
    numba.set_num_threads(1)
    numba.set_num_threads = lambda n: None
threads = None if sys.argv[4] == "tuned" else 2 if sys.argv[4] == "split" else int(sys.argv[4])
tables = sys.argv[5] == "tables"
geometry = pb.FlatTorus(length, depth) if sys.argv[6] == "torus" else pb.HalfPlane.from_size(length, depth)
if tables:
    geometry.__dict__["row_pattern"] = None           # the loops read the (E, 2) tables instead
v = np.random.default_rng(1).normal(size=(geometry.n_balls, 2))
sim = pb.Simulation(geometry, v, seed=1, scheduler=pb.UniformRandomPair(threads=threads))
sim.run(steps=min(steps, 4_000_000))              # load the loops, fill the caches
t0, c0, made = time.perf_counter(), time.process_time(), sim.collisions
sim.run(steps=steps)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(balls=geometry.n_balls, contacts=geometry.n_contacts, steps=steps, wall=wall, cpu=cpu,
                      hits=(sim.collisions - made) / steps,
                      checksum=float(np.abs(sim.velocities).sum()) + sim.collisions)))
"""

_BUSY = "while True:\n    pass\n"

DEFAULT_SIZES = ["60x30", "500x250", "1000x500", "2000x1000", "4000x2000"]


def measure(size: str, steps: int, threads: str, source: str, busy: int, kind: str = "half_plane") -> dict:
    """One run in a fresh process: ``size`` is a half-plane's ``LxD`` or, with ``kind="torus"``, a
    flat torus's ``ROWSxCOLS``."""
    length, depth = size.split("x")
    spinners = [subprocess.Popen([sys.executable, "-c", _BUSY]) for _ in range(busy)]
    try:
        out = subprocess.run([sys.executable, "-c", _CHILD, length, depth, str(steps), threads, source, kind],
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
    print(f"One thread, half-planes from a Gaussian state, {steps:,} steps, CPU ns per step (median of {repeats}); "
          "collisions per step: a half-plane freezes, so small ones measure mostly picks that do not collide")
    print("| half-plane | balls | contacts | collisions per step | row pattern ns/step | x 60x30 | tables ns/step | "
          "x 60x30 |")
    print("|---|---|---|---|---|---|---|---|")
    first = {}
    for size in sizes:
        cells = []
        for source in ("rows", "tables"):
            r = median_of(repeats, size, steps, "1", source, 0)
            ns = r["cpu"] / steps * 1e9
            first.setdefault(source, ns)
            cells.append(f"{ns:.1f} | {ns / first[source]:.2f}")
        print(f"| {size} | {r['balls']:,} | {r['contacts']:,} | {r['hits']:.2g} | {' | '.join(cells)} |", flush=True)


#: flat tori with about the half-planes' numbers of balls (510 ... 2.31M)
TORUS_SIDES = ["24x21", "190x190", "380x380", "760x760", "1520x1520"]


def reference(size: str, steps: int) -> float:
    """ns per step of the C yardstick (`benchmarks/c/reference.sh`, Gaussian state) on the torus ``size``."""
    script = ROOT / "benchmarks" / "c" / "reference.sh"
    if not script.exists():
        return float("nan")
    rows, cols = size.split("x")
    out = subprocess.run(["bash", str(script), rows, cols, str(steps), "gaussian"], capture_output=True, text=True,
                         check=True).stdout
    return 1e3 / float(out.split("Msteps/s=")[1].split()[0])


def part_torus(sizes: list[str], steps: int, repeats: int) -> None:
    print(f"One thread, flat tori at equilibrium (Gaussian state: a torus never freezes, so every size collides on "
          f"the same share of its steps), {steps:,} steps, ns per step (median of {repeats}); the C yardstick "
          "(best of the same number of runs) on the same torus in the same run")
    print("| torus | balls | contacts | collisions per step | ns/step | x smallest | C ns/step | x smallest | "
          "ours / C |")
    print("|---|---|---|---|---|---|---|---|---|")
    first = {}
    for size in sizes:
        r = median_of(repeats, size, steps, "1", "rows", 0, "torus")
        ns = r["cpu"] / steps * 1e9
        c = min(reference(size, steps) for _ in range(repeats))
        first.setdefault("ours", ns), first.setdefault("c", c)
        print(f"| {size} | {r['balls']:,} | {r['contacts']:,} | {r['hits']:.2g} | {ns:.1f} | "
              f"{ns / first['ours']:.2f} | "
              f"{c:.1f} | {c / first['c']:.2f} | {ns / c:.2f} |", flush=True)


def side_by_side(size: str, steps: int, kind: str, repeats: int) -> float:
    """Two one-thread runs at once, one per core: their summed throughput against one run alone (medians
    of ``repeats``), what two cores give independent chains: the most a chain on two threads could gain."""
    alone = median_of(repeats, size, steps, "1", "rows", 0, kind)["wall"]
    sums = []
    for _ in range(repeats):
        with concurrent.futures.ThreadPoolExecutor(2) as pool:
            pair = list(pool.map(lambda _: measure(size, steps, "1", "rows", 0, kind)["wall"], range(2)))
        sums.append(sum(alone / w for w in pair))
    return statistics.median(sums)


def part_threads(sizes: list[str], steps: int, repeats: int, busy_counts: list[int], kind: str = "half_plane") -> None:
    what = "tori" if kind == "torus" else "half-planes"
    print(f"Threads, {what} from a Gaussian state, {steps:,} steps, wall ns per step (median of {repeats}); "
          f"{os.cpu_count()} cores; 'two runs': two one-thread runs at once against one alone (the ceiling)")
    print(f"| {kind.replace('_', '-')} | busy processes | collisions per step | 1 thread | 2 threads | tuned | 2 / 1 | "
          "tuned / 1 | two runs |")
    print("|---|---|---|---|---|---|---|---|---|")
    for size in sizes:
        for busy in busy_counts:
            runs = {t: median_of(repeats, size, steps, t, "rows", busy, kind) for t in ("1", "2", "tuned")}
            if len({r["checksum"] for r in runs.values()}) != 1:
                raise SystemExit(f"{size}: the thread counts end on different velocities")
            ns = {t: r["wall"] / steps * 1e9 for t, r in runs.items()}
            ceiling = f"{side_by_side(size, steps, kind, repeats):.2f}" if busy == 0 else ""
            print(f"| {size} | {busy} | {runs['1']['hits']:.2g} | {ns['1']:.1f} | {ns['2']:.1f} | {ns['tuned']:.1f} | "
                  f"{ns['1'] / ns['2']:.2f} | {ns['1'] / ns['tuned']:.2f} | {ceiling} |", flush=True)
    print("the same velocities and counts on every thread count: yes")


def part_split(sizes: list[str], steps: int, repeats: int) -> None:
    print(f"The parallel chain's work: its 2 regions' blocks run by one thread, against the sequential loop, "
          f"half-planes from a Gaussian state, {steps:,} steps, CPU ns per step (median of {repeats}); two threads "
          "can beat one only where the ratio is below 2")
    print("| half-plane | collisions per step | sequential ns/step | regions on one thread ns/step | ratio |")
    print("|---|---|---|---|---|")
    for size in sizes:
        one, split = (median_of(repeats, size, steps, t, "rows", 0) for t in ("1", "split"))
        if one["checksum"] != split["checksum"]:
            raise SystemExit(f"{size}: the split loop ends on other velocities")
        a, b = one["cpu"] / steps * 1e9, split["cpu"] / steps * 1e9
        print(f"| {size} | {one['hits']:.2g} | {a:.1f} | {b:.1f} | {b / a:.2f} |", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=["sizes", "torus", "threads", "torus-threads", "split", "both"],
                        default="both", help="both: sizes and threads (half-planes)")
    parser.add_argument("--sizes", nargs="+", default=None, help="half-planes LxD or tori RxC (default: 60x30 ... "
                                                                 "4000x2000; tori 24x21 ... 1520x1520; threads: "
                                                                 "2000x1000 4000x2000, tori 760x760 1520x1520)")
    parser.add_argument("--steps", type=float, default=2e8, help="steps per measurement")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--busy", type=int, nargs="+", default=[0, 1], help="busy processes beside the thread runs")
    args = parser.parse_args(argv)
    if args.part in ("sizes", "both"):
        part_sizes(args.sizes or DEFAULT_SIZES, int(args.steps), args.repeats)
    if args.part == "torus":
        part_torus(args.sizes or TORUS_SIDES, int(args.steps), args.repeats)
    if args.part in ("threads", "both"):
        part_threads(args.sizes or ["2000x1000", "4000x2000"], int(args.steps), args.repeats, args.busy)
    if args.part == "split":
        part_split(args.sizes or ["2000x1000", "4000x2000"], int(args.steps), args.repeats)
    if args.part == "torus-threads":
        part_threads(args.sizes or TORUS_SIDES[-2:], int(args.steps), args.repeats, args.busy, "torus")
    return 0


if __name__ == "__main__":
    sys.exit(main())
