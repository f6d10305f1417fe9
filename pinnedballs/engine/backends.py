"""How a simulation's chain runs: one backend per arithmetic and device, chosen when it is built.

Every backend speaks the engine's chunk protocol, which the run driver (`engine.driver`) calls through
``Simulation._run``: ``run(sim, max_steps, max_collisions, until_frozen) -> steps taken``, leaving the
simulation's counters, random stream, scheduler state and margin as the compiled loop
(`engine.loops`'s ``limited``) leaves them, however the run is split. Each also counts the live
contacts (``approaching``), says whether none is left (``is_frozen``) and gives the velocities now.

* `LoopBackend`: floats on the CPU. The compiled loops; a scheduler's own loop for plain steps
  (`ColoredSweep`); the paper's picks on several threads, by regions on the xoshiro stream
  (`engine.parallel`) or by deterministic reservations on the counter stream (`engine.reservations`);
  the logging loops when someone listens for collisions.
* `ExactBackend`: exact or certified arithmetic (`engine.exact`, `engine.fixed`) on the same picks.
* `DeviceBackend`: floats on an NVIDIA GPU (`engine.gpu`), the counter stream's chain with the CPU's bits.

A backend reads the simulation's arrays (``sim._counters``, ``sim._rng``, ``sim._sched_state``,
``sim._margin``, and the exact chain ``sim._exact``) at each call, so `Simulation.set_state` may
replace them.
"""

from __future__ import annotations

import numpy as np

from .chain import COLLISIONS, LIVE, STEPS, Chain, LiveSet, incidence
from .errors import FieldError
from .loops import FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT, LOOKAHEAD_BYTES, NO_PATTERN, live_kernel, loops
from .parallel import MIN_PARALLEL_CONTACTS, TUNED_SEGMENT, ParallelChain, bands_pay
from .threads import most_threads

__all__ = ["LoopBackend", "ExactBackend", "DeviceBackend", "DEVICES", "LOG_CAPACITY"]

#: the devices a simulation runs on
DEVICES = ("cpu", "cuda")
#: collisions a logging loop records before handing them to the listeners
LOG_CAPACITY = 1 << 16
_NO_LOG = np.empty((0, 2), dtype=np.int64)


def _tables(sim) -> tuple:
    return sim._sched_state, sim._selector.aux, sim._rng, sim._counters, sim._margin


class LoopBackend:
    """Floats on the CPU: the engine's compiled loops for one rule and one scheduler (module docstring)."""

    name = "cpu"

    def __init__(self, sim):
        s, dim, flat = sim._selector, sim.geometry.dim, sim.geometry.contacts.flat
        self.loops = loops(sim._collide, s.select, s.begin, s.changed, s.skips, dim, flat)
        self.own_steps = None if s.steps is None else s.steps(sim._collide, dim, flat)
        self.live_flags, self.any_live = live_kernel(sim._collide, dim, flat)
        self._live = None  # the LiveSet, built when a tracked run first needs it
        self._parallel = None  # the threaded chain, built when a run first asks (False: none)

    # ------------------------------------------------------------ the protocol
    def run(self, sim, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        if sim.collision_listeners:
            return self._run_logged(sim, max_steps, max_collisions, until_frozen)
        chain, s, tables = self.chain(sim), sim._selector, _tables(sim)
        if s.tracks:
            return self.loops.tracked(*chain, *tables, max_steps, max_collisions, until_frozen,
                                      *self.refresh_live(sim), _NO_LOG)
        plain = not until_frozen and max_collisions == np.iinfo(np.int64).max
        if plain and self.own_steps is not None:
            return self.own_steps(*chain, *tables, max_steps)
        limited, pattern = self.limited(sim, logged=False)
        parallel = self.parallel_chain(sim)
        if parallel is not None:
            return parallel.run(chain, pattern, limited, self.any_live, *tables, max_steps, max_collisions,
                                until_frozen, TUNED_SEGMENT if plain else self.freeze_chunk(sim))
        return limited(*chain, pattern, *tables, max_steps, max_collisions, until_frozen,
                       max_steps if plain else self.freeze_chunk(sim), np.empty_like(sim._sched_state), _NO_LOG)

    def velocities(self, sim) -> np.ndarray:
        return sim._velocities

    def approaching(self, sim) -> int:
        flags = np.empty(sim.geometry.n_contacts, dtype=np.uint8)
        return int(self.live_flags(*self.chain(sim), flags))

    def is_frozen(self, sim) -> bool:
        return not self.any_live(*self.chain(sim))

    def live_flags_of(self, sim, velocities: np.ndarray) -> np.ndarray:
        """``(E,) uint8``: the live contacts of ``velocities`` (a state about to be restored)."""
        flags = np.empty(sim.geometry.n_contacts, dtype=np.uint8)
        self.live_flags(*self.chain(sim)._replace(v=velocities), flags)
        return flags

    # ------------------------------------------------------------ the loops
    @staticmethod
    def chain(sim) -> Chain:
        c = sim.geometry.contacts
        return Chain(sim._velocities, c.pairs, c.ends, c.units, sim._mass_array, sim._params)

    def parallel_chain(self, sim):
        """The chain on several threads where the scheduler allows it and it pays, built once; else None:
        on the xoshiro stream the regions of `engine.parallel` (a large system, regions with few
        crossings, narrow bands around the cuts: not a torus), on the counter stream the reservations of
        `engine.reservations`."""
        if self._parallel is None:
            self._parallel = False
            s, c, g = sim._selector, sim.geometry.contacts, sim.geometry
            wanted = getattr(sim.scheduler, "threads", None)
            threads = most_threads() if wanted is None else wanted
            rows = self.limited(sim, logged=False)[1] is not NO_PATTERN
            if threads > 1 and len(c) >= MIN_PARALLEL_CONTACTS and not s.tracks:
                built = None
                if s.uniform and bands_pay(c.pairs, g.n_balls, threads):
                    built = ParallelChain.build(sim._collide, g.dim, c.flat, c.pairs, g.n_balls, rows, threads,
                                                tuned=wanted is None)
                elif s.counter:
                    from .reservations import ReservationChain

                    built = ReservationChain.build(sim._collide, g.dim, c.flat, c.pairs, g.n_balls, rows, threads,
                                                   tuned=wanted is None)
                self._parallel = built if built is not None else False
        return self._parallel or None

    def limited(self, sim, logged: bool):
        """``(loop, pattern)``: the limited loop for this system's size, and the row pattern it reads
        (`engine.rows`): the tables when they fit in cache, the tables prefetched, or the lattice's row
        pattern prefetched when the tables do not."""
        loops_, s, c = self.loops, sim._selector, sim.geometry.contacts
        if c.pairs.nbytes + c.ends.nbytes + sim._velocities.nbytes <= LOOKAHEAD_BYTES or s.skips:
            return (loops_.limited_logged if logged else loops_.limited), NO_PATTERN
        pattern = sim.geometry.row_pattern
        if pattern is None:
            return (loops_.limited_prefetched_logged if logged else loops_.limited_prefetched), NO_PATTERN
        return (loops_.limited_rows_logged if logged else loops_.limited_rows), pattern

    @staticmethod
    def freeze_chunk(sim) -> int:
        """Steps between two scans for the freeze in an untracked loop (`engine.loops`)."""
        return max(FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT * sim.geometry.n_contacts)

    def refresh_live(self, sim) -> LiveSet:
        """The live set of the current velocities (flags and ``counters[LIVE]`` recomputed)."""
        if self._live is None:
            c = sim.geometry.contacts
            ptr, inc = incidence(c.pairs, sim.geometry.n_balls)
            self._live = LiveSet(ptr, inc, np.empty(len(c), dtype=np.uint8))
        sim._counters[LIVE] = self.live_flags(*self.chain(sim), self._live.flags)
        return self._live

    def _run_logged(self, sim, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        """`run` telling ``sim.collision_listeners`` of every collision: the engine's logging loops
        (sequential: the same bits as the others), a log of `LOG_CAPACITY` collisions at a time."""
        chain, s, loops_, tables = self.chain(sim), sim._selector, self.loops, _tables(sim)
        log, taken = np.empty((LOG_CAPACITY, 2), dtype=np.int64), 0
        while True:
            before = sim.collisions
            if s.tracks:
                taken += loops_.tracked_logged(*chain, *tables, max_steps - taken, max_collisions, until_frozen,
                                               *self.refresh_live(sim), log)
            else:
                limited, pattern = self.limited(sim, logged=True)
                taken += limited(*chain, pattern, *tables, max_steps - taken, max_collisions, until_frozen,
                                 self.freeze_chunk(sim), np.empty_like(sim._sched_state), log)
            made = sim.collisions - before
            if made:
                for listener in sim.collision_listeners:
                    listener(log[:made, 0].copy(), log[:made, 1].copy())
            if made < len(log) or taken >= max_steps or sim.collisions >= max_collisions:
                return taken


class ExactBackend:
    """Exact or certified arithmetic on the CPU: the compiled selector's picks in blocks, each tried by the
    field chain (`engine.exact.FieldChain.run`); a block cut short is drawn again to its end, so the
    stream and the scheduler's state are those of the float loop after the same steps. A decision
    certified arithmetic cannot make raises once the picks before it are counted."""

    name = "cpu"

    def __init__(self, sim):
        s = sim._selector
        self.loops = loops(sim._collide, s.select, s.begin, s.changed, s.skips, sim.geometry.dim,
                           sim.geometry.contacts.flat)

    def run(self, sim, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        ex, s, n = sim._exact, sim._selector, sim.geometry.n_contacts
        ex.prepare(until_frozen)
        taken, collisions = 0, sim.collisions
        while taken < max_steps and collisions < max_collisions and not (until_frozen and ex.live == 0) \
                and ex.failure is None:
            block = int(min(ex.block, max_steps - taken))
            rng, state = sim._rng.copy(), sim._sched_state.copy()
            picks = ex.picks_buffer(block)
            self.loops.picks(sim._sched_state, s.aux, sim._rng, n, picks)
            used, made, at = ex.run(picks, max_collisions - collisions, until_frozen, sim.steps + taken + 1)
            if made and sim.collision_listeners:
                steps = sim.steps + taken + 1 + np.asarray(at, dtype=np.int64)
                contacts = picks[np.asarray(at, dtype=np.int64)]
                for listener in sim.collision_listeners:
                    listener(steps, contacts)
            if used < block:
                sim._rng[:], sim._sched_state[:] = rng, state
                self.loops.picks(sim._sched_state, s.aux, sim._rng, n, picks[:used])
            taken, collisions = taken + used, collisions + made
        sim._counters[STEPS] += taken  # the velocities are rounded when read (`velocities`)
        sim._counters[COLLISIONS], sim._counters[LIVE] = collisions, ex.live
        failure, ex.failure = ex.failure, None
        if failure is not None:
            raise failure
        return taken

    def velocities(self, sim) -> np.ndarray:
        return sim._exact.sync()

    def approaching(self, sim) -> int:
        return sim._exact.count_live()

    def is_frozen(self, sim) -> bool:
        return self.approaching(sim) == 0


class DeviceBackend:
    """Floats on an NVIDIA GPU (`engine.gpu.chain.DeviceChain`): the counter stream's chain by deterministic
    reservations, with the CPU loop's bits. The velocities live on the GPU; reading them copies them
    back once after each run (then they are kept until the next run or `set_velocities`)."""

    name = "cuda"

    def __init__(self, sim, **options):
        check_device(sim)
        from .gpu.chain import DeviceChain

        g = sim.geometry
        pattern = g.row_pattern if g.row_shape() is not None else None
        self.chain = DeviceChain(sim._velocities, g.contacts, pattern, sim._mass_array, sim._params, sim._collide,
                                 sim._rng[:2], **options)
        self._host = sim._velocities  # the velocities as last read (None: the GPU's have moved on)

    def run(self, sim, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        if sim.collision_listeners:
            raise FieldError("device", "the collision log runs on the CPU: build the simulation with device='cpu' "
                                       "(the same bits on the counter stream)")
        taken = self.chain.run(sim._counters, sim._rng, sim._margin, max_steps, max_collisions, until_frozen)
        if taken:
            self._host = None
        return taken

    def velocities(self, sim) -> np.ndarray:
        if self._host is None:
            self._host = self.chain.velocities()
        return self._host

    def set_velocities(self, v: np.ndarray) -> None:
        self.chain.set_velocities(v)
        self._host = np.array(v, dtype=np.float64)

    def approaching(self, sim) -> int:
        return self.chain.count_live()

    def is_frozen(self, sim) -> bool:
        return self.approaching(sim) == 0


def check_device(sim) -> None:
    """A `FieldError` unless ``sim`` can run on a GPU: float arithmetic and the counter stream (other schedulers
    and arithmetics run on the CPU), numba-cuda installed, the rule's functions compiled for the GPU with the
    CPU's rounding (`gpu.compile.check_rule`: any rule, a user's too), and a GPU."""
    from .gpu import importable, load
    from .gpu.compile import check_rule

    if sim.arithmetic != "float":
        raise FieldError("device", f"'cuda' runs float arithmetic; {sim.arithmetic} arithmetic runs on the CPU")
    if not sim._selector.counter:
        raise FieldError("device", f"'cuda' runs UniformRandomPair(stream='counter') (the pick of step s a function "
                                   f"of the seed and s); {sim.scheduler!r} runs on the CPU")
    importable()  # numba-cuda, or one line saying it is missing
    check_rule(sim.rule, sim._collide, sim.geometry.dim, bool(sim.geometry.contacts.flat))
    load()  # a GPU, or one line saying there is none
