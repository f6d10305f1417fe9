"""The paper's chain on every core, with the bits of one: `UniformRandomPair`'s picks run by regions.

The balls are cut into ``p`` regions by index (row bands on a lattice), each holding about ``E/p``
contacts. A contact with both balls in one region is *local*; the few that join two regions
(about 2 per column at each cut) are *crossings*. Picks that share no ball commute, so each region's
picks can run on its own thread, in their order, as long as nothing that runs early shares a ball
with something that must run later. So in each block of picks the crossings are *deferred*: a
crossing, and every later pick of the block that shares a ball with a deferred one, runs after all
the others, in time order. The result is the sequential chain's, bit for bit: every collision sees
the velocities it would have seen.

**Blocks.** The picks come in blocks of ``p * W`` words of the random stream. Phase G: thread ``t``
jumps the stream ``t * W`` words ahead (`engine.streams.jump`) and turns its ``W`` words into picks exactly
as `random.bounded` does (Lemire's test rejects a word on its own, so the picks of a block are the
accepted words in order) and files each under its region, or as a crossing; picks touching a ball
near a cut are also put on a watch list. Where the contacts are numbered by their lower ball (a
lattice's are), a pick far from every cut is filed by its contact index alone (`contact_windows`);
only those near a cut are decoded (tables or the lattice's row pattern) in phase G. Phase E decodes
the rest as it runs them, a few records ahead, where the velocity rows' cache misses hide the work.
Then one thread follows the crossings' wake through the watch list (`_defer`; if the wake ever
leaves the watched bands, the block runs in time order instead). Phase E: each region's picks but
the deferred ones; the thread that finishes last runs the deferred picks.

**Threads that never wait for one another's absence.** Every piece of work (a G segment, the wake, a
region's share) is claimed with a compare-and-swap on a counter, so a thread that finds the others
late does their work itself: one thread alone runs the whole block, and a thread the operating
system deschedules costs the others only the piece it holds. Waiting threads spin with ``pause``,
then yield their core (``sched_yield``). A thread that arrives after a block is complete skips it.
Nothing depends on how many threads actually ran, or in which order they claimed.

The caller (`ParallelChain`) runs whole blocks only where they cannot pass a limit (steps left,
collisions left), runs the rest with the sequential loop, and finds the freeze as the sequential
loop does (a scan after each chunk; the chunk that froze runs again on one thread up to its last
collision), so the steps, collisions, velocities, random state and margin are those of one thread.
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import prange

from ..chain import COLLISIONS, LAST, STEPS
from ..closing import trial_form
from ..jit.cache import INLINED, jit_cached_if_possible, njit_cached
from ..jit.intrinsics import atomic_add, atomic_cas, atomic_load, atomic_store, fixed_width, give_way, pause, prefetch
from ..margin import merge_margin, track
from ..rows import decode
from ..streams.jump import jump, jump_polynomial
from ..streams.xoshiro import load, next_uint64, store
from .stretches import tuned_blocks, tuned_limits
from .tuning import TUNED_SEGMENT, ThreadTuner, thread_counts

__all__ = ["ParallelChain", "counted_trial", "region_cuts", "bands_pay",
           "parallel_blocks", "WORDS", "MAX_CROSSING_SHARE", "MAX_BAND_SHARE", "MIN_PARALLEL_CONTACTS", "TUNED_SEGMENT"]

#: words of the stream each thread turns into picks per block
WORDS = 1 << 14
#: regions are not worth it when more than this share of the contacts joins two of them
MAX_CROSSING_SHARE = 0.02
#: systems with fewer contacts run on one thread (a freeze scan's chunk holds a few blocks at least)
MIN_PARALLEL_CONTACTS = 1 << 16
#: records ahead whose contacts are decoded and velocity rows fetched while a region runs
AHEAD = 16
_RING = 32  # the ring of those contacts: a power of two above AHEAD
#: the bands watched for the wake of a crossing reach this many contacts from a cut (in ball index:
#: ``BAND_HOPS`` times the largest ``|j - i|`` of a contact)
BAND_HOPS = 8
#: regions are not worth it when the watched bands would hold more than this share of the balls: a
#: contact joining balls far apart in index (a torus's wrap-around) makes every pick a watched one,
#: and two threads then run far slower than one (docs/performance.md)
MAX_BAND_SHARE = 0.25

# the shared counters (`sync`), each on its own cache line
_LINE = 8
(NEXT_GEN, GEN_DONE, NEXT_CLOSURE, CLOSURE_DONE, ESCAPED, FINISHED, BLOCKS_DONE,
 NEXT_TASK) = (k * _LINE for k in range(8))


def sync_length(threads: int) -> int:
    """The length of the ``sync`` array for ``threads`` regions."""
    return NEXT_TASK + threads * _LINE


def region_cuts(pairs: np.ndarray, n_balls: int, threads: int) -> np.ndarray | None:
    """``(threads - 1,) int64`` ball indices cutting the balls into regions of about equal numbers of
    contacts, or None when more than `MAX_CROSSING_SHARE` of the contacts would join two regions."""
    low = np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    high = np.maximum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    per_ball = np.cumsum(np.bincount(low, minlength=n_balls))
    cuts = np.searchsorted(per_ball, np.arange(1, threads) * len(pairs) / threads).astype(np.int64) + 1
    if len(np.unique(cuts)) != threads - 1 or cuts.min() <= 0 or cuts.max() >= n_balls:
        return None
    crossing = (np.searchsorted(cuts, low, side="right") != np.searchsorted(cuts, high, side="right")).mean()
    return cuts if crossing <= MAX_CROSSING_SHARE else None


def _reach(pairs: np.ndarray) -> int:
    """The largest ``|j - i|`` of a contact: how far in ball index one hop can go."""
    return int(np.abs(pairs[:, 1].astype(np.int64) - pairs[:, 0].astype(np.int64)).max(initial=0))


def bands_pay(pairs: np.ndarray, n_balls: int, threads: int) -> bool:
    """Whether the bands watched around ``threads - 1`` cuts hold at most `MAX_BAND_SHARE` of the
    ``n_balls`` balls (each reaches ``BAND_HOPS`` times the largest ``|j - i|`` of a contact on
    either side of its cut): false on a torus, whose wrap-around contacts join balls ``N - 1`` apart."""
    return 2 * BAND_HOPS * _reach(pairs) * (threads - 1) <= MAX_BAND_SHARE * n_balls


@njit_cached(inline="always")
def _region(cuts, ball):
    r = 0
    for c in range(cuts.shape[0]):
        r += 1 if ball >= cuts[c] else 0
    return r


def contact_windows(pairs: np.ndarray, cuts: np.ndarray, band: int) -> np.ndarray:
    """``(cuts, 3) int64``: for each cut ``c``, the contact indices ``[w0, w2)`` whose lower ball lies in
    ``[c - band - reach, c + band)`` (every contact that touches a ball within ``band`` of the cut, or may
    cross it), and ``w1``, the first contact whose lower ball is at least ``c``. Where the contacts are
    numbered by their lower ball (a lattice's are), a contact outside every window lies in region ``sum
    (k >= w1)`` and near no cut, known from its index. Otherwise one window holds every contact."""
    low = np.minimum(pairs[:, 0], pairs[:, 1]).astype(np.int64)
    if len(low) and np.any(np.diff(low) < 0):
        return np.array([[0, 0, len(low)]] * len(cuts), dtype=np.int64)
    reach = _reach(pairs)
    return np.array([[np.searchsorted(low, c - band - reach), np.searchsorted(low, c), np.searchsorted(low, c + band)]
                     for c in cuts], dtype=np.int64)


@njit_cached(inline="always")
def _by_index(windows, k):
    """``(region, False)`` of contact ``k`` when its index tells (`contact_windows`), else ``(0, True)``: it
    must be decoded."""
    r = 0
    for c in range(windows.shape[0]):
        if windows[c, 0] <= k < windows[c, 2]:
            return 0, True
        r += 1 if k >= windows[c, 1] else 0
    return r, False


#: ``pause`` this many times before yielding the core
SPINS = 1 << 10


@njit_cached(inline="always")
def _spin_until(sync, index, value):
    """Wait until ``sync[index] >= value`` (acquire): spin a while, then yield the core at each look, so
    a thread waiting for one the operating system has descheduled lets it run."""
    spins = 0
    while atomic_load(sync, index) < value:
        if spins < SPINS:
            spins += 1
            pause()
        else:
            give_way()


@functools.cache
def counted_trial(collide: Callable, dim: int, flat: bool) -> Callable:
    """``attempt(v, units, masses, params, i, j, a, b, position, tau, m, last, made) -> (m, last, made)``: try
    contact ``(i, j, a, b)``, the pick at ``position``, by the rule's trial (`closing.trial_form`), and count
    it: the margin ``m`` (`margin.track`), the position of the last collision and the collisions, updated.
    What a thread of a threaded chain does with each pick it runs. Compiled once on its own and inlined by
    LLVM (a worker calls it from three places: inlined by numba, each typed the rule's form again, 2 s each)."""
    trial = trial_form(collide, dim, flat)

    @jit_cached_if_possible(**INLINED)
    def attempt(v, units, masses, params, i, j, a, b, position, tau, m, last, made):
        hit, w = trial(v, units, masses, params, i, j, a, b, True)
        m = track(hit, w, tau, m[0], m[1], m[2], m[3])
        if hit:
            made += 1
            last = max(last, position)
        return m, last, made

    return attempt


@functools.cache
def parallel_blocks(collide: Callable, dim: int, flat: bool, rows: bool) -> Callable:
    """The compiled blocks of the chain for one rule's ``collide``, ``dim``, ``flat`` and the contacts'
    source (``rows``: the row pattern, else the tables):

    blocks(v, pairs, ends, units, masses, params, pattern, cuts, band, windows, poly, rng_words, n, scratch,
           history, sync, out) -> picks

    runs ``len(history)`` blocks of ``p * W`` words (``p = len(cuts) + 1`` regions, ``poly`` the jump
    polynomial of ``W`` words) on numba's threads, advances ``rng_words`` past them, and returns the
    picks taken. ``band``: the balls within ``band`` of a cut are watched for crossings (see the module
    docstring); ``windows``: `contact_windows`; ``scratch`` = `Scratch` arrays. ``out (p, 6) float64`` receives each
    thread's collisions, the position of its last collision (-1: none; positions count the call's picks from
    0) and its margin (4). ``history (blocks, 6) int64`` receives each block's picks, deferred picks
    and final stream state (4 words). ``sync``: zeros, `SYNC` int64.
    """
    attempt = counted_trial(collide, dim, flat)
    D, ROWS = dim, rows

    @njit_cached(inline="always")
    def contact(pairs, ends, pattern, k):
        if ROWS:
            return decode(pattern, np.int64(k))
        return np.int64(pairs[k, 0]), np.int64(pairs[k, 1]), np.int64(ends[k, 0]), np.int64(ends[k, 1])

    @njit_cached(inline="always")
    def generate(s, n, pairs, ends, pattern, cuts, band, windows, recs, counts, watch, nwatch, t, W, p):
        """Segment ``t`` of a block: ``W`` words from state ``s`` into its regions' records (``recs[t, r]``,
        crossings under ``r = p``), those near a cut also listed in ``watch[t]`` as ``r << 32 | q``;
        ``(picks, s')``. A record is ``(k, i << 32 | j, position)``; a contact outside every cut's
        window (`contact_windows`) is filed by its index alone (``i, j`` not decoded: 0)."""
        n64 = np.uint64(n)
        threshold = (np.uint64(1 << 32) - n64) % n64
        local = np.zeros(p + 1, np.int64)  # this segment's counts (a write per pick, kept off shared lines)
        picks, watched = 0, 0
        for _ in range(W):
            x, s = next_uint64(s)
            m = (x >> np.uint64(32)) * n64
            low = m & np.uint64(0xFFFFFFFF)
            if low < n64 and low < threshold:  # Lemire's test, word by word: `random.bounded`
                continue
            k = np.int64(m >> np.uint64(32))
            r, near = _by_index(windows, k)
            ij = np.int64(0)
            if near:
                i, j, _, _ = contact(pairs, ends, pattern, k)
                ri, rj = _region(cuts, i), _region(cuts, j)
                r = ri if ri == rj else p
                ij = (i << 32) | j
                near = r == p or _near(cuts, band, i) or _near(cuts, band, j)
            q = local[r]
            recs[t, r, q, 0], recs[t, r, q, 1], recs[t, r, q, 2] = k, ij, picks
            local[r] = q + 1
            if near:
                watch[t, watched] = (r << 32) | q
                watched += 1
            picks += 1
        for r in range(p + 1):
            counts[t, r] = local[r]
        nwatch[t] = watched
        return picks, s

    @njit_cached(inline="always")
    def record(v, units, masses, params, pairs, ends, pattern, recs, t, r, q, base, tau, m, last, made):
        """Try the record ``recs[t, r, q]`` (its position ``base + recs[t, r, q, 2]``), its contact decoded.
        (Scalars, not the record's view: a view per pick costs numba reference counting.)"""
        i, j, a, b = contact(pairs, ends, pattern, recs[t, r, q, 0])
        return attempt(v, units, masses, params, i, j, a, b, base + (recs[t, r, q, 2] & _POSITION), tau, m, last,
                       made)

    @njit_cached(inline="always")
    def region(v, units, masses, params, pairs, ends, pattern, recs, ring, t, r, count, base, tau, m, last, made):
        """Region ``r``'s records of segment ``t`` in order, deferred ones left out: each decoded `AHEAD`
        records early (into ``ring``) and its velocity rows fetched then."""
        for q in range(min(AHEAD, count)):
            i, j, a, b = contact(pairs, ends, pattern, recs[t, r, q, 0])
            ring[q, 0], ring[q, 1], ring[q, 2], ring[q, 3] = i, j, a, b
            prefetch(v, i)
            prefetch(v, j)
        for q in range(count):
            if q + AHEAD < count:
                i, j, a, b = contact(pairs, ends, pattern, recs[t, r, q + AHEAD, 0])
                e = (q + AHEAD) % _RING
                ring[e, 0], ring[e, 1], ring[e, 2], ring[e, 3] = i, j, a, b
                prefetch(v, i)
                prefetch(v, j)
            if recs[t, r, q, 2] & _DEFERRED:
                continue
            e = q % _RING
            m, last, made = attempt(v, units, masses, params, ring[e, 0], ring[e, 1], ring[e, 2], ring[e, 3],
                                    base + (recs[t, r, q, 2] & _POSITION), tau, m, last, made)
        return m, last, made

    @njit_cached(inline="always")
    def in_order(v, units, masses, params, pairs, ends, pattern, recs, counts, t, p, base, tau, m, last, made):
        """Segment ``t``'s records, all of them, in time order (a merge of its ``p + 1`` lists by position)."""
        heads = np.zeros(p + 1, np.int64)
        total = 0
        for r in range(p + 1):
            total += counts[t, r]
        for _ in range(total):
            best, at = -1, _POSITION
            for r in range(p + 1):
                if heads[r] < counts[t, r]:
                    position = recs[t, r, heads[r], 2] & _POSITION
                    if position < at:
                        best, at = r, position
            m, last, made = record(v, units, masses, params, pairs, ends, pattern, recs, t, best, heads[best], base,
                                   tau, m, last, made)
            heads[best] += 1
        return m, last, made

    @jit_cached_if_possible
    def worker(tid, v, pairs, ends, units, masses, params, pattern, cuts, band, windows, poly, rng_words, n, recs,
               counts, watch, nwatch, npick, marks, deferred, history, sync, out):
        """One thread's share of `blocks` (a function of its own: numba's analysis of a parallel loop
        does not follow the tuples the margin travels in)."""
        p, W, n_blocks = cuts.shape[0] + 1, recs.shape[2], history.shape[0]
        v, units = fixed_width(v, D), fixed_width(units, D)
        tau = params[params.shape[0] - 1]
        m = (np.inf, 0.0, 0.0, 0.0)
        last, made = np.int64(-1), np.int64(0)
        offsets = np.empty(p + 1, np.int64)
        ring = np.empty((_RING, 4), np.int64)  # the contacts decoded ahead in `region`
        base = np.int64(0)  # picks before this block
        for blk in range(n_blocks):
            if atomic_load(sync, BLOCKS_DONE) > blk:  # done by the others: its numbers are in the history
                base += history[blk, 0]
                continue
            s_block = load(rng_words) if blk == 0 else load(history[blk - 1, 2:6].view(np.uint64))
            # phase G: claim segments of this block's words
            while True:
                g = atomic_load(sync, NEXT_GEN)
                if g >= (blk + 1) * p:
                    break
                if atomic_cas(sync, NEXT_GEN, g, g + 1) == g:
                    t = g - blk * p
                    st = s_block
                    for _ in range(t):
                        st = jump(st, poly)
                    npick[t], st = generate(st, n, pairs, ends, pattern, cuts, band, windows, recs, counts, watch,
                                            nwatch, t, W, p)
                    if t == p - 1:  # the block's last word: where the next block starts
                        store(history[blk, 2:6].view(np.uint64), st)
                    atomic_add(sync, GEN_DONE, 1)
            _spin_until(sync, GEN_DONE, (blk + 1) * p)
            # the crossings and what must follow them: one thread defers them (in time order)
            if atomic_cas(sync, NEXT_CLOSURE, blk, blk + 1) == blk:
                sync[ESCAPED] = _defer(recs, watch, nwatch, cuts, band, marks, deferred, p)
                atomic_store(sync, CLOSURE_DONE, blk + 1)
            _spin_until(sync, CLOSURE_DONE, blk + 1)
            offsets[0] = base
            for t in range(p):
                offsets[t + 1] = offsets[t] + npick[t]
            escaped = sync[ESCAPED] != 0
            # phase E: each region's picks but the deferred ones, all segments in order; the last to
            # finish runs the deferred picks in time order (or, if the crossings' wake left the bands,
            # the whole block in time order)
            for k in range(p):
                r = (tid + k) % p
                if atomic_cas(sync, NEXT_TASK + r * _LINE, blk, blk + 1) != blk:
                    continue
                if not escaped:
                    for t in range(p):
                        m, last, made = region(v, units, masses, params, pairs, ends, pattern, recs, ring, t, r,
                                               counts[t, r], offsets[t], tau, m, last, made)
                if atomic_add(sync, FINISHED, 1) == (blk + 1) * p - 1:
                    if escaped:
                        for t in range(p):
                            m, last, made = in_order(v, units, masses, params, pairs, ends, pattern, recs, counts, t,
                                                     p, offsets[t], tau, m, last, made)
                    else:
                        for d in range(deferred[0]):
                            e = deferred[1 + d]
                            t, r2, q = e >> 48, (e >> 32) & 0xFFFF, e & 0xFFFFFFFF
                            m, last, made = record(v, units, masses, params, pairs, ends, pattern, recs, t, r2, q,
                                                   offsets[t], tau, m, last, made)
                    history[blk, 0], history[blk, 1] = offsets[p] - base, deferred[0]
                    atomic_store(sync, BLOCKS_DONE, blk + 1)
            _spin_until(sync, BLOCKS_DONE, blk + 1)
            base += history[blk, 0]
        out[tid, 0], out[tid, 1] = made, last
        out[tid, 2], out[tid, 3], out[tid, 4], out[tid, 5] = m

    @jit_cached_if_possible(parallel=True)
    def blocks(v, pairs, ends, units, masses, params, pattern, cuts, band, windows, poly, rng_words, n, recs, counts,
               watch, nwatch, npick, marks, deferred, history, sync, out):
        for tid in prange(cuts.shape[0] + 1):
            worker(np.int64(tid), v, pairs, ends, units, masses, params, pattern, cuts, band, windows, poly, rng_words,
                   n, recs, counts, watch, nwatch, npick, marks, deferred, history, sync, out)
        store(rng_words, load(history[history.shape[0] - 1, 2:6].view(np.uint64)))
        total = np.int64(0)
        for blk in range(history.shape[0]):
            total += history[blk, 0]
        return total

    return blocks


#: the bit of a record's position that says it is deferred, and the position itself
_DEFERRED = np.int64(1) << 62
_POSITION = _DEFERRED - 1


@njit_cached(inline="always")
def _near(cuts, band, ball):
    """True when ``ball`` lies within ``band`` balls of a cut (a crossing's wake can reach it)."""
    for c in range(cuts.shape[0]):
        if cuts[c] - band <= ball < cuts[c] + band:
            return True
    return False


@njit_cached(inline="always")
def _mark_index(cuts, band, ball):
    """Where ``ball``'s mark lives (``2 * band`` marks per cut), or -1 outside every band."""
    for c in range(cuts.shape[0]):
        if cuts[c] - band <= ball < cuts[c] + band:
            return c * 2 * band + ball - (cuts[c] - band)
    return -1


@njit_cached
def _defer(recs, watch, nwatch, cuts, band, marks, deferred, p):
    """Defer every crossing, and every later pick that shares a ball with a deferred one, in time order:
    mark their records, list them in ``deferred`` (``[count, t << 48 | r << 32 | q, ...]``). Deferred
    picks run after all others, in their order: no pick that runs early shares a ball with one that
    runs later. Every pick touching a ball within ``band`` of a cut is watched, so the wake is followed
    in full while it stays in the bands; returns 1 when a deferred pick reaches a ball outside them (the
    block must then run in time order), else 0."""
    count, escaped = 0, 0
    for t in range(p):
        for e in range(nwatch[t]):
            w = watch[t, e]
            r, q = w >> 32, w & 0xFFFFFFFF
            ij = recs[t, r, q, 1]
            i, j = ij >> 32, ij & 0xFFFFFFFF
            mi, mj = _mark_index(cuts, band, i), _mark_index(cuts, band, j)
            if r == p or (mi >= 0 and marks[mi] != 0) or (mj >= 0 and marks[mj] != 0):
                for mk in (mi, mj):
                    if mk < 0:
                        escaped = 1
                    else:
                        marks[mk] = 1
                recs[t, r, q, 2] |= _DEFERRED
                deferred[1 + count] = (t << 48) | (r << 32) | q
                count += 1
    for d in range(count):  # clear the marks for the next block
        e = deferred[1 + d]
        ij = recs[e >> 48, (e >> 32) & 0xFFFF, e & 0xFFFFFFFF, 1]
        for ball in (ij >> 32, ij & 0xFFFFFFFF):
            mk = _mark_index(cuts, band, ball)
            if mk >= 0:
                marks[mk] = 0
    deferred[0] = count
    return escaped


class ParallelChain:
    """`parallel_blocks` for one simulation: its regions, scratch and the limits of a run.

    Built by `build` (None where regions do not pay: a crossing share above `MAX_CROSSING_SHARE`); a
    simulation also asks `bands_pay` first.
    `run` takes the place of the sequential limited loop, with its bits.
    """

    def __init__(self, blocks: Callable, cuts: np.ndarray, band: int, threads: int, words: int = WORDS,
                 tuned: bool = False, windows: np.ndarray | None = None):
        self.blocks, self.cuts, self.band, self.threads, self.words = blocks, cuts, band, threads, words
        #: `contact_windows` (None: one window holds every contact: each is decoded when drawn)
        self.windows = np.array([[0, 0, 1 << 62]] * len(cuts), dtype=np.int64) if windows is None else windows
        #: chooses, stretch by stretch, between all threads and one (None: always all)
        self.tuner = ThreadTuner(thread_counts(threads)) if tuned else None
        self.poly = jump_polynomial(words)
        p = threads
        self.scratch = (np.empty((p, p + 1, words, 3), dtype=np.int64),  # recs: (k, i << 32 | j, position)
                        np.empty((p, p + 1), dtype=np.int64),  # counts (row t: thread t's, once per segment)
                        np.empty((p, words), dtype=np.int64),  # watch: picks near a cut
                        np.empty(p, dtype=np.int64),  # nwatch
                        np.empty(p, dtype=np.int64),  # npick
                        np.zeros((p - 1) * 2 * band, dtype=np.uint8),  # marks: deferred balls near each cut
                        np.empty(p * words + 1, dtype=np.int64))  # deferred picks
        self.out = np.empty((p, 6))

    @classmethod
    def build(cls, collide: Callable, dim: int, flat: bool, pairs: np.ndarray, n_balls: int, rows: bool,
              threads: int, words: int = WORDS, tuned: bool = False) -> ParallelChain | None:
        cuts = region_cuts(pairs, n_balls, threads) if threads > 1 else None
        if cuts is None:
            return None
        band = BAND_HOPS * _reach(pairs)
        return cls(parallel_blocks(collide, dim, flat, rows), cuts, band, threads, words, tuned,
                   contact_windows(pairs, cuts, band))

    @property
    def block(self) -> int:
        """Words per block: the most picks a block can take."""
        return self.threads * self.words

    def _whole(self, chain, pattern, rng, counters, margin, count: int, sequential: Callable) -> int:
        """``count`` blocks (`tuned_blocks`); the steps taken."""
        return tuned_blocks(self.tuner, self.block, count, sequential,
                            lambda blocks: self._blocks(chain, pattern, rng, counters, margin, blocks))

    def _blocks(self, chain, pattern, rng, counters, margin, count: int) -> int:
        """``count`` blocks; the picks they took. The counters (``LAST`` too), stream and margin advanced."""
        history = np.empty((count, 6), dtype=np.int64)
        sync = np.zeros(sync_length(self.threads), dtype=np.int64)
        picks = self.blocks(chain.v, chain.pairs, chain.ends, chain.units, chain.masses, chain.params, pattern,
                            self.cuts, np.int64(self.band), self.windows, self.poly, rng, np.int64(len(chain.pairs)),
                            *self.scratch,
                            history, sync, self.out)
        made, last = int(self.out[:, 0].sum()), int(self.out[:, 1].max())
        for row in self.out:
            merge_margin(margin, row[2:6])
        counters[STEPS] += picks
        counters[COLLISIONS] += made
        if last >= 0:
            counters[LAST] = counters[STEPS] - picks + last + 1
        return int(picks)

    def run(self, chain, pattern, limited, any_live, state, aux, rng, counters, margin, max_steps: int,
            max_collisions: int, until_frozen: bool, chunk_steps: int, tune: np.ndarray | None = None,
            choice=None) -> int:
        """What the sequential ``limited`` loop does for these limits, bit for bit (`tuned_run` of `run_in_chunks`)."""
        return tuned_limits(self.tuner, self._whole, self.block, chain, pattern, limited, any_live, state, aux, rng,
                            counters, margin, max_steps, max_collisions, until_frozen, chunk_steps, tune,
                            choice)
