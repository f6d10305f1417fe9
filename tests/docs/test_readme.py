"""The README's Python example prints what its comment says it prints, on a fresh install."""

import contextlib
import io
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


def test_readme_example_prints_its_comment():
    (block,) = [b for b in _blocks(ROOT / "README.md") if "print(" in b]
    printed = [line for line in block.splitlines() if line.startswith("print(")]
    assert len(printed) == 1, "the README example has one print, whose comment is its output"
    expected = printed[0].partition("#")[2].strip()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block, "README.md", "exec"), {})
    assert out.getvalue().strip() == expected


def test_getting_started_example_runs_and_freezes():
    """The same half-plane run on docs/getting-started.md ends frozen with its energy kept to 1e-12."""
    ns: dict = {}
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        for block in _blocks(ROOT / "docs" / "getting-started.md"):
            if "pb.load(" in block:  # needs a run directory on disk; the CLI tests cover it
                continue
            if "pb.run_study(" in block:  # writes a study directory: tests/docs/test_studies_page.py runs it
                continue
            if 'if __name__ == "__main__":' in block:  # a script, run as a file (test_user_pages), or a recipe
                continue
            exec(compile(block, "getting-started.md", "exec"), ns)
    sim = ns["sim"]
    assert sim.is_frozen()
    assert abs(sim.energy() - 100.0) < 1e-12 * 100
    steps, collisions, energy = out.getvalue().split()
    assert (int(steps), int(collisions), float(energy)) == (sim.steps, sim.collisions, 100.0)


def test_the_collision_log_example_prints_its_comments(tmp_path, monkeypatch):
    """docs/trajectories.md's collision log: logged, read back, replayed to the same bits, each
    print's output as its comment says."""
    (block,) = [b for b in _blocks(ROOT / "docs" / "trajectories.md") if "CollisionLog.read" in b]
    expected = [line.partition("#")[2].strip() for line in block.splitlines() if line.startswith("print(")]
    monkeypatch.chdir(tmp_path)  # it writes events.h5 where it runs
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block, "trajectories.md", "exec"), {})
    assert [line.strip() for line in out.getvalue().splitlines()] == [e.split(":")[0] for e in expected]
