"""The pages a user reads (README.md and docs/*.md) say what the software does and what was measured, not the
project's history: no issue numbers (which change came from which issue is CHANGELOG.md's, the targets and
whether they were met benchmarks/results/targets.md's). And what a newcomer's first hour needs works as the
pages write it: the GPU code without a GPU, a Dask cluster started from a script."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pinnedballs as pb

ROOT = Path(__file__).resolve().parents[2]
USER_PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]

#: how a page names one of the project's issues: "issue 33", "issues 23, 25", "issue #4", "(issue 34, item 11)",
#: "Issue 35 (2026-11-27)", "the issue that asked", "the issue's own reading"
ISSUE = re.compile(r"\bissues?\s*(?:#\s*)?\d|\(issues?\b|\bissue\s*#|\bthe issue\b", re.IGNORECASE)


def text(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def blocks(path: Path, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text(path), flags=re.S)


# ---------------------------------------------------------------- pages for users, history apart


@pytest.mark.parametrize("page", USER_PAGES, ids=lambda p: p.name)
def test_a_user_page_names_no_issue(page):
    assert page.name != "CHANGELOG.md"
    named = [f"{page.name}:{n}: {line.strip()}" for n, line in enumerate(text(page).splitlines(), 1)
             if ISSUE.search(line)]
    assert not named, "project history goes to CHANGELOG.md, targets to benchmarks/results/:\n" + "\n".join(named)


def test_the_pattern_finds_what_the_pages_used_to_say():
    for said in ("## Issue 34, item 11 (2026-11-27): the small torus", "seed 0 (issue 33)", "before issue 17's",
                 "Issues 23, 25 and 27", "issue #12", "as the issue measured", "(issue 27 item 2)"):
        assert ISSUE.search(said), said
    for fine in ("NVIDIA/numba-cuda#118", "an issue of its own", "tissue 3"):
        assert not ISSUE.search(fine), fine


def test_history_and_targets_have_files_of_their_own():
    changelog = text(ROOT / "CHANGELOG.md")
    dates = re.findall(r"^## (\d{4}-\d\d-\d\d)$", changelog, flags=re.M)
    assert len(dates) >= 5 and dates == sorted(dates, reverse=True)          # dated entries, newest first
    targets = text(ROOT / "benchmarks" / "results" / "targets.md")
    assert re.search(r"\| met \|", targets) and re.search(r"\| missed \|", targets)
    readme = text(ROOT / "README.md")
    assert "CHANGELOG.md" in readme and "benchmarks/results/targets.md" in readme


def test_one_table_gives_the_bits_of_a_certified_run_and_the_other_pages_point_to_it():
    collisions = text(ROOT / "docs" / "collisions.md")
    assert "the table above" not in collisions
    section = collisions.split("## Choosing the bits of a certified run", 1)[1].split("\n## ", 1)[0]
    header = next(line for line in section.splitlines() if line.startswith("| half-plane"))
    for column in ("`precision`", "`late_precision`", "CPU time", "memory", "machine, date"):
        assert column in header
    for size in ("500x250", "1000x500", "2000x1000"):
        assert re.search(rf"^\| {size} ", section, flags=re.M), size
    for page in ("extended.md", "gpu.md", "performance.md"):
        assert "collisions.md#choosing-the-bits-of-a-certified-run" in text(ROOT / "docs" / page), page


def sentences(page: str) -> list[str]:
    """The sentences of ``docs/page`` (or README.md), each on one line."""
    words = " ".join(text(ROOT / page if page == "README.md" else ROOT / "docs" / page).split())
    return re.split(r"(?<=[.;:])\s+(?=[A-Z`(])", words)


@pytest.mark.parametrize("page", ["extending.md", "getting-started.md", "README.md"])
def test_the_pages_mark_a_run_as_the_writer_does(page):
    """`ResultsWriter.abort`: a Ctrl-C, or an exception in a writer or an observable, "interrupted" (it goes on);
    a decision certified arithmetic cannot make, or an error that left the chain between two states, "failed"
    (it cannot): no page says that any exception, or one in the loop, marks a run "interrupted"."""
    said = sentences(page)
    wrong = [x for x in said if '"interrupted"' in x and re.search(r"\bany (other )?exception|the loop\b", x)]
    wrong += [x for x in said if x.startswith("Any other exception during the run is saved the same way")]
    assert not wrong, wrong
    failed = [x for x in said if '"failed"' in x]
    assert any("certified" in x and "between two states" in x for x in failed), failed


def test_the_gpu_page_says_certified_replicas_on_a_cluster_are_refused_as_the_code_does():
    """`run.ensemble.ensemble_plan` refuses a certified ensemble on a Dask cluster's GPUs (tests/run/cli/
    test_device_refusals.py); the page said in one place that it is refused and in another that it runs on
    the cluster's CPUs."""
    about = [x for x in sentences("gpu.md") if "certified" in x and re.search(r"Dask cluster", x)]
    assert about and all("refused" in x for x in about), about


#: a time a page quotes for a command or a notebook: "about 10 seconds", "about 15 s", "about half a minute"
TIMING = re.compile(r"\b(?:about|in) (?:\d[\d.,]* ?(?:s|seconds?|minutes?)|(?:half a|a|one to two) minutes?)\b")


@pytest.mark.parametrize("page", ["README.md", "docs/reproduce.md", *sorted(
    str(p.relative_to(ROOT)) for p in (ROOT / "docs" / "tutorials").glob("*.py"))])
def test_a_time_a_page_quotes_says_it_holds_on_a_quiet_machine(page):
    """README's "about 10 s" for reproduce --quick, "about 15 s" for the simulator's example and the tutorials'
    "about half a minute" held only on a quiet machine (a shared one took twice as long): each says so."""
    words = " ".join(text(ROOT / page).replace("#", " ").split())
    quoted = [m for m in re.finditer(TIMING, words)]
    assert quoted or page != "README.md"
    bare = [words[max(0, m.start() - 60):m.end() + 60] for m in quoted if "quiet" not in words[m.start():m.end() + 60]]
    assert not bare, bare


# ---------------------------------------------------------------- the GPU without a GPU


def try_it_without_a_gpu() -> str:
    gpu = text(ROOT / "docs" / "gpu.md")
    return gpu.split("## Try it without a GPU", 1)[1].split("\n## ", 1)[0]


def test_the_gpu_example_runs_on_the_counter_stream_and_the_pages_show_it_under_the_simulator():
    spec = pb.load_spec(ROOT / "examples" / "gpu_counter_stream.json")
    assert spec.scheduler.kind == "uniform_random_pair" and spec.scheduler.stream == "counter"
    assert spec.build().geometry.n_balls <= 100                               # small enough for the simulator
    command = "NUMBA_ENABLE_CUDASIM=1 python3 -m pinnedballs run examples/gpu_counter_stream.json"
    assert command in try_it_without_a_gpu() and command in text(ROOT / "README.md")


@pytest.mark.slow
@pytest.mark.cuda
def test_the_commands_to_try_the_gpu_without_one_give_the_cpus_run(tmp_path):
    """docs/gpu.md's commands, as written but for the directories: the simulated GPU's run is the CPU's,
    bit for bit, with the steps and collisions its comment says."""
    (commands,) = [b for b in blocks(ROOT / "docs" / "gpu.md", "bash")
                   if "NUMBA_ENABLE_CUDASIM=1" in b and " pinnedballs run " in b]
    runs = [line.split("#")[0].split() for line in commands.splitlines() if " pinnedballs run " in line]
    assert len(runs) == 2 and runs[0][0] == "NUMBA_ENABLE_CUDASIM=1" and "--device" in runs[0]
    results = {}
    for argv in runs:
        env = {"NUMBA_ENABLE_CUDASIM": "1"} if argv[0] == "NUMBA_ENABLE_CUDASIM=1" else {}
        argv = argv[1:] if env else argv
        out = argv[argv.index("--out") + 1]
        argv[argv.index("--out") + 1] = str(tmp_path / out)
        assert argv[:3] == ["python3", "-m", "pinnedballs"]
        done = subprocess.run([sys.executable, *argv[1:], "--quiet", "--no-figures"], cwd=ROOT, capture_output=True,
                              text=True, timeout=300, env={**_environment(), **env})
        assert done.returncode == 0, done.stderr
        results[out] = pb.load(tmp_path / out)
    gpu, cpu = results["results/gpu"], results["results/cpu"]
    assert (gpu.device, cpu.device) == ("cuda", "cpu")
    said = re.search(r"([\d,]+) steps, ([\d,]+) collisions", commands).groups()
    assert (gpu.steps, gpu.collisions) == (cpu.steps, cpu.collisions) == tuple(int(n.replace(",", "")) for n in said)
    assert np.array_equal(gpu.velocities.view(np.uint64), cpu.velocities.view(np.uint64))


def _environment() -> dict[str, str]:
    import os

    return {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}


# ---------------------------------------------------------------- Dask for a newcomer


def dask_scripts() -> list[str]:
    return [b for b in blocks(ROOT / "docs" / "getting-started.md", "python") if 'if __name__ == "__main__":' in b]


def test_the_dask_section_shows_the_guard_the_cluster_by_hand_and_a_slurm_recipe():
    page = text(ROOT / "docs" / "getting-started.md")
    local, slurm = dask_scripts()
    assert "LocalCluster(" in local and "SLURMCluster(" in slurm
    for script in (local, slurm):
        compile(script, "getting-started.md", "exec")
    assert "Nanny failed to start" in page and "a recipe, not tested here" in page
    by_hand = "\n".join(b for b in blocks(ROOT / "docs" / "getting-started.md", "bash") if "dask scheduler" in b)
    assert re.search(r"^dask worker tcp://\S+", by_hand, flags=re.M)
    assert re.search(r"pinnedballs ensemble .* --dask tcp://\S+", by_hand)
    tutorial = text(ROOT / "docs" / "tutorials" / "ensembles_scaling.py")
    assert 'if __name__ == "__main__":' in tutorial and "dask scheduler" in tutorial


@pytest.mark.slow
def test_the_local_cluster_script_runs_as_a_script(tmp_path):
    """The guarded script of docs/getting-started.md, saved as a file and run from the checkout (unguarded,
    its workers, which import the file again, would each start a cluster: 'Nanny failed to start')."""
    script = tmp_path / "ensemble_local.py"
    script.write_text(dask_scripts()[0], encoding="utf-8")
    done = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert re.search(r"^count\s+8\.0+$", done.stdout, flags=re.M), done.stdout
    assert "Traceback" not in done.stderr and " - ERROR - " not in done.stderr, done.stderr  # closed in order
