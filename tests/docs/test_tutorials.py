"""The tutorials (issue 24, item 1): each ``docs/tutorials/*.py`` (a jupytext percent script) runs top to
bottom as a notebook in a fresh kernel, shows its pictures and tables, and prints what its text says;
each is a page of the documentation site."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TUTORIALS = sorted((ROOT / "docs" / "tutorials").glob("*.py"))
#: a cell that runs longer is a hang (the longest, the Dask cluster's start, takes about 15 s)
CELL_SECONDS = 120


def executed(path: Path, tmp_path: Path):
    """The notebook of ``path`` after running every cell in a fresh kernel, in ``tmp_path``."""
    jupytext = pytest.importorskip("jupytext")
    nbclient = pytest.importorskip("nbclient")
    nb = jupytext.read(path)
    nbclient.NotebookClient(nb, timeout=CELL_SECONDS, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    return nb


def outputs(nb, code: str) -> list[dict]:
    """The outputs of the one code cell whose source contains ``code``."""
    (cell,) = [c for c in nb.cells if c.cell_type == "code" and code in c.source]
    return cell.outputs


def text(outs: list[dict]) -> str:
    """What the cell printed, then the text of what it showed."""
    return "".join(o.get("text", "") or o.get("data", {}).get("text/plain", "") for o in outs)


def printed(outs: list[dict]) -> str:
    return "".join(o.get("text", "") for o in outs if o.get("output_type") == "stream")


def kinds(nb) -> list[str]:
    return [kind for c in nb.cells if c.cell_type == "code" for o in c.outputs for kind in o.get("data", {})]


def test_every_tutorial_is_a_percent_script_and_a_page_of_the_site():
    assert [p.name for p in TUTORIALS] == ["ensembles_scaling.py", "first_run.py"]
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    for path in TUTORIALS:
        source = path.read_text(encoding="utf-8")
        assert "format_name: percent" in source and source.count("# %%") >= 10
        assert f"tutorials/{path.name}" in nav


@pytest.mark.slow
def test_a_first_run_and_its_figures(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "first_run.py", tmp_path)
    assert printed(outputs(nb, "frozen = sim.run_until_frozen")) == "True 266938 47668 100.0\n"  # the README's
    assert "geometry.lenght: unknown key; did you mean 'length'?" in text(outputs(nb, "pb.load_spec(bad)"))
    last = text(outputs(nb, "table.iloc[-1]"))
    assert re.search(r"steps\s+243682", last) and re.search(r"frozen\s+True", last)
    assert kinds(nb).count("image/png") >= 8                               # the pictures, and the geometry's
    assert "data:image/gif;base64," in outputs(nb, "res.animate(")[0]["data"]["text/html"]


@pytest.mark.slow
def test_ensembles_and_the_scaling_law(tmp_path):
    nb = executed(ROOT / "docs" / "tutorials" / "ensembles_scaling.py", tmp_path)
    fit = re.fullmatch(r"collisions ~ [\d.]+ N\^([\d.]+)\n", printed(outputs(nb, "np.polyfit")))
    assert 1.5 < float(fit.group(1)) < 1.8                                 # docs/extended.md: 1.72 to 1.63 here
    assert text(outputs(nb, "on_dask.to_pandas().equals")) == "True"       # the same table on Dask
    assert text(outputs(nb, "pb.load_ensemble(")).startswith("True\nEnsembleResult(8 replicas of half_plane")
    scaling = text(outputs(nb, "scaling = pd.DataFrame"))
    assert all(f"{size} " in scaling for size in ("10x5", "20x10", "30x15", "60x30", "100x50"))
