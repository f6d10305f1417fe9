"""The paper's torus chain against the C yardstick, in the same run: ns per step and the ratio.

UniformRandomPair + Elastic on the 38x38 flat torus (one moving ball of energy 100, seed 1, as
`bench_chain.py` and docs/performance.md) and, in turns with it, the plain C loop
``benchmarks/c/reference.sh ROWS COLS STEPS`` (xoshiro256**, the same lattice). The machine
may be loaded: every contestant runs in its own fresh process, the contestants take turns round
after round (C, ours, C, ours, ...), and each one's best (smallest ns per step) is kept; the ratio
is C's best ns per step over ours (above 1: faster than C). Per-round ratios (ours against the C run
just before it) show the spread.

``--tree DIR`` (repeatable) adds another copy of the package (a directory holding ``pinnedballs/``,
e.g. ``git archive COMMIT pinnedballs | tar -x -C DIR``) to the turns, so two versions are compared
in one run; collisions and energy are printed for each, so the bits can be compared too.

    python benchmarks/bench_torus.py                     # 38x38, 50M steps, 5 rounds
    python benchmarks/bench_torus.py --rounds 9 --steps 100000000
    python benchmarks/bench_torus.py --tree /tmp/old     # this checkout and /tmp/old, each against C
    python benchmarks/bench_torus.py --regimes           # blocks with or without a branch, by collision rate
    python benchmarks/bench_torus.py --family            # tori 24x24 to 1000x1000, one ball and Gaussian, vs C

``--regimes`` times the table loop on one thread (``UniformRandomPair(threads=1)``: a half-plane of 500x250
has enough contacts for the ``threads`` engine, whose tuner and threads would be timed instead of the loop)
with every block run with a branch on each collision (``PINNEDBALLS_LOOP=branch``: the loop as it was),
every block but the first without one (``branch_free``), as the share of collisions of the block before
chooses (``threshold``: `engine.sequential.choice.BRANCH_FREE_PERCENT`, the rule before blocks were timed) and
as the default chooses (``auto``: each way's cost timed on this CPU, `engine.sequential.choice`), on systems
that collide on different fractions of their picks; each row also says which loop ran and the share of its
picks without a branch.

``--family`` runs each torus of `FAMILY` (one ball of energy 100, and Gaussian velocities) against the C
yardstick in turns, ``--rounds`` times (with ``--tree``, each copy too), and gives the median ratio of CPU ns
a step (C over ours) and the loop that ran.

Every mode prints the CPU's model, L2 cache and vector extensions first (`pinnedballs.util.provenance.cpu_line`).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "benchmarks" / "c" / "reference.sh"

_CHILD = r"""
import json, sys, time
import numpy as np
import pinnedballs as pb
rows, cols, steps = map(int, sys.argv[1:4])
geom = pb.FlatTorus(rows, cols)
if len(sys.argv) > 4 and sys.argv[4] == "gaussian":
    v = np.random.default_rng(1).normal(size=(geom.n_balls, 2))
else:
    v = np.zeros((geom.n_balls, 2))
    v[0, 0] = np.sqrt(200.0)                   # energy 100, as in the paper
sim = pb.Simulation(geom, v, rule=pb.Elastic(), scheduler=pb.UniformRandomPair(), seed=1)
sim.run(steps=1)                               # compiles, or loads numba's disk cache
t0, c0 = time.perf_counter(), time.process_time()
sim.run(steps=steps - 1)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps(dict(ns=wall / (steps - 1) * 1e9, cpu_ns=cpu / (steps - 1) * 1e9, collisions=sim.collisions,
                      energy=repr(sim.energy()), file=pb.__file__,
                      device=getattr(sim.engine, "resources", dict)())))  # a --tree before 1.0 may not say
"""


_REGIME = r"""
import json, sys, time, warnings
import numpy as np
import pinnedballs as pb
warnings.simplefilter("ignore")                  # a half-plane's thin margin, said once per run
case = sys.argv[1]
one = pb.UniformRandomPair(threads=1)            # the loop itself, never the threads engine's tuner
if case.startswith("half"):                      # the paper's half-plane until frozen (seed 7)
    length, depth = map(float, case[4:].split("x"))
    g = pb.HalfPlane.from_size(length, depth)
    v = np.zeros((g.n_balls, 2))
    b = g.boundary_center()
    v[b] = -np.sqrt(200.0) * g.boundary.outward[b]
    def make():
        return pb.Simulation(g, v, seed=7, scheduler=one)
    make().run_until_frozen(max_steps=1000)      # compiles, or loads numba's disk cache
    sim = make()
    t = time.process_time()
    sim.run_until_frozen(max_steps=10**12)
else:                                           # a torus, one ball of energy 100 or Gaussian velocities
    start, size, steps = case.split(":")
    rows, cols = map(int, size.split("x"))
    g = pb.FlatTorus(rows, cols)
    if start == "gaussian":
        v = np.random.default_rng(1).normal(size=(g.n_balls, 2))
    else:
        v = np.zeros((g.n_balls, 2))
        v[0, 0] = np.sqrt(200.0)
    sim = pb.Simulation(g, v, seed=1, scheduler=one)
    sim.run(steps=1)
    t = time.process_time()
    sim.run(steps=int(steps))
cpu = time.process_time() - t
used = sim.engine.resources()
print(json.dumps(dict(ns=cpu / sim.steps * 1e9, steps=sim.steps, collisions=sim.collisions, energy=repr(sim.energy()),
                      engine=sim.engine_name, threads=used["threads"], loop=used.get("loop", {}))))
"""

REGIMES = ("single:38x38:20000000", "gaussian:200x100:10000000", "half200x100", "half500x250")
#: the ways `--regimes` forces (``PINNEDBALLS_LOOP``), the default last
WAYS = ("branch", "branch_free", "threshold", "auto")
#: the tori of `--family`: (rows, cols, steps)
FAMILY = ((24, 24, 20_000_000), (38, 38, 20_000_000), (64, 40, 20_000_000), (128, 128, 20_000_000),
          (200, 200, 20_000_000), (400, 300, 20_000_000), (1000, 1000, 50_000_000))


def regimes(rounds: int) -> None:
    """CPU ns per step of each regime, each way forced, and as the default chooses; the median of ``rounds``."""
    print(f"CPU ns per step on one thread, median of {rounds} (min-max; each run in a fresh process, in turns); "
          f"load average {os.getloadavg()[0]:.1f}")
    print("| system | steps | collisions per step | " + " | ".join(WAYS) + " | chosen: engine, share without a "
          "branch | auto / fastest forced |")
    print("|---|---|---|" + "---|" * len(WAYS) + "---|---|")
    for case in REGIMES:
        times: dict[str, list[float]] = {w: [] for w in WAYS}
        seen, chosen = set(), ""
        for _ in range(rounds):
            for way in WAYS:
                out = subprocess.run([sys.executable, "-c", _REGIME, case], capture_output=True, text=True, cwd=ROOT,
                                     check=True, env=dict(os.environ, PINNEDBALLS_LOOP=way))
                d = json.loads(out.stdout.strip().splitlines()[-1])
                times[way].append(d["ns"])
                seen.add((d["steps"], d["collisions"], d["energy"]))
                if way == "auto":
                    chosen = f"{d['engine']} ({d['threads']} thread), {d['loop'].get('branch_free', 0):.0%}"
        if len(seen) != 1:
            raise SystemExit(f"{case}: the runs differ: {seen}")
        steps, collisions, _ = seen.pop()
        med = {w: statistics.median(t) for w, t in times.items()}
        fastest = min(med[w] for w in WAYS[:-1])
        print(f"| {case} | {steps:,} | {collisions / steps:.2f} | "
              + " | ".join(f"{med[w]:.2f} ({min(times[w]):.2f}-{max(times[w]):.2f})" for w in WAYS)
              + f" | {chosen} | {med['auto'] / fastest:.3f} |", flush=True)


def family(rounds: int, trees: list[Path], names: list[str]) -> None:
    """Each torus of `FAMILY`, one ball and Gaussian, against C in turns (C before each tree's run): the median
    ratio of CPU ns a step, C's over ours."""
    binary = reference_binary()
    print(f"tori against the C yardstick, CPU ns a step, {rounds} rounds in turns (C, ours); "
          f"load average {os.getloadavg()[0]:.1f}")
    print("| torus | start | tree | C ns | ours ns | C / ours: median (min-max) | loop |")
    print("|---|---|---|---|---|---|---|")
    for rows, cols, steps in FAMILY:
        for start in ("single", "gaussian"):
            for tree in trees:
                run_ours(tree, rows, cols, 1000, start)  # compile or load outside the turns
            c_ns, ours_ns, ratios = ([[] for _ in trees] for _ in range(3))
            loops = [""] * len(trees)
            for _ in range(rounds):
                for t, tree in enumerate(trees):
                    c = run_reference(binary, rows, cols, steps, start)
                    ours = run_ours(tree, rows, cols, steps, start)
                    c_ns[t].append(c["cpu_ns"])
                    ours_ns[t].append(ours["cpu_ns"])
                    ratios[t].append(c["cpu_ns"] / ours["cpu_ns"])
                    loop = ours.get("device", {}).get("loop", {})
                    loops[t] = f"{loop.get('name', '')} {loop.get('branch_free', '')}".strip()
            for t, name in enumerate(names):
                r = ratios[t]
                print(f"| {rows}x{cols} | {start} | {name} | {statistics.median(c_ns[t]):.2f} | "
                      f"{statistics.median(ours_ns[t]):.2f} | {statistics.median(r):.3f} ({min(r):.3f}-{max(r):.3f}) | "
                      f"{loops[t]} |", flush=True)


def run_ours(tree: Path, rows: int, cols: int, steps: int, start: str = "single") -> dict:
    """One timed run of the package found in ``tree``, in a fresh process."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    out = subprocess.run([sys.executable, "-c", _CHILD, str(rows), str(cols), str(steps), start],
                         capture_output=True, text=True, env=env, cwd=tree)
    if out.returncode:
        raise SystemExit(f"{tree}: the benchmark's child failed:\n{out.stderr}")
    result = json.loads(out.stdout.strip().splitlines()[-1])
    if not Path(result["file"]).resolve().is_relative_to(tree.resolve()):
        raise SystemExit(f"{tree}: imported pinnedballs from {result['file']}, not from this tree")
    return result


def reference_binary() -> str:
    """The C yardstick's program, built by ``reference.sh`` (which builds it when its source is newer)."""
    subprocess.run(["bash", str(REFERENCE), "4", "4", "1"], capture_output=True, check=True)
    return str(Path(os.environ.get("TMPDIR", "/tmp")) / "pinnedballs-yardstick")


def run_reference(binary: str, rows: int, cols: int, steps: int, start: str = "single") -> dict:
    """One run of the C loop: ns per step by its own clock (wall) and by its CPU time (the operating system's
    account of the process, less that of a run of 1,000 steps: start-up and building the tables)."""
    def once(n: int) -> tuple[str, float]:
        proc = subprocess.Popen([binary, str(rows), str(cols), str(n), start], stdout=subprocess.PIPE, text=True)
        text = proc.stdout.read()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode:
            raise SystemExit(f"{binary} failed with status {proc.returncode}")
        return text, usage.ru_utime + usage.ru_stime
    _, setup = once(1000)
    text, cpu = once(steps)
    fields = dict(re.findall(r"(\S+)=(\S+)", text))
    return dict(ns=1e3 / float(fields["Msteps/s"]), cpu_ns=max(cpu - setup, 0.0) / steps * 1e9,
                collisions=int(fields["collisions"]), energy=fields["energy"])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=38)
    parser.add_argument("--cols", type=int, default=38)
    parser.add_argument("--steps", type=int, default=50_000_000, help="steps per run (default 50,000,000)")
    parser.add_argument("--rounds", type=int, default=5, help="turns of every contestant (default 5)")
    parser.add_argument("--tree", type=Path, action="append", default=[],
                        help="another copy of the package to time in the same turns (repeatable)")
    parser.add_argument("--no-self", action="store_true", help="time only the --tree copies, not this checkout")
    parser.add_argument("--regimes", action="store_true",
                        help="blocks with and without a branch at several collision rates (this checkout only)")
    parser.add_argument("--family", action="store_true", help="tori from 24x24 to 1000x1000 against C")
    args = parser.parse_args(argv)
    from pinnedballs.util.provenance import cpu_line

    print(cpu_line(), flush=True)
    if args.regimes:
        regimes(args.rounds)
        return 0
    trees = ([] if args.no_self else [ROOT]) + [t.resolve() for t in args.tree]
    names = [("this checkout" if t == ROOT else str(t)) for t in trees]
    if args.family:
        family(args.rounds, trees, names)
        return 0
    binary = reference_binary()
    for tree in trees:  # compile (or load numba's cache) outside the turns
        run_ours(tree, args.rows, args.cols, 1000)
    best_c, best = {}, [{} for _ in trees]
    ratios: list[dict] = [{"ns": [], "cpu_ns": []} for _ in trees]
    print(f"{args.rows}x{args.cols} torus, paper chain (one ball of energy 100, seed 1), {args.steps:,} steps a run, "
          f"{args.rounds} rounds; load average {os.getloadavg()[0]:.1f}", flush=True)
    for r in range(args.rounds):
        line = []
        for t, tree in enumerate(trees):
            c = run_reference(binary, args.rows, args.cols, args.steps)
            ours = run_ours(tree, args.rows, args.cols, args.steps)
            for clock in ("ns", "cpu_ns"):
                best_c[clock] = min(best_c.get(clock, float("inf")), c[clock])
                best[t][clock] = min(best[t].get(clock, float("inf")), ours[clock])
                ratios[t][clock].append(c[clock] / ours[clock])
            best[t]["run"] = ours
            line.append(f"C {c['cpu_ns']:.2f} / {names[t]} {ours['cpu_ns']:.2f} cpu ns "
                        f"(x{c['cpu_ns'] / ours['cpu_ns']:.3f}; wall x{c['ns'] / ours['ns']:.3f})")
        print(f"round {r + 1}: " + "; ".join(line), flush=True)
    print(f"C yardstick: best {best_c['cpu_ns']:.2f} cpu ns/step, {best_c['ns']:.2f} wall ns/step "
          f"({1e3 / best_c['ns']:.1f} Msteps/s)")
    for t, name in enumerate(names):
        b, run = best[t], best[t]["run"]
        print(f"{name}: best {b['cpu_ns']:.2f} cpu ns/step, {b['ns']:.2f} wall ns/step ({1e3 / b['ns']:.1f} Msteps/s); "
              f"{run['collisions']:,} collisions, energy {run['energy']}")
        for clock, label in (("cpu_ns", "cpu"), ("ns", "wall")):
            rs = sorted(ratios[t][clock])
            print(f"    {label}: ratio of bests (C ns / ours ns) {best_c[clock] / b[clock]:.3f}x; per round median "
                  f"{rs[len(rs) // 2]:.3f}x, range {rs[0]:.3f}-{rs[-1]:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
