"""What freeze detection costs: CPU time of ``run_until_frozen`` against ``run(steps=S)`` for the same S.

On the paper's half-plane (one boundary ball sent inward with energy 100, seed 7) at each size:
a fresh simulation runs until frozen (S steps, C collisions), another fresh one runs exactly S
steps; both must end in the same state, bit for bit. The ratio of their CPU times is the price of
detecting the freeze (the issue's target: at most 1.15 on 1000x500). Each size runs in its own
process, after a warm-up run that loads (or compiles) the loops.

    python benchmarks/bench_freeze.py                      # 200x100, 500x250, 1000x500
    python benchmarks/bench_freeze.py --sizes 200x100 --chunks 1 2 4 8 16   # chunk length per contact
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys, time
import numpy as np
import pinnedballs as pb
from pinnedballs.engine.sequential import loops

length, depth, chunk, seed = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
if chunk:
    loops.FREEZE_CHUNK_PER_CONTACT = chunk
half = pb.HalfPlane.from_size(length, depth)
v = np.zeros((half.n_balls, 2))
b = half.boundary_center()
v[b] = -np.sqrt(200.0) * half.boundary.outward[b]

def fresh():
    return pb.Simulation(half, v, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=seed)

warm = fresh()                       # loads (or compiles) every loop used below
warm.run_until_frozen(max_steps=1000)
warm.run(steps=1000)
frozen = fresh()
t = time.process_time()
assert frozen.run_until_frozen(max_steps=10**13)
t_frozen = time.process_time() - t
plain = fresh()
t = time.process_time()
plain.run(steps=frozen.steps)
t_steps = time.process_time() - t
assert plain.get_state().identical(frozen.get_state()) and plain.is_frozen()
print(json.dumps(dict(balls=half.n_balls, contacts=half.n_contacts, steps=frozen.steps, collisions=frozen.collisions,
                      chunk_per_contact=loops.FREEZE_CHUNK_PER_CONTACT, cpu_frozen=t_frozen, cpu_steps=t_steps,
                      ratio=t_frozen / t_steps)))
"""


def measure(length: float, depth: float, chunk: int, seed: int) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, str(length), str(depth), str(chunk), str(seed)],
                         capture_output=True, text=True, cwd=ROOT, check=True)
    return json.loads(out.stdout)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["200x100", "500x250", "1000x500"], help="LENGTHxDEPTH")
    parser.add_argument("--chunks", nargs="+", type=int, default=[0],
                        help="steps per contact in an untracked chunk (0: the engine's default)")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    for size in args.sizes:
        length, depth = (float(x) for x in size.split("x"))
        for chunk in args.chunks:
            r = measure(length, depth, chunk, args.seed)
            print(f"{size} half-plane ({r['balls']:,} balls, {r['contacts']:,} contacts), "
                  f"chunk {r['chunk_per_contact']} per contact: {r['steps']:,} steps, {r['collisions']:,} collisions "
                  f"to frozen; CPU until frozen {r['cpu_frozen']:.2f} s, run(steps=S) {r['cpu_steps']:.2f} s, "
                  f"ratio {r['ratio']:.3f}", flush=True)


if __name__ == "__main__":
    main()
