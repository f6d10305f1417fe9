"""The C yardstick ships with the project (issue 49, item 12): ``benchmarks/c/reference.sh`` builds and runs the
paper's chain in plain C, and every benchmark that quotes a ratio against C runs this copy, so a user can run
the README's and docs/performance.md's comparisons again."""

import pathlib
import re
import shutil
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "benchmarks" / "c" / "reference.sh"
LINE = re.compile(r"^reference N=(\d+) steps=(\d+) collisions=(\d+) energy=([\d.]+) Msteps/s=([\d.]+)$")
needs_cc = pytest.mark.skipif(shutil.which("cc") is None, reason="the C yardstick is built with cc")


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(SCRIPT), *args], capture_output=True, text=True, timeout=120)


@needs_cc
def test_the_paper_start_keeps_its_energy():
    """38x38 torus, ball 0 of energy 100, 200,000 elastic steps: the energy stays 100 to 1e-9, and a ball at
    rest hit by a moving one takes a collision (some steps collide, fewer than all)."""
    out = _run("38", "38", "200000")
    assert out.returncode == 0, out.stderr
    n, steps, collisions, energy, rate = LINE.match(out.stdout.strip()).groups()
    assert (int(n), int(steps)) == (38 * 38, 200_000)
    assert 0 < int(collisions) < int(steps)
    assert float(energy) == pytest.approx(100.0, abs=1e-9) and float(rate) > 0


@needs_cc
def test_a_bad_size_is_refused_with_exit_status_2():
    out = _run("3", "3", "10")
    assert out.returncode == 2 and out.stderr.strip() == "ROWS even >= 4, COLS >= 3" and out.stdout == ""


def test_every_benchmark_runs_the_shipped_yardstick():
    """No benchmark reaches outside the repository for its C loop."""
    benches = sorted((ROOT / "benchmarks").glob("*.py"))
    outside = [p.name for p in benches if re.search(r"""["']shared["']\s*/\s*["']bench["']|shared/bench""",
                                                    p.read_text())]
    using = [p.name for p in benches if "benchmarks\" / \"c\"" in p.read_text()]
    assert outside == [] and {"bench_torus.py", "bench_chain.py", "bench_sizes.py"} <= set(using)
