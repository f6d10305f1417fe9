"""The paper's chain on every core, with the bits of one: batches of the counter stream's picks run by
deterministic reservations (Blelloch, Fineman, Gibbons, Shun, PPoPP 2012).

**Why the bits are the sequential chain's.** A collision reads and writes only its two balls' velocity
rows, so two picks on disjoint balls commute. Take a *batch* of ``K`` consecutive steps of the counter
stream (`engine.streams.philox`: step ``s``'s pick is a function of the key and ``s``, so any thread computes
any step's pick). If every ball sees the picks that touch it in step order, every pick sees the
velocities it sees in the sequential chain, whatever runs beside it: the velocities, collisions and
closing speeds (hence the margin: a min, a max and two counts, merged in any order) are the
sequential chain's, bit for bit, for any batch size and any number of threads. The batch runs in
*rounds*: a pending pick runs when it is the lowest pending pick on both of its balls (it *holds*
them); the lowest pending pick of the batch always does, so every round runs one at least.

**Reservations without atomics.** On x86 every locked instruction is a full fence, and an atomic
minimum per ball on an array larger than the cache costs a cache miss each. Here the balls are cut
by index into ``p`` ranges of about equal numbers of contacts (row bands on a lattice; the cuts are
multiples of 64), and each range has one *owner*, the only one to read or write its balls'
reservations: a bitmap of *blocked* balls, one bit a ball (``n_balls / 8`` bytes, in cache where the
velocities are not). A round has two phases, separated by barriers:

* *scan*: owner ``r`` goes through the round's pending picks that touch its balls, in step order,
  blocking as it goes the balls of every pick it leaves pending. A pick with both balls in the range
  whose balls are not blocked is the lowest pending pick on both (every earlier pick on them has just
  run): it runs at once, its velocity rows fetched a few picks ahead. Otherwise it is left pending. A
  *crossing* (its balls in two ranges) is left pending too: each of its owners says whether its ball
  was free (the crossing's *grant* at that end), then blocks it.
* *crossings*: a crossing granted at both ends holds both balls (every earlier pick on them has run,
  every later one is pending): the owner of its first ball runs it. Two such crossings share no ball.

So ball ``b``'s picks run in step order: in each round, a prefix of those left in ``b``'s owner's scan,
then perhaps one crossing. The picks left (few: the crossings of the cuts, about ``2 * cols`` contacts
per cut on a lattice, and the picks behind them on the same balls) go round again until none is left;
then the next batch. A round writes only its owner's bits, velocity rows and grants: no atomic but
at the barriers.

**A batch.** Phase G: the batch's steps are cut into ``p`` segments; segment ``t`` draws its picks (one
Philox block for four steps) into ``rec`` and files each position under the range of each of its
balls (``lists[t, r]``, in step order: segment after segment, each range's list is in step order),
found from the contact's index alone (``contact_owner``, a byte a contact); only a crossing is decoded
there. Then the rounds: a scan decodes each pick (the tables, or the lattice's row pattern without a
branch: `row_contact`) a few picks before it runs it, and fetches its velocity rows then. Every piece of work (a
segment, an owner's scan, an owner's crossings) is claimed with a compare-and-swap on a counter, so a thread that finds
the others late does their work itself; whoever finishes a phase's last task decides the next phase (scan, crossings,
next batch, end) and publishes it. Waiting threads spin with ``pause``, then yield their core. Nothing depends on how
many threads ran, or who claimed what.

The caller (`ReservationChain`) runs whole batches only where they cannot pass a limit (steps left,
collisions left), runs the rest with the sequential loop, and finds the freeze as the sequential loop
does (a scan after each chunk; the chunk that froze runs again on one thread from its start to its
last collision, so the margin ends there too), so the steps, collisions, velocities, stream and
margin are those of one thread. Its `ThreadTuner` runs a stretch on one thread (the sequential loop)
where that is faster: beside busy processes. (What it gains, by size and load: benchmarks/bench_reservations.py,
docs/performance.md.)
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import prange

from ..chain import COLLISIONS, LAST, STEPS
from ..jit.cache import jit_cached_if_possible, njit_cached
from ..jit.intrinsics import atomic_add, atomic_cas, atomic_load, atomic_store, fixed_width, give_way, pause, prefetch
from ..margin import merge_margin
from ..streams.philox import block, counter_pick, lemire
from .regions import counted_trial
from .stretches import tuned_blocks, tuned_limits
from .tuning import ThreadTuner, thread_counts

__all__ = ["ReservationChain", "reservation_batches", "range_bounds", "batch_size", "row_contact", "MIN_BATCH",
           "MAX_BATCH", "MAX_CROSSING_SHARE", "BALLS_PER_WORD", "BATCH_PER_THREAD", "CROSSING"]

#: balls per word of the blocked bitmap: range cuts fall on multiples of it, so no word has two owners
BALLS_PER_WORD = 64
#: the default batch: about ``BATCH_PER_THREAD`` steps per thread, at most ``n_balls / BALLS_PER_PICK`` (a
#: batch's rounds grow with its share of the balls), within [`MIN_BATCH`, `MAX_BATCH`]: long batches share
#: their barriers among more picks (benchmarks/bench_reservations.py)
BATCH_PER_THREAD = 1 << 16
BALLS_PER_PICK = 4
MIN_BATCH, MAX_BATCH = 1 << 10, 1 << 20
#: ranges are not worth it when more than this share of the contacts joins two of them
MAX_CROSSING_SHARE = 0.25
#: picks decoded (their velocity rows fetched) ahead in a scan, and the ring that holds them
AHEAD = 16
_RING = 32  # a power of two above AHEAD
#: `contact_owner`'s word for a contact whose balls lie in two ranges
CROSSING = 255

# the shared words (`sync`), each on its own cache line: the phase published, the tasks claimed and
# done (counted over the whole call), picks run in the batch, crossings pending in the round, and the
# phase's kind, batch and round
_LINE = 8
PHASE, CLAIM, DONE, RAN, PENDING, KIND, BATCH, ROUND = (k * _LINE for k in range(8))
SYNC = ROUND + _LINE
_LOW = np.int64(0xFFFFFFFF)
_FIELD, _SHIFT = (1 << 24) - 1, 1 << 23  # `rows`' fields
GENERATE, SCAN, CROSS, END = 0, 1, 2, 3

#: ``pause`` this many times before yielding the core
SPINS = 1 << 10


def batch_size(n_balls: int, threads: int) -> int:
    """Steps a batch by default: a power of two (module constants)."""
    steps = min(BATCH_PER_THREAD * threads, n_balls / BALLS_PER_PICK)
    return int(min(MAX_BATCH, max(MIN_BATCH, 1 << max(0, round(np.log2(max(1.0, steps)))))))


def range_bounds(pairs: np.ndarray, n_balls: int, ranges: int) -> np.ndarray | None:
    """``(ranges + 1,) int64`` ball indices ``0 = b_0 < b_1 < ... < b_ranges = n_balls`` cutting the balls
    into ranges of about equal numbers of contacts (counted at their lower ball), the cuts multiples
    of `BALLS_PER_WORD`; None when that leaves a range empty or more than `MAX_CROSSING_SHARE` of the
    contacts join two ranges."""
    if ranges < 1 or ranges >= CROSSING or len(pairs) == 0:
        return None
    low = np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    high = np.maximum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    per_ball = np.cumsum(np.bincount(low, minlength=n_balls))
    cuts = np.searchsorted(per_ball, np.arange(1, ranges) * len(pairs) / ranges) + 1
    cuts = (np.rint(cuts / BALLS_PER_WORD) * BALLS_PER_WORD).astype(np.int64)
    bounds = np.concatenate([[0], cuts, [n_balls]]).astype(np.int64)
    if np.any(np.diff(bounds) <= 0):
        return None
    crossing = (np.searchsorted(bounds, low, side="right") != np.searchsorted(bounds, high, side="right")).mean()
    return bounds if crossing <= MAX_CROSSING_SHARE else None


@njit_cached(inline="always")
def row_contact(pattern, k):
    """`rows.decode` without a branch: ``(i, j, a, b)`` of contact ``k`` (int64) from its row pattern. The
    row's parity picks the half of the table; as a branch it is a coin toss the processor loses half
    the time on random picks, so it is computed instead (docs/performance.md)."""
    table, per_row, rows, cols, inverse = pattern
    r = np.int64(np.float64(k) * inverse)
    r -= np.int64(r * per_row > k)  # the float quotient is off by at most one
    r += np.int64((r + 1) * per_row <= k)
    last = np.int64(r >= rows - 1)
    r = min(r, rows - 1)
    e = table[k - r * per_row + ((r & 1) * (1 - last) + 2 * last) * per_row]
    i = r * cols + (e & _FIELD)
    return i, i + ((e >> 24) & _FIELD) - _SHIFT, (e >> 48) & 0xFF, e >> 56


@njit_cached(inline="always")
def _row_contact(pairs, ends, pattern, k):
    """Contact ``k`` from the lattice's row pattern (`row_contact`)."""
    return row_contact(pattern, np.int64(k))


@njit_cached(inline="always")
def _table_contact(pairs, ends, pattern, k):
    """Contact ``k`` from the tables."""
    return np.int64(pairs[k, 0]), np.int64(pairs[k, 1]), np.int64(ends[k, 0]), np.int64(ends[k, 1])


@njit_cached(inline="always")
def _spin_until(sync, index, value):
    """Wait until ``sync[index] >= value`` (acquire): spin a while, then yield the core at each look."""
    spins = 0
    while atomic_load(sync, index) < value:
        if spins < SPINS:
            spins += 1
            pause()
        else:
            give_way()


@njit_cached(inline="always")
def _blocked(bits, ball):
    return ((bits[ball >> 6] >> np.uint64(ball & 63)) & np.uint64(1)) != np.uint64(0)


@njit_cached(inline="always")
def _block(bits, ball):
    bits[ball >> 6] |= np.uint64(1) << np.uint64(ball & 63)


@njit_cached(inline="always")
def _free(bits, ball):
    bits[ball >> 6] &= ~(np.uint64(1) << np.uint64(ball & 63))


@functools.cache
def reservation_batches(collide: Callable, dim: int, flat: bool, rows: bool) -> Callable:
    """The compiled batches of the chain for one rule's ``collide``, ``dim``, ``flat`` and the contacts'
    source (``rows``: the row pattern, else the tables):

    batches(v, pairs, ends, units, masses, params, pattern, owners, rng_words, n, size, count, scratch, sync, out)

    runs ``count`` batches of ``size`` steps from the counter stream's words ``rng_words = (k0, k1, s, 0)``
    (left as they are: the caller advances them) on numba's threads; ``n`` contacts. ``owners = (owner,
    contact_owner)``: the range of each word of 64 balls ``(ceil(n_balls / 64),) uint8``, and of each
    contact ``(n,) uint8`` (`CROSSING`: its balls lie in two). ``scratch`` for ``p`` ranges: ``rec (size,)
    int64`` (the contact of each pick), ``lists (p, p, ceil(size / p)) int32`` and ``counts (p, p) int64``
    (segment ``t``'s picks touching range ``r``), ``pend (2, p, size) int32`` and ``npend (2, p) int64``
    (the round lists), ``bits (ceil(n_balls / 64),) uint64`` (zeros), ``grant (size, 2) uint8``, ``done
    (size,) uint8``. ``sync``: zeros (`SYNC` int64) but ``sync[KIND] = GENERATE``. ``out (p, 6) float64``
    receives each thread's collisions, the position of its last collision (-1: none; positions count
    the call's steps from 0) and its margin (4).
    """
    attempt = counted_trial(collide, dim, flat)
    D, ROWS = dim, rows

    contact = _row_contact if rows else _table_contact

    @njit_cached(inline="always")
    def generate(rng_words, n, pairs, ends, pattern, owner, contact_owner, rec, lists, counts, done, s0, size, t):
        """Segment ``t`` of the batch of steps ``[s0, s0 + size)``: its picks into ``rec``, each position filed
        under the range of each of its balls (``lists[t, r]``, ``counts[t, r]``): a contact within a range by
        its index alone (``contact_owner``), a crossing decoded."""
        p, width = lists.shape[0], lists.shape[2]
        k0, k1, n64 = rng_words[0], rng_words[1], np.uint64(n)
        w0 = w1 = w2 = w3 = np.uint64(0)
        lo, hi = t * width, min((t + 1) * width, size)
        for q in range(lo, hi):  # the picks: one Philox block for four steps
            s = np.uint64(s0 + q)
            e = s & np.uint64(3)
            if q == lo or e == np.uint64(0):
                w0, w1, w2, w3 = block(s >> np.uint64(2), np.uint64(0), np.uint64(0), np.uint64(0), k0, k1)
            x = w0 if e == np.uint64(0) else (w1 if e == np.uint64(1) else (w2 if e == np.uint64(2) else w3))
            k, accepted = lemire(x, n64)
            if not accepted:  # a rejected word (probability below n / 2^64): the stream's own retries
                k = counter_pick(k0, k1, s, n64)
            rec[q] = np.int64(k)
        local = np.zeros(p, np.int64)  # this segment's counts, written once at the end
        for q in range(lo, hi):  # filed by range (the contacts' ranges fetched ahead)
            if q + AHEAD < hi:
                prefetch(contact_owner, rec[q + AHEAD])
            r = np.int64(contact_owner[rec[q]])
            if r != CROSSING:
                lists[t, r, local[r]] = q
                local[r] += 1
            else:
                i, j, _, _ = contact(pairs, ends, pattern, rec[q])
                for r in (np.int64(owner[i >> 6]), np.int64(owner[j >> 6])):
                    lists[t, r, local[r]] = q
                    local[r] += 1
                done[q] = 0
        for r in range(p):
            counts[t, r] = local[r]

    @njit_cached(inline="always")
    def fetch(v, pairs, ends, pattern, rec, src, n_src, e, ring):
        """Decode pick ``src[e]`` into ``ring`` and fetch its velocity rows; for the tables, fetch the contact of
        pick ``src[e + AHEAD]``. Past the end (``e >= n_src``) it does the last pick's again: no branch here,
        so numba prunes the reference counting of the arrays (a branch keeps it: two locked instructions
        an array a pick)."""
        if not ROWS:  # a constant
            ahead = rec[src[min(e + AHEAD, n_src - 1)]]
            prefetch(pairs, ahead)
            prefetch(ends, ahead)
        i, j, a, b = contact(pairs, ends, pattern, rec[src[min(e, n_src - 1)]])
        at = e % _RING
        ring[at, 0], ring[at, 1], ring[at, 2], ring[at, 3] = i, j, a, b
        prefetch(v, i)
        prefetch(v, j)

    @njit_cached(inline="always")
    def scan(v, pairs, ends, pattern, units, masses, params, owner, rec, src, n_src, dst, left, bits, grant, done,
             ring, r, base, tau, m, last, made):
        """Owner ``r``'s round, for ``n_src`` of its pending positions ``src`` in step order (module docstring):
        the picks left appended to ``dst`` from ``left`` on; each pick decoded `AHEAD` picks early, and its
        velocity rows fetched then. Returns ``(m, last, made, ran, left, crossings)``: the picks run, the end
        of ``dst``, and the crossings pending whose first ball is ``r``'s."""
        ran, crossings = 0, 0
        if n_src == 0:
            return m, last, made, ran, left, crossings
        for e in range(AHEAD):
            fetch(v, pairs, ends, pattern, rec, src, n_src, e, ring)
        for e in range(n_src):
            fetch(v, pairs, ends, pattern, rec, src, n_src, e + AHEAD, ring)
            at = e % _RING
            i, j = ring[at, 0], ring[at, 1]
            q = np.int64(src[e])
            ri, rj = owner[i >> 6], owner[j >> 6]
            if ri == rj:
                if _blocked(bits, i) or _blocked(bits, j):
                    _block(bits, i)
                    _block(bits, j)
                    dst[left] = q
                    left += 1
                else:
                    m, last, made = attempt(v, units, masses, params, i, j, ring[at, 2], ring[at, 3], base + q, tau,
                                            m, last, made)
                    ran += 1
            elif done[q] == 0:  # a crossing (one that ran in the last round's crossings is dropped)
                end = 0 if ri == r else 1
                ball = i if end == 0 else j
                grant[q, end] = 0 if _blocked(bits, ball) else 1
                _block(bits, ball)
                dst[left] = q
                left += 1
                crossings += 1 - end
        return m, last, made, ran, left, crossings

    @njit_cached(inline="always")
    def unblock(pairs, ends, pattern, owner, rec, dst, left, bits, r):
        """Clear range ``r``'s blocked bits (those of the picks left, ``dst[:left]``) for the next round."""
        for e in range(left):
            i, j, _, _ = contact(pairs, ends, pattern, rec[dst[e]])
            for ball in (i, j):
                if owner[ball >> 6] == r:
                    _free(bits, ball)

    @njit_cached(inline="always")
    def cross(v, pairs, ends, pattern, units, masses, params, owner, rec, lst, n_lst, grant, done, r, base, tau, m,
              last, made):
        """Owner ``r``'s crossings of the round: those whose first ball is in its range and that hold both
        balls run. Returns ``(m, last, made, ran)``."""
        ran = 0
        for e in range(n_lst):
            q = np.int64(lst[e])
            i, j, a, b = contact(pairs, ends, pattern, rec[q])
            if owner[i >> 6] == r and owner[j >> 6] != r and grant[q, 0] != 0 and grant[q, 1] != 0:
                m, last, made = attempt(v, units, masses, params, i, j, a, b, base + q, tau, m, last, made)
                done[q] = 1
                ran += 1
        return m, last, made, ran

    @jit_cached_if_possible
    def worker(tid, v, pairs, ends, units, masses, params, pattern, owners, rng_words, n, size, count, scratch, sync,
               out):
        """One thread's share of `batches`: claim tasks of the phase published until the end."""
        owner, contact_owner = owners
        rec, lists, counts, pend, npend, bits, grant, done = scratch
        p = lists.shape[0]
        v, units = fixed_width(v, D), fixed_width(units, D)
        tau = params[params.shape[0] - 1]
        m = (np.inf, 0.0, 0.0, 0.0)
        last, made = np.int64(-1), np.int64(0)
        ring = np.empty((_RING, 4), np.int64)  # the picks decoded ahead in `scan`
        s_first = np.int64(rng_words[2])
        while True:
            phase = atomic_load(sync, PHASE)
            kind, batch, rnd = sync[KIND], sync[BATCH], sync[ROUND]
            if kind == END:
                break
            while True:  # claim the phase's tasks
                c = atomic_load(sync, CLAIM)
                if c >= (phase + 1) * p:
                    break
                if atomic_cas(sync, CLAIM, c, c + 1) != c:
                    continue
                task, base = c - phase * p, batch * size
                into, back = (rnd + 1) & 1, rnd & 1  # the round lists it writes, and the last round's
                if kind == GENERATE:
                    generate(rng_words, n, pairs, ends, pattern, owner, contact_owner, rec, lists, counts, done,
                             s_first + base, size, task)
                elif kind == SCAN:
                    ran, left, crossings = 0, 0, 0
                    for t in range(p if rnd == 0 else 1):  # the first round: the batch's picks, segment by segment
                        src = lists[t, task] if rnd == 0 else pend[back, task]
                        n_src = counts[t, task] if rnd == 0 else npend[back, task]
                        m, last, made, r1, left, c1 = scan(v, pairs, ends, pattern, units, masses, params, owner, rec,
                                                           src, n_src, pend[into, task], left, bits, grant, done, ring,
                                                           task, base, tau, m, last, made)
                        ran, crossings = ran + r1, crossings + c1
                    unblock(pairs, ends, pattern, owner, rec, pend[into, task], left, bits, task)
                    npend[into, task] = left
                    atomic_add(sync, RAN, ran)
                    atomic_add(sync, PENDING, crossings)
                else:
                    m, last, made, ran = cross(v, pairs, ends, pattern, units, masses, params, owner, rec,
                                               pend[into, task], npend[into, task], grant, done, task, base, tau, m,
                                               last, made)
                    atomic_add(sync, RAN, ran)
                if atomic_add(sync, DONE, 1) == (phase + 1) * p - 1:  # the phase's last task: what comes next
                    _next_phase(sync, kind, batch, rnd, size, count)
                    atomic_store(sync, PHASE, phase + 1)
            _spin_until(sync, PHASE, phase + 1)
        out[tid, 0], out[tid, 1] = made, last
        out[tid, 2], out[tid, 3], out[tid, 4], out[tid, 5] = m

    @jit_cached_if_possible(parallel=True)
    def batches(v, pairs, ends, units, masses, params, pattern, owners, rng_words, n, size, count, scratch, sync, out):
        for tid in prange(out.shape[0]):
            worker(np.int64(tid), v, pairs, ends, units, masses, params, pattern, owners, rng_words, n, size, count,
                   scratch, sync, out)

    return batches


@njit_cached(inline="always")
def _next_phase(sync, kind, batch, rnd, size, count):
    """After a phase (its tasks all done): the next one's kind, batch and round into ``sync``."""
    if kind == GENERATE:
        sync[KIND], sync[ROUND], sync[PENDING] = SCAN, 0, 0
    elif kind == SCAN and sync[PENDING] > 0:
        sync[KIND] = CROSS
    elif sync[RAN] < size:  # after crossings, picks are left: another round
        sync[KIND], sync[ROUND], sync[PENDING] = SCAN, rnd + 1, 0
    elif batch + 1 < count:
        sync[KIND], sync[BATCH], sync[RAN] = GENERATE, batch + 1, 0
    else:
        sync[KIND] = END


class ReservationChain:
    """`reservation_batches` for one simulation: its ranges, scratch and the limits of a run.

    Built by `build` (None on one thread, or where ranges do not pay: `range_bounds`). `run` takes the
    place of the sequential limited loop on the counter stream, with its bits.
    """

    def __init__(self, batches: Callable, pairs: np.ndarray, bounds: np.ndarray, n_balls: int, threads: int,
                 batch: int, tuned: bool = False):
        self.batches, self.bounds, self.threads, self.batch = batches, bounds, threads, int(batch)
        p, size = len(bounds) - 1, self.batch
        words = -(-n_balls // BALLS_PER_WORD)
        owner = np.repeat(np.arange(p, dtype=np.uint8), np.diff(-(-bounds // BALLS_PER_WORD)))[:words]
        ends = owner[pairs // BALLS_PER_WORD]
        #: the range of each word of 64 balls, and of each contact (`CROSSING`: two)
        self.owners = (owner, np.where(ends[:, 0] == ends[:, 1], ends[:, 0], CROSSING).astype(np.uint8))
        #: chooses, stretch by stretch, between all threads and one (None: always all)
        self.tuner = ThreadTuner(thread_counts(threads)) if tuned else None
        self.scratch = (np.empty(size, np.int64),  # rec: the contact of each pick
                        np.empty((p, p, -(-size // p)), np.int32),  # lists: segment t's picks on range r
                        np.zeros((p, p), np.int64),  # counts
                        np.empty((2, p, size), np.int32),  # pend: the round lists of each range
                        np.zeros((2, p), np.int64),  # npend
                        np.zeros(words, np.uint64),  # bits: blocked balls (clear between rounds)
                        np.zeros((size, 2), np.uint8),  # grant: each end of a crossing free
                        np.zeros(size, np.uint8))  # done: a crossing ran
        self.out = np.empty((threads, 6))

    @classmethod
    def build(cls, collide: Callable, dim: int, flat: bool, pairs: np.ndarray, n_balls: int, rows: bool,
              threads: int, tuned: bool = False, batch: int | None = None) -> ReservationChain | None:
        bounds = range_bounds(pairs, n_balls, threads) if threads > 1 else None
        if bounds is None:
            return None
        size = batch_size(n_balls, threads) if batch is None else int(batch)
        if not 1 <= size < 1 << 31 or n_balls >= 1 << 31:  # positions are int32, a pick's balls share an int64
            raise ValueError(f"batch must be in [1, 2^31) and the balls fewer than 2^31, got {size} and {n_balls}")
        return cls(reservation_batches(collide, dim, flat, rows), pairs, bounds, n_balls, threads, size, tuned)

    def _whole(self, chain, pattern, rng, counters, margin, count: int, sequential: Callable) -> int:
        """``count`` batches (`stretches.tuned_blocks`); the steps taken."""
        return tuned_blocks(self.tuner, self.batch, count, sequential,
                            lambda batches: self._batches(chain, pattern, rng, counters, margin, batches))

    def _batches(self, chain, pattern, rng, counters, margin, count: int) -> int:
        """``count`` batches; the steps they took. The counters (``LAST`` too), stream and margin advanced."""
        sync = np.zeros(SYNC, dtype=np.int64)
        sync[KIND] = GENERATE
        self.batches(*chain, pattern, self.owners, rng, np.int64(len(chain.pairs)), np.int64(self.batch),
                     np.int64(count), self.scratch, sync, self.out)
        steps = count * self.batch
        made, last = int(self.out[:, 0].sum()), int(self.out[:, 1].max())
        for row in self.out:
            merge_margin(margin, row[2:6])
        rng[2] += np.uint64(steps)
        counters[STEPS] += steps
        counters[COLLISIONS] += made
        if last >= 0:
            counters[LAST] = counters[STEPS] - steps + last + 1
        return steps

    def run(self, chain, pattern, limited, any_live, state, aux, rng, counters, margin, max_steps: int,
            max_collisions: int, until_frozen: bool, chunk_steps: int, tune: np.ndarray | None = None,
            choice=None) -> int:
        """What the sequential ``limited`` loop does for these limits, bit for bit (`stretches.tuned_limits`:
        whole batches on the threads, the rest and the freeze on one)."""
        return tuned_limits(self.tuner, self._whole, self.batch, chain, pattern, limited, any_live, state, aux, rng,
                            counters, margin, max_steps, max_collisions, until_frozen, chunk_steps, tune,
                            choice)

