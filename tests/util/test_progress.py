"""A call's progress (`pinnedballs.util.progress`; issue 34, items 1 and 2): a call that ends within
its delay builds no bar at all (in a notebook, no widget: 2,000 short runs left 22,011 and a 24 MB
tutorial); a bar closes on its final state, which a saved notebook keeps as its text; while numba
compiles the bar says so, and its rate counts from the end of the compile."""

from __future__ import annotations

import re
import time

import pytest
from numba import njit

from pinnedballs.util import progress
from pinnedballs.util.progress import COMPILING, Progress

#: a tqdm bar's meter, "[00:01<00:02, 3.4 steps/s]" or, the end unknown, "[00:01, 3.4 steps/s]"
METER = re.compile(r"\[\d+:\d\d(?::\d\d)?[<,]")


def compile_something() -> None:
    """A compile numba announces: a function new to it, never in its disk cache."""
    njit(lambda x: x + 1)(1)


def test_a_call_within_its_delay_builds_no_bar(monkeypatch):
    monkeypatch.setattr(progress, "_in_notebook", lambda: True)
    with Progress(None, 1000, "steps", "running") as bar:
        bar.update(500)
        bar.update(1000)
        assert bar.visible and bar.bar is None  # shown after its delay, not built before


def test_a_call_past_its_delay_shows_its_final_count(monkeypatch, capfd):
    monkeypatch.setattr(progress, "_on_a_terminal", lambda: True)
    monkeypatch.setattr(progress, "DELAY", 0.0)  # the delay has passed: a slow machine, or a long call
    with Progress(None, 1000, "steps", "running") as bar:
        bar.update(1000, "collisions=7")
    err = capfd.readouterr().err
    assert err.endswith("\n") and "running: 100%" in err.rsplit("\r", 1)[-1] and "collisions=7" in err


def test_the_bar_says_what_compiles_while_numba_compiles(capfd):
    with Progress(True, 100, "steps", "running") as bar:
        before = time.time()
        compile_something()
        after = time.time()
        assert before <= bar.bar.since[0] <= after  # the rate counts from the end of the compile
        bar.update(100)
    draws = capfd.readouterr().err.split("\r")
    compiling = [d for d in draws if d.startswith(COMPILING)]
    assert compiling and all(d.startswith("compiling <lambda> (compile 1):   0%|") for d in compiling)
    assert not [d for d in draws if "steps/s" in d and "100%" not in d]  # no rate while nothing has run
    assert not [d for d in draws if "?" in d or ": :" in d]  # tqdm's '?' rate, a doubled colon (issue 49)
    assert draws[-1].startswith("running: 100%")


def test_a_bar_without_an_end_while_nothing_has_run_shows_no_rate(capfd):
    """The issue's bar: "until frozen: compiling: : 0.00 steps [01:07, ? steps/s]"."""
    with Progress(True, None, "steps", "until frozen") as bar:
        compile_something()
        assert re.fullmatch(r"until frozen: 0\.00 steps \[\d\d:\d\d\]", str(bar.bar))
        bar.update(5000, "collisions=7")
        assert re.fullmatch(r"until frozen: 5\.00k steps \[\d\d:\d\d, [0-9.]+[kMG]? steps/s, collisions=7\]",
                            str(bar.bar))
    draws = capfd.readouterr().err.split("\r")
    assert [d for d in draws if re.match(r"compiling <lambda> \(compile 1\): 0\.00 steps \[\d\d:\d\d\] *$", d)]


def test_a_compile_within_the_delay_builds_no_bar(monkeypatch):
    monkeypatch.setattr(progress, "_in_notebook", lambda: True)
    with Progress(None, 100, "steps", "running") as bar:
        compile_something()
        bar.update(100)
        assert bar.bar is None


def test_a_closed_bar_hears_no_compile(capfd):
    with Progress(True, 100, "steps", "running"):
        pass
    capfd.readouterr()
    compile_something()
    assert capfd.readouterr().err == ""


# ---------------------------------------------------------------- in a real Jupyter kernel


def executed(cells: list[str], tmp_path):
    """A notebook of ``cells`` run in a fresh kernel."""
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in cells])
    nbclient.NotebookClient(nb, timeout=300, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    return nb


def widget_models(nb) -> list[str]:
    """The model names of the widgets a saved notebook keeps."""
    state = nb.metadata.get("widgets", {}).get("application/vnd.jupyter.widget-state+json", {}).get("state", {})
    return [model["model_name"] for model in state.values()]


RUNS = """
import numpy as np
import pinnedballs as pb
g = pb.FlatTorus(6, 6)
v = np.random.default_rng(0).standard_normal((g.n_balls, 2))
for seed in range(200):  # short calls, progress=None: none shows a bar
    pb.Simulation(g, v, seed=seed).run(steps=100)
"""

LONG = """
import pinnedballs.util.progress
pinnedballs.util.progress.DELAY = 0.0  # as if the call had run its 2 s
sim = pb.Simulation(g, v, seed=0)
sim.run(steps=5000)
"""


@pytest.mark.slow
def test_short_runs_in_a_notebook_leave_no_widget_and_a_long_one_its_final_state(tmp_path):
    pytest.importorskip("ipywidgets")
    nb = executed([RUNS, LONG], tmp_path)
    assert widget_models(nb).count("HBoxModel") == 1  # one bar, the long call's (2,200 models before)
    (shown,) = [o for o in nb.cells[1].outputs if o["output_type"] == "display_data"]
    assert "application/vnd.jupyter.widget-view+json" in shown["data"]
    assert re.match(r"running: 100%.*\| 5\.00k/5\.00k \[", shown["data"]["text/plain"])  # not its first "0.00/5.00k"
