"""The default thread count against one thread, in pairs of runs, beside busy processes (issues 49 and 51).

Each system runs twice a round, in fresh processes, one after the other: with the default (``UniformRandomPair()``,
``ColoredSweep()``: the ``threads`` engine, its count chosen by `ThreadTuner`) and with one thread
(``threads=1``), the order swapped every round; each prints its wall and CPU seconds (the whole process's CPU
time during the timed run, every thread's), the steps and collisions (which must agree: the bits never depend
on the count) and what the tuner chose. ``--busy N`` starts N processes that burn a core each for the whole
benchmark, as other users' jobs would. The table gives, per system, the median over the rounds of each run's
wall and CPU seconds, the ratio of the default's wall time to one thread's (per pair: its median, least and
most) and the default's CPU seconds over its wall seconds. Targets (issue 51, item 4): the default at most 1.05x
one thread's wall time, and its CPU at most 1.3x its wall unless it is at least 1.3x faster than one thread.

    python benchmarks/bench_threads_vs_one.py                          # all systems, 3 rounds, one busy process
    python benchmarks/bench_threads_vs_one.py --busy 0 --systems half500x250 --rounds 5
    python benchmarks/bench_threads_vs_one.py --tree /tmp/before       # another copy of the package, same turns

Systems: ``half500x250`` and ``half1000x500`` (the paper's half-plane from one moving ball to frozen, seed 2),
``torus38x38`` (the paper's torus, one ball of energy 100, 50M steps), ``sweep1000x1000`` (ColoredSweep on the
1000x1000 torus at equilibrium, 10 sweeps: 30M steps).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SYSTEMS = ("half500x250", "half1000x500", "torus38x38", "sweep1000x1000")

_CHILD = r"""
import json, sys, time
import numpy as np
import pinnedballs as pb
system, one = sys.argv[1], sys.argv[2] == "1"
threads = 1 if one else None
if system.startswith("half"):
    length, depth = map(float, system[4:].split("x"))
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    b = g.boundary_center()
    v[b] = -np.sqrt(200.0) * g.boundary.outward[b]
    make = lambda: pb.Simulation(g, v, seed=2, scheduler=pb.UniformRandomPair(threads=threads))
    make().run_until_frozen(max_steps=300_000, progress=False)   # compiles, or loads numba's disk cache
    sim = make()
    run = lambda: sim.run_until_frozen(max_steps=10**13, progress=False)
elif system.startswith("torus"):
    g = pb.FlatTorus(*map(int, system[5:].split("x")))
    v = np.zeros((g.n_balls, 2))
    v[0, 0] = np.sqrt(200.0)
    sim = pb.Simulation(g, v, seed=1, scheduler=pb.UniformRandomPair(threads=threads))
    sim.run(steps=1, progress=False)
    run = lambda: sim.run(steps=50_000_000, progress=False)
else:
    g = pb.FlatTorus(*map(int, system[5:].split("x")))
    v = np.random.default_rng(1).normal(size=(g.n_balls, 2))
    sim = pb.Simulation(g, v, seed=1, scheduler=pb.ColoredSweep(threads=threads))
    sim.run(steps=1, progress=False)                           # compiles; builds the colour classes
    run = lambda: sim.run(steps=10 * g.n_contacts, progress=False)
import warnings
warnings.simplefilter("ignore")
w, c = time.perf_counter(), time.process_time()
run()
wall, cpu = time.perf_counter() - w, time.process_time() - c
print(json.dumps(dict(wall=wall, cpu=cpu, steps=sim.steps, collisions=sim.collisions,
                      engine=getattr(sim, "engine_name", "?"),  # a --tree before 1.0 may not say
                      device=getattr(sim.engine, "resources", dict)(), file=pb.__file__)))
"""


def burner() -> subprocess.Popen:
    """A process that burns one core until killed (another user's job)."""
    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


def child(tree: Path, system: str, one: bool) -> dict:
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", _CHILD, system, "1" if one else "default"], capture_output=True,
                         text=True, env=env, cwd=tree)
    if out.returncode:
        raise SystemExit(f"{tree}: {system} failed:\n{out.stderr[-3000:]}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not Path(result["file"]).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"{tree}: imported pinnedballs from {result['file']}, not from this tree")
    return result


def spread(values: list[float]) -> str:
    return f"{statistics.median(values):.3f} ({min(values):.3f}-{max(values):.3f})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--systems", nargs="+", default=list(SYSTEMS), choices=SYSTEMS)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--busy", type=int, default=1, help="processes burning a core each (default 1)")
    parser.add_argument("--tree", type=Path, action="append", default=[],
                        help="another copy of the package (a directory holding pinnedballs/) in the same turns")
    parser.add_argument("--no-self", action="store_true", help="time only the --tree copies")
    args = parser.parse_args(argv)
    from pinnedballs.util.provenance import cpu_line

    trees = ([] if args.no_self else [ROOT]) + [t.resolve() for t in args.tree]
    print(cpu_line())
    print(f"{args.busy} busy process(es); load average before {os.getloadavg()[0]:.1f}; {args.rounds} rounds, "
          f"default and one thread in turns (order swapped each round); "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}", flush=True)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a kill still ends the busy processes
    busy = [burner() for _ in range(args.busy)]
    rows = []
    try:
        for tree in trees:
            name = "this checkout" if tree == ROOT else str(tree)
            for system in args.systems:
                child(tree, system, True)  # compile or load both outside the turns
                child(tree, system, False)
                runs: dict[bool, list[dict]] = {True: [], False: []}
                for r in range(args.rounds):
                    for one in ((False, True) if r % 2 == 0 else (True, False)):
                        runs[one].append(child(tree, system, one))
                    d, o = runs[False][-1], runs[True][-1]
                    if (d["steps"], d["collisions"]) != (o["steps"], o["collisions"]):
                        raise SystemExit(f"{system}: the default and one thread differ: {d} / {o}")
                    print(f"  {name} {system} round {r + 1}: default {d['wall']:.2f} s wall, {d['cpu']:.2f} s CPU "
                          f"({d['device']}); one thread {o['wall']:.2f} s wall, {o['cpu']:.2f} s CPU", flush=True)
                ratio = [d["wall"] / o["wall"] for d, o in zip(runs[False], runs[True])]
                usage = [d["cpu"] / d["wall"] for d in runs[False]]
                rows.append((name, system, runs, ratio, usage))
    finally:
        for p in busy:
            p.kill()
    print(f"load average after {os.getloadavg()[0]:.1f}")
    print("| tree | system | default wall s | default CPU s | one thread wall s | one thread CPU s | default / one "
          "(wall) | default CPU / wall |")
    print("|---|---|---|---|---|---|---|---|")
    for name, system, runs, ratio, usage in rows:
        med = {one: {k: statistics.median(r[k] for r in runs[one]) for k in ("wall", "cpu")} for one in runs}
        print(f"| {name} | {system} | {med[False]['wall']:.2f} | {med[False]['cpu']:.2f} | {med[True]['wall']:.2f} | "
              f"{med[True]['cpu']:.2f} | {spread(ratio)} | {spread(usage)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
