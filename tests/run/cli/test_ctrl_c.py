"""Ctrl-C at any moment of ``python -m pinnedballs run`` (issue 42, item 7): one line on stderr and exit
status 130, from the first instant, while the package is imported, and while numba compiles (seconds on a
first run: the command ends at once instead of waiting for the compile), the run directory left whole.

Each child is the real program with an empty numba cache. To send the signal at a known moment, a
``sitecustomize`` module (on the child's path) holds the child there and says so on stdout: at the import of
a module, or at the start of numba's compile of a function (the signal then lands inside numba's compiler,
on the main thread or on the thread the driver compiles on); or, for the latency of a real compile, it only
says that the compile began.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from helpers import TORUS, assert_identical, reference, resume, spec, write

from pinnedballs.results.load import load
from pinnedballs.run.writers import ResultsWriter
from pinnedballs.specs.run import load_spec

pytestmark = pytest.mark.slow  # subprocesses, first compiles

ROOT = Path(__file__).resolve().parents[3]

RUN = spec(TORUS, geometry__rows=10, geometry__cols=10, initial={"kind": "gaussian", "energy": 100.0},
           stop={"steps": 6_000}, snapshots={"every_steps": 1000}, checkpoint={"every_seconds": 0}, seed=21)

#: PB_HOLD="import:MODULE" holds the child as it imports MODULE; "compile:NAME" inside numba's compile of the
#: function NAME (at the first function it compiles for it); "began:NAME" only says that it began
HOLDER = r'''
import os, sys, time

kind, _, what = os.environ.get("PB_HOLD", "").partition(":")


def say(word):
    os.write(1, (word + "\n").encode())


if kind == "import":
    class Hold:
        def find_spec(self, name, path=None, target=None):
            if name == what:
                sys.meta_path.remove(self)
                say("holding")
                time.sleep(60)
            return None

    sys.meta_path.insert(0, Hold())
elif kind in ("compile", "began"):
    from numba.core import event

    class Hold(event.Listener):
        inside = False  # the compile of `what` began: hold at the first compile it makes, inside it

        def on_start(self, ev):
            named = getattr(getattr(ev.data.get("dispatcher"), "py_func", None), "__name__", None) == what
            if (kind == "began" and named) or (kind == "compile" and self.inside):
                event.unregister("numba:compile", self)
                say("holding")
                if kind == "compile":
                    time.sleep(60)
            self.inside = self.inside or named

        def on_end(self, ev):
            pass

    event.register("numba:compile", Hold())
'''


def program(tmp_path: Path, hold: str, out: Path, *flags: str) -> tuple[int, str, float]:
    """``python -m pinnedballs run`` on `RUN` into ``out`` with an empty numba cache, held at ``hold``
    (`HOLDER`); SIGINT once it says so. The exit status, stderr, and the seconds from the signal to its end."""
    site = tmp_path / "site"
    site.mkdir(exist_ok=True)
    (site / "sitecustomize.py").write_text(HOLDER)
    env = {**os.environ, "PYTHONPATH": f"{site}{os.pathsep}{ROOT}", "PB_HOLD": hold,
           "NUMBA_CACHE_DIR": str(tmp_path / "numba_cache")}
    child = subprocess.Popen([sys.executable, "-m", "pinnedballs", "run", str(write(tmp_path / "s.json", RUN)),
                              "--out", str(out), "--quiet", "--no-figures", *flags],
                             env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline() == "holding\n", child.stderr.read()
        if hold.startswith("began:"):
            time.sleep(0.5)  # into the compile (seconds long)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        _, err = child.communicate(timeout=120)
        return child.returncode, err, time.monotonic() - sent
    finally:
        if child.poll() is None:
            child.kill()


@pytest.fixture(scope="module")
def ref(tmp_path_factory):
    return reference(tmp_path_factory.mktemp("ref"), RUN)


def test_while_the_command_line_imports(tmp_path):
    """Once ``python -m pinnedballs`` runs its first line: before, a Ctrl-C among the imports printed a
    KeyboardInterrupt traceback of 13 to 27 lines and ended the program by the signal (status -2)."""
    code, err, seconds = program(tmp_path, "import:pinnedballs.run.cli.main", tmp_path / "out")
    assert (code, err) == (130, "pinnedballs: interrupted\n")
    assert seconds < 5  # at once: a loaded machine's process exit
    assert not (tmp_path / "out").exists()


def test_while_the_package_imports(tmp_path):
    """Python imports the package (its ``__init__``: numpy, numba, h5py, ...) before ``__main__``'s first line:
    the package's first line hands a Ctrl-C there to the command line's words."""
    code, err, _ = program(tmp_path, "import:numba", tmp_path / "out")
    assert (code, err) == (130, "pinnedballs: interrupted\n")


def test_while_numba_compiles_a_check_as_the_simulation_is_built(tmp_path):
    """The contact checks compile as the simulation is built, before the run writes anything: the one line
    says so, and the directory was never made."""
    out = tmp_path / "out"
    code, err, seconds = program(tmp_path, "compile:_first_fault", out)
    assert (code, err) == (130, f"pinnedballs: interrupted while numba compiled, before the run wrote anything in "
                                f"{out}\n")
    assert seconds < 5  # at once, where it waited for numba before
    assert not out.exists()


def test_while_numba_compiles_the_loop_the_run_resumes_to_the_same_bits(tmp_path, ref):
    """The loop compiles on the driver's thread for it, before the run writes anything (a rule numba cannot
    compile is refused with nothing written: issue 49, item 5): the command ends at once, the directory never
    made, and ``--resume`` starts the run and ends on the bits of an unbroken run."""
    out = tmp_path / "out"
    code, err, seconds = program(tmp_path, "compile:run_to_limits", out)
    assert (code, err) == (130, f"pinnedballs: interrupted while numba compiled, before the run wrote anything in "
                                f"{out}\n")
    assert seconds < 5
    assert not out.exists()
    assert resume(tmp_path / "s.json", out) == 0
    assert_identical(load(out), ref)


def first_checkpoint(spec_path: Path, out: Path) -> None:
    """What a run of ``spec_path`` killed after its first checkpoint leaves in ``out``: its results at step 0."""
    spec = load_spec(spec_path)
    writer = ResultsWriter(out, snapshots=spec.snapshots.build(), spec=spec)
    writer.attach(spec.build())
    writer.close()


def test_while_numba_compiles_a_resumed_run(tmp_path, ref):
    """A resumed run's directory is left as it was."""
    out = tmp_path / "out"
    first_checkpoint(write(tmp_path / "s.json", RUN), out)
    os.utime(out / "results.h5", ns=(0, 0))  # written before this command
    code, err, _ = program(tmp_path, "compile:run_to_limits", out, "--resume")
    assert (code, err) == (130, f"pinnedballs: interrupted while numba compiled, before the run went on; {out} is "
                                f"as it was: continue with --resume\n")
    assert resume(tmp_path / "s.json", out) == 0
    assert_identical(load(out), ref)


def test_in_the_middle_of_a_real_compile(tmp_path):
    """Half a second into the compile of the loop (seconds long on a first run), nothing held: the command
    ends within about a second of the Ctrl-C (it waited for the compile before, then ran a chunk)."""
    out = tmp_path / "out"
    code, err, seconds = program(tmp_path, "began:run_to_limits", out)
    assert code == 130 and err.startswith("pinnedballs: interrupted while numba compiled") and err.count("\n") == 1
    assert seconds < 2.5  # about a second on a loaded 2-core machine; a compile takes 3 s or more
