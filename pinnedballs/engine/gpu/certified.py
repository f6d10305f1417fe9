"""Certified arithmetic's picks on a GPU: `fixed.FixedChain`'s own kernel functions, by deterministic reservations.

`DevicePicks` stands in for the CPU's `fixed_kernels.run_picks` and `count_live` (`FixedChain.picks`), so a
certified run on ``device="cuda"`` is the CPU's `FieldBackend` and `FixedChain` (one harness: `engine.harness`),
whose picks are tried on the GPU. It gives the CPU's certified run bit for bit: the steps, the collisions, the
fixed-point state, its bounds and margin.

**How.** The picks of a call are cut into *segments* at the points the CPU's loop acts between picks: a scan for
the freeze (every ``chunk`` picks), a check for narrowing (``every``), a batch of the bound rule (``K`` steps,
`fixed_kernels._round_off`; at most ``2^KEY_BITS`` picks). A segment runs in *rounds* (Blelloch et al., PPoPP
2012, as `kernels`, whose keys it uses): every pending pick reserves its two balls (an atomic minimum of its key),
a pick holding both is tried (the CPU's `fixed_kernels._decide` and `_collide`, compiled for the device), the
others reserve them again for the next round; a round is one launch. Every
ball sees its picks in step order, so each collision reads and writes what the CPU's does; the one value
shared by all, ``G``, is fixed for a batch by the batched bound rule, and what a batch rounds off is summed in
integers (a sum per thread, added by the host), so neither depends on the order of the rounds. The first
collision of a batch folds the batches before (`fixed_kernels.fold`): the host folds before the segment and
takes the fold back when the segment made no collision.

**The state stays on the GPU** between calls; the chain reads it through `DevicePicks.to_host` (a checkpoint,
a narrowing, the exact values), `take_dirty` (the velocities of the balls that changed, gathered there) and
`settled` (the check for narrowing, counted there). The counter stream's picks are drawn on the GPU, a segment
at a time (`engine.streams.philox.CounterPicks`). A call that must end at a pick inside a segment (a pick
certified arithmetic cannot decide, the collision target with collisions after it) runs again from a copy of
its start kept on the GPU, to that pick; the pick that cannot be decided is then tried by the CPU's kernel,
which says why (``info``). The margin, the indices of the collisions and the counters are the CPU's, computed
from each pick's decision and closing speed.

Its speed on a GPU: `benchmarks/results/measurements.md`. Each round is one launch and a read of its count by the
host, and each segment's outcomes are read back to the host.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import cuda

from ..field import fixed_kernels as fk
from ..field.fixed import CPUPicks
from ..streams.philox import CounterPicks
from .compile import SIMULATED, device_function
from .device import counter_pick, launching
from .kernels import EMPTY, KEY_BITS, TOP

__all__ = ["DevicePicks", "THREADS", "BLOCK"]

#: the GPU threads that try picks (the simulator runs one block of a few)
THREADS, BLOCK = (2, 2) if SIMULATED else (1 << 16, 128)
#: a pick's outcome (`_attempt`): not tried yet, set aside, collided, undecidable, needs a wider state
_PENDING, _ASIDE, _HIT, _UNDECIDED, _WIDEN = -9, 0, 1, -1, -2


@functools.cache
def _kernels():
    """``(reserve, attempt, live, draw, settled, gather)``: the kernels, built on first use."""
    decide, collide, closing = (device_function(f) for f in (fk._decide, fk._collide, fk._closing))
    Tables, State, Scratch = fk.Tables, fk.State, fk.Scratch

    @cuda.jit
    def reserve(picks, order, n, pairs, own, high):
        """The picks ``order[:n]`` reserve their balls: the key ``high | t`` of pick ``t``."""
        for idx in range(cuda.grid(1), n, cuda.gridsize(1)):
            t = order[idx]
            k = picks[t]
            mine = np.uint32(high | t)
            cuda.atomic.min(own, pairs[k, 0], mine)
            cuda.atomic.min(own, pairs[k, 1], mine)

    @cuda.jit
    def attempt(picks, order, n, own, own_next, high, high_next, later, count, first, scale, certify,
                pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax, rmax, parity,
                X, rows, dirty, B, Pp, acc, T, rho, bound, W, tmp, big, info, out, xs, inside):
        """Try the picks ``order[:n]`` whose key ``high | t`` holds both their balls in ``own`` (``out[t]``,
        ``xs[t]``, ``inside[t]``: outcome, closing speed, decided in fixed point); the others go to ``later``
        (``count[0]`` of them) and reserve their balls in ``own_next`` with the next round's key."""
        tid = cuda.grid(1)
        tables = Tables(pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax, rmax, parity)
        state = State(X, rows, dirty, B, Pp, acc, T, rho[tid], bound)
        scratch = Scratch(W[tid], tmp[tid], big[tid])
        for idx in range(tid, n, cuda.gridsize(1)):
            t = order[idx]
            k = picks[t]
            i, j = pairs[k, 0], pairs[k, 1]
            mine = np.uint32(high | t)
            if own[i] != mine or own[j] != mine:
                later[cuda.atomic.add(count, 0, 1)] = t
                after = np.uint32(high_next | t)
                cuda.atomic.min(own_next, i, after)
                cuda.atomic.min(own_next, j, after)
                continue
            decision, computed, x = decide(k, tables, state, scale, certify, scratch, info[tid])
            xs[t] = x
            inside[t] = 1 if computed else 0
            if decision < 0:
                out[t] = _UNDECIDED
            elif decision == 0:
                out[t] = _ASIDE
            else:
                if not computed:
                    closing(tables, X, i, j, np.int64(ls[k] >> 1), scratch.W)
                out[t] = _HIT if collide(k, tables, state, scale, certify, scratch, first + t) else _WIDEN

    @cuda.jit
    def live(n_contacts, scale, certify, pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax,
             rmax, parity, X, rows, dirty, B, Pp, acc, T, rho, bound, W, tmp, big, info, counts):
        """``counts[0]`` += the live contacts, ``counts[1]`` += those that cannot be decided."""
        tid = cuda.grid(1)
        tables = Tables(pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax, rmax, parity)
        state = State(X, rows, dirty, B, Pp, acc, T, rho, bound)
        scratch = Scratch(W[tid], tmp[tid], big[tid])
        alive, lost = 0, 0
        for k in range(tid, n_contacts, cuda.gridsize(1)):
            decision, _, _ = decide(k, tables, state, scale, certify, scratch, info[tid])
            if decision < 0:
                lost += 1
            else:
                alive += decision
        cuda.atomic.add(counts, 0, alive)
        cuda.atomic.add(counts, 1, lost)

    @cuda.jit
    def draw(k0, k1, s0, size, n_contacts, out):
        """``out[t]``: the counter stream's pick of step ``s0 + t`` (`engine.streams.philox.counter_pick`)."""
        for t in range(cuda.grid(1), size, cuda.gridsize(1)):
            out[t] = np.int64(counter_pick(k0, k1, s0 + np.uint64(t), n_contacts))

    @cuda.jit
    def settled(X, rows, B, Pp, dropped, counts):
        """``counts[0]`` += the balls at rest, ``counts[1]`` += the exact ones (bounds 0) with a limb below
        ``dropped`` that is not 0 (`fixed.FixedChain.settled`)."""
        D = X.shape[1]
        rest, long = 0, 0
        for b in range(cuda.grid(1), X.shape[0], cuda.gridsize(1)):
            if rows[b, D] == 0.0:
                rest += 1
            exact = True
            for m in range(B.shape[1]):
                if B[b, m] != 0.0 or Pp[b, m] != 0.0:
                    exact = False
            if exact:
                found = False
                for d in range(D):
                    for c in range(X.shape[2]):
                        for h in range(dropped):
                            if X[b, d, c, h] != 0:
                                found = True
                if found:
                    long += 1
        cuda.atomic.add(counts, 0, rest)
        cuda.atomic.add(counts, 1, long)

    @cuda.jit
    def gather(X, balls, out):
        """``out[r] = X[balls[r]]``."""
        for r in range(cuda.grid(1), balls.shape[0], cuda.gridsize(1)):
            b = balls[r]
            for d in range(X.shape[1]):
                for c in range(X.shape[2]):
                    for h in range(X.shape[3]):
                        out[r, d, c, h] = X[b, d, c, h]

    return reserve, attempt, live, draw, settled, gather


class DevicePicks:
    """`fixed_kernels.run_picks` and `count_live` with the picks tried on a GPU (module docstring); the same
    arguments and results, so `FixedChain` calls it where it calls them. The state stays on the GPU between calls;
    `to_host`, `take_dirty` and `settled` are how the chain reads it."""

    #: it draws the counter stream's picks itself (`engine.streams.philox.CounterPicks`)
    draws = True

    @staticmethod
    def resources() -> dict:
        """Where its picks are tried, as a run's provenance records it: the GPU (`engine.gpu.describe`)."""
        from . import describe

        return {"kind": "cuda", **describe()}

    def __init__(self):
        self.cuda = cuda
        self.kernels = _kernels()
        self._d = None  # the device copies: tables, state, scratch, info
        #: which side holds the newest state: "host", "device", or "both" (the same)
        self._newest = "host"
        #: totals over the calls: segments, rounds, calls run again to a pick, states copied each way, segments whose
        #: picks it drew
        self.stats = {"segments": 0, "rounds": 0, "again": 0, "uploads": 0, "downloads": 0, "drawn": 0}

    # ------------------------------------------------------------ the state, there and back
    def _device(self, tables, state, scratch) -> dict:
        """The device copies, uploaded when the host holds the newest state."""
        d = self._d
        if self._newest == "host" or d is None or d["shapes"] != [a.shape for a in state]:
            to = self.cuda.to_device
            d = self._d = {"tables": (), "source": None,
                           "state": [to(np.ascontiguousarray(a)) for a in state], "shapes": [a.shape for a in state],
                           "scratch": tuple(to(np.zeros((THREADS,) + a.shape, dtype=a.dtype)) for a in scratch),
                           "info": to(np.zeros((THREADS, 4)))}
            self._newest = "both"
            self.stats["uploads"] += 1
        if d["source"] is not tables:  # (the chain grades its tables for each state it is given: `grading`)
            to = self.cuda.to_device
            d["tables"], d["source"] = tuple(to(a) if isinstance(a, np.ndarray) else a for a in tables), tables
        return d

    def to_host(self, state, writes: bool) -> None:
        """The host's arrays made the newest state (``X, rows, dirty, B, Pp`` copied back if the GPU's are newer);
        ``writes``: the host is about to change them, so the next call uploads them."""
        if self._newest == "device":
            for host, there in zip(state[:5], self._d["state"][:5]):
                host[...] = there.copy_to_host()
            self._newest = "both"
            self.stats["downloads"] += 1
        if writes:
            self._newest = "host"

    def take_dirty(self, state) -> tuple[np.ndarray, np.ndarray]:
        """``(balls, X[balls])``: the balls changed since the last call, their flags cleared (`FixedChain.sync`)."""
        if self._newest == "host":
            return CPUPicks.take_dirty(state)
        there = self._d["state"]
        dirty = there[2].copy_to_host()
        balls = np.flatnonzero(dirty)
        X = np.empty((len(balls),) + state.X.shape[1:], dtype=np.uint64)
        if len(balls):
            out = self.cuda.to_device(X)
            self._launch(self.kernels[5], there[0], self.cuda.to_device(balls.astype(np.int64)), out)
            X = out.copy_to_host()
            there[2].copy_to_device(np.zeros_like(dirty))
            state.dirty[balls] = 0
        return balls, X

    def settled(self, state, late_P: int) -> bool:
        """`FixedChain.settled`, counted on the GPU where its state is newest."""
        if self._newest == "host":
            return CPUPicks.settled(state, late_P)
        counts = self.cuda.to_device(np.zeros(2, dtype=np.int64))
        X, rows, _, B, Pp = self._d["state"][:5]
        self._launch(self.kernels[4], X, rows, B, Pp, state.X.shape[3] - late_P, counts)
        rest, long = counts.copy_to_host().tolist()
        return rest == 0 and long <= state.X.shape[0] // 1000

    def _launch(self, kernel, *args):
        with launching():
            kernel[THREADS // BLOCK, BLOCK](*args)

    # ------------------------------------------------------------ the live contacts
    def count_live(self, tables, state, scale, certify, scratch, info):
        d = self._device(tables, state, scratch)
        counts = self.cuda.to_device(np.zeros(2, dtype=np.int64))
        st = list(d["state"])
        st[7] = self.cuda.to_device(np.zeros(2, dtype=np.uint64))  # (read by no decision)
        self._launch(self.kernels[2], tables.pairs.shape[0], scale, certify, *d["tables"], *st, *d["scratch"],
                     d["info"], counts)
        alive, lost = counts.copy_to_host().tolist()
        if lost:  # the CPU's kernel finds the first that cannot be decided, and says why
            self.to_host(state, writes=False)
            return fk.count_live(tables, state, scale, certify, scratch, info)
        return alive

    # ------------------------------------------------------------ a call of run_picks
    def run_picks(self, tables, state, scale, certify, picks, t, collisions_left, until_frozen, chunk, at, prog,
                  scratch, info, margin, at_last, first, every):
        """`fixed_kernels.run_picks`, its picks tried on the GPU (module docstring): ``picks`` an array or the
        counter stream's `CounterPicks`, drawn on the GPU. A call that must end at a pick inside a segment (the
        collision target, a pick that cannot be decided) runs again from a copy of its start to that pick."""
        d = self._device(tables, state, scratch)
        self._newest = "device"
        if not isinstance(picks, CounterPicks):
            d["picks"] = self.cuda.to_device(np.ascontiguousarray(picks, dtype=np.int64))
        copies = d.get("start")
        if copies is None or any(a.shape != b.shape for a, b in zip(copies, d["state"][:5])):
            copies = d["start"] = [self.cuda.device_array_like(a) for a in d["state"][:5]]
        for copy, there in zip(copies, d["state"][:5]):
            copy.copy_to_device(there)
        start = [a.copy() for a in (prog, margin, at_last, state.acc, state.rho, state.bound)]
        args = (tables, state, scale, certify, picks, collisions_left, until_frozen, chunk, at, prog, scratch, info,
                margin, at_last, first, every)
        status, end, cut = self._picks(d, t, len(picks), *args)
        if cut is not None:  # again from the call's start, to the pick it stops at
            self.stats["again"] += 1
            for copy, there in zip(copies, d["state"][:5]):
                there.copy_to_device(copy)
            for now, then in zip((prog, margin, at_last, state.acc, state.rho, state.bound), start):
                now[...] = then
            status, end, again = self._picks(d, t, cut[1], *args)
            assert again is None, "a call made again to its pick ended elsewhere"
            if cut[0] == "undecided":  # the CPU's kernel, from this pick: why it cannot go on
                self.to_host(state, writes=True)
                host = picks.host() if isinstance(picks, CounterPicks) else picks
                return fk.run_picks(tables, state, scale, certify, host, end, collisions_left, until_frozen, chunk,
                                    at, prog, scratch, info, margin, at_last, first, every)
        return status, end

    def _picks(self, d, t, limit, tables, state, scale, certify, picks, collisions_left, until_frozen, chunk, at, prog,
               scratch, info, margin, at_last, first, every):
        """`run_picks`' loop over picks ``t`` to ``limit`` in segments: ``(status, t, cut)``, ``cut`` None or
        ``(why, pick)`` when a segment found a pick to end at (the state then runs past it: to be made again)."""
        K = int(state.bound[0])
        made, last, fresh, countdown = int(prog[0]), int(prog[1]), int(prog[2]), int(prog[4])
        n = len(picks)
        status = fk.DONE
        due = int(fk._due(first, t, every, prog[5]))
        while t < limit:
            if t == due:
                status = fk.DUE
                break
            end = min(limit, ((first + t) // K + 1) * K - first)  # the bound rule's batch ends
            if due > t:
                end = min(end, due)
            if until_frozen:
                end = min(end, t + countdown)
            outcome, xs, inside = self._segment(d, tables, state, scale, certify, picks, t, end, first, K)
            undecided = np.flatnonzero(outcome < 0)
            hits = np.flatnonzero(outcome == _HIT)
            bad, left = int(undecided[0]) if len(undecided) else len(outcome), collisions_left - made
            target = int(hits[left - 1]) + 1 if len(hits) >= left else None
            if target is not None and target <= bad:  # it ends right after the target collision
                if len(hits) > left:  # (a later collision changed the state)
                    return status, t, ("target", t + target)
                outcome, xs, inside = outcome[:target], xs[:target], inside[:target]
            elif len(undecided):
                return status, t, ("undecided", t + bad)
            used = len(outcome)
            before = margin[1:].copy()
            self._margin(outcome, xs, margin)
            if len(hits):
                at[made:made + len(hits)] = t + hits
                made, last, fresh = made + len(hits), t + int(hits[-1]), 1
                upto = slice(0, int(hits[-1]) + 1)
                at_last[:] = before
                self._margin(outcome[upto], xs[upto], np.array([np.inf, *at_last]), at_last)
                prog[3] = -1
            prog[6] += int(inside.sum())
            t += used
            countdown -= used
            if made == collisions_left:
                break
            if until_frozen and fresh and (countdown <= 0 or t == n):
                prog[0], prog[1], prog[2], prog[4] = made, last, fresh, countdown
                live = self.count_live(tables, state, scale, certify, scratch, info)
                if live < 0:
                    status = fk.UNCOUNTED
                    break
                prog[3], fresh = live, 0
                if live == 0:
                    status, t = fk.FROZEN, last + 1
                    margin[1], margin[2] = at_last[0], at_last[1]
                    break
            if countdown <= 0:
                countdown = chunk
        prog[0], prog[1], prog[2], prog[4] = made, last, fresh, countdown
        return status, t, None

    @staticmethod
    def _margin(outcome, xs, margin, into=None) -> None:
        """The CPU's margin after the picks ``outcome, xs`` (`fixed_kernels.run_picks`), into ``margin`` (or
        ``into`` for its last two entries)."""
        hit = outcome == _HIT
        aside = ~hit
        if hit.any():
            margin[0] = min(margin[0], float(xs[hit].min()))
        zeros = int(np.count_nonzero(aside & (xs == 0.0)))
        others = xs[aside & (xs != 0.0) & ~np.isnan(xs)]
        largest = max(float(margin[1]), float(others.max())) if len(others) else float(margin[1])
        target = margin[1:] if into is None else into
        target[0], target[1] = largest, margin[2] + zeros

    def _segment(self, d, tables, state, scale, certify, picks, t, end, first, K):
        """Picks ``t`` to ``end`` (in one batch of the bound rule): ``(outcome, closing speeds, inside)``. The batch's
        first collision folds the batches before (`fixed_kernels.fold`): folded here, taken back if none."""
        acc, rho, bound = state.acc.copy(), state.rho.copy(), state.bound.copy()
        batch = (first + t) // K
        if batch != bound[1]:
            fk.fold(state.acc, state.rho, state.bound, batch, tables.emax, tables.rmax, tables.root[2])
        outcome, xs, inside, sums = self._rounds(d, state, scale, certify, picks, t, end, first)
        if not np.any(outcome == _HIT):
            state.acc[:], state.rho[:], state.bound[:] = acc, rho, bound
        else:
            state.rho[0] += np.uint64(sums[0])
            state.rho[1] += np.uint64(sums[1])
        return outcome, xs, inside

    def _segment_picks(self, d, picks, t, end):
        """Picks ``t`` to ``end`` on the GPU: a slice of those uploaded, or the counter stream's drawn there."""
        if not isinstance(picks, CounterPicks):
            return d["picks"][t:end]
        size = end - t
        self.stats["drawn"] += 1
        buffer = d.get("drawn")
        if buffer is None or len(buffer) < size:
            buffer = d["drawn"] = self.cuda.device_array(max(size, 1024), dtype=np.int64)
        self._launch(self.kernels[3], picks.key[0], picks.key[1], np.uint64(picks.s0 + t), size,
                     np.uint64(picks.n_contacts), buffer)
        return buffer[:size]

    def _rounds(self, d, state, scale, certify, picks, t, end, first):
        """Picks ``t`` to ``end`` in rounds of reservations: their outcomes, closing speeds and whether each was
        decided in fixed point, and the batch's sums of ``|rho|``. A round's keys are ``g << KEY_BITS | t``, ``g``
        one less each round, in two owner arrays in turn (`kernels`' scheme), so no round clears them; when
        ``g`` runs out both are cleared and the pending picks reserve again."""
        cuda, (reserve, attempt) = self.cuda, self.kernels[:2]
        size = end - t
        outcome = cuda.to_device(np.full(size, _PENDING, dtype=np.int8))
        xs, inside = cuda.to_device(np.zeros(size)), cuda.to_device(np.zeros(size, dtype=np.uint8))
        rho = cuda.to_device(np.zeros((THREADS, 2), dtype=np.uint64))
        d["state"][5].copy_to_device(state.acc)
        d["state"][8].copy_to_device(state.bound)
        st, pairs = d["state"], d["tables"][0]
        picks = self._segment_picks(d, picks, t, end)
        order = cuda.to_device(np.arange(size, dtype=np.int32))
        later = cuda.device_array(size, dtype=np.int32)
        count = cuda.to_device(np.zeros(1, dtype=np.int32))
        n, g = size, 0
        while n > 0:
            if g < 1:  # (at the start, and when the generations run out) every owner word free, then reserve
                g = TOP
                owners = [cuda.to_device(np.full(len(state.rows), EMPTY, dtype=np.uint32)) for _ in (0, 1)]
                self._launch(reserve, picks, order, n, pairs, owners[g & 1], np.uint32(g << KEY_BITS))
            self.stats["rounds"] += 1
            count.copy_to_device(np.zeros(1, dtype=np.int32))
            self._launch(attempt, picks, order, n, owners[g & 1], owners[(g - 1) & 1], np.uint32(g << KEY_BITS),
                         np.uint32((g - 1) << KEY_BITS), later, count, first + t, scale, certify, *d["tables"],
                         *st[:7], rho, st[8], *d["scratch"], d["info"], outcome, xs, inside)
            n, g = int(count.copy_to_host()[0]), g - 1
            order, later = later, order
        self.stats["segments"] += 1
        sums = rho.copy_to_host().astype(object).sum(axis=0)  # exact: Python's integers
        return outcome.copy_to_host(), xs.copy_to_host(), inside.copy_to_host(), sums
