"""docs/getting-started.md's parameter studies (issue 48): its study file is examples/studies/half_plane_sizes.json,
and its Python runs that study, from a checkout's examples, to the scaling law it prints."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shutil
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGE = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
SECTION = PAGE[PAGE.index("## A family of systems: parameter studies"):PAGE.index("## The contacts of a geometry")]


def test_the_page_shows_the_example_study_as_it_is():
    (shown,) = re.findall(r"```json\n(.*?)```", SECTION, flags=re.S)
    assert json.loads(shown) == json.loads((ROOT / "examples" / "studies" / "half_plane_sizes.json").read_text())
    commands = re.findall(r"^python3 -m pinnedballs (\S+)", SECTION, flags=re.M)
    assert commands == ["study", "info", "plot", "study", "schema"]


@pytest.mark.slow
def test_the_pages_python_runs_the_study(tmp_path, monkeypatch):
    shutil.copytree(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    (block,) = re.findall(r"```python\n(.*?)```", SECTION, flags=re.S)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block, "getting-started.md", "exec"), {})
    exponent = re.fullmatch(r"collisions ~ N\^([\d.]+) ± ([\d.]+)\n", out.getvalue())
    assert 1.5 < float(exponent.group(1)) < 1.9  # about 1.7 at these sizes (docs/extended.md)
    assert (tmp_path / "results" / "study" / "points.json").is_file()
