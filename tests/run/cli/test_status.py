"""Feedback from the first second: on a terminal a status line names each stage from the start;
off a terminal and with --quiet, nothing. Terminals are pseudo-terminals (`pty`), bounded in time."""

from __future__ import annotations

import fcntl
import io
import json
import os
import pty
import select
import struct
import subprocess
import sys
import termios
import time
from pathlib import Path

import pytest
from helpers import TORUS, spec, write

from pinnedballs.run.cli import main as cli
from pinnedballs.run.cli import status

pytestmark = pytest.mark.slow  # subprocesses, full runs: the full suite (CI) runs these

ROOT = Path(__file__).resolve().parents[3]
LIMIT_SECONDS = 240  # a bound on a hung child, not a measurement


def on_terminal(*argv) -> tuple[int, str, str]:
    """``(exit status, what the terminal showed on stderr, stdout)`` of ``pinnedballs ARGV`` with stderr a pty."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a terminal 100 columns wide
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MPLBACKEND": "Agg"}
    proc = subprocess.Popen([sys.executable, "-m", "pinnedballs", *map(str, argv)], stdout=subprocess.PIPE,
                            stderr=slave, stdin=subprocess.DEVNULL, env=env)
    os.close(slave)
    shown = bytearray()
    deadline = time.monotonic() + LIMIT_SECONDS
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 1.0)
            if ready:
                try:
                    chunk = os.read(master, 65536)
                except OSError:  # the child closed the terminal
                    break
                if not chunk:
                    break
                shown += chunk
            elif proc.poll() is not None:
                break
        out = proc.communicate(timeout=max(1.0, deadline - time.monotonic()))[0].decode()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
    return proc.returncode, shown.decode(errors="replace"), out


def stages(shown: str) -> list[str]:
    """The status messages in the order shown (each written after a line clear)."""
    return [part.split(" ...")[0] for part in shown.split(status.CLEAR)
            if part.startswith("pinnedballs: ")]


RUN = spec(stop={"steps": 400_000}, snapshots={"at_steps": [200_000]})


def test_run_on_a_terminal_names_each_stage_from_the_start(tmp_path):
    code, shown, out = on_terminal("run", write(tmp_path / "s.json", RUN), "--out", tmp_path / "out")
    assert code == 0, shown
    assert shown.startswith(status.CLEAR + "pinnedballs: reading the spec ...")  # before the heavy imports
    assert stages(shown) == ["pinnedballs: reading the spec", "pinnedballs: building the geometry",
                             "pinnedballs: compiling the loop (once: numba caches it on disk)",
                             "pinnedballs: drawing figures"]
    bar = shown[shown.index("compiling the loop"):shown.index("drawing figures")]
    assert "running:" in bar and "400k/400k" in bar                      # the bar, to the end
    assert shown.endswith(status.CLEAR)                                   # the line left clean
    assert out.startswith("steps: 400,000 steps")


def test_run_with_quiet_shows_nothing_on_a_terminal(tmp_path):
    code, shown, out = on_terminal("run", write(tmp_path / "s.json", TORUS), "--out", tmp_path / "out", "--quiet",
                                   "--no-figures")
    assert (code, shown, out) == (0, "", "")


def test_a_bad_spec_on_a_terminal_ends_on_one_clean_error_line(tmp_path):
    bad = spec(geometry__rows=5)
    code, shown, _ = on_terminal("run", write(tmp_path / "s.json", bad), "--out", tmp_path / "out")
    assert code == 2
    assert shown.split(status.CLEAR)[-1] == ("pinnedballs: error: geometry.rows: must be even for a flat torus, "
                                             "got 5\r\n")


def test_ensemble_on_a_terminal_shows_progress_over_replicas(tmp_path):
    small = spec(stop={"steps": 2_000}, snapshots=...)
    code, shown, out = on_terminal("ensemble", write(tmp_path / "s.json", small), "--replicas", 3, "--workers", 1,
                                   "--out", tmp_path / "ens")
    assert code == 0, shown
    assert stages(shown)[:2] == ["pinnedballs: reading the spec", "pinnedballs: building the geometry"]
    assert stages(shown)[-1] == "pinnedballs: writing the tables and histograms"
    assert "replicas:   0%" in shown and "3/3" in shown
    assert out.startswith("3 of 3 replicas done")


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("terminal, quiet, shown", [(True, False, True), (True, True, False), (False, False, False)],
                         ids=["terminal", "terminal --quiet", "pipe"])
def test_reproduce_reports_its_stages_on_a_terminal_only(tmp_path, monkeypatch, terminal, quiet, shown):
    import pinnedballs.run.reproduction as reproduction

    seen = {}

    def fake(out, *, log, progress, **kwargs):  # records what the command asked for, writes what it reads
        seen.update(log=log, progress=progress)
        if log is not None:
            log("[   0.0 s] half-plane: single runs")
        Path(out).mkdir(parents=True, exist_ok=True)
        (Path(out) / "results.json").write_text(json.dumps({"wall_seconds": 0.0, "failures": []}))
        return Path(out) / "report.md"

    monkeypatch.setattr(reproduction, "reproduce", fake)
    err = _Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    assert cli.main(["reproduce", "--out", str(tmp_path / "r"), *(["--quiet"] if quiet else [])]) == 0
    assert seen["progress"] is shown  # the stages are told in any case (a note names its run), and shown here only:
    text = err.getvalue()
    if shown:
        assert text == (f"{status.CLEAR}pinnedballs: loading the reproduction ...{status.CLEAR}"
                        "[   0.0 s] half-plane: single runs\n")
    else:
        assert text == ""
