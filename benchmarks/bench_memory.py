"""Peak memory of a 1000x1000 torus run, stage by stage: where a run's megabytes go.

Each stage runs in a fresh process that goes through every stage before it and prints its peak
resident set (``ru_maxrss``): so the peak after "Simulation" is the most the process held up to
and including building the simulation. The stages: python with numpy; ``import pinnedballs``; the
geometry and its contact tables; the `Simulation`; its first ``run(steps=...)`` (the loop loaded,
the lattice's row pattern built); and a ``run_until_frozen`` (which asks whether a torus can
freeze). A second pass, in one process, gives the Python and numpy allocations of each stage
(tracemalloc: what a stage keeps and its peak above what it started with; numba's own
allocations in compiled code are not seen). Last, what each heavy module costs to import on its own
(numpy and the module, in a fresh process), and which of them ``import pinnedballs`` loads.

    python benchmarks/bench_memory.py                       # 1000x1000
    python benchmarks/bench_memory.py --rows 500 --cols 500
    python benchmarks/bench_memory.py --tree /tmp/old       # also another copy of the package, same stages
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

STAGES = ("python + numpy", "import pinnedballs", "geometry + contacts", "Simulation", "run(steps)",
          "run_until_frozen")

_CHILD = r"""
import json, resource, sys, time, tracemalloc, warnings
stage, rows, cols, steps, traced = (int(a) for a in sys.argv[1:6])
marks = []
def mark(name, t0):
    cur, peak = tracemalloc.get_traced_memory() if traced else (0, 0)
    marks.append(dict(stage=name, rss=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                      kept=(cur - mark.cur) / 1e6, peak=(peak - mark.cur) / 1e6, s=time.perf_counter() - t0))
    mark.cur = cur
    if traced:
        tracemalloc.reset_peak()
mark.cur = 0
if traced:
    tracemalloc.start()
t0 = time.perf_counter()
import numpy as np
mark("python + numpy", t0)
if stage >= 1:
    t0 = time.perf_counter()
    import pinnedballs as pb
    mark("import pinnedballs", t0)
if stage >= 2:
    t0 = time.perf_counter()
    geom = pb.FlatTorus(rows, cols)
    _ = geom.contacts
    mark("geometry + contacts", t0)
if stage >= 3:
    t0 = time.perf_counter()
    v = np.zeros((geom.n_balls, 2))
    v[0, 0] = np.sqrt(200.0)                     # energy 100, as in the paper
    sim = pb.Simulation(geom, v, seed=1)
    mark("Simulation", t0)
if stage >= 4:
    t0 = time.perf_counter()
    sim.run(steps=steps)
    mark("run(steps)", t0)
if stage >= 5:
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # a torus never freezes, and says so
        sim.run_until_frozen(max_steps=steps)
    mark("run_until_frozen", t0)
heavy = [m for m in ("scipy", "scipy.stats", "matplotlib", "pandas", "dask", "h5py", "networkx", "numba", "gmpy2",
                     "tqdm", "ipywidgets", "sympy") if m in sys.modules]
print(json.dumps(dict(marks=marks, heavy=heavy)))
"""

HEAVY = ("numba", "scipy.stats", "h5py", "networkx", "gmpy2", "matplotlib.pyplot", "pandas", "dask")


def child(tree: Path, stage: int, rows: int, cols: int, steps: int, traced: bool) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(stage), str(rows), str(cols), str(steps), str(int(traced))],
                         capture_output=True, text=True, env=dict(os.environ, PYTHONPATH=str(tree)), cwd=tree)
    if out.returncode:
        raise SystemExit(f"{tree}: stage {stage} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def import_cost(module: str) -> float | None:
    """Peak RSS in MB of a fresh python that imports numpy and ``module`` (None: not installed)."""
    code = f"import resource, numpy, {module}; print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    return float(out.stdout) if out.returncode == 0 else None


def report(tree: Path, rows: int, cols: int, steps: int) -> None:
    print(f"\n{tree}: {rows}x{cols} torus, {steps:,} steps")
    child(tree, len(STAGES) - 1, rows, cols, 1000, False)  # numba's cache filled: no stage below compiles
    peaks = [child(tree, k, rows, cols, steps, False)["marks"][-1]["rss"] for k in range(len(STAGES))]
    traced = child(tree, len(STAGES) - 1, rows, cols, steps, True)
    print("| stage | peak RSS MB (fresh process) | + MB | traced: kept MB | traced: peak above its start MB | s |")
    print("|---|---|---|---|---|---|")
    before = 0.0
    for name, peak, m in zip(STAGES, peaks, traced["marks"]):
        print(f"| {name} | {peak:.0f} | {peak - before:+.0f} | {m['kept']:.1f} | {m['peak']:.1f} | {m['s']:.2f} |")
        before = peak
    print(f"heavy modules loaded by the end: {', '.join(traced['heavy'])}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=1000)
    parser.add_argument("--cols", type=int, default=1000)
    parser.add_argument("--steps", type=int, default=1_000_000, help="steps of each run stage (default 1,000,000)")
    parser.add_argument("--tree", type=Path, action="append", default=[],
                        help="another copy of the package (a directory holding pinnedballs/) to measure too")
    args = parser.parse_args(argv)
    for tree in [ROOT] + [t.resolve() for t in args.tree]:
        report(tree, args.rows, args.cols, args.steps)
    base = import_cost("sys")
    print(f"\nimport cost of each heavy module alone (numpy and it, fresh process; numpy alone {base:.0f} MB):")
    for module in HEAVY:
        cost = import_cost(module)
        print(f"  {module}: " + ("not installed" if cost is None else f"{cost:.0f} MB (+{cost - base:.0f})"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
