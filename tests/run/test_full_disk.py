"""A full disk (issue 10, item 6): a run that fills its disk ends with one line and exit status 1,
its last checkpoint intact and resumable to the bits of an uninterrupted run, no ``.tmp`` left;
figures that cannot be written leave no partial PNG.

The disk is a small tmpfs where mounting works (as root, as here). Elsewhere it is simulated:
the child's binary writes fail with ENOSPC once a byte budget is spent.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import TORUS, assert_identical, reference, resume, spec, write

import pinnedballs as pb
from pinnedballs.run.cli.main import main

pytestmark = pytest.mark.slow  # subprocesses, full runs: the full suite (CI) runs these

ROOT = Path(__file__).resolve().parents[2]
DISK_BYTES = 512 * 1024

#: 400 balls, a snapshot (6.4 kB) and a checkpoint every 100 steps: about 1.3 MB of results
RUN = spec(TORUS, geometry__rows=20, geometry__cols=20, initial={"kind": "gaussian", "energy": 100.0},
           stop={"steps": 20_000}, snapshots={"every_steps": 100}, checkpoint={"every_seconds": 0}, seed=7)

CHILD = """
import builtins, errno, os, sys
budget = int(os.environ.get("PB_DISK_BYTES", "0"))
if budget:  # no small file system to fill: binary writes fail once the budget is spent
    left, real_open = [budget], builtins.open

    class Full:
        def __init__(self, f):
            self.f = f
        def write(self, data):
            left[0] -= len(data)
            if left[0] < 0:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), self.f.name)
            return self.f.write(data)
        def __getattr__(self, name):
            return getattr(self.f, name)
        def __enter__(self):
            return self
        def __exit__(self, *exc):
            self.f.close()

    def open_(file, mode="r", *args, **kwargs):
        f = real_open(file, mode, *args, **kwargs)
        return Full(f) if "w" in mode and "b" in mode else f
    builtins.open = open_
from pinnedballs.run.cli import main as cli
sys.exit(cli.main(sys.argv[1:]))
"""


def _run(*argv: str) -> bool:
    return subprocess.run(argv, capture_output=True).returncode == 0


@contextlib.contextmanager
def small_disk(where: Path, size: int = DISK_BYTES):
    """``(directory, env)``: a file system of ``size`` bytes at ``where`` and the environment
    that makes the child see it full at ``size`` bytes (empty where it is a real tmpfs)."""
    where.mkdir()
    if _run("mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)):
        try:
            yield where, {}
        finally:
            _run("umount", str(where))
    else:
        yield where, {"PB_DISK_BYTES": str(size)}


def child(env: dict, *argv) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    return subprocess.run([sys.executable, "-c", CHILD, *map(str, argv)], env=env, capture_output=True,
                          text=True, timeout=300)


def assert_disk_full(r: subprocess.CompletedProcess) -> None:
    """Exit 1, one line saying the disk is full, no traceback, no native crash."""
    assert r.returncode == 1, (r.returncode, r.stderr[-2000:])
    assert "Traceback" not in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    assert r.stderr.startswith("pinnedballs: error: ") and os.strerror(errno.ENOSPC) in r.stderr


def leftovers(top: Path) -> list[str]:
    return sorted(str(p) for p in top.rglob("*") if p.name.endswith(".tmp") or p.name.endswith(".lock"))


def test_a_run_that_fills_the_disk_stops_cleanly_and_resumes_bit_identical(tmp_path):
    s = write(tmp_path / "s.json", RUN)
    with small_disk(tmp_path / "disk") as (disk, env):
        out = disk / "run"
        assert_disk_full(child(env, "run", s, "--out", out, "--quiet", "--no-figures"))
        assert leftovers(disk) == []
        res = pb.load(out)  # the last good checkpoint, checked
        assert res.status == "running" and 0 < res.steps < 20_000
        assert [x.steps for x in res.snapshots] == list(range(100, res.steps + 1, 100))
        saved = tmp_path / "saved"
        shutil.copytree(out, saved)  # room to go on: the same files on a large disk
    assert resume(s, saved) == 0
    assert_identical(pb.load(saved), reference(tmp_path, RUN))


def test_figures_that_do_not_fit_leave_no_partial_png(tmp_path):
    s = write(tmp_path / "s.json", spec(TORUS, geometry__rows=10, geometry__cols=10))
    done = tmp_path / "done"
    assert main(["run", str(s), "--out", str(done), "--quiet", "--no-figures"]) == 0  # a fresh run, no figures
    with small_disk(tmp_path / "disk", 1024 * 1024) as (disk, env):
        out = disk / "run"
        shutil.copytree(done, out)
        filler = disk / "filler"
        if not env:  # a real tmpfs: fill it up
            with open(filler, "wb", buffering=0) as f, contextlib.suppress(OSError):
                while True:
                    f.write(b"\0" * 4096)
        else:
            env = {"PB_DISK_BYTES": "1"}
        assert_disk_full(child(env, "plot", out))
        assert sorted(p.name for p in out.iterdir()) == ["results.data", "results.h5", "spec.json"]
        assert leftovers(disk) == []
        pb.load(out)
