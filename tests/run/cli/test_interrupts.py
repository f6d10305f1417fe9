"""Ctrl-C on the command line (issue 20, item 3): the exit status and the results file always agree.
Exit 130 leaves the file "interrupted" at a state of the run (never "running" at step 0), from
which --resume ends on the bits of an unbroken run; a run that had finished exits 0, even when
the Ctrl-C (once or twice) comes during its final write or its figures."""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import TORUS, assert_identical, reference, resume, spec, write

from pinnedballs.results.load import load

pytestmark = pytest.mark.slow  # subprocesses

ROOT = Path(__file__).resolve().parents[3]

RUN = spec(TORUS, geometry__rows=10, geometry__cols=10, initial={"kind": "gaussian", "energy": 100.0},
           stop={"steps": 6_000}, snapshots={"every_steps": 250}, checkpoint={"every_seconds": 0}, seed=21)

#: the command line with small chunks; SIGNAL_AT_DONE="before" or "after" sends itself two SIGINTs
#: just before or just after the final checkpoint (the one that says "done") is written
CHILD = """
import os, signal, sys
from pinnedballs.run.cli import main as cli
from pinnedballs.engine import driver
from pinnedballs.results import store
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 500, 0
when, checkpoint = os.environ.get("SIGNAL_AT_DONE", ""), store.ResultsStore.checkpoint
def twice():
    os.kill(os.getpid(), signal.SIGINT)
    os.kill(os.getpid(), signal.SIGINT)
def signalling(self, frames, state, **kwargs):
    if kwargs.get("status") == "done" and when == "before":
        twice()
    checkpoint(self, frames, state, **kwargs)
    if kwargs.get("status") == "done" and when == "after":
        twice()
store.ResultsStore.checkpoint = signalling
sys.exit(cli.main())  # as the program does: its arguments from sys.argv
"""


def child(spec_path: Path, out: Path, *flags: str, **env) -> subprocess.Popen:
    env = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    return subprocess.Popen([sys.executable, "-c", CHILD, "run", str(spec_path), "--out", str(out), "--quiet", *flags],
                            env=env, stderr=subprocess.PIPE, text=True)


@pytest.fixture(scope="module")
def ref(tmp_path_factory):
    return reference(tmp_path_factory.mktemp("ref"), RUN)


def check_agrees(code: int, err: str, spec_path: Path, out: Path, ref) -> None:
    """Exit 0 and a finished run, or 130 and an interrupted one that resumes to the unbroken bits."""
    res = load(out)
    if code == 0:
        assert res.complete, err
        assert_identical(res, ref)
        return
    assert code == 130 and res.status == "interrupted", (code, res.status, err)
    assert err.splitlines()[-1] == (f"pinnedballs: interrupted at step {res.steps:,}; the checkpoint in {out} is "
                                    f"complete: continue with --resume")
    assert [s[:2] for s in res.snapshots] == [s[:2] for s in ref.snapshots if s.steps <= res.steps]
    assert resume(spec_path, out) == 0
    assert_identical(load(out), ref)


@pytest.mark.parametrize("seed", range(8))
def test_two_sigints_at_a_random_moment(tmp_path, ref, seed):
    """From the moment the first index exists (step 0, still compiling) to the end of the run."""
    spec_path = write(tmp_path / "s.json", RUN)
    out = tmp_path / "out"
    c = child(spec_path, out, "--no-figures")
    deadline = time.monotonic() + 120
    while not (out / "results.h5").exists() and c.poll() is None and time.monotonic() < deadline:
        time.sleep(0.002)
    rng = random.Random(seed)
    time.sleep(0.0 if seed == 0 else rng.uniform(0.0, 2.0))
    c.send_signal(signal.SIGINT)
    time.sleep(rng.uniform(0.0, 0.02))
    c.send_signal(signal.SIGINT)
    _, err = c.communicate(timeout=120)
    check_agrees(c.returncode, err, spec_path, out, ref)


@pytest.mark.parametrize("when", ["before", "after"])
@pytest.mark.parametrize("figures", [False, True], ids=["no figures", "figures"])
def test_a_finished_run_never_exits_130(tmp_path, ref, when, figures):
    """Two Ctrl-Cs just before or just after the write that says "done": the run is done, exit 0, and
    the figures it did not draw are named."""
    spec_path = write(tmp_path / "s.json", RUN)
    out = tmp_path / "out"
    c = child(spec_path, out, *([] if figures else ["--no-figures"]), SIGNAL_AT_DONE=when)
    _, err = c.communicate(timeout=120)
    assert c.returncode == 0, err
    assert_identical(load(out), ref)
    if figures:
        assert err == (f"pinnedballs: the run in {out} is done (steps); interrupted before its figures: draw them "
                       f"with pinnedballs plot {out}\n")
        assert not list(out.glob("*.png"))
    else:
        assert err == f"pinnedballs: the run in {out} is done (steps); the interrupt came as it finished\n"


def test_a_ctrl_c_turned_into_another_exception_is_still_a_ctrl_c(tmp_path, monkeypatch):
    """A Ctrl-C in the middle of an import comes out as RuntimeError("Error calling __set_name__")
    from the KeyboardInterrupt (seen in CI): the command still exits 130 with its one line."""
    from helpers import call

    import pinnedballs.run.execute as execute
    from pinnedballs.run.cli.interrupts import interrupted_by

    def interrupted_import(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as exc:
            raise RuntimeError("Error calling __set_name__ on '_axis_method_wrapper' instance") from exc

    monkeypatch.setattr(execute, "execute", interrupted_import)
    code, _, err = call("run", write(tmp_path / "s.json", RUN), "--out", tmp_path / "out", "--quiet")
    assert (code, err) == (130, f"pinnedballs: interrupted before the run wrote anything in {tmp_path / 'out'}\n")
    assert not interrupted_by(RuntimeError("a plain error")) and interrupted_by(KeyboardInterrupt())


def test_a_run_without_figures_never_imports_matplotlib(tmp_path):
    """A second Ctrl-C can land anywhere in a run; a run that draws nothing gives it no
    matplotlib import to land in (and starts 0.5-1 s sooner)."""
    spec_path = write(tmp_path / "s.json", RUN)
    code = ("import sys; from pinnedballs.run.cli import main as cli; "
            f"code = cli.main(['run', {str(spec_path)!r}, '--out', {str(tmp_path / 'out')!r}, '--quiet', "
            "'--no-figures']); print(code, 'matplotlib' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.stdout.split() == ["0", "False"], done.stderr
