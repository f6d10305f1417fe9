"""A worker that dies loses nothing (issue 20): an ensemble whose Dask worker or local process is
killed mid-run ends with the same bits as an undisturbed one; a replica whose worker dies each
time it runs is the only one reported, by its index, with how to run it alone."""

from __future__ import annotations

import contextlib
import functools
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from helpers import pickled_by_value

from pinnedballs.run import ensemble as ens
from pinnedballs.run import ensemble_files as ens_files
from pinnedballs.run import executors
from pinnedballs.run.cli import main as cli
from pinnedballs.specs import parse_spec

pytestmark = pytest.mark.slow  # clusters, processes killed

ROOT = Path(__file__).resolve().parents[2]

#: replicas of about a second each
LONG = {"geometry": {"kind": "flat_torus", "rows": 8, "cols": 8},
        "initial": {"kind": "single_ball", "ball": 0, "direction": [1.0, 0.0], "energy": 100.0},
        "stop": {"steps": 150_000_000}, "snapshots": {"at_steps": [5_000]}, "seed": 3}
SHORT = {**LONG, "stop": {"steps": 20_000}}


def die(spec, index, seed, *, mark: Path | None = None):
    """A replica task whose process dies running replica 2: every time, or (``mark``) the first time only."""
    if index == 2 and (mark is None or not mark.exists()):
        if mark is not None:
            mark.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return ens.run_replica(spec, index, seed)


def undisturbed(data: dict, replicas: int) -> list[dict]:
    return ens.run_ensemble(parse_spec(data), replicas, workers=1).rows


# ---------------------------------------------------------------- local processes


def test_a_local_process_killed_once_costs_nothing(tmp_path):
    """Before: every replica still in the pool failed with BrokenProcessPool."""
    task = functools.partial(die, mark=tmp_path / "died")
    result = ens.run_ensemble(parse_spec(SHORT), 6, workers=2, task=task)
    assert (tmp_path / "died").exists() and result.failures == []
    assert result.rows == undisturbed(SHORT, 6)


def test_a_replica_whose_local_process_always_dies_is_the_only_one_reported():
    result = ens.run_ensemble(parse_spec(SHORT), 6, workers=2, task=die)
    assert result.failures == [{"replica": 2, "seed_entropy": 3, "spawn_key": "[2]", ens.ERROR_COLUMN:
                                f"WorkerDied: the process running it died {executors.MAX_DEATHS} times (killed, or "
                                f"out of memory?)"}]
    assert [r for r in result.rows if r["replica"] != 2] == [r for r in undisturbed(SHORT, 6) if r["replica"] != 2]


def dies_at_birth(parent):
    """A pool process's start that kills it: an OOM killer that takes every new worker."""
    os.kill(os.getpid(), signal.SIGKILL)


def test_pools_whose_processes_all_die_at_birth_end_with_every_replica_reported(monkeypatch):
    """Before: each pool broke before any replica started, and the ensemble made pools for ever."""
    monkeypatch.setattr(executors, "_worker_starts", dies_at_birth)
    result = ens.run_ensemble(parse_spec(SHORT), 3, workers=2, progress=False)
    assert result.failures == [{"replica": k, "seed_entropy": 3, "spawn_key": f"[{k}]", ens.ERROR_COLUMN:
                                f"WorkerDied: the pool's processes died {executors.MAX_DEATHS} times before any job "
                                f"ended (killed, or out of memory?)"} for k in range(3)]


#: seconds a replica run again waits for the other one lost beside it to run again too
TOGETHER = 30.0


def killed_beside_another(spec, index, seed, *, where: Path):
    """A replica task whose process dies running replica 0 the first time, once replica 1 runs beside it (both
    are then lost); each run again of replicas 0 and 1 waits (at most `TOGETHER` s) for the other's to begin,
    and writes when it began and ended ("span-<index>")."""
    died = where / "died"
    if index == 0 and not died.exists():
        while not (where / "first-1").exists():
            time.sleep(0.01)
        died.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    if index == 1 and not died.exists():
        (where / "first-1").touch()
        time.sleep(60)  # killed with its pool long before
    if index in (0, 1):
        begun = time.time()
        (where / f"again-{index}").touch()
        while not (where / f"again-{1 - index}").exists() and time.time() < begun + TOGETHER:
            time.sleep(0.01)
        (where / f"span-{index}").write_text(f"{begun!r} {time.time()!r}")
    return ens.run_replica(spec, index, seed)


def test_replicas_lost_with_a_killed_process_run_again_in_parallel(tmp_path):
    """Issue 42: a worker killed (replica 0's) takes replica 1, running beside it, down with it; both run again
    at the same time in a fresh pool, not one after the other, to the rows of an undisturbed ensemble."""
    task = functools.partial(killed_beside_another, where=tmp_path)
    result = ens.run_ensemble(parse_spec(SHORT), 4, workers=2, task=task, progress=False)
    assert (tmp_path / "died").exists() and result.failures == []
    assert result.rows == undisturbed(SHORT, 4)
    (begun0, ended0), (begun1, ended1) = ([float(t) for t in (tmp_path / f"span-{k}").read_text().split()]
                                          for k in (0, 1))
    assert max(begun0, begun1) < min(ended0, ended1)  # both ran again at once


def test_the_command_line_names_the_replica_and_how_to_run_it_alone(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(ens, "run_replica", _dying_replica)  # the default task, looked up when the ensemble runs
    spec = tmp_path / "s.json"
    spec.write_text(json.dumps(SHORT))
    code = cli.main(["ensemble", str(spec), "--replicas", "4", "--workers", "2", "--out", str(tmp_path / "out"),
                     "--quiet"])
    err = capsys.readouterr().err
    assert code == 1 and err == (
        f"pinnedballs: replica 2 (seed entropy 3, spawn key [2]) failed: WorkerDied: the process running it died "
        f"{executors.MAX_DEATHS} times (killed, or out of memory?); rerun it alone with pinnedballs.run.ensemble."
        f"run_replica(pinnedballs.specs.load_spec({str(spec)!r}), 2), which gives the rows it would have had\n")
    assert [r["replica"] for r in ens_files.read_table(tmp_path / "out" / ens.TABLE_NAME)] == \
        ["0", "0", "1", "1", "2", "3", "3"]


_REAL_REPLICA = ens.run_replica


def _dying_replica(spec, index, seed=None):
    if index == 2:
        os.kill(os.getpid(), signal.SIGKILL)
    return _REAL_REPLICA(spec, index, seed)


#: ``python DRIVER SIGNALS pinnedballs-arguments...``: the command line, its replicas telling through files
#: in SIGNALS where they are: replica 0 starts once replica 1 runs on the other process, then says
#: "done-0-PID" (that process is then idle, waiting for a job); replica 1 says "running-1-PID", then
#: waits for the file "go" (it is busy until then). Forked workers inherit the task.
DRIVER = """
import os, sys, time
from pathlib import Path
from pinnedballs.run.cli.main import main
from pinnedballs.run import ensemble as ens

signals, real = Path(sys.argv[1]), ens.run_replica

def wait_for(pattern):
    while not list(signals.glob(pattern)):
        time.sleep(0.01)

def replica(spec, index, seed=None):
    if index == 0:
        wait_for("running-1-*")
    if index == 1:
        (signals / f"running-1-{os.getpid()}").touch()
        wait_for("go")
    rows = real(spec, index, seed)
    (signals / f"done-{index}-{os.getpid()}").touch()
    return rows

ens.run_replica = replica  # the command's task, looked up when its ensemble starts
sys.exit(main(sys.argv[2:]))
"""


def pid_of(signals: Path, pattern: str, deadline: float) -> int:
    """The process id in the name of the file matching ``pattern`` in ``signals``, once there is one."""
    while time.monotonic() < deadline:
        found = sorted(signals.glob(pattern))
        if found:
            return int(found[0].name.rpartition("-")[2])
        time.sleep(0.01)
    raise AssertionError(f"no {pattern} within the test's time")


def test_the_command_outlives_an_idle_worker_killed_from_outside(tmp_path):
    """Issue 34, item 8: a SIGKILL (the OOM killer's) of the worker that waits for a job while the other
    runs replica 1. Before, the command waited for ever: the broken pool terminated its survivor with
    SIGTERM, which the command's handler (inherited by the forked workers) turned into a
    KeyboardInterrupt that the survivor reported, and it then waited for ever for a job, on the call
    queue's lock that the killed worker held. Now replica 1 runs again, and the table is the one an
    undisturbed ensemble writes, bit for bit."""
    signals = tmp_path / "signals"
    signals.mkdir()
    (tmp_path / "driver.py").write_text(DRIVER)
    spec = tmp_path / "s.json"
    spec.write_text(json.dumps(SHORT))
    out = tmp_path / "out"
    child = subprocess.Popen([sys.executable, str(tmp_path / "driver.py"), str(signals), "ensemble", str(spec),
                              "--replicas", "2", "--workers", "2", "--out", str(out), "--quiet"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                             env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        deadline = time.monotonic() + 240  # for a loaded machine; each step takes a second or so
        idle = pid_of(signals, "done-0-*", deadline)
        os.kill(idle, signal.SIGKILL)
        (signals / "go").touch()
        _, err = child.communicate(timeout=max(60.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        raise AssertionError("the ensemble hung after its worker was killed") from None
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(child.pid, signal.SIGKILL)  # the command and its workers, whatever happened
        if child.returncode is None:
            child.communicate()
    assert (child.returncode, err) == (0, "")
    expected = tmp_path / "undisturbed.csv"
    ens_files.write_table(ens.run_ensemble(parse_spec(SHORT), 2, workers=1, progress=False), expected)
    assert (out / ens.TABLE_NAME).read_bytes() == expected.read_bytes()


# ---------------------------------------------------------------- a Dask cluster


@pytest.fixture
def cluster():
    """Two worker processes, each restarted by its nanny when it dies; a task whose workers died twice
    is given up (Dask's default is 4 times: the same, slower)."""
    distributed = pytest.importorskip("dask.distributed")
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                     dashboard_address=None) as c, distributed.Client(c) as client:
        yield client


def test_a_dask_worker_killed_mid_run_costs_nothing(cluster):
    pids, killed = cluster.run(os.getpid), []

    def kill_a_busy_worker():
        while not killed:
            busy = sorted(w for w, keys in cluster.processing().items() if keys)
            if busy:
                time.sleep(0.3)  # into its replica
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(pids[busy[0]])
            time.sleep(0.01)

    killer = threading.Thread(target=kill_a_busy_worker, daemon=True)
    killer.start()
    result = ens.run_ensemble(parse_spec(LONG), 4, cluster=cluster)
    killer.join(timeout=60)
    assert killed and killed[0] not in cluster.run(os.getpid).values()  # that worker died and was replaced
    assert result.failures == [] and result.rows == undisturbed(LONG, 4)


@pytest.fixture
def one_worker():
    """One worker process, restarted by its nanny when it dies; a task on a worker that dies is given
    up at once (``allowed-failures`` 0): every replica waiting on it when it dies gets ``KilledWorker``."""
    distributed = pytest.importorskip("dask.distributed")
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                     dashboard_address=None) as c, distributed.Client(c) as client:
        yield client


def test_a_replica_given_up_beside_the_one_that_kills_its_worker_is_run_again(one_worker):
    """Dask gives up on every task on a worker that died, the innocent ones waiting beside the killer
    too (here replica 3, queued behind replica 2 on the only worker). Each is run again alone: only
    replica 2, which kills its worker alone as well, is reported. (Before, replica 3 was reported
    too: with two workers and one allowed failure this made the test below fail now and then.)"""
    with pickled_by_value(sys.modules[__name__]):
        result = ens.run_ensemble(parse_spec(SHORT), 4, cluster=one_worker, task=die)
    assert [row["replica"] for row in result.failures] == [2]
    assert result.failures[0][ens.ERROR_COLUMN].startswith("KilledWorker: Attempted to run task")
    assert [r for r in result.rows if r["replica"] != 2] == [r for r in undisturbed(SHORT, 4) if r["replica"] != 2]


def test_a_replica_whose_dask_worker_always_dies_is_the_only_one_reported(cluster):
    with pickled_by_value(sys.modules[__name__]):
        result = ens.run_ensemble(parse_spec(SHORT), 4, cluster=cluster, task=die)
    failed, = result.failures
    assert (failed["replica"], failed["spawn_key"]) == (2, "[2]")
    assert failed[ens.ERROR_COLUMN].startswith("KilledWorker: Attempted to run task")
    assert [r for r in result.rows if r["replica"] != 2] == [r for r in undisturbed(SHORT, 4) if r["replica"] != 2]


_AFTER_THREADS = '''
import json, sys
import numba
import pinnedballs as pb
from pinnedballs.run import executors

def main():
    spec = pb.load_spec(sys.argv[1])
    first = executors._start_method()
    spec.build().run(1000)  # a ColoredSweep: numba's OpenMP threads start in this process
    layer = numba.threading_layer()
    res = pb.run_ensemble(spec, 3, workers=2, progress=False)
    then = executors._start_method()
    print(json.dumps({"first": first is None, "layer": layer, "then": then and then.get_start_method(),
                      "failures": len(res.failures), "collisions": res.column("collisions").tolist()}))

if __name__ == "__main__":
    main()
'''


def test_an_ensemble_after_threads_in_this_process_runs(tmp_path):
    """GNU OpenMP does not survive fork: once this process has run numba's threads (a ColoredSweep, a chain
    on >= 65,536 contacts), a forked worker that runs them again is ended by numba ("fork() called from a
    process already using GNU OpenMP"), and every replica failed. The pool then starts its processes from
    a fork server, and the replicas give the bits they give in this process."""
    import subprocess

    spec = {**SHORT, "scheduler": {"kind": "colored_sweep", "shuffle": True}}
    (tmp_path / "spec.json").write_text(json.dumps(spec))
    (tmp_path / "after_threads.py").write_text(_AFTER_THREADS)
    out = subprocess.run([sys.executable, "after_threads.py", "spec.json"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=600, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout.splitlines()[-1])
    assert got["first"] and got["layer"] == "omp" and got["then"] == "forkserver"
    assert "GNU OpenMP" not in out.stderr and got["failures"] == 0
    alone = ens.run_ensemble(parse_spec(spec), 3, workers=1, progress=False)
    assert got["collisions"] == alone.column("collisions").tolist()
