"""Ensembles on a GPU (`run.ensemble_gpu`, under numba-cuda's simulator): the CPU's rows for the same seeds,
replica for replica, whatever the stop and the snapshots, one replica a thread or one after another."""

import functools
import json

import numpy as np
import pytest

import pinnedballs as pb
from pinnedballs.run import ensemble_gpu
from pinnedballs.run.ensemble import run_replica
from pinnedballs.specs.run import parse_spec
from pinnedballs.util.errors import InputError

pytestmark = pytest.mark.cuda  # numba-cuda's simulator runs the kernels: skipped without it (conftest)


def spec(stop, snapshots=None, **more):
    return parse_spec({"geometry": {"kind": "half_plane", "length": 20, "depth": 10},
                       "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1],
                                   "energy": 100},
                       "scheduler": {"kind": "uniform_random_pair", "stream": "counter"},
                       "stop": stop, "seed": 3, **({"snapshots": snapshots} if snapshots else {}), **more})


def same_rows(a, b) -> bool:
    """Row for row equal, a NaN equal to a NaN (a correlation over no moving ball)."""
    return json.dumps(a.rows, sort_keys=True) == json.dumps(b.rows, sort_keys=True)


@pytest.mark.parametrize("stop, snapshots", [
    ({"frozen": True, "max_steps": 10**6}, {"every_steps": 500}),
    ({"collisions": 150}, {"at_collisions": [0, 100]}),
    ({"steps": 1700}, None)])
def test_the_gpu_gives_the_cpus_rows(stop, snapshots):
    s = spec(stop, snapshots)
    cpu = pb.run_ensemble(s, 4, workers=1, progress=False)
    gpu = pb.run_ensemble(s, 4, device="cuda", progress=False)
    assert gpu.where == "GPU" and not gpu.failures
    assert same_rows(cpu, gpu)


def test_a_lattices_replicas_decode_their_picks_from_its_row_pattern():
    """The half-plane above (600 balls, below the CPU's row-pattern size) runs its replicas on the pattern, with
    the CPU's rows (the test above); a graph has none, and its replicas read the tables."""
    g = pb.HalfPlane.from_size(20, 10)
    assert g.row_pattern is None and ensemble_gpu.replica_pattern(g) is not None
    graph = pb.GraphGeometry.from_positions([[0.0, 0.0], [2.0, 0.0], [4.0, 0.0]])
    assert ensemble_gpu.replica_pattern(graph) is None


def test_large_systems_run_one_replica_after_another(monkeypatch):
    monkeypatch.setattr(ensemble_gpu, "MAX_THREAD_CONTACTS", 10)
    s = spec({"frozen": True, "max_steps": 10**6}, {"every_collisions": 100})
    assert same_rows(pb.run_ensemble(s, 2, workers=1, progress=False),
                     pb.run_ensemble(s, 2, device="cuda", progress=False))


def test_a_task_that_observes_more_runs_on_the_gpu_too():
    def observe(geometry, velocities, masses):
        return {"largest_speed": float(np.sqrt((velocities**2).sum(axis=1)).max())}

    s = spec({"frozen": True, "max_steps": 10**6}, {"every_steps": 700})
    task = functools.partial(run_replica, observe=observe)
    assert same_rows(pb.run_ensemble(s, 3, workers=1, progress=False, task=task),
                     pb.run_ensemble(s, 3, device="cuda", progress=False, task=task))


def test_what_a_gpu_ensemble_refuses():
    s = spec({"steps": 100})
    with pytest.raises(InputError, match="device: 'cuda' runs the built-in replica task"):
        pb.run_ensemble(s, 2, device="cuda", task=lambda spec, index, seed: [])
    with pytest.raises(InputError, match="device: must be 'cpu' or 'cuda'"):
        pb.run_ensemble(s, 2, device="tpu")
    xoshiro = spec({"steps": 100}, scheduler={"kind": "uniform_random_pair"})
    with pytest.raises(ValueError, match=r'runs the scheduler \{"kind": "uniform_random_pair", "stream": "counter"\}'):
        pb.run_ensemble(xoshiro, 2, device="cuda")


def test_a_certified_ensemble_runs_one_replica_at_a_time_on_the_gpu_with_the_cpus_rows():
    """Certified arithmetic: each replica a certified chain on the GPU (`engine.gpu.certified`), any task (here
    the scaling study's, which runs a replica again without narrowing when it fails narrowed); the CPU's rows.
    On a Dask cluster it is refused in one line."""
    from pinnedballs.run.reproduction.extended.scaling_study import certified_replica

    s = parse_spec({"geometry": {"kind": "half_plane", "length": 10, "depth": 5},
                    "initial": {"kind": "single_ball", "ball": "boundary_center", "direction": [0, 1], "energy": 100},
                    "scheduler": {"kind": "uniform_random_pair", "stream": "counter"}, "arithmetic": "certified",
                    "precision": 128, "stop": {"steps": 120}, "seed": 7})
    cpu = pb.run_ensemble(s, 2, workers=1, progress=False, task=certified_replica)
    gpu = pb.run_ensemble(s, 2, device="cuda", progress=False, task=certified_replica)
    assert gpu.where == "GPU, one replica at a time" and not gpu.failures and same_rows(cpu, gpu)
    assert all(row["collisions"] > 10 for row in gpu.rows if row["at"] == "final")
    with pytest.raises(InputError, match="^device: 'cuda' runs a certified ensemble's replicas one at a time on this "
                                         "process's GPU; on a Dask cluster, certified replicas run on its CPUs"):
        pb.run_ensemble(s, 2, device="cuda", dask_address="tcp://127.0.0.1:1")


def test_gpu_replicas_are_simulations_whose_states_go_on_with_the_cpus_bits():
    """Replicas as state: simulations built on the CPU run together on the GPU (`run_replicas`) to a stop; each
    then holds the state of the same simulation run alone on the CPU (stream words and scheduler state too), and
    goes on, on the CPU, to the CPU's frozen state."""
    from pinnedballs.engine.stop import Stop
    from pinnedballs.run.ensemble_gpu import run_replicas

    g = pb.HalfPlane.from_size(12, 6)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = [0.5, 10.0]
    counter = pb.UniformRandomPair(stream="counter")
    gpu = [pb.Simulation(g, v, scheduler=counter, seed=seed) for seed in range(3)]
    cpu = [pb.Simulation(g, v, scheduler=counter, seed=seed) for seed in range(3)]
    stops = [Stop(steps=150), Stop(collisions=7, until_frozen=True), Stop(steps=10**6, until_frozen=True)]
    reasons = run_replicas(gpu, stops)
    cpu[0].run(steps=150)
    cpu[1].run(collisions=7)
    cpu[2].run_until_frozen(max_steps=10**6)
    assert reasons[2] == "frozen" and gpu[1].collisions == 7
    for a, b in zip(gpu, cpu):
        assert a.get_state().identical(b.get_state()) and a.engine_name == "threads"   # a CPU engine's state
        a.run_until_frozen(max_steps=10**6)
        b.run_until_frozen(max_steps=10**6)
        assert a.get_state().identical(b.get_state()) and a.closing_margin() == b.closing_margin()
