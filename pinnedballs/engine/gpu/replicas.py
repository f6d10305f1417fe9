"""Many small systems on one GPU: one replica a GPU thread, each the sequential chain on its own stream.

A replica that fits a thread (its velocities in GPU memory, its picks a function of its own key and
step) runs the engine's ``limited`` loop as the CPU runs it, within the limits of `engine.harness`
compiled for the device: chunks of steps, a scan for a live contact after a chunk with a collision, the
chunk that froze ended at its last collision (the counter stream needs no rewind: its next pick is the one
of that step), the margin's remnant side as of that collision. So each replica's velocities, counters and
margin are those of a `Simulation` on the CPU with the same seed (`run.ensemble_gpu` builds the ensemble's rows from
them).

`ReplicaChains` holds the replicas of one geometry and rule: velocities ``(R, N, dim)``, keys, the
per-replica thresholds, and runs them all, each to its own limits, in one launch.
"""

from __future__ import annotations

import functools
import os

import numpy as np
from numba import cuda

from ...util.errors import FieldError
from ..chain import COLLISIONS, LAST, LIVE, STEPS
from ..harness import given, limits_loop, taken
from ..margin import track as margin_track
from . import load
from .chain import upload_contacts
from .compile import device_function, device_trial
from .device import SIMULATED, contact_reader, counter_pick, device, launching, lemire, philox_block

__all__ = ["replicas_kernel", "ReplicaChains", "ReplicaSet", "S_STEPS", "S_COLLISIONS", "S_LAST", "S_FROZEN",
           "STATE_SIZE"]

#: columns of the per-replica ``state (R, STATE_SIZE) int64``: steps (= the stream's position), collisions,
#: the steps right after the last collision (0: none), 1 when the last launch ended at a freeze, and the
#: contact the last scan of `lanes_kernel` found live (its next scan starts there: whether any is live does
#: not depend on where a scan starts)
S_STEPS, S_COLLISIONS, S_LAST, S_FROZEN, S_HINT = range(5)
STATE_SIZE = 5
#: threads per block (a replica each)
REPLICA_BLOCK = 4 if SIMULATED else 64
_U0, _U2, _U3 = np.uint64(0), np.uint64(2), np.uint64(3)


@functools.cache
def replicas_kernel(collide, dim: int, flat: bool, rows: bool):
    """``run(V, pairs, ends, table, meta, inverse, units, masses, P, keys, state, M, limits, chunk)``: replica
    ``r`` (thread ``r``) runs its chain on ``V[r] (N, dim)`` with ``params P[r]``, key ``keys[r]``,
    counters ``state[r]`` and margin ``M[r] (4,)`` until ``limits[r] = (steps, collisions, until_frozen)``
    (absolute counts) as the CPU's ``limited`` loop with freeze chunks of ``chunk`` steps: the limits of
    `engine.harness`, compiled for the device from the same source. ``data = (v, pairs, ends, table, meta,
    inverse, units, masses, params, k0, k1, s0)``; ``carry = (margin (4), its remnant side as of the last
    collision (2), the Philox block held and its four words)``."""
    trial, track, contact = device_trial(collide, dim, flat), device_function(margin_track), contact_reader(rows)

    @device
    def any_live(v, pairs, ends, table, meta, inverse, units, masses, params):
        for k in range(pairs.shape[0]):
            i, j, a, b = contact(pairs, ends, table, meta, inverse, np.int64(k))
            hit, w = trial(v, units, masses, params, i, j, a, b, False)
            if hit:
                return True
        return False

    @device
    def mark(data, carry, count, left):
        return carry  # the counter stream needs no rewind: the next pick is the one of its step

    @device
    def advance(data, carry, count, left, taken, collisions):
        v, pairs, ends, table, meta, inverse, units, masses, params, k0, k1, s0 = data
        m0, m1, m2, m3, at1, at3, q, w0, w1, w2, w3 = carry
        n, tau = np.uint64(pairs.shape[0]), params[params.shape[0] - 1]
        first = s0 + taken
        s, end = first, first + count
        made, last = np.int64(0), np.int64(-1)
        at1, at3 = m1, m3
        while s < end:
            if (s >> 2) != q:  # one Philox block gives the words of four steps
                q = s >> 2
                w0, w1, w2, w3 = philox_block(np.uint64(q), _U0, _U0, _U0, k0, k1)
            e = s & 3
            x = w0 if e == 0 else (w1 if e == 1 else (w2 if e == 2 else w3))
            c, accepted = lemire(x, n)
            if not accepted:
                c = counter_pick(k0, k1, np.uint64(s), n)
            i, j, a, b = contact(pairs, ends, table, meta, inverse, np.int64(c))
            hit, w = trial(v, units, masses, params, i, j, a, b, True)
            m0, m1, m2, m3 = track(hit, w, tau, m0, m1, m2, m3)
            s += 1
            if hit:
                made += 1
                last = s - first - 1
                at1, at3 = m1, m3
                if made == left:
                    break
        return s - first, made, last, (m0, m1, m2, m3, at1, at3, q, w0, w1, w2, w3)

    @device
    def live(data, carry):
        v, pairs, ends, table, meta, inverse, units, masses, params, k0, k1, s0 = data
        return any_live(v, pairs, ends, table, meta, inverse, units, masses, params)

    @device
    def settle(data, start, carry, used, count, frozen):
        m0, m1, m2, m3, at1, at3, q, w0, w1, w2, w3 = carry
        if frozen:  # the run ends right after its last collision, and so does its margin
            m1, m3 = at1, at3
        return m0, m1, m2, m3, at1, at3, q, w0, w1, w2, w3

    # the harness and its prepare as device functions of their own (numba inlines no function called with or
    # taking *args; NVVM inlines them)
    to_limits = cuda.jit(device=True)(limits_loop(mark, advance, live, settle, cuda.jit(device=True)(given),
                                                  device(taken)))

    @cuda.jit
    def run(V, pairs, ends, table, meta, inverse, units, masses, P, keys, state, M, limits, chunk):
        r = cuda.grid(1)
        if r >= V.shape[0]:
            return
        s0 = state[r, S_STEPS]
        data = (V[r], pairs, ends, table, meta, inverse, units, masses, P[r], keys[r, 0], keys[r, 1], s0)
        m0, m1, m3 = M[r, 0], M[r, 1], M[r, 3]
        carry = (m0, m1, M[r, 2], m3, m1, m3, np.int64(-1), _U0, _U0, _U0, _U0)
        taken, collisions, frozen, last, carry = to_limits(data, carry, state[r, S_COLLISIONS], limits[r, 0] - s0,
                                                           limits[r, 1], limits[r, 2] != 0, chunk)
        state[r, S_STEPS], state[r, S_COLLISIONS] = s0 + taken, collisions
        if last >= 0:
            state[r, S_LAST] = s0 + last
        state[r, S_FROZEN] = 1 if frozen else 0
        M[r, 0], M[r, 1], M[r, 2], M[r, 3] = carry[0], carry[1], carry[2], carry[3]

    return run


#: lanes of a block that runs one replica (`lanes_kernel`): a batch of this many steps at a time
LANES = 8 if SIMULATED else 32
#: how replicas are laid out on the GPU: ``"thread"`` (`replicas_kernel`) or ``"block"`` (`lanes_kernel`);
#: ``PINNEDBALLS_GPU_REPLICAS`` overrides it (the bits are the same). One a thread is the default: the faster
#: of the two on the ensembles tried (docs/performance.md)
LAYOUT = "thread"


@functools.cache
def lanes_kernel(collide, dim: int, flat: bool, rows: bool):
    """`replicas_kernel`'s work with one block of `LANES` threads a replica: each batch of up to `LANES`
    steps is decoded one step a lane and run by deterministic reservations within the block (a lane runs
    its pick when no earlier pending pick of the batch shares a ball with it; most batches need one round),
    then lane 0 counts the batch's collisions and folds its closing speeds into the margin in step order.
    A batch never passes the collision target (it holds one step when fewer collisions are left than lanes),
    the freeze scan is shared by the lanes, and the chunk that froze ends at its last collision, as on the
    CPU."""
    trial, track, contact = device_trial(collide, dim, flat), device_function(margin_track), contact_reader(rows)
    L = LANES

    @cuda.jit
    def run(V, pairs, ends, table, meta, inverse, units, masses, P, keys, state, M, limits, chunk):
        r = cuda.blockIdx.x
        t = cuda.threadIdx.x
        if r >= V.shape[0]:
            return
        si = cuda.shared.array(L, np.int64)
        sj = cuda.shared.array(L, np.int64)
        sa = cuda.shared.array(L, np.int64)
        sb = cuda.shared.array(L, np.int64)
        waiting = cuda.shared.array(L, np.int32)
        hits = cuda.shared.array(L, np.int32)
        speeds = cuda.shared.array(L, np.float64)
        ctl = cuda.shared.array(8, np.int64)  # steps, collisions, last, frozen, live found, made
        v, params = V[r], P[r]
        n_contacts = pairs.shape[0]
        n = np.uint64(n_contacts)
        k0, k1, tau = keys[r, 0], keys[r, 1], params[params.shape[0] - 1]
        max_steps, max_collisions, until_frozen = limits[r, 0], limits[r, 1], limits[r, 2] != 0
        m0, m1, m2, m3 = M[r, 0], M[r, 1], M[r, 2], M[r, 3]  # lane 0's
        at1, at3 = m1, m3
        hint = max(state[r, S_HINT], 0)
        if t == 0:
            ctl[0], ctl[1], ctl[2], ctl[3] = state[r, S_STEPS], state[r, S_COLLISIONS], state[r, S_LAST], 0
        cuda.syncthreads()
        if until_frozen:
            hint = scan(v, pairs, ends, table, meta, inverse, units, masses, params, n_contacts, hint, ctl, t)
            if t == 0 and hint < 0:
                ctl[3] = 1
            cuda.syncthreads()
        while ctl[3] == 0 and ctl[0] < max_steps and ctl[1] < max_collisions:
            end = min(ctl[0] + chunk, max_steps)
            if t == 0:
                ctl[5] = 0
                at1, at3 = m1, m3
            cuda.syncthreads()
            while ctl[0] < end and ctl[1] < max_collisions:
                s0 = ctl[0]
                kb = min(L, end - s0) if max_collisions - ctl[1] >= L else 1
                waiting[t] = 0
                hits[t] = 0
                if t < kb:
                    s = s0 + t
                    w0, w1, w2, w3 = philox_block(np.uint64(s >> 2), _U0, _U0, _U0, k0, k1)
                    e = s & 3
                    c, accepted = lemire(w0 if e == 0 else (w1 if e == 1 else (w2 if e == 2 else w3)), n)
                    if not accepted:
                        c = counter_pick(k0, k1, np.uint64(s), n)
                    i, j, a, b = contact(pairs, ends, table, meta, inverse, np.int64(c))
                    si[t], sj[t], sa[t], sb[t] = i, j, a, b
                    waiting[t] = 1
                cuda.syncthreads()
                while True:  # rounds: a lane runs when no earlier waiting lane shares a ball with it
                    ready = waiting[t] == 1
                    if ready:
                        i, j = si[t], sj[t]
                        for u in range(t):
                            if waiting[u] == 1 and (si[u] == i or si[u] == j or sj[u] == i or sj[u] == j):
                                ready = False
                    cuda.syncthreads()
                    if ready:
                        hit, w = trial(v, units, masses, params, si[t], sj[t], sa[t], sb[t], True)
                        hits[t] = 1 if hit else 0
                        speeds[t] = w
                        waiting[t] = 0
                    if cuda.syncthreads_count(waiting[t]) == 0:
                        break
                if t == 0:  # the batch in step order: counters and margin, as the sequential loop keeps them
                    for u in range(kb):
                        hit = hits[u] == 1
                        m0, m1, m2, m3 = track(hit, speeds[u], tau, m0, m1, m2, m3)
                        if hit:
                            ctl[1] += 1
                            ctl[5] += 1
                            ctl[2] = s0 + u + 1
                            at1, at3 = m1, m3
                    ctl[0] = s0 + kb
                cuda.syncthreads()
            if until_frozen and ctl[5] > 0:
                hint = scan(v, pairs, ends, table, meta, inverse, units, masses, params, n_contacts, hint, ctl, t)
                if t == 0 and hint < 0:  # frozen: the run ends right after its last collision, its margin too
                    ctl[3] = 1
                    ctl[0] = ctl[2]
                    m1, m3 = at1, at3
                cuda.syncthreads()
        if t == 0:
            state[r, S_STEPS], state[r, S_COLLISIONS], state[r, S_LAST], state[r, S_FROZEN] = \
                ctl[0], ctl[1], ctl[2], ctl[3]
            state[r, S_HINT] = max(hint, 0)
            M[r, 0], M[r, 1], M[r, 2], M[r, 3] = m0, m1, m2, m3

    @cuda.jit(device=True)
    def scan(v, pairs, ends, table, meta, inverse, units, masses, params, n_contacts, hint, ctl, t):
        """A live contact found by the lanes together (each from ``hint + lane``, a stride of lanes apart, until
        one finds one), the same for every lane; -1 when none is live."""
        if t == 0:
            ctl[4] = -1
        cuda.syncthreads()
        for m in range(t, n_contacts, L):
            if ctl[4] >= 0:
                break
            k = hint + m
            if k >= n_contacts:
                k -= n_contacts
            i, j, a, b = contact(pairs, ends, table, meta, inverse, np.int64(k))
            hit, w = trial(v, units, masses, params, i, j, a, b, False)
            if hit:
                ctl[4] = k
        cuda.syncthreads()
        found = ctl[4]
        cuda.syncthreads()
        return found

    return run


def replica_layout() -> str:
    """How replicas are laid out (`LAYOUT`, or ``PINNEDBALLS_GPU_REPLICAS``)."""
    layout = os.environ.get("PINNEDBALLS_GPU_REPLICAS", LAYOUT)
    return layout if layout in ("thread", "block") else LAYOUT


class ReplicaChains:
    """``R`` replicas of one geometry, rule and masses on the GPU (module docstring).

    v: ``(R, N, dim)`` velocities; ``params (R, P)`` each replica's rule params with its threshold last;
    ``keys (R, 2) uint64`` their counter streams' keys; ``contacts``, ``pattern``, ``masses (N,)`` and
    ``collide`` as for `chain.DeviceChain`.
    """

    def __init__(self, v: np.ndarray, params: np.ndarray, keys: np.ndarray, contacts, pattern, masses: np.ndarray,
                 collide):
        cuda_ = load()
        self.replicas, self.n_balls, self.dim = v.shape
        self.n_contacts = len(contacts.pairs)
        rows = pattern is not None
        to = cuda_.to_device
        self._v = to(np.ascontiguousarray(v, dtype=np.float64))
        self._tables = upload_contacts(cuda_, contacts, pattern, masses)
        self._params = to(np.ascontiguousarray(params, dtype=np.float64))
        self._keys = to(np.ascontiguousarray(keys, dtype=np.uint64))
        self.state = np.zeros((self.replicas, STATE_SIZE), dtype=np.int64)
        self.margin = np.tile(np.array([np.inf, 0.0, 0.0, 0.0]), (self.replicas, 1))
        self.layout = replica_layout()
        make = lanes_kernel if self.layout == "block" else replicas_kernel
        self._kernel = make(collide, self.dim, bool(contacts.flat), rows)
        self._cuda = cuda_

    def run(self, limits: np.ndarray, chunk: int) -> None:
        """Run replica ``r`` to ``limits[r] = (steps, collisions, until_frozen)`` (absolute counts; a replica
        already there takes no step); `state` and `margin` are updated."""
        state, margin = self._cuda.to_device(self.state), self._cuda.to_device(self.margin)
        blocks, threads = ((self.replicas, LANES) if self.layout == "block" else
                           (-(-self.replicas // REPLICA_BLOCK), REPLICA_BLOCK))
        with launching():
            self._kernel[blocks, threads](self._v, *self._tables, self._params, self._keys, state, margin,
                                                self._cuda.to_device(np.ascontiguousarray(limits, dtype=np.int64)),
                                                np.int64(chunk))
            self._cuda.synchronize()
        self.state[:], self.margin[:] = state.copy_to_host(), margin.copy_to_host()

    def velocities(self, replica: int | None = None) -> np.ndarray:
        """A host copy of replica ``replica``'s velocities ``(N, dim)``, or of all ``(R, N, dim)``."""
        return self._v.copy_to_host() if replica is None else self._v[replica].copy_to_host()


class ReplicaSet:
    """Replicas as state: the `engine.chain.ChainState` of each of ``R`` simulations of one model (one geometry,
    rule and masses; each its own velocities, threshold, counter stream, counters and margin), run together
    on the GPU by `ReplicaChains` and written back into those states after each launch. So each simulation
    holds its replica's state, its stream's words and its scheduler's included, and goes on as a `Simulation`
    (on the CPU or the GPU) with the bits of one that ran alone.

    backends: the simulations' backends (``sim.engine``), of one geometry and rule on the counter stream, each at
    a step where its stream's position is its step count (``rng[2] == steps``, as every run on that stream
    leaves it); pattern: the lattice's row pattern for the kernels (`run.ensemble_gpu.replica_pattern`) or None.
    """

    def __init__(self, backends: list, pattern=None):
        first = backends[0].model
        for b in backends:
            m, st = b.model, b.state
            if m.geometry is not first.geometry or m.collide is not first.collide or not m.selector.counter:
                raise FieldError("replicas", "must be simulations of one geometry and rule on the counter stream")
            if int(st.rng[2]) != st.steps:
                raise FieldError("replicas", f"a replica's stream is at {int(st.rng[2])}, its steps at {st.steps}")
        self.states = [b.state for b in backends]
        g = first.geometry
        self.chains = ReplicaChains(np.stack([b.velocities() for b in backends]),
                                    np.stack([b.model.params for b in backends]),
                                    np.stack([st.rng[:2] for st in self.states]), g.contacts, pattern,
                                    first.masses, first.collide)
        for r, st in enumerate(self.states):
            self.chains.state[r, [S_STEPS, S_COLLISIONS, S_LAST]] = st.counters[[STEPS, COLLISIONS, LAST]]
            self.chains.margin[r] = st.margin

    def __len__(self) -> int:
        return len(self.states)

    def run(self, limits: np.ndarray, chunk: int) -> None:
        """Run replica ``r`` to ``limits[r] = (steps, collisions, until_frozen)`` (absolute counts), in one
        launch; every state is then its replica's (velocities copied back in one transfer)."""
        self.chains.run(limits, chunk)
        v = self.chains.velocities()
        for r, st in enumerate(self.states):
            st.velocities[:] = v[r]
            steps, collisions, last = self.chains.state[r, [S_STEPS, S_COLLISIONS, S_LAST]]
            st.counters[STEPS], st.counters[COLLISIONS], st.counters[LAST], st.counters[LIVE] = \
                steps, collisions, last, -1
            st.rng[2] = np.uint64(steps)  # the counter stream's position: the next pick is that of this step
            st.margin[:] = self.chains.margin[r]

    def frozen(self, replica: int) -> bool:
        """Whether replica ``replica``'s last launch ended at its freeze."""
        return bool(self.chains.state[replica, S_FROZEN])
