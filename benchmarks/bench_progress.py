"""Many short runs in a Jupyter notebook: the default progress (``None``) against ``progress=False``.

A notebook run in a fresh kernel (nbclient, ipykernel; ipywidgets if installed, as a user's Jupyter
has it) makes ``--runs`` small simulations and runs each 100 steps, in rounds that alternate the
default and ``progress=False`` (a shared machine's load falls on both alike). Prints the wall time
of each (the sum over rounds), their ratio, the widgets the kernel holds and the saved notebook's
size. Target (issue 34, item 1): the default within 1.2x of ``progress=False``, at most a handful
of widgets (2,000 runs took 10.9 s against 0.30 s and left 22,011 widgets before).

    python benchmarks/bench_progress.py            # 2,000 runs of each
    python benchmarks/bench_progress.py --runs 500 --rounds 5
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile

import nbclient
import nbformat

SETUP = """
import json, time
import numpy as np
import pinnedballs as pb
try:
    import ipywidgets
except ImportError:
    ipywidgets = None
g = pb.FlatTorus(6, 6)
v = np.random.default_rng(0).standard_normal((g.n_balls, 2))
pb.Simulation(g, v, seed=0).run(steps=100, progress=False)  # compiled before the clock starts
"""

LOOP = """
seconds = {{"default": 0.0, "off": 0.0}}
for r in range({rounds}):
    for name, progress in (("default", None), ("off", False))[::1 if r % 2 == 0 else -1]:
        t = time.perf_counter()
        for seed in range({per_round}):
            pb.Simulation(g, v, seed=seed).run(steps=100, progress=progress)
        seconds[name] += time.perf_counter() - t
widgets = None if ipywidgets is None else len(ipywidgets.widgets.widget._instances)
print(json.dumps(dict(seconds, widgets=widgets)))
"""


def measure(runs: int, rounds: int) -> dict:
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(SETUP), nbformat.v4.new_code_cell(
        LOOP.format(rounds=rounds, per_round=runs // rounds))])
    with tempfile.TemporaryDirectory() as tmp:
        nbclient.NotebookClient(nb, timeout=3600, kernel_name="python3",
                                resources={"metadata": {"path": tmp}}).execute()
    (printed,) = [o["text"] for o in nb.cells[1].outputs if o.get("name") == "stdout"]
    return dict(json.loads(printed), bytes=len(nbformat.writes(nb)))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2000, help="short runs of each kind")
    parser.add_argument("--rounds", type=int, default=4, help="rounds the runs are split in, alternating")
    args = parser.parse_args(argv)
    r = measure(args.runs, args.rounds)
    print(f"{args.runs:,} runs of 100 steps in a notebook, {args.rounds} alternating rounds")
    print(f"progress=None (default): {r['default']:.3f} s")
    print(f"progress=False:          {r['off']:.3f} s")
    print(f"ratio:                   {r['default'] / r['off']:.2f}x (target: at most 1.2x)")
    print(f"widgets in the kernel:   {'no ipywidgets' if r['widgets'] is None else r['widgets']}")
    print(f"saved notebook:          {r['bytes'] / 1e3:,.1f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
