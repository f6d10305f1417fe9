"""Ensembles on a GPU (`run_ensemble(..., device="cuda")`): the rows the CPU gives for the same seeds.

Small systems run one replica a GPU thread (`engine.gpu.replicas.ReplicaChains`), as many at once as the
GPU's memory holds (`REPLICA_MEMORY_SHARE` of it), group after group. A replica's stream is its own
seed's counter stream, so it runs the chain its `Simulation` would run on the CPU; this module plays
the run driver's part for each (`engine.driver`): it stops every replica at the counts where the spec's
snapshots fall and at its stop, in the driver's order (the snapshots' trigger, then the stop's reason,
a run stopped by steps found frozen on its last step), and builds its rows from its velocities as
`run_replica` does. Systems larger than `MAX_THREAD_CONTACTS` contacts run one replica after another,
each a `Simulation(device="cuda")` (the chain by deterministic reservations on the whole GPU).
"""

from __future__ import annotations

import types
from typing import Callable

import numpy as np

from ..engine.chain import NO_LIMIT
from ..engine.philox import counter_stream
from ..engine.random import seed_state
from ..engine.state import RunState, mass_array
from ..rules import threshold

__all__ = ["run_on_gpu", "MAX_THREAD_CONTACTS", "REPLICA_MEMORY_SHARE"]

#: systems with more contacts than this run one replica at a time on the whole GPU
MAX_THREAD_CONTACTS = 1 << 16
#: the share of the GPU's free memory one group of replicas' velocities may take
REPLICA_MEMORY_SHARE = 0.5
#: steps a replica takes in one launch at most (a launch cannot be interrupted: Ctrl-C waits for it)
LAUNCH_STEPS = 1 << 26


def run_on_gpu(spec, seeds: list, observe: Callable, row_of: Callable, tick: Callable[[], None]) -> dict[int, list]:
    """The rows of replicas ``0 .. len(seeds) - 1`` of ``spec``, by replica. ``row_of(sim, index, seed, at,
    state, frozen, reason, observe)`` builds one row (`ensemble.replica_row`) with ``observe``'s columns,
    ``tick()`` is told of each replica done."""
    from ..engine.backends import check_device

    proto = spec.build(seed=seeds[0])
    check_device(proto)  # floats, a built-in rule, the counter stream, numba-cuda and a GPU: or one line why
    if proto.geometry.n_contacts > MAX_THREAD_CONTACTS:
        return _one_at_a_time(spec, seeds, observe, row_of, tick)
    out: dict[int, list] = {}
    for group in _groups(len(seeds), proto):
        out.update(_Group(spec, proto, [(k, seeds[k]) for k in group], observe, row_of).run())
        for _ in group:
            tick()
    return out


def _one_at_a_time(spec, seeds, observe, row_of, tick) -> dict[int, list]:
    from ..engine.driver import drive
    from ..results.format import Record
    from .writers import OnSnapshot

    out = {}
    for k, seed in enumerate(seeds):
        sim = spec.build(seed=seed, device="cuda")
        sim._margin_warned = True
        rows, counter = [], spec.snapshots.counter if spec.snapshots else ""

        def on_snapshot(record: Record) -> None:
            rows.append(row_of(sim, k, seed, f"{counter}={getattr(record.state, counter)}", record.state,
                               record.frozen, "", observe))

        writers = [OnSnapshot(spec.snapshots.build(), on_snapshot)] if spec.snapshots else []
        reason = drive(sim, spec.stop.build(), writers)
        rows.append(row_of(sim, k, seed, "final", sim.get_state(), sim.is_frozen(), reason, observe))
        out[k] = rows
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


class _Group:
    """Replicas of one spec on the GPU, each driven to its snapshots and its stop (module docstring)."""

    def __init__(self, spec, proto, members: list, observe: Callable, row_of: Callable):
        from ..engine.gpu.replicas import ReplicaChains

        self.spec, self.proto, self.members, self.row_of = spec, proto, members, row_of
        self.observe = observe
        g, masses = proto.geometry, proto._mass_array
        v, params, keys, self.views = [], [], [], []
        for k, seed in members:
            velocities = proto._check_velocities(spec.initial.build(g, mass_array(spec.build_masses(g.n_balls),
                                                                                   g.n_balls), seed))
            tau = threshold(velocities, masses, proto.resolution)
            v.append(velocities)
            params.append(np.append(proto._params[:-1], tau))
            keys.append(counter_stream(seed_state(seed))[:2])
            # what a row reads of a simulation: its geometry, masses, threshold and resolution
            self.views.append(types.SimpleNamespace(geometry=g, masses=proto.masses, threshold=tau,
                                                    resolution=proto.resolution, smallest_exact_collision=None))
        self.chains = ReplicaChains(np.stack(v), np.stack(params), np.stack(keys), g.contacts, None, masses,
                                    proto._collide)
        self.stop = spec.stop.build()
        self.trigger = spec.snapshots.build() if spec.snapshots else None
        self.counter = spec.snapshots.counter if spec.snapshots else ""

    def _state(self, r: int, velocities: np.ndarray) -> RunState:
        st = self.chains.state[r]
        return RunState(velocities, int(st[0]), int(st[1]), np.zeros(4, dtype=np.uint64), np.zeros(1, dtype=np.int64),
                        None, self.chains.margin[r].copy(), None)

    def _live(self, velocities: np.ndarray) -> int:
        return int(self.proto._backend.live_flags_of(self.proto, velocities).sum())

    def run(self) -> dict[int, list]:
        from ..engine.driver import _least

        n = len(self.members)
        rows: list[list] = [[] for _ in range(n)]
        checked: list = [None] * n
        frozen = np.zeros(n, dtype=bool)
        done = np.zeros(n, dtype=bool)
        self._fire(rows, checked, range(n))
        chunk = max(1 << 12, 4 * self.proto.geometry.n_contacts)
        while not done.all():
            limits = np.zeros((n, 3), dtype=np.int64)
            for r in range(n):
                steps, collisions = (int(x) for x in self.chains.state[r, :2])
                counts = types.SimpleNamespace(steps=steps, collisions=collisions)
                reason = "" if done[r] else self.stop.reason(counts, frozen[r])
                if reason == self.stop.steps_reason and self.stop.until_frozen and \
                        self._live(self.chains.velocities(r)) == 0:
                    reason = self.stop.reason(counts, True)  # froze on the very last step
                if reason and not done[r]:
                    done[r] = True
                    self._finish(rows, r, reason)
                t = self.trigger
                step_to = _least(self.stop.steps, None if t is None else t.next_steps(steps))
                collide_to = _least(self.stop.collisions, None if t is None else t.next_collisions(collisions))
                limits[r] = (steps if done[r] else min(NO_LIMIT if step_to is None else step_to, steps + LAUNCH_STEPS),
                             NO_LIMIT if collide_to is None else collide_to, int(self.stop.until_frozen))
            if done.all():
                break
            before = self.chains.state[:, :2].copy()
            self.chains.run(limits, chunk)
            moved = [r for r in range(n) if not done[r]]
            for r in moved:
                st = self.chains.state[r]
                short = st[0] < limits[r, 0] and st[1] < limits[r, 1]
                frozen[r] = bool(short and self.stop.until_frozen and st[3])
                if short and not frozen[r] and st[0] == before[r, 0]:
                    raise RuntimeError(f"replica {self.members[r][0]} took no step and did not freeze")
            self._fire(rows, checked, moved)
        return {k: rows[r] for r, (k, _) in enumerate(self.members)}

    def _fire(self, rows, checked, replicas) -> None:
        """The snapshot rows of the replicas whose trigger fires at their counts now (`driver._fire`)."""
        if self.trigger is None:
            return
        for r in replicas:
            now = tuple(int(x) for x in self.chains.state[r, :2])
            if checked[r] != now and self.trigger.fires(checked[r], now):
                v = self.chains.velocities(r)
                state = self._state(r, v)
                k, seed = self.members[r]
                rows[r].append(self.row_of(self.views[r], k, seed, f"{self.counter}={getattr(state, self.counter)}",
                                           state, self._live(v) == 0, "", self.observe))
            checked[r] = now

    def _finish(self, rows, r: int, reason: str) -> None:
        v = self.chains.velocities(r)
        k, seed = self.members[r]
        rows[r].append(self.row_of(self.views[r], k, seed, "final", self._state(r, v), self._live(v) == 0, reason,
                                   self.observe))
