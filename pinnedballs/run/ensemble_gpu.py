"""Ensembles on a GPU (`run_ensemble(..., device="cuda")`): the rows the CPU gives for the same seeds.

Small systems run one replica a GPU thread (`engine.gpu.replicas.ReplicaChains`), as many at once as the
GPU's memory holds (`REPLICA_MEMORY_SHARE` of it), group after group. A replica's stream is its own
seed's counter stream, so it runs the chain its `Simulation` would run on the CPU. Each replica is a real
`Simulation`, built on the CPU as a replica on the CPU is (its velocities checked, its threshold, its stream
seeded), whose state the GPU's replicas engine runs with the others' (`engine.gpu.replicas.ReplicaSet`: replicas
as state) and writes back after every launch; so a replica goes on as a simulation with the CPU's bits
(`run_replicas`). Each goes through the run driver (`engine.driver.Drive`), as a replica on the CPU does: the
driver says where its next chunk ends (the spec's stop, its snapshots' trigger), the chunks of all the replicas
run in one launch, and the driver fires the snapshot rows and finds the stop's reason.
Systems larger than `MAX_THREAD_CONTACTS` contacts run one replica after another, each a
`Simulation(device="cuda")` (the chain by deterministic reservations on the whole GPU).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..engine import door
from ..engine.chain import NO_LIMIT
from ..engine.devices import as_device
from ..engine.driver import Drive, Writer, drive
from ..engine.rows import row_pattern

__all__ = ["run_on_gpu", "run_replicas", "on_worker_gpu", "groups", "gpu_workers", "replica_pattern",
           "MAX_THREAD_CONTACTS", "REPLICA_MEMORY_SHARE", "LAUNCH_STEPS", "WORKER_GROUP"]

#: systems with more contacts than this run one replica at a time on the whole GPU
MAX_THREAD_CONTACTS = 1 << 16
#: the share of the GPU's free memory one group of replicas' velocities may take
REPLICA_MEMORY_SHARE = 0.5
#: steps a replica takes in one launch at most (a launch cannot be interrupted: Ctrl-C waits for it)
LAUNCH_STEPS = 1 << 26
#: replicas one Dask job runs on its worker's GPU at most: the unit Dask runs again elsewhere when a worker is lost
WORKER_GROUP = 1 << 14


def run_on_gpu(spec, seeds: list, observe: Callable, row_of: Callable, tick: Callable[[], None],
               first: int = 0) -> dict[int, list]:
    """The rows of replicas ``first .. first + len(seeds) - 1`` of ``spec`` (their ``seeds``), by replica.
    ``row_of(sim, index, seed, at, state, frozen, reason, observe)`` builds one row (`ensemble.replica_row`) with
    ``observe``'s columns, ``tick()`` is told of each replica done."""
    proto = spec.build(seed=seeds[0])
    # floats, the counter stream, a rule the GPU runs with the CPU's bits, numba-cuda and a GPU: or one line why
    door.check(proto.engine.model, proto.arithmetic, "cuda", replicas=True)
    if proto.geometry.n_contacts > MAX_THREAD_CONTACTS:
        return _one_at_a_time(spec, seeds, observe, row_of, tick, first)
    out: dict[int, list] = {}
    for group in _groups(len(seeds), proto):
        out.update(_Group(spec, proto, [(first + k, seeds[k]) for k in group], observe, row_of).run())
        for _ in group:
            tick()
    return out


# ---------------------------------------------------------------- on a cluster's GPUs


def on_worker_gpu(spec, first: int, seeds: list, observe: Callable, row_of: Callable) -> dict[int, list]:
    """A Dask job: the rows of replicas ``first, first + 1, ...`` (their ``seeds``) of ``spec``, run on the GPU
    of the worker that runs it (`run_on_gpu`), by replica."""
    return run_on_gpu(spec, seeds, observe, row_of, lambda: None, first)


def groups(replicas: int, workers: int, most: int = WORKER_GROUP) -> list[range]:
    """Replica indices in jobs for ``workers`` GPUs: as many jobs as workers (or more, of at most ``most``
    replicas each), in order. The rows never depend on how they are grouped."""
    size = max(1, min(most, -(-replicas // max(1, workers))))
    return [range(a, min(replicas, a + size)) for a in range(0, replicas, size)]


def _sees_a_gpu() -> str:
    """On a worker: "" when it can run a GPU chain, else the one line saying why not."""
    from ..engine.gpu import GPUUnavailable, load

    try:
        load()
    except GPUUnavailable as exc:
        return exc.problem
    return ""


def gpu_workers(client) -> int:
    """The number of the workers of ``client``'s cluster, each of which must see a GPU (numba-cuda's simulator
    counts); an `InputError` on ``device`` naming those that do not, or saying there are none."""
    from ..util.errors import InputError

    seen = client.run(_sees_a_gpu)
    if not seen:
        raise InputError("device: 'cuda' on Dask: the cluster has no worker")
    lacking = {worker: why for worker, why in seen.items() if why}
    if lacking:
        worker, why = sorted(lacking.items())[0]
        raise InputError(f"device: 'cuda' on Dask needs a GPU on every worker; {len(lacking)} of {len(seen)} have "
                         f"none ({worker}: {why})")
    return len(seen)


class _Rows(Writer):
    """The rows of one replica: a snapshot row each time the spec's trigger fires, and the final row."""

    def __init__(self, spec, index: int, seed, observe: Callable, row_of: Callable):
        self.trigger = spec.snapshots.build() if spec.snapshots else None
        self.counter = spec.snapshots.counter if spec.snapshots else ""
        self.index, self.seed, self.observe, self.row_of = index, seed, observe, row_of
        self.rows: list = []

    def write(self, sim) -> None:
        state = sim.get_state()
        self.rows.append(self.row_of(sim, self.index, self.seed, f"{self.counter}={getattr(state, self.counter)}",
                                     state, sim.is_frozen(), "", self.observe))

    def finish(self, sim, reason: str) -> None:
        self.rows.append(self.row_of(sim, self.index, self.seed, "final", sim.get_state(), sim.is_frozen(), reason,
                                     self.observe))


def _one_at_a_time(spec, seeds, observe, row_of, tick, first: int) -> dict[int, list]:
    out = {}
    for k, seed in enumerate(seeds):
        sim = spec.build(seed=seed, device="cuda")
        sim.warns_thin_margin = False  # the ensemble says it once
        rows = _Rows(spec, first + k, seed, observe, row_of)
        drive(sim, spec.stop.build(), [rows])
        out[first + k] = rows.rows
        tick()
    return out


def _groups(count: int, proto) -> list[range]:
    """Replica indices in groups whose velocities fit `REPLICA_MEMORY_SHARE` of the GPU's free memory."""
    from ..engine.gpu import load

    cuda = load()
    try:
        free = float(cuda.current_context().get_memory_info()[0])
    except Exception:  # noqa: BLE001 - the simulator has no memory to ask about
        free = float(1 << 33)
    if not np.isfinite(free):  # the simulator says infinity
        free = float(1 << 33)
    per = max(1, proto.velocities.nbytes + 256)
    size = max(1, min(count, int(REPLICA_MEMORY_SHARE * free) // per))
    return [range(a, min(count, a + size)) for a in range(0, count, size)]


def replica_pattern(g) -> tuple | None:
    """The lattice's row pattern (`engine.rows`) for the replica kernels, or None (not a lattice): a
    replica's thread decodes its picks from it instead of reading four entries of the contact tables a
    pick, at any size (the CPU's loops read the tables below `rows.MIN_BALLS`, where they stay in cache)."""
    shape = g.row_shape()
    return None if shape is None else row_pattern(g.contacts.pairs, g.contacts.ends, *shape, min_balls=0)


def run_replicas(sims: list, stops: list, writers: list | None = None, chunk: int = LAUNCH_STEPS,
                 engine: str | None = None) -> list[str]:
    """Run ``sims`` (simulations of one geometry and rule on the counter stream, each its own state) together on
    this process's GPU, simulation ``r`` to its `Stop` ``stops[r]`` with its ``writers[r]``, by the door's replicas
    engine (`engine.builtin.GPUReplicas`, or the one named ``engine``): each simulation's state is then its
    replica's, and it goes on as a `Simulation`, on either device, with the bits of one that ran alone. Returns
    each one's stop reason."""
    model = sims[0].engine.model
    engine = door.choose(model, sims[0].arithmetic, "cuda", replicas=True, engine=engine)
    replicas = engine.build_replicas([sim.engine for sim in sims], as_device("cuda"), replica_pattern(model.geometry))
    writers = writers or [[] for _ in sims]
    drives = [Drive(sim, stop, list(w), chunk=chunk) for sim, stop, w in zip(sims, stops, writers)]
    until_frozen = [d.stop.until_frozen for d in drives]
    freeze_chunk = max(1 << 12, 4 * model.geometry.n_contacts)
    for d in drives:
        d.attach()
        d.start()
    active = list(range(len(sims)))
    while True:
        limits = np.zeros((len(sims), 3), dtype=np.int64)
        moving = []
        for r in active:
            asked = drives[r].next()
            if asked is None:
                continue
            steps, collisions = asked
            limits[r] = (sims[r].steps + steps, NO_LIMIT if collisions is None else collisions, int(until_frozen[r]))
            moving.append(r)
        if not moving:
            break
        for r in set(range(len(sims))) - set(moving):  # done: no step
            limits[r] = (sims[r].steps, NO_LIMIT, 0)
        before = [sims[r].steps for r in range(len(sims))]
        replicas.run(limits, freeze_chunk)
        for r in moving:
            sim = sims[r]
            short = sim.steps < limits[r, 0] and sim.collisions < limits[r, 1]
            frozen = bool(short and until_frozen[r] and replicas.frozen(r))
            if short and not frozen and sim.steps == before[r]:
                raise RuntimeError(f"replica {r} took no step and did not freeze")
            drives[r].advanced(frozen)
        active = moving
    return [d.reason for d in drives]


class _Group:
    """Replicas of one spec on the GPU, each a `Simulation` driven to its snapshots and its stop (module
    docstring)."""

    def __init__(self, spec, proto, members: list, observe: Callable, row_of: Callable):
        self.spec, self.members = spec, members
        self.sims = [spec.build(seed=seed, geometry=proto.geometry) for _, seed in members]  # real simulations
        for sim in self.sims:
            sim.warns_thin_margin = False  # the ensemble says it once
        self.rows = [_Rows(spec, k, seed, observe, row_of) for k, seed in members]

    def run(self) -> dict[int, list]:
        run_replicas(self.sims, [self.spec.stop.build() for _ in self.sims], [[rows] for rows in self.rows])
        return {k: self.rows[r].rows for r, (k, _) in enumerate(self.members)}
