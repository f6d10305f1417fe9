"""An ensemble stops when told and leaves nothing running (issue 26, items 1 and 8).

Ctrl-C (a SIGINT to the main process alone, as a notebook's "interrupt kernel" sends, or to the whole
process group, as a terminal's Ctrl-C does) stops an ensemble within a second or two with
KeyboardInterrupt, in this process, on local processes (killed at once) and on a Dask cluster (its
unfinished jobs cancelled). ``kill -9`` of the main process leaves no local worker running: each
notices its parent's death and ends. Before: a SIGINT to the main process waited for every running
replica to end, and after a ``kill -9`` the workers ran on for more than 90 s.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # subprocesses, process pools, clusters

psutil = pytest.importorskip("psutil")

ROOT = Path(__file__).resolve().parents[2]

#: replicas of minutes each: an ensemble that stops within seconds was stopped
ENDLESS = {"geometry": {"kind": "flat_torus", "rows": 8, "cols": 8},
           "initial": {"kind": "single_ball", "ball": 0, "direction": [1.0, 0.0], "energy": 100.0},
           "stop": {"steps": 10**12}, "seed": 3}

CHILD = """
import json, sys, time
from pinnedballs.run.ensemble import run_ensemble
from pinnedballs.specs import parse_spec

where, spec = sys.argv[1], parse_spec(json.loads(sys.argv[2]))
options = {"workers": int(where)} if where != "dask" else {}
if where == "dask":
    from dask.distributed import Client, LocalCluster
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None)
    options = {"cluster": Client(cluster)}
print("started", flush=True)
try:
    run_ensemble(spec, 4, progress=False, **options)
except KeyboardInterrupt:
    print("interrupted", flush=True)
    if where == "dask":
        options["cluster"].close()
        cluster.close()
    sys.exit(130)
"""


@pytest.fixture
def start():
    """``start(where, **popen)``: the CHILD running an ensemble ``where``, once it says it started; every
    child and its descendants are killed when the test ends, whatever happened."""
    started = []

    def run(where: str, **popen) -> subprocess.Popen:
        child = subprocess.Popen([sys.executable, "-c", CHILD, where, json.dumps(ENDLESS)], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(ROOT)},
                                 **popen)
        started.append((child, psutil.Process(child.pid)))
        assert line_within(child, 120) == "started\n"
        return child

    yield run
    for child, proc in started:
        with_descendants = [proc, *_SEEN]
        try:
            with_descendants += proc.children(recursive=True)
        except psutil.NoSuchProcess:
            pass
        for p in with_descendants:
            try:
                p.kill()
            except psutil.NoSuchProcess:
                pass
        child.communicate()


def line_within(child: subprocess.Popen, seconds: float) -> str:
    """The child's next line of output, or "" if none comes within ``seconds``."""
    ready, _, _ = select.select([child.stdout], [], [], seconds)
    return child.stdout.readline() if ready else ""


#: every worker process seen, for the fixture to kill should a test fail
_SEEN: list = []


def workers_of(child: subprocess.Popen, count: int) -> list:
    """The ``count`` pool processes ``child`` started, once they run (waiting up to 2 minutes)."""
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        found = psutil.Process(child.pid).children(recursive=True)
        if len(found) >= count:
            _SEEN.extend(found)
            return found
        assert child.poll() is None, child.communicate()
        time.sleep(0.1)
    raise AssertionError(f"{count} workers never started")


def gone(processes: list, within: float) -> bool:
    """Whether every one of ``processes`` has ended (or is a zombie left to be reaped) within ``within`` s."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        alive = [p for p in processes if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]
        if not alive:
            return True
        time.sleep(0.1)
    return False


def interrupted_within(child: subprocess.Popen, send, seconds: float = 10) -> None:
    """After ``send()`` (a SIGINT) the child says "interrupted" within ``seconds`` and exits 130.
    (A second or two is expected; the margin is for a loaded machine.)"""
    send()
    line = line_within(child, seconds)
    assert line == "interrupted\n", f"no KeyboardInterrupt within {seconds} s of the signal"
    _, err = child.communicate(timeout=120)
    assert child.returncode == 130, err


@pytest.mark.parametrize("group", [False, True], ids=["sigint to the main process", "ctrl-c to the group"])
def test_ctrl_c_stops_an_ensemble_on_local_processes_and_kills_them(start, group):
    child = start("2", start_new_session=True)
    workers = workers_of(child, 2)
    time.sleep(1.0)  # into their replicas
    interrupted_within(child,
                       lambda: os.killpg(child.pid, signal.SIGINT) if group else child.send_signal(signal.SIGINT))
    assert gone(workers, within=10)


def test_ctrl_c_stops_an_ensemble_in_this_process(start):
    child = start("1")
    time.sleep(2.0)  # into the first replica's run
    interrupted_within(child, lambda: child.send_signal(signal.SIGINT))


def test_ctrl_c_stops_an_ensemble_on_dask(start):
    pytest.importorskip("dask.distributed")
    child = start("dask")
    workers_of(child, 2)  # the cluster's worker processes
    time.sleep(3.0)  # the jobs on them
    interrupted_within(child, lambda: child.send_signal(signal.SIGINT))


def test_kill_9_of_the_main_process_leaves_no_worker_running(start):
    child = start("2")
    workers = workers_of(child, 2)
    time.sleep(1.0)
    child.kill()
    child.wait(timeout=30)
    assert gone(workers, within=10), [p.pid for p in workers if p.is_running()]


def test_the_watch_alone_ends_an_orphan(tmp_path):
    """`watch_parent`'s thread alone, as on a system without Linux's PR_SET_PDEATHSIG: a process
    whose parent exits (after it started watching) ends within a poll or two, not after its sleep."""
    watching = tmp_path / "watching"
    script = f"""
import os, sys, time
from pinnedballs.run import executors
me = os.getpid()
pid = os.fork()
if pid:  # the parent: once the child watches, say its pid and exit
    while not os.path.exists({str(watching)!r}):
        time.sleep(0.01)
    print(pid, flush=True)
    os._exit(0)
sys.platform = "darwin"  # no PR_SET_PDEATHSIG: the thread is the only guard
executors.watch_parent(me, every=0.1)
open({str(watching)!r}, "w").close()
time.sleep(120)
"""
    parent = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert watching.exists()
    try:
        orphan = [psutil.Process(int(parent.stdout))]
    except psutil.NoSuchProcess:
        return  # it has ended already
    assert gone(orphan, within=10)
