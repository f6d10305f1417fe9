"""The tutorials (issue 24, item 1): each ``docs/tutorials/*.py`` (a jupytext percent script) runs top to
bottom as a notebook in a fresh kernel, shows its pictures and tables, and prints what its text says;
each is a page of the documentation site."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.py"))
#: a cell that runs longer is a hang (the longest, `check_rule` compiling a rule defined in a notebook
#: in own_components, takes about 45 s on 2 cores under a load of 10)
CELL_SECONDS = 120


#: an executed tutorial, as saved (its pictures, the widget state of its bars) is at most this long
#: (exact_counts was 20 MB, 15.6 of them the widgets of calls that had shown no bar: issue 34, item 1) ...
TUTORIAL_BYTES = 1_000_000
#: ... but first_run, whose pictures and movie alone take 1.25 MB
FIRST_RUN_BYTES = 1_600_000
#: the widget state a saved tutorial keeps, at most: the bars of the calls that ran over 2 s, about 9 kB
#: each (none or one here; 30 leave room for a slow machine)
WIDGET_BYTES = 300_000


def executed(path: Path, tmp_path: Path):
    """The notebook of ``path`` after running every cell in a fresh kernel, in ``tmp_path``, its temporary
    folder a private one that the tutorial leaves as it found it (a run of first_run left 1.2 MB there)."""
    jupytext = pytest.importorskip("jupytext")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    nb = run(jupytext.read(path), tmp_path, env={**os.environ, "TMPDIR": str(scratch)})
    left = sorted(p.name for p in scratch.iterdir() if p.name != "dask-scratch-space")  # Dask's own, reused
    assert not left, f"{path.name} left {left} in its temporary folder"
    return nb


def run(nb, tmp_path: Path, env: dict[str, str] | None = None):
    """``nb`` after running every cell in a fresh kernel, in ``tmp_path`` (with the environment ``env``)."""
    nbclient = pytest.importorskip("nbclient")
    nbclient.NotebookClient(nb, timeout=CELL_SECONDS, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute(**({"env": env} if env else {}))
    return nb


def assert_small(nb, most: int = TUTORIAL_BYTES) -> None:
    """``nb`` saved as a file is at most ``most`` bytes, its widget state at most `WIDGET_BYTES`."""
    import nbformat

    assert len(json.dumps(nb.metadata.get("widgets", {}))) <= WIDGET_BYTES
    assert len(nbformat.writes(nb).encode()) <= most


def outputs(nb, code: str) -> list[dict]:
    """The outputs of the one code cell whose source contains ``code``."""
    (cell,) = [c for c in nb.cells if c.cell_type == "code" and code in c.source]
    return cell.outputs


def text(outs: list[dict]) -> str:
    """What the cell printed, then the text of what it showed, without progress bars (`printed`)."""
    return "".join(_without_bars(o) if o.get("output_type") == "stream" else _shown(o) for o in outs)


def printed(outs: list[dict]) -> str:
    """What the cell printed (stdout and stderr), without progress bars: a call that runs more than 2 s,
    as any may on a busy machine, shows one in a notebook: a widget with ipywidgets, else tqdm's text
    on stderr, each redraw after a carriage return that the kernel's stream may have dropped (a busy
    CI showed the redraws run together) and its closing newline a chunk of its own."""
    return "".join(_without_bars(o) for o in outs if o.get("output_type") == "stream")


#: a tqdm bar's meter: "[00:01<00:02, 3.4 steps/s]", the end unknown "[00:01, 3.4 steps/s]", or before anything
#: has run "[00:00]" (no rate yet: `util.progress`)
_BAR = re.compile(r"\[\d+:\d\d(?::\d\d)?[<,\]]")
#: the kind of output a widget is (tqdm's bar, when ipywidgets is installed)
WIDGET = "application/vnd.jupyter.widget-view+json"


def _without_bars(out: dict) -> str:
    """A stream's text; on stderr without a bar's lines (its redraws, split at their carriage returns,
    and its closing newline)."""
    text = out.get("text", "")
    if out.get("name") != "stderr":
        return text
    return "".join(line for line in text.splitlines(keepends=True) if line.strip() and not _BAR.search(line))


def _shown(out: dict) -> str:
    """The text of what a cell showed; none for a widget (a bar's text is its state)."""
    data = out.get("data", {})
    return "" if WIDGET in data else data.get("text/plain", "")


def kinds(nb) -> list[str]:
    return [kind for c in nb.cells if c.cell_type == "code" for o in c.outputs for kind in o.get("data", {})]


def test_every_tutorial_is_a_percent_script_and_a_page_of_the_site():
    assert [p.name for p in TUTORIALS] == ["ensembles_scaling.py", "exact_counts.py", "first_run.py",
                                           "own_components.py", "studies.py"]
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for path in TUTORIALS:
        source = path.read_text(encoding="utf-8")
        assert "format_name: percent" in source and source.count("# %%") >= 10
        assert f"tutorials/{path.name}" in nav


@pytest.mark.slow
def test_a_first_run_and_its_figures(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "first_run.py", tmp_path)
    assert_small(nb, FIRST_RUN_BYTES)
    assert printed(outputs(nb, "frozen = sim.run_until_frozen")) == "True 266938 47668 100.0\n"  # the README's
    assert "geometry.lenght: unknown key; did you mean 'length'?" in text(outputs(nb, "pb.load_spec(bad)"))
    last = text(outputs(nb, "table.iloc[-1]"))
    assert re.search(r"steps\s+243682", last) and re.search(r"frozen\s+True", last)
    assert kinds(nb).count("image/png") >= 8                               # the pictures, and the geometry's
    assert "data:image/gif;base64," in outputs(nb, "res.animate(")[0]["data"]["text/html"]


@pytest.mark.slow
def test_ensembles_and_the_scaling_law(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "ensembles_scaling.py", tmp_path)
    assert_small(nb)
    fit = re.fullmatch(r"collisions ~ [\d.]+ N\^([\d.]+)\n", printed(outputs(nb, "np.polyfit")))
    assert 1.5 < float(fit.group(1)) < 1.8                                 # docs/extended.md: 1.72 to 1.63 here
    assert text(outputs(nb, "on_dask.to_pandas().equals")) == "True"       # the same table on Dask
    said = "".join(_without_bars(o) for c in nb.cells if c.cell_type == "code" for o in c.outputs
                   if o.get("output_type") == "stream")
    assert "Traceback" not in said and " - ERROR - " not in said, said     # the cluster closed after its client
    assert text(outputs(nb, "pb.load_ensemble(")).startswith("True\nEnsembleResult(8 replicas of half_plane")
    scaling = text(outputs(nb, "scaling = pd.DataFrame"))
    assert all(f"{size} " in scaling for size in ("10x5", "20x10", "30x15", "60x30", "100x50"))


@pytest.mark.slow
def test_parameter_studies(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "studies.py", tmp_path)
    assert_small(nb)
    fits = re.findall(r"(along|across): collisions ~ [\d.]+ N\^([\d.]+) ± ([\d.]+)\n",
                      printed(outputs(nb, 'res.fit("collisions"')))
    assert [name for name, *_ in fits] == ["along", "across"]
    assert all(1.5 < float(a) < 1.9 and 0 < float(se) < 0.2 for _, a, se in fits)  # docs/extended.md: about 1.7
    assert "image/png" in kinds(nb) and "StudyResult" in text(outputs(nb, "res = pb.run_study("))
    assert printed(outputs(nb, "more = pb.run_study(")) == ("ran now: [6, 7]\n"
                                                             "the six points done keep their rows: True\n")
    assert "points:      8 of 8 done" in printed(outputs(nb, '"info"'))


@pytest.mark.slow
def test_your_own_geometry_rule_and_scheduler(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "own_components.py", tmp_path)
    assert_small(nb)
    assert printed(outputs(nb, "check_geometry(honeycomb)")) == "honeycomb: every geometry check passed\n"
    assert printed(outputs(nb, "star = Star(arms=5, length=6)")) == (
        "Star(arms=5, length=6): 31 balls, 30 contacts; every geometry check passed\n")
    assert printed(outputs(nb, "check_rule(ByDirection(1.0, 0.5))")) == "ByDirection: every rule check passed\n"
    assert printed(outputs(nb, "check_scheduler(Wander())")) == "Wander: every scheduler check passed\n"
    # the star's three runs (the text: all frozen; the elastic one keeps 100 over three arms; the
    # lossy one loses energy, the wandering picks far less, nearly all of it down arm 0 along x)
    table = text(outputs(nb, "table = pd.DataFrame.from_dict(rows"))
    elastic, uniform, wandering = (re.search(rf"{name}\s+True\s+\d+\s+\d+\s+([\d.]+)\s+([\d.]+)", table)
                                   for name in ("elastic, uniform picks", "ByDirection, uniform picks",
                                                "ByDirection, wandering picks"))
    assert float(elastic.group(1)) == pytest.approx(100.0, abs=1e-9)
    assert float(uniform.group(1)) < 90 < float(wandering.group(1)) < 100
    assert float(wandering.group(2)) == pytest.approx(100 * np.cos(np.pi / 12) ** 2, abs=0.1)  # arm 0: cos²15°
    assert re.fullmatch(r"frozen True after \d+ collisions: energy 44.981 -> \d+\.\d+\n",
                        printed(outputs(nb, "honeycomb.n_balls, 2))")))
    # the kit's message for a rule that makes energy
    broken = printed(outputs(nb, "check_rule(ByDirection(1.0, 1.2))"))
    assert re.fullmatch(r"energy never created: 2-D flat, equal masses, pair \d+: t_i = .*: energy ([\d.]+) "
                        r"became ([\d.]+)\n", broken)
    before, after = map(float, re.search(r"energy ([\d.]+) became ([\d.]+)", broken).groups())
    assert after > before
    assert printed(outputs(nb, "CheckedByDirection(1.0, 1.2)")) == (
        "r_y: a coefficient of restitution must be in [0, 1], got 1.2\n")
    tests = printed(outputs(nb, "mark = parametrize_with_checks")).splitlines()
    assert tests[0] == "15 tests:" and "Wander()-check_scheduler_split_run" in tests
    assert kinds(nb).count("image/png") >= 4                               # two geometries, the runs, a simulation


@pytest.mark.slow
def test_exact_counts_and_every_order(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "exact_counts.py", tmp_path)
    assert_small(nb)
    same = printed(outputs(nb, "float_run, exact_run = "))
    assert same.startswith("same count: True | last collision on the same step: True\n")
    difference = float(re.search(r"exact ones: ([\d.e+-]+)", same).group(1))
    assert 0 < difference < 1e-14                                          # a few ULP of speeds up to 14
    counts = text(outputs(nb, "counts = pd.DataFrame(rows).T"))
    assert re.search(r"float\s+True\s+48417\s+8321\s+100.0", counts)
    assert re.search(r"exact\s+True\s+48417\s+8321\s+100.0", counts)
    margin = printed(outputs(nb, "margin = float_run.closing_margin()"))
    smallest, largest = map(float, re.search(r"smallest collision ([\d.e+-]+) thresholds, largest remnant "
                                             r"([\d.e+-]+) thresholds", margin).groups())
    assert smallest / largest > 1e10 and margin.endswith("thin: False\n")  # "about ten orders of magnitude"
    thin = printed(outputs(nb, "big_run = pb.Simulation("))
    assert thin.startswith("476553 collisions; smallest collision 1.19 thresholds, largest remnant 0.0707")
    assert "\nMarginWarning: the closing margin is thin (" in thin
    near = text(outputs(nb, "EXACT_BIG = 476_553"))
    assert re.search(r"60x30\s+8321\s+8321\s+8321\s+8321\s+8321\s+8321", near)
    assert re.search(r"200x100\s+476555\s+476553\s+476553\s+476551\s+476540\s+476553", near)
    assert printed(outputs(nb, "agree = n_e.index[")) == (
        "60 x 30: N_e - exact = +43 at e = 1e-30 and -3,442 at e = 1e-2; N_e = exact at 21 of 57 resolutions, "
        "from 3.2e-17 to 3.2e-07\n"
        "200 x 100: N_e - exact = +1,686 at e = 1e-30 and -423,078 at e = 1e-2; N_e = exact at 3 of 57 "
        "resolutions, from 3.2e-17 to 3.2e-16\n")
    assert printed(outputs(nb, "orders = pb.explore_orders(tiny, v_tiny)")).startswith(
        "Collisions until frozen over every order (1,652 distinct states): fewest 7, most 15.\n")
    assert printed(outputs(nb, "scheduler=pb.Replay(orders.max_order)")) == \
        "frozen True after 15 steps, 15 collisions\n"
    random_order = re.fullmatch(r"random order: (\d+) to (\d+) collisions, mean ([\d.]+); every order: 7 to 15\n",
                                printed(outputs(nb, "random_counts = []")))
    assert 7 <= int(random_order.group(1)) and int(random_order.group(2)) < 15  # the text: never the most
    best = printed(outputs(nb, "best = pb.search_max_collisions(")).splitlines()
    assert best[0] == "Collisions until frozen over every order (3 distinct states): fewest 2, most 2."
    assert best[1].startswith("Most collisions found: 7 (best of 200 trials")
    assert printed(outputs(nb, "scheduler=pb.Replay(best.order)")) == "True 7\n"
    assert kinds(nb).count("image/png") >= 3                               # N_e, the replayed state, the orders


# ---------------------------------------------------------------- the checks read no progress bar

#: cells run with every call showing its bar at once, as on a machine where each takes over 2 s
#: (issue 34, item 3: a busy CI read a bar as a cell's output): tqdm's text on stderr, or its widget
BARS_AT_ONCE = {"text": "import sys\nsys.modules['ipywidgets'] = None  # no widget: tqdm's text\n", "widget": ""}
CELLS = ["import pinnedballs.util.progress\npinnedballs.util.progress.DELAY = 0.0\n"
         "import numpy as np\nimport pinnedballs as pb\n"
         "def kicked(g):\n    v = np.zeros((g.n_balls, 2))\n    v[g.boundary_center()] = [0.0, 1.0]\n    return v\n",
         "best = pb.search_max_collisions(pb.HalfPlane(2, 2), trials=20, seed=0)\nprint('most', best.collisions)",
         "orders = pb.explore_orders(pb.HalfPlane(4, 4), kicked(pb.HalfPlane(4, 4)), max_states=50)\n"
         "orders.max_collisions >= orders.min_collisions",
         "sim = pb.Simulation(pb.HalfPlane(10, 5), kicked(pb.HalfPlane(10, 5)), seed=0)\n"
         "print(sim.run_until_frozen(max_steps=10**6), sim.run(steps=1000), sim.collisions)"]


@pytest.mark.slow
@pytest.mark.parametrize("bar", ["text", "widget"])
def test_the_checks_read_what_cells_print_not_their_bars(bar, tmp_path):
    """`printed` and `text` read what the cells print and show, bars or none (they kept the redraws of a
    bar with no end, split at their carriage returns, its closing newline, and a widget's text)."""
    import nbformat

    import pinnedballs as pb

    if bar == "widget":
        pytest.importorskip("ipywidgets")
    nb = run(nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(c) for c in [BARS_AT_ONCE[bar], *CELLS]]),
             tmp_path)
    best = pb.search_max_collisions(pb.HalfPlane(2, 2), trials=20, seed=0, progress=False)
    g = pb.HalfPlane(10, 5)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.0, 1.0]
    sim = pb.Simulation(g, v, seed=0)
    sim.run_until_frozen(max_steps=10**6, progress=False)
    barred = [c for c in nb.cells if c.outputs and any(o.get("name") == "stderr" or WIDGET in o.get("data", {})
                                                       for o in c.outputs)]
    assert len(barred) == 3  # each call showed its bar
    assert printed(outputs(nb, "best = pb.search_max_collisions(")) == f"most {best.collisions}\n"
    assert text(outputs(nb, "orders = pb.explore_orders(")) == "True"
    assert printed(outputs(nb, "sim.run_until_frozen(")) == f"True 1000 {sim.collisions}\n"
