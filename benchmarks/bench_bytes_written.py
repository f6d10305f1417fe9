"""Bytes a run writes against the size of what it leaves: a 200x200 flat torus with 100 snapshots.

Runs the spec as ``pinnedballs run`` does (`runner.execute`, no figures) in a child process
and reads the child's ``wchar`` from ``/proc/self/io``: every byte it handed to ``write``,
temporary files included. The final size is the sum of the run directory's files.
Target (issue 9): written <= 3 x final. Format 1 copied the whole file at each checkpoint.

    python benchmarks/bench_bytes_written.py             # checkpoints as the spec's default (60 s, and after snapshots)
    python benchmarks/bench_bytes_written.py --every 0   # a checkpoint after every chunk (the worst case)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_CHILD = r"""
import json, sys, time
from pathlib import Path
from pinnedballs.run import execute as runner
from pinnedballs.specs import parse_spec

def wchar():
    return int(dict(line.split(": ") for line in open("/proc/self/io").read().splitlines())["wchar"])

spec, out = parse_spec(json.loads(sys.argv[1])), Path(sys.argv[2])
sim = spec.build()  # compile and build before counting
before, t0 = wchar(), time.perf_counter()
runner.execute(spec, out, figures=False, progress=False)
written, seconds = wchar() - before, time.perf_counter() - t0
final = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
print(json.dumps({"written": written, "final": final, "seconds": seconds}))
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=200)
    parser.add_argument("--snapshots", type=int, default=100)
    parser.add_argument("--every-steps", type=int, default=100_000)
    parser.add_argument("--every", type=float, default=60.0, help="checkpoint every_seconds")
    args = parser.parse_args()
    spec = {"geometry": {"kind": "flat_torus", "rows": args.rows, "cols": args.rows},
            "initial": {"kind": "single_ball", "ball": 0, "direction": [1, 0], "energy": 100},
            "stop": {"steps": args.snapshots * args.every_steps},
            "snapshots": {"every_steps": args.every_steps}, "checkpoint": {"every_seconds": args.every}, "seed": 1}
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        done = subprocess.run([sys.executable, "-c", _CHILD, json.dumps(spec), str(Path(tmp) / "run")], env=env,
                              check=True, capture_output=True, text=True)
    r = json.loads(done.stdout.strip().splitlines()[-1])
    mb = 1e6
    print(f"{args.rows}x{args.rows} torus, {args.snapshots} snapshots every {args.every_steps:,} steps, "
          f"checkpoint every {args.every:g} s: wrote {r['written'] / mb:,.1f} MB for a final "
          f"{r['final'] / mb:,.1f} MB: {r['written'] / r['final']:.2f}x (target <= 3x); run {r['seconds']:.1f} s")


if __name__ == "__main__":
    main()
