"""First runs on a fresh install: what numba's compiles cost before a run starts, and a second time.

Each case runs in a fresh process with an empty numba cache (``NUMBA_CACHE_DIR`` a new temporary
folder), then again in a second process with the cache the first one left; each stage is timed
(wall seconds, CPU seconds of the process beside them):

* ``half_plane``: the package's own parts, nothing compiled: ``pb.HalfPlane.from_size(1000, 500)``
  with one moving ball, building the ``Simulation`` (the geometry's checks), its first
  ``run(steps=1000)``, then ``run_until_frozen(max_steps=10**6)`` (on two threads or more, the
  threaded chain's blocks);
* ``exact``: the same for ``pb.HalfPlane.from_size(30, 15)`` in exact arithmetic, until frozen;
* ``rule``, ``scheduler``: a user's rule (``collide``) or scheduler (``pick``) in a module of its
  own, inlined into the engine's loops: the package's own parts are first compiled by an untimed
  run with built-in parts (as a user's machine has them cached), then the user's part is timed:
  its first ``run(steps=10)`` and its first ``run_until_frozen``;
* ``notebook_rule``: the same rule defined in a notebook's cell (no source file: its source in
  `linecache` under an ipykernel's file name, as IPython keeps it); the second process is a second
  kernel;
* ``check_rule``: ``pinnedballs.testing.check_rule`` on a user's rule (the tutorial's ``ByDirection``,
  in its module), the package's own parts compiled first as for ``rule``.

Targets (issue 34, item 2; issue 42, item 8): every first run of a built-in configuration within 5 s, a
user's rule within 1.5 s, the same rule in a second kernel (a second process, the cache warm) within
0.5 s. The last table sets each figure beside its target.

    python benchmarks/bench_compile.py                          # this checkout, every case
    python benchmarks/bench_compile.py --case half_plane --case exact --repeats 1
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
    from pinnedballs.engine.streams.xoshiro import bounded
except ImportError:
    try:  # the layout before engine/ had rooms
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


@njit
def collide_by_direction(v, units, i, j, a, b, masses, params, dim, flat, write):
    """The tutorial's: restitution params[0] along x, params[1] along y, interpolated by t_y^2; any masses."""
    r_x, r_y, tau = params[0], params[1], remnant_threshold(params)
    w = closing_speed(v, units, i, j, a, b, dim, flat)
    if w <= tau:
        return False
    t_jy = -units[a, 1] if flat else units[b, 1]
    r = r_x + (r_y - r_x) * 0.5 * (units[a, 1] ** 2 + t_jy**2)
    s = (1.0 + r) * w / (masses[i] + masses[j])
    changed = False
    for k in range(dim):
        t_jk = -units[a, k] if flat else units[b, k]
        new_i, new_j = v[i, k] - s * masses[j] * units[a, k], v[j, k] - s * masses[i] * t_jk
        changed |= (new_i != v[i, k]) | (new_j != v[j, k])
        if write:
            v[i, k], v[j, k] = new_i, new_j
    return changed


class ByDirection(CollisionRule):
    def __init__(self, r_x, r_y):
        self.r_x, self.r_y = float(r_x), float(r_y)

    def kernel(self, equal_masses):
        return collide_by_direction, np.array([self.r_x, self.r_y])


class Among(pb.Scheduler):
    def __init__(self, contacts):
        self.contacts = np.asarray(contacts, dtype=np.int64)

    def kernel(self):
        return pick_among

    def initial_state(self, n):
        return np.concatenate([[len(self.contacts)], self.contacts])
'''

_CHILD = r'''
import json, os, sys, time
import numpy as np
import pinnedballs as pb
times = {}


def timed(stage, call):
    t, c = time.perf_counter(), time.process_time()
    out = call()
    times[stage], times[stage + "_cpu"] = time.perf_counter() - t, time.process_time() - c
    return out


def kicked(g):
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0, 3.0]
    return v


case = sys.argv[1]
if case == "half_plane":
    g = pb.HalfPlane.from_size(1000, 500)
    sim = timed("build", lambda: pb.Simulation(g, kicked(g), seed=0))
    timed("steps", lambda: sim.run(steps=1000, progress=False))
    timed("frozen", lambda: sim.run_until_frozen(max_steps=10**6, progress=False))
elif case == "exact":
    g = pb.HalfPlane.from_size(30, 15)
    sim = timed("build", lambda: pb.Simulation(g, kicked(g), seed=0, arithmetic="exact"))
    timed("frozen", lambda: sim.run_until_frozen(max_steps=10**7, progress=False))
else:
    import userparts
    g = pb.HalfPlane(20, 20)
    warm = pb.Simulation(g, kicked(g), seed=0)          # the package's own parts, compiled or loaded untimed
    warm.run(steps=10); warm.run_until_frozen(10**6)
    if case == "check_rule":
        from pinnedballs.testing import check_rule
        timed("checks", lambda: check_rule(userparts.ByDirection(1.0, 0.5)))
        print(json.dumps(times))
        sys.exit()
    rule = userparts.Sticky(0.9) if case == "rule" else pb.Elastic()
    if case == "notebook_rule":  # the rule's source in a cell, as IPython runs one
        import linecache
        cell = open(userparts.__file__).read()
        name = f"/tmp/ipykernel_{os.getpid()}/1618033988.py"
        linecache.cache[name] = (len(cell), None, cell.splitlines(True), name)
        namespace = {"__name__": "__main__"}
        exec(compile(cell, name, "exec"), namespace)
        rule = namespace["Sticky"](0.9)
    scheduler = userparts.Among(np.arange(g.n_contacts)) if case == "scheduler" else pb.UniformRandomPair()
    sim = pb.Simulation(g, kicked(g), rule=rule, scheduler=scheduler, seed=0)
    timed("steps", lambda: sim.run(steps=10))
    timed("frozen", lambda: sim.run_until_frozen(max_steps=10**6))
print(json.dumps(times))
'''


def first_runs(tree: Path, case: str, cache: Path, user: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": f"{tree}{os.pathsep}{user}", "NUMBA_CACHE_DIR": str(cache)}
    out = subprocess.run([sys.executable, "-c", _CHILD, case], capture_output=True, text=True, cwd=user, env=env)
    if out.returncode:
        raise SystemExit(f"the {case} child on {tree} failed:\n{out.stderr}")
    return json.loads(out.stdout.strip().splitlines()[-1])


#: the cases, and the stages each times
CASES = {"half_plane": ("build", "steps", "frozen"), "exact": ("build", "frozen"), "rule": ("steps", "frozen"),
         "scheduler": ("steps", "frozen"), "notebook_rule": ("steps", "frozen"), "check_rule": ("checks",)}

#: the targets: (case, what, the second process's figure (else the first's), seconds or None)
TARGETS = [("half_plane", "a built-in configuration's first run (build, steps, frozen)", False, 5.0),
           ("exact", "a built-in configuration's first run (build, frozen)", False, 5.0),
           ("rule", "a user's rule, first run (steps, frozen)", False, 1.5),
           ("rule", "the same rule in a second process", True, 0.5),
           ("notebook_rule", "a user's rule in a notebook, first kernel", False, 1.5),
           ("notebook_rule", "the same rule in a second kernel", True, 0.5),
           ("scheduler", "a user's scheduler, first run (no target of its own)", False, None),
           ("check_rule", "check_rule on a first rule (no target of its own)", False, None)]


def _median(runs: list[dict]) -> dict:
    """The run of median total wall time."""
    runs = sorted(runs, key=lambda r: sum(v for k, v in r.items() if not k.endswith("_cpu")))
    return runs[len(runs) // 2]


def _stages(run: dict, stages: tuple[str, ...]) -> str:
    return " | ".join(f"{run[s]:.2f} ({run[s + '_cpu']:.2f})" for s in stages)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tree", action="append", type=Path, help="a checkout of pinnedballs (default: this one)")
    parser.add_argument("--case", action="append", choices=sorted(CASES), help="a case (default: every one)")
    parser.add_argument("--repeats", type=int, default=3, help="fresh caches per case (the median is shown)")
    args = parser.parse_args(argv)
    trees = [tree.resolve() for tree in args.tree or [ROOT]]
    cases = args.case or list(CASES)
    fresh = {(tree, case): [] for case in cases for tree in trees}
    cached = {key: [] for key in fresh}
    for _ in range(args.repeats):  # the trees interleaved: a shared machine's load falls on each alike
        for tree, case in fresh:
            with tempfile.TemporaryDirectory() as tmp:
                user = Path(tmp) / "user"
                user.mkdir()
                (user / "userparts.py").write_text(_USER)
                fresh[tree, case].append(first_runs(tree, case, Path(tmp) / "cache", user))
                cached[tree, case].append(first_runs(tree, case, Path(tmp) / "cache", user))
    print(f"wall seconds, CPU seconds of the process in brackets; the median of {args.repeats} fresh caches "
          f"({os.cpu_count()} cores)")
    for case in cases:
        stages = CASES[case]
        print()
        print(f"| checkout | {case} | " + " | ".join(f"first {s}" for s in stages) + " | second process: "
              + " | ".join(stages) + " |")
        print("|---|---|" + "---|" * 2 * len(stages))
        for tree in trees:
            f, c = _median(fresh[tree, case]), _median(cached[tree, case])
            print(f"| {tree.name} | {case} | {_stages(f, stages)} | {_stages(c, stages)} |")
    print()
    print("| checkout | figure | wall seconds | target | |")
    print("|---|---|---|---|---|")
    for case, what, second, target in TARGETS:
        if case not in cases:
            continue
        for tree in trees:
            run = _median((cached if second else fresh)[tree, case])
            seconds = sum(run[s] for s in CASES[case])
            verdict = "" if target is None else "met" if seconds <= target else "missed"
            print(f"| {tree.name} | {case}: {what} | {seconds:.2f} | {'-' if target is None else f'<= {target:g}'} | "
                  f"{verdict} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
