"""What the collision log costs per collision: CPU time of a run with and without `pb.CollisionLog`.

The paper's half-plane (one boundary ball sent inward, energy 100, seed 7) run until frozen twice
in a fresh process each (after a warm-up that loads the loops): once plain, once writing every
collision's step and contact to ``events.h5``; the difference divided by the collisions.

    python benchmarks/bench_collision_log.py               # 200x100 and 500x250
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys, tempfile, time
import numpy as np
import pinnedballs as pb
length, depth, logged = float(sys.argv[1]), float(sys.argv[2]), sys.argv[3] == "log"
half = pb.HalfPlane.from_size(length, depth)
v = np.zeros((half.n_balls, 2))
b = half.boundary_center()
v[b] = -np.sqrt(200.0) * half.boundary.outward[b]
warm = pb.Simulation(half, v, seed=7)
warm.run_until_frozen(1000, writers=[pb.CollisionLog(tempfile.mkdtemp() + "/w.h5")] if logged else None)
sim = pb.Simulation(half, v, seed=7)
writers = [pb.CollisionLog(tempfile.mkdtemp() + "/events.h5")] if logged else None
t = time.process_time()
sim.run_until_frozen(10**12, writers=writers)
print(json.dumps(dict(cpu=time.process_time() - t, steps=sim.steps, collisions=sim.collisions)))
"""


def measure(length: float, depth: float, mode: str) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(length), str(depth), mode], capture_output=True, text=True,
                         cwd=ROOT, check=True)
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["200x100", "500x250"], help="LENGTHxDEPTH")
    args = parser.parse_args()
    for size in args.sizes:
        length, depth = (float(x) for x in size.split("x"))
        plain, logged = measure(length, depth, "plain"), measure(length, depth, "log")
        assert (plain["steps"], plain["collisions"]) == (logged["steps"], logged["collisions"])
        per = (logged["cpu"] - plain["cpu"]) / plain["collisions"] * 1e9
        print(f"{size} half-plane: {plain['collisions']:,} collisions; CPU plain {plain['cpu']:.2f} s, with the log "
              f"{logged['cpu']:.2f} s: {per:.1f} ns per collision logged", flush=True)


if __name__ == "__main__":
    main()
