"""What a new user rule or scheduler pays in compilation on its first runs.

A user's rule (``collide``) or scheduler (``pick``) is inlined into the engine's loops, so its first
``run(steps=...)`` and first ``run_until_frozen()`` compile loops for that combination. Each case
runs in a fresh process with an empty numba cache (``NUMBA_CACHE_DIR``): the package's own parts
are first compiled by an untimed run with built-in parts (as they would already be cached on a
user's machine), then the user's part is timed: its first ``run(steps=10)``, its first
``run_until_frozen``, and both again in a second process with the cache the first one left.

    python benchmarks/bench_compile.py                          # this checkout
    python benchmarks/bench_compile.py --tree /path/to/old/checkout --tree .   # before and after
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

#: a user's module: a restitution rule of its own and a scheduler picking among listed contacts
_USER = r'''
import numpy as np
from numba import njit
import pinnedballs as pb
try:
    from pinnedballs.engine.random import bounded
except ImportError:  # the layout before issue 16
    from pinnedballs.random import bounded
from pinnedballs.rules import CollisionRule, closing_speed
try:
    from pinnedballs.rules import remnant_threshold
except ImportError:  # before issue 18: no remnant threshold
    @njit(inline="always")
    def remnant_threshold(params):
        return 0.0


@njit(inline="always")
def collide_sticky(v, units, i, j, a, b, masses, params, dim, flat, write):
    tau = remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    c = w * (1.0 + params[0]) / 2.0
    changed = False
    for k in range(dim):
        tj = -units[a, k] if flat else units[b, k]
        new_i, new_j = v[i, k] - c * units[a, k], v[j, k] - c * tj
        changed |= (new_i != v[i, k]) | (new_j != v[j, k])
        if write:
            v[i, k], v[j, k] = new_i, new_j
    return changed


class Sticky(CollisionRule):
    def __init__(self, keep):
        self.keep = keep

    def kernel(self, equal_masses):
        return collide_sticky, np.array([self.keep])


@njit(inline="always")
def pick_among(state, rng, n_contacts):
    r, rng = bounded(rng, state[0])
    return np.uint64(state[1 + np.int64(r)]), rng


class Among(pb.Scheduler):
    def __init__(self, contacts):
        self.contacts = np.asarray(contacts, dtype=np.int64)

    def kernel(self):
        return pick_among

    def initial_state(self, n):
        return np.concatenate([[len(self.contacts)], self.contacts])
'''

_CHILD = r'''
import json, sys, time
import numpy as np
import pinnedballs as pb
import userparts
case = sys.argv[1]
g = pb.HalfPlane(20, 20)
v = np.zeros((g.n_balls, 2)); v[g.boundary_center()] = [0, 3.0]
warm = pb.Simulation(g, v, seed=0)          # the package's own parts, compiled or loaded untimed
warm.run(steps=10); warm.run_until_frozen(10**6)
rule = userparts.Sticky(0.9) if case == "rule" else pb.Elastic()
scheduler = userparts.Among(np.arange(g.n_contacts)) if case == "scheduler" else pb.UniformRandomPair()
sim = pb.Simulation(g, v, rule=rule, scheduler=scheduler, seed=0)
t, c = time.perf_counter(), time.process_time(); sim.run(steps=10)
steps, steps_cpu = time.perf_counter() - t, time.process_time() - c
t, c = time.perf_counter(), time.process_time(); sim.run_until_frozen(max_steps=10**6)
frozen, frozen_cpu = time.perf_counter() - t, time.process_time() - c
print(json.dumps(dict(steps=steps, frozen=frozen, steps_cpu=steps_cpu, frozen_cpu=frozen_cpu,
                      collisions=sim.collisions)))
'''


def first_runs(tree: Path, case: str, cache: Path, user: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": f"{tree}{os.pathsep}{user}", "NUMBA_CACHE_DIR": str(cache)}
    out = subprocess.run([sys.executable, "-c", _CHILD, case], capture_output=True, text=True, cwd=user, env=env)
    if out.returncode:
        raise SystemExit(f"the {case} child on {tree} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def _median(runs: list[dict]) -> dict:
    """The run of median total CPU time."""
    runs = sorted(runs, key=lambda r: r["steps_cpu"] + r["frozen_cpu"])
    return runs[len(runs) // 2]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", action="append", type=Path, help="a checkout of pinnedballs (default: this one)")
    parser.add_argument("--repeats", type=int, default=3, help="fresh caches per case (the median is shown)")
    args = parser.parse_args(argv)
    trees = [tree.resolve() for tree in args.tree or [ROOT]]
    fresh = {(tree, case): [] for tree in trees for case in ("rule", "scheduler")}
    cached = {key: [] for key in fresh}
    for _ in range(args.repeats):  # the trees interleaved: a shared machine's load falls on each alike
        for tree, case in fresh:
            with tempfile.TemporaryDirectory() as tmp:
                user = Path(tmp) / "user"
                user.mkdir()
                (user / "userparts.py").write_text(_USER)
                fresh[tree, case].append(first_runs(tree, case, Path(tmp) / "cache", user))
                cached[tree, case].append(first_runs(tree, case, Path(tmp) / "cache", user))
    print("CPU seconds in the child (time.process_time), wall seconds in brackets; the median of "
          f"{args.repeats} fresh caches")
    print()
    print("| checkout | user part | first run(steps) | first run_until_frozen | total | cached: total |")
    print("|---|---|---|---|---|---|")
    for (tree, case), runs in fresh.items():
        f, c = _median(runs), _median(cached[tree, case])
        print(f"| {tree.name} | {case} | {f['steps_cpu']:.2f} ({f['steps']:.2f}) | {f['frozen_cpu']:.2f} "
              f"({f['frozen']:.2f}) | {f['steps_cpu'] + f['frozen_cpu']:.2f} ({f['steps'] + f['frozen']:.2f}) | "
              f"{c['steps_cpu'] + c['frozen_cpu']:.2f} ({c['steps'] + c['frozen']:.2f}) |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
