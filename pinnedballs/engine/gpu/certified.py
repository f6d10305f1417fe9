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

A segment that must end early (a pick certified arithmetic cannot decide, the collision target) is made again
from a copy of its start, to that pick; the pick that cannot be decided is then tried by the CPU's kernel, which
says why (``info``). The margin, the indices of the collisions and the counters are the CPU's, computed from
each pick's decision and closing speed. States written under the bound rule in step order (files from before
the batched rule) resume on the CPU only.

The state crosses to the GPU and back on every call (`fixed.FixedChain.run`'s blocks): a first version whose
bits are tested under the simulator; keeping it on the GPU between calls is the next step.
"""

from __future__ import annotations

import functools

import numpy as np
from numba import cuda

from ..field import fixed_kernels as fk
from .compile import SIMULATED, device_function
from .device import launching
from .kernels import EMPTY, KEY_BITS, TOP

__all__ = ["DevicePicks", "THREADS", "BLOCK"]

#: the GPU threads that try picks (the simulator runs one block of a few)
THREADS, BLOCK = (8, 8) if SIMULATED else (1 << 16, 128)
#: a pick's outcome (`_attempt`): not tried yet, set aside, collided, undecidable, needs a wider state
_PENDING, _ASIDE, _HIT, _UNDECIDED, _WIDEN = -9, 0, 1, -1, -2


@functools.cache
def _kernels():
    """``(reserve, attempt, live)``: the kernels, built on first use (numba-cuda imported by then)."""
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
                pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax, rmax,
                X, rows, dirty, B, Pp, acc, T, rho, bound, W, tmp, big, info, out, xs, inside):
        """Try the picks ``order[:n]`` whose key ``high | t`` holds both their balls in ``own`` (``out[t]``,
        ``xs[t]``, ``inside[t]``: outcome, closing speed, decided in fixed point); the others go to ``later``
        (``count[0]`` of them) and reserve their balls in ``own_next`` with the next round's key."""
        tid = cuda.grid(1)
        tables = Tables(pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax, rmax)
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
             rmax, X, rows, dirty, B, Pp, acc, T, rho, bound, W, tmp, big, info, counts):
        """``counts[0]`` += the live contacts, ``counts[1]`` += those that cannot be decided."""
        tid = cuda.grid(1)
        tables = Tables(pairs, ls, uf, usum, e, wterms, wcount, kterms, kcount, coef, root, emax, rmax)
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

    return reserve, attempt, live


class DevicePicks:
    """`fixed_kernels.run_picks` and `count_live` with the picks tried on a GPU (module docstring); the same
    arguments and results, so `FixedChain` calls it where it calls them."""

    def __init__(self):
        self.cuda = cuda
        self.kernels = _kernels()
        #: totals over the calls: segments, rounds, segments made again to a pick
        self.stats = {"segments": 0, "rounds": 0, "again": 0}

    # ------------------------------------------------------------ the state, there and back
    def _upload(self, tables, state, scratch):
        to = self.cuda.to_device
        d = {"tables": tuple(to(a) if isinstance(a, np.ndarray) else a for a in tables),
             "state": [to(np.ascontiguousarray(a)) for a in state], "threads": THREADS}
        W, tmp, big = scratch
        d["scratch"] = tuple(to(np.zeros((THREADS,) + a.shape, dtype=a.dtype)) for a in (W, tmp, big))
        d["info"] = to(np.zeros((THREADS, 4)))
        return d

    @staticmethod
    def _download(d, state) -> None:
        """The arrays the picks change (``X, rows, dirty, B, Pp``) back to the host; the bound rule's scalars
        (``acc, rho, bound``) are the host's throughout."""
        for host, there in zip(state[:5], d["state"][:5]):
            host[...] = there.copy_to_host()

    def _launch(self, kernel, *args):
        with launching():
            kernel[THREADS // BLOCK, BLOCK](*args)

    # ------------------------------------------------------------ the live contacts
    def count_live(self, tables, state, scale, certify, scratch, info):
        d = self._upload(tables, state, scratch)
        return self._count(d, tables, state, scale, certify, scratch, info)

    def _count(self, d, tables, state, scale, certify, scratch, info):
        counts = self.cuda.to_device(np.zeros(2, dtype=np.int64))
        rho = self.cuda.to_device(np.zeros(2, dtype=np.uint64))
        st = list(d["state"])
        st[7] = rho  # read by no decision
        self._launch(self.kernels[2], tables.pairs.shape[0], scale, certify, *d["tables"], *st, *d["scratch"], d["info"],
                     counts)
        alive, lost = counts.copy_to_host().tolist()
        if lost:  # the CPU's kernel finds the first that cannot be decided, and says why
            return fk.count_live(tables, state, scale, certify, scratch, info)
        return alive

    # ------------------------------------------------------------ a call of run_picks
    def run_picks(self, tables, state, scale, certify, picks, t, collisions_left, until_frozen, chunk, at, prog,
                  scratch, info, margin, at_last, first, every):
        """`fixed_kernels.run_picks`, its picks tried on the GPU (module docstring)."""
        K = int(state.bound[0])
        if K <= 0:
            raise ValueError("a certified state under the bound rule in step order runs on the CPU")
        made, last, fresh, countdown = int(prog[0]), int(prog[1]), int(prog[2]), int(prog[4])
        n = len(picks)
        status = fk.DONE
        due = int(fk._due(first, t, every, prog[5]))
        d = self._upload(tables, state, scratch)
        d["picks"] = self.cuda.to_device(np.ascontiguousarray(picks, dtype=np.int64))
        changed = False
        while t < n:
            if t == due:
                status = fk.DUE
                break
            end = min(n, ((first + t) // K + 1) * K - first)  # the bound rule's batch ends
            if due > t:
                end = min(end, due)
            if until_frozen:
                end = min(end, t + countdown)
            outcome, xs, inside = self._segment(d, tables, state, scale, certify, t, end, first, K,
                                                collisions_left - made)
            changed = True
            used = len(outcome)
            hits = np.flatnonzero(outcome == _HIT)
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
            if len(outcome) and outcome[-1] < 0:  # the CPU's kernel, from this pick: why it cannot go on
                t -= 1
                self._download(d, state)
                changed = False
                prog[0], prog[1], prog[2], prog[4] = made, last, fresh, countdown
                return fk.run_picks(tables, state, scale, certify, picks, t, collisions_left, until_frozen, chunk,
                                    at, prog, scratch, info, margin, at_last, first, every)
            if made == collisions_left:
                break
            if until_frozen and fresh and (countdown <= 0 or t == n):
                self._download(d, state)  # (the host's rows and bounds, for the CPU's kernel if one is undecided)
                live = self._count(d, tables, state, scale, certify, scratch, info)
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
        if changed:
            self._download(d, state)
        prog[0], prog[1], prog[2], prog[4] = made, last, fresh, countdown
        return status, t

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

    def _segment(self, d, tables, state, scale, certify, t, end, first, K, left):
        """Picks ``t`` to ``end`` (one batch of the bound rule), stopping after the ``left``-th collision or before a
        pick that cannot be decided: ``(outcome, closing speeds, inside)`` of the picks used (the last one
        undecided, its outcome negative, when that is why it stopped)."""
        saved = d.get("saved")  # a copy of the segment's start, on the GPU
        if saved is None or any(a.shape != b.shape for a, b in zip(saved, d["state"][:5])):
            saved = d["saved"] = [self.cuda.device_array_like(a) for a in d["state"][:5]]
        for copy, there in zip(saved, d["state"][:5]):
            copy.copy_to_device(there)
        acc, rho, bound = state.acc.copy(), state.rho.copy(), state.bound.copy()
        batch = (first + t) // K
        if batch != bound[1]:  # the batch's first collision folds the batches before (taken back if none)
            fk.fold(state.acc, state.rho, state.bound, batch, tables.emax, tables.rmax, tables.root[2])
        outcome, xs, inside, sums = self._rounds(d, state, scale, certify, t, end, first)
        undecided = np.flatnonzero(outcome < 0)
        hits = np.flatnonzero(outcome == _HIT)
        stop = len(outcome)
        if len(undecided):
            stop = int(undecided[0])
        if len(hits) >= left and int(hits[left - 1]) + 1 <= stop:
            stop = int(hits[left - 1]) + 1
        if stop < len(outcome) or len(undecided):  # again, to the pick it stops at
            self.stats["again"] += 1
            for there, copy in zip(d["state"][:5], saved):
                there.copy_to_device(copy)
            outcome, xs, inside, sums = self._rounds(d, state, scale, certify, t, t + stop, first)
            if len(undecided) and stop == int(undecided[0]):  # the pick itself, for run_picks to hand on
                outcome = np.append(outcome, np.int8(_UNDECIDED))
                xs, inside = np.append(xs, np.nan), np.append(inside, np.uint8(0))
        if not np.any(outcome == _HIT):  # no collision: the fold taken back
            state.acc[:], state.rho[:], state.bound[:] = acc, rho, bound
        else:
            state.rho[0] += np.uint64(sums[0])
            state.rho[1] += np.uint64(sums[1])
        return outcome, xs, inside

    def _rounds(self, d, state, scale, certify, t, end, first):
        """Picks ``t`` to ``end`` in rounds of reservations: their outcomes, closing speeds and whether each was
        decided in fixed point, and the batch's sums of ``|rho|``. A round's keys are ``g << KEY_BITS | t``, ``g``
        one less each round, in two owner arrays in turn (`kernels`' scheme), so no round clears them; when
        ``g`` runs out both are cleared and the pending picks reserve again."""
        cuda, (reserve, attempt, _) = self.cuda, self.kernels
        size = end - t
        outcome = cuda.to_device(np.full(size, _PENDING, dtype=np.int8))
        xs, inside = cuda.to_device(np.zeros(size)), cuda.to_device(np.zeros(size, dtype=np.uint8))
        rho = cuda.to_device(np.zeros((THREADS, 2), dtype=np.uint64))
        d["state"][5].copy_to_device(state.acc)
        d["state"][8].copy_to_device(state.bound)
        st, pairs = d["state"], d["tables"][0]
        picks = d["picks"][t:end]
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
