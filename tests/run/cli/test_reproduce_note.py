"""Off a terminal, where ``reproduce`` shows no stages, its thin-margin note names the run it is about (issue 42,
item 5): the quick reproduction's 200x100 half-plane (seed 0) freezes with collisions closing within 7.06
thresholds of the criterion."""

from __future__ import annotations

import pytest
from helpers import call


@pytest.mark.slow
def test_the_quick_reproductions_thin_margin_note_names_its_run(tmp_path):
    code, stdout, err = call("reproduce", "--quick", "--out", tmp_path / "repro")
    notes = [line for line in err.splitlines() if line.startswith("pinnedballs: note: ")]
    assert code == 0 and len(notes) == 1, err
    assert notes[0].startswith("pinnedballs: note: half-plane 200x100: single run: the closing margin is thin "
                               "(smallest collision 7.06 thresholds"), notes
    assert stdout.startswith(f"wrote {tmp_path / 'repro' / 'report.md'} in ")
