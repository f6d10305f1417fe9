"""The paper's chain on several threads: deterministic reservations on the counter stream against the
sequential loop, and against today's regions on the xoshiro stream, idle and beside busy processes.

Half-planes ``pb.HalfPlane.from_size(L, D)`` (2000x1000: 577,000 balls; 4000x2000: 2,310,000) with
Gaussian velocities. Each cell runs in a fresh process with ``NUMBA_NUM_THREADS`` the most threads
asked for; in it every configuration starts from the same velocities and seed, is warmed up (the loops
compiled, ``--warm`` steps) and timed over ``--steps`` steps; the median of ``--repeats`` processes.
Configurations: ``counter/1`` (the sequential loop on the counter stream), ``counter/k``
(`engine.threads.reservations` on ``k`` threads), ``counter/auto`` (the default: all threads, the count chosen
by `ThreadTuner`), and the same on the xoshiro stream (``xoshiro/k``: the regions of `engine.threads.regions`).
A *busy process* spins on one core for the whole measurement, as another user's job would. Ratios
are to one thread of the same stream. Targets (issue): 2 idle cores at least 1.3x one thread, beside a
busy process at least 0.95x, 16 cores at least 6x.

    python benchmarks/bench_reservations.py
    python benchmarks/bench_reservations.py --sizes 2000x1000 --threads 2 4 8 16 --busy 0 --repeats 1

Another script can call `measure` (one process per cell) and print with `table`.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_BUSY = "while True:\n    pass\n"


def _busy_seconds() -> float | None:
    """CPU seconds every process on the machine has used (Linux's /proc/stat), or None."""
    try:
        with open("/proc/stat") as f:
            fields = [int(x) for x in f.readline().split()[1:]]
    except OSError:
        return None
    return (sum(fields) - fields[3] - fields[4]) / os.sysconf("SC_CLK_TCK")  # all but idle and iowait


def _child(size: tuple[int, int], configs: list[tuple[str, int | None]], steps: int, warm: int,
           rounds: int) -> list[dict]:
    """In a process of its own: every configuration on the same half-plane, velocities and seed, warmed
    up, then timed ``rounds`` times in turn over ``steps`` steps (the machine's drift shared alike);
    the median round of each."""
    import numba
    import numpy as np

    import pinnedballs as pb

    geometry = pb.HalfPlane.from_size(*size)
    v = np.random.default_rng(1).normal(size=(geometry.n_balls, 2))
    sims = [pb.Simulation(geometry, v.copy(), scheduler=pb.UniformRandomPair(threads=threads, stream=stream), seed=3)
            for stream, threads in configs]
    for sim in sims:
        sim.run(steps=warm)  # compiles the loops, builds the chain
    times = [[] for _ in sims]
    for _ in range(rounds):
        for sim, timed in zip(sims, times):
            wall, cpu, machine = time.perf_counter(), time.process_time(), _busy_seconds()
            sim.run(steps=steps)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            others = None if machine is None else max(0.0, (_busy_seconds() - machine - cpu) / wall)
            timed.append((wall / steps * 1e9, cpu / wall, others))
    rows = []
    for (stream, threads), sim, timed in zip(configs, sims, times):
        ns, cores, others = sorted(timed)[len(timed) // 2]
        rows.append(dict(size=f"{size[0]}x{size[1]}", balls=geometry.n_balls, stream=stream,
                         threads="auto" if threads is None else threads, ns_per_step=ns, cores_used=cores,
                         others=others, most=numba.config.NUMBA_NUM_THREADS,
                         checksum=hashlib.sha1(sim.velocities.tobytes()
                                               + sim.get_state().rng_state.tobytes()).hexdigest()))
    return rows


def _configs(threads: list[int]) -> list[tuple[str, int | None]]:
    return [(stream, k) for stream in ("counter", "xoshiro") for k in [1, *threads, None]]


def measure(sizes: list[tuple[int, int]], threads: list[int], steps: int, busy: int = 0, repeats: int = 1,
            warm: int = 2_000_000, rounds: int = 5) -> list[dict]:
    """For each size, the sequential loop, the chain on each thread count in ``threads`` and the default
    (tuned) on both streams, timed ``rounds`` times in turn over ``steps`` steps in each of ``repeats``
    processes, beside ``busy`` spinning processes: one dict a
    configuration (size, balls, stream, threads, ns_per_step (median of ``repeats`` processes), low,
    high, cores_used (by the run), others (cores the rest of the machine used meanwhile, the most of the
    repeats: the busy processes and whatever else ran), ratio to one thread of the same stream, busy,
    same_bits (every thread count left the same velocities and stream as one thread))."""
    out = []
    for size in sizes:
        runs = []
        for _ in range(repeats):
            env = {**os.environ, "NUMBA_NUM_THREADS": str(max([1, *threads]))}
            spinners = [subprocess.Popen([sys.executable, "-c", _BUSY]) for _ in range(busy)]
            try:
                done = subprocess.run([sys.executable, __file__, "--child",
                                       json.dumps([size, threads, steps, warm, rounds])],
                                      capture_output=True, text=True, cwd=ROOT, env=env)
            finally:
                for p in spinners:
                    p.kill()
                    p.wait()
            if done.returncode:
                raise SystemExit(done.stderr)
            runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
        for c, first in enumerate(runs[0]):
            rates = [run[c]["ns_per_step"] for run in runs]
            out.append(dict(first, ns_per_step=statistics.median(rates), low=min(rates), high=max(rates), busy=busy,
                            cores_used=statistics.median(run[c]["cores_used"] for run in runs),
                            others=max((run[c]["others"] or 0.0) for run in runs)))
        for row in out[-len(runs[0]):]:
            one = next(r for r in out[-len(runs[0]):] if r["stream"] == row["stream"] and r["threads"] == 1)
            row["ratio"] = one["ns_per_step"] / row["ns_per_step"]
            row["same_bits"] = row["checksum"] == one["checksum"]
    return out


def table(rows: list[dict]) -> str:
    """The rows as a markdown table."""
    lines = ["| size | busy | stream | threads | ns/step (min-max) | x one thread | cores used | others' cores "
             "| same bits |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        chain = "sequential" if r["threads"] == 1 else ("reservations" if r["stream"] == "counter" else "regions")
        lines.append(f"| {r['size']} | {r['busy']} | {r['stream']} ({chain}) | {r['threads']} | "
                     f"{r['ns_per_step']:.2f} ({r['low']:.2f}-{r['high']:.2f}) | {r['ratio']:.2f} | "
                     f"{r['cores_used']:.2f} | {r['others']:.2f} | {'yes' if r['same_bits'] else 'NO'} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["2000x1000", "4000x2000"], help="half-planes L x D (radii)")
    parser.add_argument("--threads", type=int, nargs="+", default=[os.cpu_count() or 1],
                        help="thread counts of the threaded chains (default: every core)")
    parser.add_argument("--steps", type=int, default=20_000_000, help="steps of one timed round")
    parser.add_argument("--rounds", type=int, default=5, help="timed rounds of each configuration, in turn")
    parser.add_argument("--warm", type=int, default=2_000_000, help="steps run first, untimed")
    parser.add_argument("--busy", type=int, nargs="+", default=[0, 1], help="busy processes beside the run")
    parser.add_argument("--repeats", type=int, default=3, help="processes per cell (the median is shown)")
    args = parser.parse_args(argv)
    sizes = [tuple(int(x) for x in s.split("x")) for s in args.sizes]
    print(f"{os.cpu_count()} cores; each configuration timed {args.rounds} times over {args.steps:,} steps, in turn "
          f"with the others; the median round, then the median of {args.repeats} processes")
    for busy in args.busy:
        print(table(measure(sizes, args.threads, args.steps, busy, args.repeats, args.warm, args.rounds)), flush=True)
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        size, threads, steps, warm, rounds = json.loads(sys.argv[2])
        print(json.dumps(_child(tuple(size), _configs(threads), steps, warm, rounds)))
        sys.exit(0)
    sys.exit(main())
