"""Instructions per step of the paper's chain, pinnedballs against the C yardstick (callgrind).

Seconds are noisy on a shared machine; instruction counts repeat exactly. Runs
UniformRandomPair + Elastic on the 38x38 torus (one ball of energy 100, seed 1)
under ``valgrind --tool=callgrind``, collecting only around ``sim.run(steps=N)``
(callgrind's client requests, through a tiny C library loaded with ctypes), and
the C loop ``benchmarks/c/ref_kernel.c`` at N and at 1,000 steps (the
difference is the loop alone). Needs valgrind, its headers and a C compiler.

    python benchmarks/bench_instructions.py             # N = 2,000,000 (about a minute)
    python benchmarks/bench_instructions.py --steps 200000
    python benchmarks/bench_instructions.py --start gaussian --tree /tmp/old   # at equilibrium; another copy too

``--start gaussian`` starts from i.i.d. normal velocities (equilibrium: about half the picks collide, so the
table loop runs its blocks without a branch). ``--tree DIR`` (repeatable) counts another copy of the
package too (a directory holding ``pinnedballs/``, e.g. ``git archive COMMIT pinnedballs | tar -x -C DIR``):
instruction counts compare two versions without the noise of seconds.
"""

from __future__ import annotations

import argparse
import glob
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
C_SOURCE = ROOT / "benchmarks" / "c" / "ref_kernel.c"

_CONTROL = r"""
#include <valgrind/callgrind.h>
void cg_start(void) { CALLGRIND_START_INSTRUMENTATION; CALLGRIND_ZERO_STATS; }
void cg_stop(void) { CALLGRIND_DUMP_STATS; CALLGRIND_STOP_INSTRUMENTATION; }
"""

_CHILD = r"""
import ctypes, sys
import numpy as np
import pinnedballs as pb
control = ctypes.CDLL(sys.argv[1])
steps = int(sys.argv[2])
geom = pb.FlatTorus(38, 38)
if sys.argv[3] == "gaussian":
    v = np.random.default_rng(0).standard_normal((geom.n_balls, 2))
else:
    v = np.zeros((geom.n_balls, 2))
    v[0, 0] = np.sqrt(200.0)
sim = pb.Simulation(geom, v, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=1)
sim.run(steps=1)                                 # compile or load the loop outside the count
control.cg_start()
sim.run(steps=steps)
control.cg_stop()
print(sim.collisions, repr(sim.energy()))
"""


def callgrind(command: list[str], out: str, env: dict | None = None, atstart: bool = True) -> tuple[int, str]:
    """``(instructions collected, stdout)``; with ``atstart=False`` only between the client requests."""
    flags = ["--tool=callgrind", f"--callgrind-out-file={out}.%p"] + ([] if atstart else ["--instr-atstart=no"])
    run = subprocess.run(["valgrind", *flags, *command], capture_output=True, text=True, check=True, env=env)
    files = sorted(glob.glob(f"{out}.*.1") if not atstart else glob.glob(f"{out}.*"))
    total = sum(int(re.search(r"^summary: (\d+)", Path(f).read_text(), re.M).group(1)) for f in files)
    for f in glob.glob(f"{out}.*"):
        os.remove(f)
    return total, run.stdout


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2_000_000, help="steps counted (default 2,000,000)")
    parser.add_argument("--start", choices=("single", "gaussian"), default="single",
                        help="the paper's one moving ball (default) or equilibrium")
    parser.add_argument("--tree", type=Path, action="append", default=[],
                        help="another copy of the package to count too (repeatable)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        control, ref = os.path.join(tmp, "libcgctl.so"), os.path.join(tmp, "ref_kernel")
        Path(tmp, "cgctl.c").write_text(_CONTROL)
        subprocess.run(["cc", "-O2", "-shared", "-fPIC", "-o", control, os.path.join(tmp, "cgctl.c")], check=True)
        # as reference.sh builds it, but without AVX-512, which valgrind cannot run (the loop is scalar either way)
        subprocess.run(["cc", "-O3", "-march=native", "-mno-avx512f", "-o", ref, str(C_SOURCE), "-lm"], check=True)
        small, _ = callgrind([ref, "38", "38", "1000"], os.path.join(tmp, "c_small"))
        large, _ = callgrind([ref, "38", "38", str(args.steps)], os.path.join(tmp, "c_large"))
        c_per_step = (large - small) / (args.steps - 1000)
        for tree in [ROOT, *(t.resolve() for t in args.tree)]:
            env = dict(os.environ, PYTHONPATH=str(tree))
            ours, out = callgrind([sys.executable, "-c", _CHILD, control, str(args.steps), args.start],
                                  os.path.join(tmp, "py"), env=env, atstart=False)
            collisions, energy = out.split()
            name = "this checkout" if tree == ROOT else str(tree)
            print(f"38x38 torus, {args.start} start, {args.steps:,} steps: C {c_per_step:.1f} instructions per step "
                  f"(from the paper's start); {name} {ours / args.steps:.1f} ({collisions} collisions, energy "
                  f"{energy}); ratio {ours / args.steps / c_per_step:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
