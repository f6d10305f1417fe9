"""`DeviceChain`: one simulation's chain on a GPU, run to the limits the CPU loop honours, with its bits.

The velocities live on the GPU from the moment the chain is built; the host reads them only when
asked (`velocities`). `run` is the engine's chunk protocol (`engine.sequential.loops`'s ``limited``: at most
``max_steps`` steps, stopping at a total of ``max_collisions`` collisions and, with ``until_frozen``,
right after the collision that leaves no live contact) on the counter stream, and leaves the
counters, the stream's words and the closing margin as the CPU loop leaves them:

* steps are run in launches of `kernels.chain_kernel` (batches of picks by deterministic
  reservations), each at most a *chunk* of `CHUNK_PER_CONTACT` steps per contact when the run may
  freeze or reach its collision target;
* after a chunk with a collision, a run until frozen counts the live contacts; if none is left, the
  run ends right after the chunk's last collision: the chunk goes again from a copy of its start,
  kept on the GPU, to that step, so the margin too is the CPU's;
* a chunk that reaches the collision target stops after the batch that reached it; the step of the
  target collision is read from that batch's collisions (``hits``), and the chunk goes again to it.

Batches hold `batch_size` picks by default (about a quarter of the balls, a power of two): the number of
rounds a batch needs grows with its size over the number of balls, each round a barrier of the whole grid,
and a batch too small leaves the GPU idle (docs/performance.md); the results never depend on it.
"""

from __future__ import annotations

import numpy as np

from ..chain import COLLISIONS, LAST, LIVE, STEPS
from ..harness import limits_loop
from . import load
from .device import SIMULATED, launching
from .kernels import (
    C_BATCH_C0,
    C_BATCH_S0,
    C_BATCHES,
    C_COLL,
    C_COUNT,
    C_DONE,
    C_E,
    C_GEN,
    C_HITS,
    C_K,
    C_LAST,
    C_MAXC,
    C_PICK_ROUNDS,
    C_RESETS,
    C_ROUNDS,
    C_STEP0,
    C_TOP,
    CTL_SIZE,
    EMPTY,
    MAX_BATCH,
    TOP,
    barrier_kind,
    chain_kernel,
    launch_shape,
    live_kernel,
)

__all__ = ["DeviceChain", "batch_size", "upload_contacts", "CHUNK_PER_CONTACT", "SCAN_BLOCK"]

#: a run that may freeze or reach a collision target checks between chunks of this many steps per contact
CHUNK_PER_CONTACT = 16
#: threads a block of the freeze scan
SCAN_BLOCK = 8 if SIMULATED else 256
_NO_LIMIT = np.iinfo(np.int64).max


def batch_size(n_balls: int) -> int:
    """Picks a batch by default: the power of two nearest a quarter of the balls, within [64, `MAX_BATCH`]
    (the fastest share of the balls tried, docs/performance.md)."""
    return int(min(MAX_BATCH, max(64, 1 << max(0, round(np.log2(max(1, n_balls) / 4))))))


def upload_contacts(cuda, contacts, pattern, masses: np.ndarray) -> tuple:
    """The contacts on the GPU as the kernels take them: ``(pairs, ends, table, meta, inverse, units, masses)``,
    the row pattern unpacked (`kernels` module docstring) or stand-ins that the table reader never reads."""
    table, meta, inverse = (pattern[0], np.array(pattern[1:4], dtype=np.int64), float(pattern[4])) \
        if pattern is not None else (np.zeros(1, dtype=np.int64), np.zeros(3, dtype=np.int64), 1.0)
    to = cuda.to_device
    return (to(np.ascontiguousarray(contacts.pairs)), to(np.ascontiguousarray(contacts.ends)), to(table), to(meta),
            inverse, to(np.ascontiguousarray(contacts.units, dtype=np.float64)),
            to(np.ascontiguousarray(masses, dtype=np.float64)))


class DeviceChain:
    """The chain of one simulation on the GPU (module docstring).

    v: ``(n_balls, dim)`` velocities (copied to the GPU); ``contacts`` the geometry's `Contacts`;
    ``pattern`` its row pattern (`engine.rows`) or None; ``masses (n_balls,)``; ``params`` the rule's
    params with the threshold last; ``collide`` the rule's (any that `compile.check_rule` passes); ``key`` the counter
    stream's ``(k0, k1)``; ``batch`` picks per batch (default `batch_size`); ``top`` the owner keys'
    first generation (tests lower it to reset often); ``blocks`` the grid (default: all that fit).
    """

    def __init__(self, v: np.ndarray, contacts, pattern, masses: np.ndarray, params: np.ndarray, collide, key,
                 *, batch: int | None = None, top: int = TOP, blocks: int | None = None):
        cuda = load()
        self.n_balls, self.dim = v.shape
        self.n_contacts = len(contacts.pairs)
        self.batch = batch_size(self.n_balls) if batch is None else int(batch)
        if not 1 <= self.batch <= MAX_BATCH or not 1 <= top <= TOP:
            raise ValueError(f"batch must be in [1, {MAX_BATCH}] and top in [1, {TOP}]")
        rows = pattern is not None
        to = cuda.to_device
        self._v = to(np.ascontiguousarray(v, dtype=np.float64))
        self._tables = (*upload_contacts(cuda, contacts, pattern, masses),
                        to(np.ascontiguousarray(params, dtype=np.float64)))
        self._key_host = np.array([int(key[0]), int(key[1])], dtype=np.uint64)
        self._key = to(self._key_host)
        self._own = (to(np.full(self.n_balls, EMPTY, dtype=np.uint32)),
                     to(np.full(self.n_balls, EMPTY, dtype=np.uint32)))
        k = self.batch
        self._work = (to(np.zeros((k, 4), dtype=np.int32)), to(np.zeros(k, dtype=np.int32)),
                      to(np.zeros(k, dtype=np.int32)), to(np.zeros(k, dtype=np.uint8)))
        self._margin = to(np.zeros(4, dtype=np.float64))
        self._ctl = np.zeros(CTL_SIZE, dtype=np.int64)
        self._ctl[C_GEN], self._ctl[C_TOP], self._ctl[C_K], self._ctl[C_E] = top, top, k, self.n_contacts
        self._ctl_d = to(self._ctl)
        self._count = to(np.zeros(1, dtype=np.int64))
        self._saved = None  # a copy of the velocities at a chunk's start, made when first needed
        self.barrier = barrier_kind()
        self.block, self.registers = (8, None) if SIMULATED else launch_shape()
        self._kernel = chain_kernel(collide, self.dim, bool(contacts.flat), rows, self.barrier, self.registers)
        self._bar = to(np.zeros(2, dtype=np.int64))
        self._live = live_kernel(collide, self.dim, bool(contacts.flat), rows)
        self._blocks = blocks
        self._cuda = cuda
        #: totals over the runs: batches, rounds, picks tried in rounds (a pick waits once per round
        #: it is not the lowest on both balls), owner resets
        self.stats = {"batches": 0, "rounds": 0, "pick_rounds": 0, "resets": 0}

    # ------------------------------------------------------------ state
    def velocities(self) -> np.ndarray:
        """``(n_balls, dim)`` a host copy of the velocities now."""
        return self._v.copy_to_host()

    def set_velocities(self, v: np.ndarray) -> None:
        self._v.copy_to_device(np.ascontiguousarray(v, dtype=np.float64))

    def count_live(self) -> int:
        """The number of live contacts (`Simulation.approaching`), counted on the GPU."""
        self._count.copy_to_device(np.zeros(1, dtype=np.int64))
        blocks = 1 if SIMULATED else max(1, min(-(-self.n_contacts // SCAN_BLOCK), 1024))
        with launching():
            self._live[blocks, SCAN_BLOCK](self._v, *self._tables, self.n_contacts, self._count)
        return int(self._count.copy_to_host()[0])

    # ------------------------------------------------------------ running
    def grid(self) -> int:
        """Blocks of the persistent kernel: as many as fit on the GPU at once (its blocks wait for one another)."""
        if self._blocks is None:
            args = self._arguments()
            kernel = self._kernel
            if hasattr(kernel, "compile"):  # on a GPU: compile for these arguments, then ask
                signature = tuple(kernel.typeof_pyval(a) for a in args)
                with launching():  # compiled without contraction
                    kernel.compile(signature)
                self._blocks = kernel.overloads[signature].max_cooperative_grid_blocks(self.block)
            else:  # the simulator runs one block
                self._blocks = kernel.overloads[None].max_cooperative_grid_blocks(self.block)
        return self._blocks

    def _arguments(self):
        return (self._v, *self._tables, self._key, self._ctl_d, *self._own, *self._work, self._margin, self._bar)

    def _launch(self, start: int, count: int, collisions: int, max_collisions: int, margin: np.ndarray,
                record: bool) -> tuple[int, int, int]:
        """``count`` steps from step ``start`` (stopping after a batch that reaches ``max_collisions``):
        ``(steps done, collisions in total, step after the last collision or 0)``; ``margin`` updated."""
        c = self._ctl
        c[C_STEP0], c[C_COUNT], c[C_DONE], c[C_COLL], c[C_MAXC] = start, count, 0, collisions, max_collisions
        c[C_LAST], c[C_HITS] = 0, int(record)
        c[C_BATCHES] = c[C_ROUNDS] = c[C_PICK_ROUNDS] = c[C_RESETS] = 0
        self._ctl_d.copy_to_device(c)
        self._margin.copy_to_device(margin)
        self._bar.copy_to_device(np.zeros(2, dtype=np.int64))
        grid = self.grid()
        with launching():
            self._kernel[grid, self.block](*self._arguments())
            self._cuda.synchronize()
        c[:] = self._ctl_d.copy_to_host()
        margin[:] = self._margin.copy_to_host()
        for name, index in (("batches", C_BATCHES), ("rounds", C_ROUNDS), ("pick_rounds", C_PICK_ROUNDS),
                            ("resets", C_RESETS)):
            self.stats[name] += int(c[index])
        return int(c[C_DONE]), int(c[C_COLL]), int(c[C_LAST])

    def _target_step(self, target: int) -> int:
        """The step right after collision number ``target``, which the last batch of the last launch made."""
        c = self._ctl
        first, before = int(c[C_BATCH_S0]), int(c[C_BATCH_C0])
        size = int(c[C_STEP0] + c[C_DONE]) - first
        hits = self._work[3].copy_to_host()[:size]
        at = np.flatnonzero(hits)
        return first + int(at[target - before - 1]) + 1

    def _save(self) -> None:
        if self._saved is None:
            self._saved = self._cuda.device_array_like(self._v)
        self._saved.copy_to_device(self._v)

    def _restore(self) -> None:
        self._v.copy_to_device(self._saved)

    def run(self, counters: np.ndarray, rng: np.ndarray, margin: np.ndarray, max_steps: int, max_collisions: int,
            until_frozen: bool) -> int:
        """The engine's ``limited`` loop on the GPU, within the limits of `engine.harness` (module docstring):
        ``counters (4,) int64``, the counter stream's words ``rng (4,) uint64`` and ``margin (4,)`` are read and
        left as the CPU loop leaves them. Returns the steps taken."""
        if not np.array_equal(rng[:2], self._key_host):  # a state restored with another stream's key
            self._key_host = np.array(rng[:2], dtype=np.uint64)
            self._key.copy_to_device(self._key_host)
        offset = int(counters[STEPS]) - int(rng[2])  # steps counted before the stream's first pick (none: 0)

        chunk_start = None

        def mark(data, carry, count, left):
            """The chunk's start: its step, collisions and margin, and (where it may end short) its velocities."""
            nonlocal chunk_start
            if until_frozen or left <= count:
                self._save()
            chunk_start = int(rng[2]), int(counters[COLLISIONS]), margin.copy()
            return chunk_start

        def advance(data, carry, count, left, taken, collisions):
            start, before = int(rng[2]), int(counters[COLLISIONS])
            reach = left <= count  # the target may fall within this chunk
            done, made, last = self._launch(start, count, before, max_collisions if reach else _NO_LIMIT, margin,
                                            record=reach)
            if made >= max_collisions:  # the batch that reached the target went past it: again, to its step
                done, made, last = self._again(start, before, self._target_step(max_collisions) - start, margin,
                                               chunk_start[2])
            counters[STEPS] += done
            counters[COLLISIONS] = made
            if made > before:
                counters[LAST] = last + offset
            rng[2] = np.uint64(start + done)
            return done, made - before, last - start - 1 if made > before else -1, carry

        def live(data, carry):
            return self.count_live() > 0

        def settle(data, start, carry, used, count, frozen):
            """A frozen chunk ends at its last collision: again from its start to there (once a run), the margin too."""
            s0, before, saved = start
            done = int(rng[2]) - s0
            if frozen and used < done:
                self._again(s0, before, used, margin, saved)
                counters[STEPS] -= done - used
                rng[2] = np.uint64(s0 + used)
            return carry

        chunk = max(CHUNK_PER_CONTACT * self.n_contacts, 4 * self.batch) \
            if until_frozen or max_collisions - int(counters[COLLISIONS]) <= max_steps else max_steps
        to_limits = limits_loop(mark, advance, live, settle)
        taken, _, frozen, _, _ = to_limits(None, None, int(counters[COLLISIONS]), max_steps, max_collisions,
                                           until_frozen, max(1, chunk))
        counters[LIVE] = 0 if frozen else -1
        return taken

    def _again(self, start: int, before: int, steps: int, margin: np.ndarray,
               saved: np.ndarray) -> tuple[int, int, int]:
        """The chunk from step ``start`` (``before`` collisions) run again for ``steps`` steps from its saved
        velocities and margin ``saved``: `_launch`'s ``(steps, collisions, step after the last collision)``."""
        self._restore()
        margin[:] = saved
        return self._launch(start, steps, before, _NO_LIMIT, margin, record=False)

