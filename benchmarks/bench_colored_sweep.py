"""ColoredSweep on 1 and 2 threads against the C paper chain, and a billion collisions.

The 1000x1000 torus at equilibrium (i.i.d. Gaussian velocities): ColoredSweep's
speed with NUMBA_NUM_THREADS=1 and 2 (same bits, tested), UniformRandomPair's, and
the C yardstick ``benchmarks/c/reference.sh 1000 1000 N gaussian`` (the
paper's chain in C in that regime) in the same run. Then the wall time of 1e9
collisions (the paper's "billions of collisions over millions of bodies") with
ColoredSweep on 2 threads and with UniformRandomPair, each running whole step
chunks until the collision count passes 1e9. Each measurement runs in a fresh
process, timed after the loop is compiled and the classes built.

    python benchmarks/bench_colored_sweep.py            # 10 sweeps; 1e9 collisions (several minutes)
    python benchmarks/bench_colored_sweep.py --quick    # 2 sweeps; 1e8 collisions
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "benchmarks" / "c" / "reference.sh"

_CHILD = r"""
import json, sys, time
import numba, numpy as np
import pinnedballs as pb
kind, steps, collisions = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
geom = pb.FlatTorus(1000, 1000)
v = np.random.default_rng(1).normal(size=(geom.n_balls, 2))
scheduler = {"colored": pb.ColoredSweep(), "uniform": pb.UniformRandomPair()}[kind]
t0 = time.perf_counter()
sim = pb.Simulation(geom, v, scheduler=scheduler, seed=1)
sim.run(steps=1)                                      # compile or load; ColoredSweep: build the classes
setup = time.perf_counter() - t0
chunk = steps if steps else 3 * geom.n_contacts
t0 = time.perf_counter()
while True:
    sim.run(steps=chunk)
    if not collisions or sim.collisions >= collisions:
        break
seconds = time.perf_counter() - t0
print(json.dumps(dict(threads=numba.get_num_threads(), steps=sim.steps - 1, collisions=sim.collisions,
                      seconds=seconds, setup=setup, msteps=(sim.steps - 1) / seconds / 1e6,
                      energy_drift=sim.energy() / float(0.5 * (v * v).sum()) - 1)))
"""


def run_python(kind: str, threads: int, steps: int = 0, collisions: int = 0) -> dict:
    env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
    out = subprocess.run([sys.executable, "-c", _CHILD, kind, str(steps), str(collisions)],
                         capture_output=True, text=True, check=True, cwd=ROOT, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_reference(steps: int) -> float:
    """Msteps/s of the C paper chain on the 1000x1000 torus with Gaussian velocities."""
    out = subprocess.run(["bash", str(REFERENCE), "1000", "1000", str(steps), "gaussian"],
                         capture_output=True, text=True, check=True)
    return float(dict(re.findall(r"(\S+)=(\S+)", out.stdout))["Msteps/s"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps (a smoke run, not the figures)")
    args = parser.parse_args(argv)
    contacts = 3_000_000
    sweeps = 2 if args.quick else 10
    target = 10**8 if args.quick else 10**9

    c_speed = run_reference(sweeps * contacts)
    one = run_python("colored", 1, steps=sweeps * contacts)
    two = run_python("colored", 2, steps=sweeps * contacts)
    uniform = run_python("uniform", 1, steps=sweeps * contacts)
    print(f"1000x1000 torus, Gaussian velocities, {sweeps * contacts:,} steps "
          f"(ColoredSweep setup {one['setup']:.1f} s: contacts, classes, loading the loop)")
    print("| loop | threads | Msteps/s | x C | collisions per step |")
    print("|---|---|---|---|---|")
    print(f"| C paper chain (reference.sh gaussian) | 1 | {c_speed:.1f} | 1.00 | |")
    for name, r in [("UniformRandomPair", uniform), ("ColoredSweep", one), ("ColoredSweep", two)]:
        print(f"| {name} | {r['threads']} | {r['msteps']:.1f} | {r['msteps'] / c_speed:.2f} | "
              f"{r['collisions'] / r['steps']:.3f} |")
    print(f"ColoredSweep 2 threads / 1 thread: {two['msteps'] / one['msteps']:.2f}x", flush=True)

    print(f"\n{target:.0e} collisions on the 1000x1000 torus (Gaussian start):")
    for name, kind, threads in [("ColoredSweep", "colored", 2), ("UniformRandomPair", "uniform", 1)]:
        r = run_python(kind, threads, collisions=target)
        print(f"  {name} on {threads} thread(s): {r['seconds']:.1f} s for {r['collisions']:,} collisions "
              f"({r['steps']:,} steps; relative energy drift {r['energy_drift']:.1e})", flush=True)
    print(f"C yardstick after: {run_reference(sweeps * contacts):.1f} Msteps/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
