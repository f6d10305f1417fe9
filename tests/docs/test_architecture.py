"""docs/architecture.md runs as written: its engine registers itself, runs a half-plane to frozen with the
sequential engine's bits, refuses the xoshiro stream in one line and passes the battery."""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import pytest

from pinnedballs.engine import engines, unregister
from pinnedballs.testing import engine_checks_for, parametrize_with_checks

PAGE = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


@pytest.fixture(scope="module")
def page():
    """The namespace and the printed lines after every python block of the page, in order; the page's engine
    taken out of the door afterwards."""
    ns, out = {}, io.StringIO()
    with contextlib.redirect_stdout(out):
        for block in re.findall(r"```python\n(.*?)```", PAGE.read_text(encoding="utf-8"), flags=re.S):
            exec(compile(block, str(PAGE), "exec"), ns)
    yield ns, out.getvalue().splitlines()
    unregister("python_counter")


def test_the_page_lists_the_built_in_engines_as_the_door_does():
    listed = re.search(r"^# (\[.*\])$", PAGE.read_text(encoding="utf-8"), flags=re.M).group(1)
    assert eval(listed) == [e.name for e in engines() if e.name != "python_counter"]


def test_its_engine_runs_to_frozen_with_the_sequential_bits_and_refuses_in_one_line(page):
    ns, printed = page
    assert ns["mine"].engine_name == "python_counter" and ns["theirs"].engine_name == "sequential"
    assert ns["mine"].get_state().identical(ns["theirs"].get_state()) and ns["mine"].is_frozen()
    said = re.search(r"print\(mine\.steps, mine\.collisions\)\s+# (\d+) (\d+)", PAGE.read_text(encoding="utf-8"))
    assert printed[0] == f"{said.group(1)} {said.group(2)}" == f"{ns['mine'].steps} {ns['mine'].collisions}"
    assert printed[1] == ("engine: 'python_counter' draws the counter stream's picks; engine 'sequential' runs "
                          "the others")


def test_its_engine_is_in_the_door_and_has_the_whole_battery(page):
    ns, _ = page
    assert "python_counter" in [e.name for e in engines()]
    mark = parametrize_with_checks([ns["PythonEngine"]()])
    names = [c.__name__ for c in engine_checks_for(ns["PythonEngine"]())]
    assert [p.id.rsplit("-", 1)[1] for p in mark.args[1]] == names and len(names) == 6
