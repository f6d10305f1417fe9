"""Objects that show themselves (issue 24, item 2): the HTML tables of a geometry, a simulation, a
spec, a run's results and an ensemble say the numbers a reader looks for first; geometries and
simulations show their picture (drawn once for a notebook); without matplotlib the table alone."""

from __future__ import annotations

import base64
import io
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import HALF_PLANE, TORUS, call, spec, write
from PIL import Image

import pinnedballs as pb
from pinnedballs.plot import display
from pinnedballs.run import ensemble as ens
from pinnedballs.specs import parse_spec

ROOT = Path(__file__).resolve().parents[2]


def rows(html: str) -> dict[str, str]:
    """The table's ``{name: value}``, unescaped."""
    import html as h

    return {h.unescape(k): h.unescape(v) for k, v in re.findall(r"<th[^>]*>(.*?)</th><td[^>]*>(.*?)</td>", html)}


def caption(html: str) -> str:
    return re.search(r"<caption[^>]*>(.*?)</caption>", html).group(1)


def embedded_png(html: str) -> Image.Image | None:
    found = re.search(r'src="data:image/png;base64,([^"]+)"', html)
    return None if found is None else Image.open(io.BytesIO(base64.b64decode(found.group(1))))


def half_plane_sim():
    half = pb.HalfPlane(6, 10)
    v = np.zeros((half.n_balls, 2))
    v[half.boundary_center()] = [0.0, np.sqrt(200.0)]
    return pb.Simulation(half, v, seed=3)


def test_a_geometry_shows_its_balls_contacts_and_view_beside_its_picture():
    half = pb.HalfPlane(6, 10)
    html = half._repr_html_()
    assert caption(html) == "HalfPlane: half_plane (rows=6, cols=10, radius=1.0, orientation=along)"
    assert rows(html) == {"balls": "60", "contacts": f"{half.n_contacts:,}",
                          "dimension": "2 (velocity components); positions in 2-D", "view": "plane",
                          "boundary": f"distances 0 to {half.boundary.distance.max():.3g}", "ball radius": "1"}
    picture = embedded_png(html)
    assert picture.format == "PNG" and picture.width == 8 * display.DISPLAY_DPI
    png = half._repr_png_()
    assert png.startswith(b"\x89PNG") and Image.open(io.BytesIO(png)).size == picture.size
    torus = pb.FlatTorus(4, 4)
    assert rows(torus._repr_html_())["boundary"] == "none"


def test_a_simulation_shows_its_counters_energy_and_freeze():
    sim = half_plane_sim()
    before = rows(sim._repr_html_())
    assert (before["steps"], before["collisions"], before["energy"]) == ("0", "0", "100")
    assert before["frozen"].startswith("no: ") and before["rule"] == repr(sim.rule)
    sim.run_until_frozen(max_steps=10**7)
    after = rows(sim._repr_html_())
    assert after["steps"] == f"{sim.steps:,}" and after["collisions"] == f"{sim.collisions:,}"
    assert after["frozen"] == "yes" and float(after["energy"]) == pytest.approx(100.0, rel=1e-12)
    assert after["momentum"] == "(" + ", ".join(f"{x:.6g}" for x in sim.momentum()) + ")"
    # rows, then between rows
    assert after["geometry"] == f"HalfPlane: 60 balls, {6 * 9 + 5 * 19} contacts, dimension 2"
    assert embedded_png(sim._repr_html_()) is not None


def test_the_notebook_bundle_draws_the_picture_once(monkeypatch):
    sim = half_plane_sim()
    drawn = []
    real = display.state_png
    monkeypatch.setattr(display, "state_png", lambda *a, **k: drawn.append(1) or real(*a, **k))
    bundle = sim._repr_mimebundle_()
    assert sorted(bundle) == ["image/png", "text/html"] and len(drawn) == 1
    assert embedded_png(bundle["text/html"]).tobytes() == Image.open(io.BytesIO(bundle["image/png"])).tobytes()
    assert list(sim._repr_mimebundle_(include={"text/html"}, exclude=None)) == ["text/html"]


def test_a_spec_shows_its_parts(tmp_path):
    s = pb.load_spec(write(tmp_path / "s.json", spec(TORUS, description="a small torus")))
    table = rows(s._repr_html_())
    assert table["geometry"] == "flat_torus (rows=4, cols=4, radius=1.0)"
    assert table["initial"].startswith("single_ball (ball=0, direction=[1.0, 0.0], energy=100.0")
    assert table["stop"].startswith("steps=1000") and table["seed"] == "1"
    assert table["snapshots"].startswith("at_steps=[0, 250, 1000]") and table["description"] == "a small torus"


def test_a_runs_results_show_file_status_and_snapshots(tmp_path):
    assert call("run", write(tmp_path / "s.json", HALF_PLANE), "--out", tmp_path / "r", "--quiet",
                "--no-figures")[0] == 0
    res = pb.load(tmp_path / "r")
    table = rows(res._repr_html_())
    assert table["file"] == str(tmp_path / "r" / "results.h5") and table["status"] == "done (frozen)"
    assert table["snapshots"] == "0" and table["seed"] == str(HALF_PLANE["seed"])
    assert table["steps"] == f"{res.steps:,}" and table["frozen"] == "yes"
    assert table["geometry"] == f"half_plane: 60 balls, {len(res.pairs)} contacts, dimension 2"


def test_an_ensemble_shows_its_replicas_and_final_counts():
    result = ens.run_ensemble(parse_spec(HALF_PLANE), 3, workers=1)
    table = rows(result._repr_html_())
    assert table["replicas"] == "3 (3 done, 0 failed)" and table["where"].startswith("in-process, ")
    steps = result.column("steps")
    assert table["steps"] == f"mean {steps.mean():.6g} \u00b1 {steps.std(ddof=1):.3g} over 3 final states"
    assert table["frozen"] == "3 of 3 final states"
    assert len(repr(result)) < 120


@pytest.mark.slow
def test_without_matplotlib_a_notebook_gets_the_tables_alone():
    """matplotlib blocked: no picture (None), the same table; ``import pinnedballs`` loads neither
    matplotlib nor pandas nor xarray."""
    code = ("import sys; sys.modules['matplotlib'] = None\n"
            "import json, pinnedballs as pb\n"
            "loaded = sorted(m for m in ('matplotlib', 'pandas', 'xarray') if sys.modules.get(m))\n"
            "g = pb.HalfPlane(6, 10)\n"
            "print(json.dumps([loaded, g._repr_png_(), 'data:image' in g._repr_html_(), g._repr_html_().count('<tr>'),"
            " sorted(g._repr_mimebundle_())]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True).stdout
    assert json.loads(out) == [[], None, False, 6, ["text/html"]]


def test_a_failed_certified_runs_results_say_its_freeze_is_unknown(tmp_path):
    """Issue 42: certified arithmetic at 64 bits cannot count this run's live contacts (``approaching`` -1):
    the table says unknown, not "no: -1 contacts approaching"."""
    at_64_bits = spec(HALF_PLANE, geometry={"kind": "half_plane", "length": 30, "depth": 15}, seed=1,
                      initial__ball="boundary_center", initial__direction="inward", arithmetic="certified",
                      precision=64)
    code, _, err = call("run", write(tmp_path / "s.json", at_64_bits), "--out", tmp_path / "r", "--quiet",
                        "--no-figures")
    res = pb.load(tmp_path / "r")
    assert code == 2 and (res.status, res.approaching) == ("failed", -1), err
    table = rows(res._repr_html_())
    assert table["status"].startswith("failed")
    assert table["frozen"] == "unknown: certified arithmetic could not count the live contacts at these bits"
