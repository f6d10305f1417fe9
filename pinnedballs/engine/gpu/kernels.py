"""The GPU kernels of one chain: batches of picks run by deterministic reservations, and the freeze scan.

**Deterministic reservations** (Blelloch, Fineman, Gibbons, Shun, PPoPP 2012). A *batch* takes the
next ``K`` steps of the counter stream (`engine.streams.philox`): every thread computes the picks of some
steps (one Philox block gives four), decodes each contact and *reserves* its two balls: an atomic
minimum of the pick's key on each ball's owner word. The batch then runs in *rounds*: in a round a
pending pick runs iff it holds both of its balls (it is the lowest pending pick on each), and a pick
that does not hold them reserves them again for the next round and joins the next round's list.
Two picks that run in one round share no ball, and every ball sees its picks in step order, so the
velocities, the collisions and the margin are the sequential chain's, bit for bit, for any batch
size and any number of threads (picks on disjoint balls commute; a collision reads and writes only
its two balls).

**Keys.** An owner word is a uint32 ``generation << KEY_BITS | t`` (``t`` the pick's place in its
batch). Each round counts the generation down by one, so the keys of a round are smaller than any
key left in the owner arrays by an earlier round: nothing is cleared between rounds or batches.
When the generation runs out both arrays are reset to `EMPTY` (every `top` rounds or so) and the
picks still pending reserve afresh.

**One launch, many batches.** `chain_kernel` is a persistent kernel: the whole grid is resident (as many
blocks as fit at once) and meets at a barrier between phases (`BARRIERS`), so a launch runs ``ctl[COUNT]``
steps in as many batches as it takes, with no trip to the host. It stops early after a batch that
brings the collisions to ``ctl[MAXC]``; with ``ctl[HITS]`` set, ``hits[t]`` says whether pick ``t``
of the last batch collided, so the host can find the step of a given collision.

``ctl`` (int64, `CTL_SIZE`): see the ``C_*`` names; ``bar (2,) int64`` the atomic barrier's words. Arrays: velocities
``v (N, dim)``, the tables ``pairs, ends (E, 2)``, the row pattern ``table`` with ``meta = [per_row, rows, cols]`` and
its ``inverse`` (a lattice read by index), ``units (K, dim)``, ``masses (N,)``, ``params [factor,
threshold]``, ``key (2,) uint64``, owners ``own0, own1 (N,) uint32``, picks ``rec (K, 4) int32``
(``i, j, a, b``), round lists ``list0, list1 (K,) int32``, ``hits (K,) uint8``, ``margin (4,)
float64`` (`engine.margin`, merged into).
"""

from __future__ import annotations

import functools
import os

import numpy as np
from numba import cuda

from ..margin import track as margin_track
from .compile import device_function, device_trial
from .device import INF, contact_reader, counter_pick, lemire, philox_block

__all__ = ["chain_kernel", "live_kernel", "BARRIERS", "barrier_kind", "BLOCK", "MAX_REGISTERS", "launch_shape",
           "KEY_BITS", "MAX_BATCH", "EMPTY", "TOP", "CTL_SIZE", "C_STEP0", "C_COUNT", "C_DONE", "C_COLL", "C_MAXC",
           "C_LAST", "C_GEN", "C_K", "C_TOP", "C_HITS", "C_E", "C_BATCH_S0", "C_BATCH_C0", "C_BATCHES", "C_ROUNDS",
           "C_PICK_ROUNDS", "C_RESETS", "C_RING"]

#: bits of a pick's place in its batch in an owner key: at most ``2^KEY_BITS`` picks a batch
KEY_BITS = 22
MAX_BATCH = 1 << KEY_BITS
#: an owner word nobody holds
EMPTY = 0xFFFFFFFF
#: the generation after a reset: the largest whose keys stay below `EMPTY`
TOP = ((1 << 32) - 1 >> KEY_BITS) - 1

C_STEP0, C_COUNT, C_DONE, C_COLL, C_MAXC, C_LAST, C_GEN, C_K = range(8)
C_TOP, C_HITS, C_E, C_BATCH_S0, C_BATCH_C0, C_BATCHES, C_ROUNDS, C_PICK_ROUNDS = range(8, 16)
C_RESETS = 16
C_RING = 20  #: four counters of pending picks, one per round modulo 4
CTL_SIZE = 24

_U0 = np.uint64(0)


#: how the grid's blocks meet between phases: ``"atomic"``, a counter in global memory the blocks spin on
#: (an ordinary launch of blocks that all fit at once), or ``"grid"``, cooperative groups'
#: ``this_grid().sync()`` (a cooperative launch). ``PINNEDBALLS_GPU_BARRIER`` chooses; the bits are the
#: same. The atomic counter is the default: the grid sync's call keeps many more registers a thread live,
#: so fewer blocks fit a multiprocessor (figures: docs/performance.md, "Why the engine is as it is").
BARRIERS = ("atomic", "grid")


def barrier_kind() -> str:
    """The barrier `chain_kernel` uses (``PINNEDBALLS_GPU_BARRIER``, default ``"atomic"``)."""
    kind = os.environ.get("PINNEDBALLS_GPU_BARRIER", "atomic")
    return kind if kind in BARRIERS else "atomic"


#: threads a block of `chain_kernel`, and the registers a thread may use (None: as many as it needs): the
#: fastest of the shapes tried on a GPU (docs/performance.md, "Why the engine is as it is").
#: ``PINNEDBALLS_GPU_BLOCK`` and ``PINNEDBALLS_GPU_MAXREG`` override them. The bits never depend on either.
BLOCK, MAX_REGISTERS = 256, None


def launch_shape() -> tuple[int, int | None]:
    """``(threads a block, most registers a thread)`` of `chain_kernel` (`BLOCK`, `MAX_REGISTERS`)."""
    block = int(os.environ.get("PINNEDBALLS_GPU_BLOCK", BLOCK))
    registers = os.environ.get("PINNEDBALLS_GPU_MAXREG")
    return block, (int(registers) if registers else MAX_REGISTERS)


@cuda.jit(device=True)
def _grid_sync(bar):
    cuda.cg.this_grid().sync()


@cuda.jit(device=True)
def _atomic_sync(bar):
    """Every block of the grid meets here (``bar = [arrived, generation]`` int64, zero at the launch)."""
    cuda.syncthreads()
    if cuda.threadIdx.x == 0:
        generation = cuda.atomic.add(bar, 1, 0)
        cuda.threadfence()
        if cuda.atomic.add(bar, 0, 1) == cuda.gridDim.x - 1:
            cuda.atomic.exch(bar, 0, 0)
            cuda.threadfence()
            cuda.atomic.add(bar, 1, 1)
        else:
            while cuda.atomic.add(bar, 1, 0) == generation:
                pass
        cuda.threadfence()
    cuda.syncthreads()


@functools.cache
def chain_kernel(collide, dim: int, flat: bool, rows: bool, barrier: str = "atomic", registers: int | None = None):
    """The persistent kernel running batches of the chain for one rule, ``dim``, ``flat``, contact reader,
    ``barrier`` (module docstring, `BARRIERS`) and register limit; launched on a grid that fits the GPU at once."""
    trial, track, contact = device_trial(collide, dim, flat), device_function(margin_track), contact_reader(rows)
    sync = _grid_sync if barrier == "grid" else _atomic_sync

    @cuda.jit(**({} if registers is None else {"max_registers": registers}))
    def run_batches(v, pairs, ends, table, meta, inverse, units, masses, params, key, ctl, own0, own1, rec,
                    list0, list1, hits, margin, bar):
        tx = cuda.threadIdx.x
        first = cuda.blockIdx.x * cuda.blockDim.x
        tid = first + tx
        nthr = cuda.gridsize(1)
        shared = cuda.shared.array(4, np.int64)
        shared_m = cuda.shared.array(4, np.float64)
        if tx == 0:
            shared[0] = 0
            shared[1] = 0
            shared[2] = 0
            shared[3] = 0
            shared_m[0] = INF
            shared_m[1] = 0.0
            shared_m[2] = 0.0
            shared_m[3] = 0.0
        cuda.syncthreads()
        k0, k1 = key[0], key[1]
        n_contacts = np.uint64(ctl[C_E])
        n_balls = own0.shape[0]
        tau = params[params.shape[0] - 1]
        step0, count, maxc, size, top = ctl[C_STEP0], ctl[C_COUNT], ctl[C_MAXC], ctl[C_K], ctl[C_TOP]
        record = ctl[C_HITS] != 0
        smallest, largest, near_hits, near_rest = INF, 0.0, 0.0, 0.0
        last = np.int64(0)
        made = np.int64(0)
        done, g = ctl[C_DONE], ctl[C_GEN]  # every thread follows both: only the collisions are read back
        while True:
            before = ctl[C_COLL]
            if done >= count or before >= maxc:
                break
            kb = min(size, count - done)
            s0 = step0 + done
            if g < 1:  # the generations ran out: every owner word free again
                for ball in range(tid, n_balls, nthr):
                    own0[ball] = EMPTY
                    own1[ball] = EMPTY
                if tid == 0:
                    ctl[C_RESETS] += 1
                sync(bar)
                g = top
            own = own0 if (g & 1) == 0 else own1
            high = g << KEY_BITS
            # the batch's picks, four steps of one Philox block per thread, each reserving its balls
            for q in range(np.int64(s0 >> 2) + tid, np.int64((s0 + kb - 1) >> 2) + 1, nthr):
                w0, w1, w2, w3 = philox_block(np.uint64(q), _U0, _U0, _U0, k0, k1)
                for e in range(4):
                    s = 4 * q + e
                    if s >= s0 and s < s0 + kb:
                        x = w0 if e == 0 else (w1 if e == 1 else (w2 if e == 2 else w3))
                        c, accepted = lemire(x, n_contacts)
                        if not accepted:
                            c = counter_pick(k0, k1, np.uint64(s), n_contacts)
                        t = s - s0
                        i, j, a, b = contact(pairs, ends, table, meta, inverse, np.int64(c))
                        rec[t, 0] = i
                        rec[t, 1] = j
                        rec[t, 2] = a
                        rec[t, 3] = b
                        if record:
                            hits[t] = 0
                        mine = np.uint32(high | t)
                        cuda.atomic.min(own, i, mine)
                        cuda.atomic.min(own, j, mine)
            if tid == 0:
                ctl[C_RING + 1] = 0
            sync(bar)
            r, n = 0, kb
            while n > 0:
                if g < 1:  # out of generations inside a batch: reset and reserve the pending picks afresh
                    for ball in range(tid, n_balls, nthr):
                        own0[ball] = EMPTY
                        own1[ball] = EMPTY
                    sync(bar)
                    g = top
                    own = own0 if (g & 1) == 0 else own1
                    for idx in range(tid, n, nthr):
                        t = list1[idx] if (r & 1) == 1 else list0[idx]
                        mine = np.uint32((g << KEY_BITS) | t)
                        cuda.atomic.min(own, rec[t, 0], mine)
                        cuda.atomic.min(own, rec[t, 1], mine)
                    if tid == 0:
                        ctl[C_RESETS] += 1
                    sync(bar)
                own_now = own0 if (g & 1) == 0 else own1
                own_next = own1 if (g & 1) == 0 else own0
                key_now, key_next = g << KEY_BITS, (g - 1) << KEY_BITS
                slot = C_RING + ((r + 1) & 3)
                for base in range(first, n, nthr):  # every thread of a block goes round this loop alike
                    idx = base + tx
                    waits = False
                    t = 0
                    if idx < n:
                        t = idx if r == 0 else (list1[idx] if (r & 1) == 1 else list0[idx])
                        i, j = np.int64(rec[t, 0]), np.int64(rec[t, 1])
                        mine = np.uint32(key_now | t)
                        if own_now[i] == mine and own_now[j] == mine:
                            hit, w = trial(v, units, masses, params, i, j, np.int64(rec[t, 2]),
                                             np.int64(rec[t, 3]), True)
                            smallest, largest, near_hits, near_rest = track(hit, w, tau, smallest, largest,
                                                                            near_hits, near_rest)
                            if hit:
                                made += 1
                                last = max(last, s0 + t + 1)
                                if record:
                                    hits[t] = 1
                        else:
                            waits = True
                            later = np.uint32(key_next | t)
                            cuda.atomic.min(own_next, i, later)
                            cuda.atomic.min(own_next, j, later)
                    place = 0
                    if waits:
                        place = cuda.atomic.add(shared, 0, 1)
                    cuda.syncthreads()
                    if tx == 0:
                        waiting = shared[0]
                        shared[1] = cuda.atomic.add(ctl, slot, waiting) if waiting > 0 else 0
                        shared[0] = 0
                    cuda.syncthreads()
                    if waits:
                        if (r & 1) == 1:
                            list0[shared[1] + place] = t
                        else:
                            list1[shared[1] + place] = t
                    cuda.syncthreads()
                if tid == 0:
                    ctl[C_RING + ((r + 2) & 3)] = 0
                    ctl[C_PICK_ROUNDS] += n
                sync(bar)
                n = ctl[slot]
                r += 1
                g -= 1
            # the batch is done: its collisions counted, so every thread sees whether to go on
            cuda.atomic.add(shared, 2, made)
            made = 0
            cuda.syncthreads()
            if tx == 0:
                cuda.atomic.add(ctl, C_COLL, shared[2])
                shared[2] = 0
            sync(bar)
            done += kb
            if tid == 0:  # for the host (the threads read only the collisions, after the next barrier)
                ctl[C_DONE] = done
                ctl[C_GEN] = g
                ctl[C_BATCH_S0] = s0
                ctl[C_BATCH_C0] = before
                ctl[C_BATCHES] += 1
                ctl[C_ROUNDS] += r
        cuda.atomic.min(shared_m, 0, smallest)
        cuda.atomic.max(shared_m, 1, largest)
        cuda.atomic.add(shared_m, 2, near_hits)
        cuda.atomic.add(shared_m, 3, near_rest)
        cuda.atomic.max(shared, 3, last)
        cuda.syncthreads()
        if tx == 0:
            cuda.atomic.min(margin, 0, shared_m[0])
            cuda.atomic.max(margin, 1, shared_m[1])
            cuda.atomic.add(margin, 2, shared_m[2])
            cuda.atomic.add(margin, 3, shared_m[3])
            cuda.atomic.max(ctl, C_LAST, shared[3])

    return run_batches


@functools.cache
def live_kernel(collide, dim: int, flat: bool, rows: bool):
    """``count_live(v, pairs, ends, table, meta, inverse, units, masses, params, n_contacts, out)``: adds to
    ``out[0]`` the number of live contacts (those whose pick would change a velocity), as
    `engine.sequential.loops.live_kernel`'s ``live_flags`` counts them."""
    trial, contact = device_trial(collide, dim, flat), contact_reader(rows)

    @cuda.jit
    def count_live(v, pairs, ends, table, meta, inverse, units, masses, params, n_contacts, out):
        shared = cuda.shared.array(1, np.int64)
        if cuda.threadIdx.x == 0:
            shared[0] = 0
        cuda.syncthreads()
        live = np.int64(0)
        for k in range(cuda.grid(1), n_contacts, cuda.gridsize(1)):
            i, j, a, b = contact(pairs, ends, table, meta, inverse, np.int64(k))
            hit, w = trial(v, units, masses, params, i, j, a, b, False)
            if hit:
                live += 1
        cuda.atomic.add(shared, 0, live)
        cuda.syncthreads()
        if cuda.threadIdx.x == 0 and shared[0] > 0:
            cuda.atomic.add(out, 0, shared[0])

    return count_live
