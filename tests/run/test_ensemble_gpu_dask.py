"""GPU ensembles on a Dask cluster (`run_ensemble(..., device="cuda", cluster=...)`, `pinnedballs ensemble --device
cuda --dask ADDRESS`): the replicas in groups, a group a job on a worker that owns a GPU (here numba-cuda's
simulator, which the workers inherit from the test session), and the rows the CPU gives for the same seeds."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

pytestmark = pytest.mark.cuda  # numba-cuda's simulator runs the kernels: skipped without it (conftest)

from pinnedballs.run import ensemble as ens  # noqa: E402
from pinnedballs.run.ensemble_gpu import groups  # noqa: E402
from pinnedballs.specs.run import parse_spec  # noqa: E402
from pinnedballs.util.errors import InputError  # noqa: E402

GPU_SPEC = {"geometry": {"kind": "half_plane", "rows": 5, "cols": 8},
            "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0.0, 1.0], "energy": 100.0},
            "scheduler": {"kind": "uniform_random_pair", "stream": "counter"},
            "stop": {"frozen": True, "max_steps": 10**6}, "snapshots": {"at_collisions": [20]}, "seed": 7}


@pytest.fixture(scope="module")
def gpu_cluster():
    """Two worker processes, each restarted by its nanny when it dies; the workers see the simulator's GPU."""
    distributed = pytest.importorskip("dask.distributed")
    import dask

    assert os.environ.get("NUMBA_ENABLE_CUDASIM") == "1"  # the workers inherit it (tests/conftest.py)
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}), \
            distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                     dashboard_address=None) as c, distributed.Client(c) as client:
        yield client


def test_groups_cover_every_replica_once_in_order():
    for replicas, workers, most in ((1, 4, 100), (10, 3, 100), (10, 3, 2), (16384, 8, 1 << 14), (7, 1, 3)):
        parts = groups(replicas, workers, most)
        assert [k for r in parts for k in r] == list(range(replicas))
        assert all(0 < len(r) <= most for r in parts) and len(parts) >= min(replicas, workers)


@pytest.mark.slow
def test_the_clusters_gpus_give_the_cpus_rows(gpu_cluster):
    """Six replicas in groups on two workers' GPUs: the rows (snapshots and the frozen state, margins) of the
    same replicas on the CPU, in the same order; it says where it ran."""
    spec = parse_spec(GPU_SPEC)
    on_gpus = ens.run_ensemble(spec, 6, device="cuda", cluster=gpu_cluster)
    on_cpu = ens.run_ensemble(spec, 6, workers=1)
    assert on_gpus.failures == [] and on_gpus.rows == on_cpu.rows
    assert on_gpus.where.startswith("dask ") and on_gpus.where.endswith("(a GPU a worker)")
    assert sum(row["at"] == "final" for row in on_gpus.rows) == 6


@pytest.mark.slow
def test_a_worker_lost_mid_ensemble_costs_nothing(gpu_cluster):
    """A worker killed while its GPU runs a group: Dask runs the group again on a worker that is left (or its
    nanny's new one), and the rows are the CPU's."""
    spec = parse_spec({**GPU_SPEC, "geometry": {"kind": "half_plane", "rows": 8, "cols": 12}})
    pids, killed = gpu_cluster.run(os.getpid), []

    def kill_a_busy_worker():
        while not killed:
            busy = sorted(w for w, keys in gpu_cluster.processing().items() if keys)
            if busy:
                time.sleep(0.5)  # into its group
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(pids[busy[0]])
            time.sleep(0.01)

    killer = threading.Thread(target=kill_a_busy_worker, daemon=True)
    killer.start()
    result = ens.run_ensemble(spec, 4, device="cuda", cluster=gpu_cluster)
    killer.join(timeout=60)
    assert killed and result.failures == []
    assert result.rows == ens.run_ensemble(spec, 4, workers=1).rows


def test_what_a_gpu_cannot_run_is_refused_before_any_job(gpu_cluster):
    """The xoshiro stream or exact arithmetic is refused in one line naming ``device``, before the cluster
    runs anything."""
    for changes, words in (({"scheduler": {"kind": "uniform_random_pair"}},
                            'runs the scheduler {"kind": "uniform_random_pair", "stream": "counter"}'),
                           ({"arithmetic": "exact"}, "'cuda' runs an ensemble's replicas in float arithmetic")):
        with pytest.raises(InputError, match="^device: ") as info:
            ens.run_ensemble(parse_spec({**GPU_SPEC, **changes}), 3, device="cuda", cluster=gpu_cluster)
        assert words in str(info.value) and "\n" not in str(info.value)


@pytest.mark.slow
def test_the_command_line_runs_an_ensemble_on_the_clusters_gpus(gpu_cluster, tmp_path):
    """``pinnedballs ensemble SPEC --device cuda --dask ADDRESS`` writes the table the CPU writes; ``--workers``
    with ``--device cuda`` is refused in one line, status 2, and nothing is written."""
    import json

    from pinnedballs.run.cli.main import main

    spec = tmp_path / "spec.json"
    spec.write_text(json.dumps(GPU_SPEC))
    address = gpu_cluster.scheduler.address
    assert main(["ensemble", str(spec), "--replicas", "5", "--device", "cuda", "--dask", address,
                 "--out", str(tmp_path / "gpus"), "--quiet"]) == 0
    assert main(["ensemble", str(spec), "--replicas", "5", "--workers", "1", "--out", str(tmp_path / "cpu"),
                 "--quiet"]) == 0
    assert (tmp_path / "gpus" / "replicas.csv").read_bytes() == (tmp_path / "cpu" / "replicas.csv").read_bytes()
    assert main(["ensemble", str(spec), "--replicas", "5", "--device", "cuda", "--workers", "2",
                 "--out", str(tmp_path / "refused")]) == 2
    assert not (tmp_path / "refused").exists()
