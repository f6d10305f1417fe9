"""ColoredSweep on 1 and 2 threads, on an idle machine and beside busy processes.

The 1000x1000 torus at equilibrium (i.i.d. Gaussian velocities), ``--sweeps`` sweeps of its
3,000,000 contacts, each measurement in a fresh process with ``NUMBA_NUM_THREADS`` set, timed after
the loop is loaded and the classes built; the median of ``--repeats``. A *busy process* is a
Python process spinning on one core for the whole measurement, as another user's job would.
The targets (issue 17): beside one busy process, 2 threads at least as fast as 1; idle, at least
1.6x. Each wait policy in ``--policies`` sets how numba's OpenMP threads wait at the end of a colour
class: ``pinnedballs`` is what importing pinnedballs sets (passive, `pinnedballs.engine.threads`),
``libgomp`` is libgomp's own default (spin a while, then sleep: the slow-down this benchmark was
written to measure), ``active`` spins without end; or give ``VAR=value,...`` to try others.

    python benchmarks/bench_parallel.py                          # 0, 1 and 2 busy processes; default and active
    python benchmarks/bench_parallel.py --busy 0 1 --policies default --repeats 5
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
import json, os, sys, time
import numba, numpy as np
import pinnedballs as pb
steps = int(sys.argv[1])
geom = pb.FlatTorus(1000, 1000)
v = np.random.default_rng(1).normal(size=(geom.n_balls, 2))
sim = pb.Simulation(geom, v, scheduler=pb.ColoredSweep(), seed=1)
if os.environ.get("BENCH_CHUNK"):                  # dynamic chunks of this many contacts
    numba.set_parallel_chunksize(int(os.environ["BENCH_CHUNK"]))
sim.run(steps=geom.n_contacts)                     # load the loop, build the classes
t0, c0 = time.perf_counter(), time.process_time()
sim.run(steps=steps)
wall = time.perf_counter() - t0
print(json.dumps(dict(threads=numba.get_num_threads(), layer=numba.threading_layer(),
                      policy=os.environ.get("OMP_WAIT_POLICY"), msteps=steps / wall / 1e6,
                      cores_used=(time.process_time() - c0) / wall, checksum=float(np.abs(sim.velocities).sum()))))
"""

_BUSY = "while True:\n    pass\n"

#: named wait policies (anything else: ``VAR=value,VAR=value``)
POLICIES = {
    "pinnedballs": {},                      # what importing pinnedballs sets: passive
    "libgomp": {"OMP_WAIT_POLICY": ""},     # libgomp's own default (spin a while, then sleep): before issue 17
    "active": {"OMP_WAIT_POLICY": "active"},  # spin, never sleep
}


def measure(threads: int, steps: int, policy: str, chunk: int = 0) -> dict:
    """One measurement in a fresh process."""
    env = {**os.environ, "NUMBA_NUM_THREADS": str(threads), "BENCH_CHUNK": str(chunk or "")}
    env.pop("OMP_WAIT_POLICY", None)
    env.pop("GOMP_SPINCOUNT", None)
    env.update(POLICIES[policy] if policy in POLICIES else dict(kv.split("=", 1) for kv in policy.split(",")))
    out = subprocess.run([sys.executable, "-c", _CHILD, str(steps)], capture_output=True, text=True, check=True,
                         cwd=ROOT, env=env)
    return json.loads(out.stdout.strip().splitlines()[-1])


def under_load(busy: int, threads: int, steps: int, policy: str, repeats: int, chunk: int = 0) -> dict:
    """The median of ``repeats`` measurements, each beside ``busy`` spinning processes."""
    runs = []
    for _ in range(repeats):
        spinners = [subprocess.Popen([sys.executable, "-c", _BUSY]) for _ in range(busy)]
        try:
            runs.append(measure(threads, steps, policy, chunk))
        finally:
            for p in spinners:
                p.kill()
                p.wait()
    if len({r["checksum"] for r in runs}) != 1:
        raise SystemExit(f"results differ between repeats: {[r['checksum'] for r in runs]}")
    rates = [r["msteps"] for r in runs]
    return dict(runs[0], msteps=statistics.median(rates), low=min(rates), high=max(rates),
                cores_used=statistics.median(r["cores_used"] for r in runs))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sweeps", type=int, default=100, help="sweeps of the 3,000,000 contacts per measurement")
    parser.add_argument("--repeats", type=int, default=3, help="measurements per cell (the median is shown)")
    parser.add_argument("--busy", type=int, nargs="+", default=[0, 1, 2], help="busy processes beside the run")
    parser.add_argument("--chunk", type=int, default=0,
                        help="numba.set_parallel_chunksize in the runs (0: numba's static split)")
    parser.add_argument("--policies", nargs="+", default=["pinnedballs", "libgomp"],
                        help=f"wait policies: {', '.join(POLICIES)}, or VAR=value,VAR=value")
    args = parser.parse_args(argv)
    steps = args.sweeps * 3_000_000
    print(f"ColoredSweep, 1000x1000 torus, Gaussian start, {steps:,} steps per measurement, "
          f"median of {args.repeats} (min-max); {os.cpu_count()} cores"
          + (f"; dynamic chunks of {args.chunk}" if args.chunk else ""))
    print("| wait policy | busy processes | 1 thread Msteps/s | 2 threads Msteps/s | 2 / 1 | cores used by 2 |")
    print("|---|---|---|---|---|---|")
    checksums = set()
    for policy in args.policies:
        for busy in args.busy:
            one = under_load(busy, 1, steps, policy, args.repeats, args.chunk)
            two = under_load(busy, 2, steps, policy, args.repeats, args.chunk)
            checksums |= {one["checksum"], two["checksum"]}
            name = f"{policy} ({two['policy'] or 'unset'})" if policy in POLICIES else policy
            print(f"| {name} | {busy} | {one['msteps']:.1f} ({one['low']:.0f}-{one['high']:.0f}) | "
                  f"{two['msteps']:.1f} ({two['low']:.0f}-{two['high']:.0f}) | {two['msteps'] / one['msteps']:.2f} | "
                  f"{two['cores_used']:.2f} |", flush=True)
    print(f"threading layer: {one['layer']}; the same velocities on 1 and 2 threads in every run: "
          f"{'yes' if len(checksums) == 1 else 'NO'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
