"""RejectionFree against UniformRandomPair: the paper's half-planes run until frozen.

Both run the paper's set-up (one boundary ball moving into the others, energy 100)
until no contact approaches; same law of steps and collisions, so the numbers of
steps and collisions agree in distribution, and the wall times compare the loops.
The C yardstick (``benchmarks/c/reference.sh``, the paper's chain on the 38x38
torus) runs in the same session, to say how busy the machine was. Each
measurement runs in a fresh process, after compiling on a tiny half-plane.

    python benchmarks/bench_rejection_free.py            # 500x250 and 1000x500 (several minutes)
    python benchmarks/bench_rejection_free.py --quick    # 100x50 and 200x100
    python benchmarks/bench_rejection_free.py --sizes 2000x1000 --seed 7   # about 25 minutes

Seconds are CPU seconds of the run (``time.process_time``), which a busy machine inflates less
than wall seconds; `UniformRandomPair` runs until frozen untracked (chunks and a scan, issue 17),
`RejectionFree` keeps its live set exact, collision by collision.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "benchmarks" / "c" / "reference.sh"

_CHILD = r"""
import json, sys, time
import numpy as np
import pinnedballs as pb
length, depth, kind, seed = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], int(sys.argv[4])
scheduler = {"rejection_free": pb.RejectionFree, "uniform": pb.UniformRandomPair}[kind]()
def start(geom):
    v = np.zeros((geom.n_balls, 2))
    v[geom.boundary_center()] = [0.0, np.sqrt(200.0)]   # energy 100, into the balls
    return pb.Simulation(geom, v, scheduler=scheduler, seed=seed)
start(pb.HalfPlane(rows=4, cols=4)).run_until_frozen(max_steps=10**6)   # compile or load the loop
sim = start(pb.HalfPlane.from_size(length, depth))
t0, c0 = time.perf_counter(), time.process_time()
frozen = sim.run_until_frozen(max_steps=10**14)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(balls=sim.geometry.n_balls, contacts=sim.geometry.n_contacts, frozen=frozen,
                      steps=sim.steps, collisions=sim.collisions, energy=sim.energy(), seconds=cpu, wall=wall)))
"""


def run_python(length: int, depth: int, kind: str, seed: int) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(length), str(depth), kind, str(seed)],
                         capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_reference(steps: int) -> float:
    """Msteps/s of the C paper chain on the 38x38 torus."""
    out = subprocess.run(["bash", str(REFERENCE), "38", "38", str(steps)], capture_output=True, text=True, check=True)
    return float(dict(re.findall(r"(\S+)=(\S+)", out.stdout))["Msteps/s"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller half-planes (a smoke run, not the figures)")
    parser.add_argument("--sizes", nargs="+", metavar="LxD", help="half-planes to run (default 500x250 1000x500)")
    parser.add_argument("--seed", type=int, default=1, help="the seed of every run (default 1)")
    args = parser.parse_args(argv)
    sizes = [(100, 50), (200, 100)] if args.quick else [(500, 250), (1000, 500)]
    if args.sizes:
        sizes = [tuple(int(x) for x in size.lower().split("x")) for size in args.sizes]
    c_steps = 5_000_000 if args.quick else 50_000_000
    print(f"C yardstick (paper chain, 38x38 torus) before: {run_reference(c_steps):.1f} Msteps/s", flush=True)
    print("| half-plane | balls | scheduler | steps | collisions | CPU s | wall s | ns per collision | speed-up |")
    print("|---|---|---|---|---|---|---|---|---|")
    for length, depth in sizes:
        fast = run_python(length, depth, "rejection_free", args.seed)
        slow = run_python(length, depth, "uniform", args.seed)
        assert fast["frozen"] and slow["frozen"]
        for name, r in [("UniformRandomPair", slow), ("RejectionFree", fast)]:
            gain = slow["seconds"] / r["seconds"]
            per = 1e9 * r["seconds"] / r["collisions"]
            print(f"| {length}x{depth} | {r['balls']:,} | {name} | {r['steps']:,} | {r['collisions']:,} | "
                  f"{r['seconds']:.2f} | {r['wall']:.2f} | {per:.0f} | {gain:.2f}x |", flush=True)
    print(f"C yardstick after: {run_reference(c_steps):.1f} Msteps/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
