"""Output directories (issue 10, items 3 and 4): a directory that cannot be written is refused
up front (exit 2, one line naming it, nothing written), and one run at a time writes into a
directory (an OS lock the kernel drops when the holder dies).

The tests run as root, whom permissions do not stop: a read-only file system is a tmpfs mounted
read-only (an immutable directory, ``chattr +i``, where mounting is not allowed), and an
unwritable directory is tried by a child running as ``nobody``.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
from helpers import TORUS, assert_identical, assert_input_error, call, read_only_dir, reference, resume, spec, write

import pinnedballs as pb
from pinnedballs.results.load import load
from pinnedballs.results.rundir import LOCK_NAME, DirLock, made_for
from pinnedballs.util.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
NOBODY = 65534

COMMANDS = {
    "run": lambda s, out: ["run", s, "--out", out, "--quiet", "--no-figures"],
    "ensemble": lambda s, out: ["ensemble", s, "--replicas", "2", "--workers", "1", "--out", out, "--quiet"],
    "reproduce": lambda s, out: ["reproduce", "--quick", "--workers", "1", "--out", out, "--quiet"],
}


# ---------------------------------------------------------------- item 3: unwritable output paths


@pytest.mark.parametrize("command", list(COMMANDS))
def test_output_below_a_file_or_a_dangling_link_is_refused(tmp_path, command):
    s = write(tmp_path / "s.json", TORUS)
    (tmp_path / "file").write_text("not a directory")
    (tmp_path / "dangling").symlink_to(tmp_path / "gone")
    cases = {tmp_path / "file" / "out": "file is not a directory",
             tmp_path / "file": "exists and is not a directory",
             tmp_path / "dangling": "dangling symbolic link",
             tmp_path / "dangling" / "out": "dangling symbolic link"}
    for out, words in cases.items():
        code, _, err = call(*COMMANDS[command](s, out))
        assert_input_error(code, err, "--out", str(out), words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dangling", "file", "s.json"]
    assert not (tmp_path / "gone").exists()


@pytest.mark.parametrize("command", list(COMMANDS))
def test_output_on_a_read_only_file_system_is_refused(tmp_path, command):
    s = write(tmp_path / "s.json", TORUS)
    with read_only_dir(tmp_path / "ro") as ro:
        for out in (ro, ro / "out", ro / "a" / "b"):
            code, _, err = call(*COMMANDS[command](s, out))
            assert_input_error(code, err, "--out", str(out), f"{ro} is not writable")
        assert list(ro.iterdir()) == []


def test_a_python_writer_into_a_read_only_directory_names_out_dir(tmp_path):
    sim = pb.Simulation(pb.FlatTorus(4, 4), [[1.0, 0.0]] + [[0.0, 0.0]] * 15, seed=1)
    with read_only_dir(tmp_path / "ro") as ro:
        with pytest.raises(InputError, match=f"^out_dir {ro / 'r'}: {ro} is not writable"):
            sim.run(steps=10, writers=[pb.ResultsWriter(ro / "r")])
    assert sim.steps == 0


#: imports first (root's Python lives where nobody may not read), then drops to ``uid``
CHILD_AS_NOBODY = """
import os, sys, warnings
os.umask(0)  # the kernels' cache directories root makes on import stay writable for uid
from pinnedballs.run.cli import main as cli
from pinnedballs.run import ensemble
from pinnedballs.util import atomic as io
from pinnedballs.run import reproduction
from pinnedballs.run import execute as runner
from pinnedballs.results import rundir
from pinnedballs import specs
from numba.core.registry import cpu_target
cpu_target.target_context.refresh()  # numba's registries (cmath, ...): a Simulation's contact checks load a kernel
# whatever a run imports on its first compile (numba.core.runtime.context, ...), imported now: a CI's
# Python may live under /root, which nobody cannot read once the privileges drop
warm = specs.load_spec(os.environ["PB_SPEC"]).build()
warm.run(steps=100)
with warnings.catch_warnings():  # a torus never freezes: its FreezeWarning is no line of the command's
    warnings.simplefilter("ignore")
    warm.run_until_frozen(100)
os.setgid({uid}); os.setuid({uid})
sys.exit(cli.main(sys.argv[1:]))
"""


@pytest.fixture(scope="module")
def kernels_nobody_may_write():
    """A numba cache that nobody may write, shared by the module's children (the first compiles, the
    others load: each compiling afresh cost 15-35 s a test)."""
    cache = Path(tempfile.mkdtemp(prefix="pb-nobody-numba-"))
    cache.chmod(0o777)
    yield cache
    shutil.rmtree(cache, ignore_errors=True)


@pytest.mark.slow
@pytest.mark.parametrize("command", list(COMMANDS))
def test_output_in_an_unwritable_directory_is_refused(command, kernels_nobody_may_write):
    """As a user without write permission on the parent (root ignores permissions, so as nobody)."""
    base = Path(tempfile.mkdtemp(prefix="pb-unwritable-"))  # pytest's tmp_path is closed to nobody
    try:
        s = write(base / "s.json", TORUS)
        locked = base / "locked"
        locked.mkdir()
        for p in (base, locked, s):
            p.chmod(0o555 if p.is_dir() else 0o444)
        uid = NOBODY if os.getuid() == 0 else os.getuid()
        env = {**os.environ, "PYTHONPATH": str(ROOT), "NUMBA_CACHE_DIR": str(kernels_nobody_may_write),
               "PB_SPEC": str(s)}
        for out in (locked / "out", locked):
            argv = [str(a) for a in COMMANDS[command](s, out)]
            r = subprocess.run([sys.executable, "-c", CHILD_AS_NOBODY.format(uid=uid), *argv], env=env,
                               capture_output=True, text=True, timeout=120)
            assert_input_error(r.returncode, r.stderr, "--out", str(out), "not writable (permission denied)")
        assert list(locked.iterdir()) == []
    finally:
        for p in (base, base / "locked"):
            p.chmod(0o755)
        shutil.rmtree(base)


# ---------------------------------------------------------------- item 4: one run per directory

STOP_AT_FIRST_CHECKPOINT = """
import os, signal, sys
from pinnedballs.run.cli import main as cli
from pinnedballs.engine import driver
from pinnedballs.util import atomic as io
driver.CHUNK_STEPS, driver.CHUNK_PER_CONTACT = 500, 0
commit, count = io._commit, [0]
def stopping(tmp, path):
    commit(tmp, path)
    count[0] += 1
    if count[0] == 5:  # static data, the first index, spec.json, a segment, the index after it
        os.kill(os.getpid(), signal.SIGSTOP)
io._commit = stopping
sys.exit(cli.main(sys.argv[1:]))
"""

RUN = spec(TORUS, geometry__rows=8, geometry__cols=8, initial={"kind": "gaussian", "energy": 100.0},
           stop={"steps": 5_000}, snapshots={"every_steps": 500}, checkpoint={"every_seconds": 0}, seed=5)


def _wait_stopped(child: subprocess.Popen, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert child.poll() is None, child.stderr.read()
        with open(f"/proc/{child.pid}/stat") as f:
            if f.read().rsplit(")", 1)[1].split()[0] == "T":
                return
        time.sleep(0.05)
    raise AssertionError("the first run never reached its checkpoint")


@pytest.mark.slow
def test_two_concurrent_runs_one_is_refused_and_a_killed_run_resumes(tmp_path):
    """Run A holds the directory (stopped mid-run); run B is refused naming A's pid; A is
    SIGKILLed and its --resume ends on the bits of an uninterrupted run, 10 snapshots."""
    s = write(tmp_path / "s.json", RUN)
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    a = subprocess.Popen([sys.executable, "-c", STOP_AT_FIRST_CHECKPOINT, "run", str(s), "--out", str(out),
                          "--quiet", "--no-figures"], env=env, stderr=subprocess.PIPE, text=True)
    try:
        _wait_stopped(a)
        assert load(out).steps == 500
        for argv in (["run", s, "--out", out, "--quiet"], ["run", s, "--out", out, "--resume", "--quiet"],
                     ["run", s, "--out", out, "--force", "--quiet"]):
            b = subprocess.run([sys.executable, "-m", "pinnedballs", *map(str, argv)], env=env,
                               capture_output=True, text=True, timeout=120)
            assert_input_error(b.returncode, b.stderr, f"--out {out}: in use by another run (pid {a.pid})")
        assert load(out).steps == 500  # B wrote nothing: A's checkpoint is there as A left it
    finally:
        a.send_signal(signal.SIGKILL)
        a.wait()
    assert (out / LOCK_NAME).exists()  # left by the kill, and harmless:
    assert resume(s, out) == 0
    res = load(out)
    assert len(res.snapshots) == 10 and [x.steps for x in res.snapshots] == list(range(500, 5_001, 500))
    assert_identical(res, reference(tmp_path, RUN))
    assert not (out / LOCK_NAME).exists()


@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_held_directory_is_refused_with_the_holders_pid(tmp_path, command):
    s = write(tmp_path / "s.json", TORUS)
    out = tmp_path / "out"
    with DirLock(out):
        code, _, err = call(*COMMANDS[command](s, out), "--force")
        assert_input_error(code, err, f"--out {out}: in use by another run (pid {os.getpid()})")
        assert [p.name for p in out.iterdir()] == [LOCK_NAME]
    assert list(out.iterdir()) == []


def test_python_writers_take_the_lock_and_release_it_at_the_stop(tmp_path):
    sim = pb.Simulation(pb.FlatTorus(4, 4), [[1.0, 0.0]] + [[0.0, 0.0]] * 15, seed=1)
    out = tmp_path / "r"
    with DirLock(out):
        with pytest.raises(InputError, match=rf"^out_dir {out}: in use by another run \(pid {os.getpid()}\)"):
            sim.run(steps=10, writers=[pb.ResultsWriter(out)])
    assert sim.steps == 0
    w = pb.ResultsWriter(out, snapshots={"every_steps": 5})
    sim.run(steps=10, writers=[w])
    assert not (out / LOCK_NAME).exists()  # released at the stop ...
    sim.run(steps=10, writers=[w])         # ... and taken again by the next run
    assert [x.steps for x in load(out).snapshots] == [5, 10, 15, 20]
    with DirLock(out):  # a second writer, in this process or another, waits its turn
        with pytest.raises(InputError, match="in use by another run"):
            sim.run(steps=10, writers=[pb.ResultsWriter(out, resume=True)])
    assert sim.steps == 20


FORKS_AND_DIES = """
import os, signal, sys, time
from pinnedballs.results.rundir import DirLock
lock = DirLock(sys.argv[1]).acquire()
child = os.fork()
if child == 0:  # a pool's worker, still at work when its parent is killed (not holding the parent's pipes)
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1), os.dup2(null, 2)
    time.sleep(30)
    os._exit(0)
print(child, flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_a_child_outliving_its_killed_parent_does_not_hold_the_directory(tmp_path):
    """A worker forked while the lock was held and still alive after its parent's ``kill -9``: the directory
    is free at once (an ``flock`` lives while any process holds the file open; a forked child closes its copy),
    so a ``--resume`` right after the kill is not refused as "in use"."""
    out = tmp_path / "out"
    parent = subprocess.run([sys.executable, "-c", FORKS_AND_DIES, str(out)], capture_output=True, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=60)
    child = int(parent.stdout)
    try:
        assert parent.returncode == -signal.SIGKILL
        os.kill(child, 0)  # alive
        with DirLock(out):
            pass
    finally:
        os.kill(child, signal.SIGKILL)


def test_a_forked_child_cannot_release_its_parents_lock(tmp_path):
    """A child's copy is closed, not released: the parent still holds the directory after the child exits."""
    out = tmp_path / "out"
    with DirLock(out):
        pid = os.fork()
        if pid == 0:
            os._exit(0)
        os.waitpid(pid, 0)
        with pytest.raises(InputError, match="in use by another run"):
            DirLock(out).acquire()
        assert (out / LOCK_NAME).exists()


# ---------------------------------------------------------------- a refused command leaves no parents


def test_a_block_that_raises_removes_the_directories_it_made_and_only_those(tmp_path):
    """`made_for`: a/, a/b/ and a/b/out made under the lock and the block refused: all go; a parent that
    existed stays, and so does one that came to hold something; a block that ends well keeps them."""
    out = tmp_path / "a" / "b" / "out"
    with pytest.raises(InputError, match="^refused$"), made_for(out), DirLock(out):
        raise InputError("refused")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(InputError), made_for(out):
        out.mkdir(parents=True)
        (tmp_path / "a" / "held.txt").write_text("kept")
        raise InputError("refused")
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["held.txt"]
    with made_for(out), DirLock(out):
        pass
    assert out.is_dir() and list(out.iterdir()) == []
