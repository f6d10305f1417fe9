"""How a simulation's chain runs: the backends the engines build (`engine.builtin`; the door chooses, `engine.door`).

A backend takes the chain's plain data, its `Model` (what it is) and its `ChainState` (what changes,
written in place), and never the simulation itself. Every backend speaks the engine's chunk protocol, which
the run driver (`engine.driver`) calls: ``run(max_steps, max_collisions, until_frozen) -> steps taken``,
leaving the state as the compiled loop leaves it, however the run is split: the limits kept by
`engine.harness` (the compiled loops compile it; the others call it). Each also counts the live contacts
(``approaching``), says whether none is left (``is_frozen``), gives the velocities now (``velocities``) and
the live contacts of any velocities (``live_flags``).

* `LoopBackend`: floats on the CPU. The compiled loops; a scheduler's own loop for plain steps
  (`ColoredSweep`); the paper's picks on several threads, by regions on the xoshiro stream
  (`engine.threads.regions`) or by deterministic reservations on the counter stream (`engine.threads.reservations`);
  the logging loops when someone listens for collisions.
* `engine.field.backend.FieldBackend`: exact or certified arithmetic (`engine.field`), in the number field of
  the contact normals, on the same picks.
* `DeviceBackend`: floats on an NVIDIA GPU (`engine.gpu`), the counter stream's chain with the CPU's bits.
"""

from __future__ import annotations

import numpy as np

from ..util.errors import FieldError
from .chain import LIVE, NO_LIMIT, ChainState, LiveSet, Model, incidence
from .protocol import Backend
from .sequential.choice import described, loop_setting, new_tune
from .sequential.loops import FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT, NO_PATTERN, loops
from .sequential.sizes import LoopChoice
from .threads.regions import MIN_PARALLEL_CONTACTS, TUNED_SEGMENT, ParallelChain, bands_pay
from .threads.tuning import most_threads

__all__ = ["LoopBackend", "DeviceBackend", "LOG_CAPACITY"]

#: collisions a logging loop records before handing them to the listeners
LOG_CAPACITY = 1 << 16
_NO_LOG = np.empty((0, 2), dtype=np.int64)
#: the settings that force the table loop (`engine.sequential.choice.LOOP_SETTINGS`)
_TABLES = ("tables", "branch", "branch_free", "threshold")


class LoopBackend(Backend):
    """Floats on the CPU: the engine's compiled loops for one rule and one scheduler (module docstring); with
    ``parallel`` the paper's picks on several threads where they pay (the ``threads`` engine), with ``own_loop``
    the scheduler's own loop for plain steps (``colored_sweep``); neither: one core (``sequential``)."""

    def __init__(self, model: Model, state: ChainState, listeners: list | None = None, device=None, *,
                 parallel: bool = False, own_loop: bool = False):
        super().__init__(model, state, listeners, device)
        s, g = model.selector, model.geometry
        self.loops = loops(model.collide, s.select, s.begin, s.changed, s.skips, g.dim, g.contacts.flat)
        self.own_steps = None if s.steps is None or not own_loop else s.steps(model.collide, g.dim, g.contacts.flat)
        #: ``PINNEDBALLS_LOOP`` as it was when the chain was built (`engine.sequential.choice.loop_setting`)
        self.setting = loop_setting()
        #: how the table loop runs its blocks, and what it measured of them on this CPU (`choice.new_tune`)
        self.tune = new_tune(self.setting)
        c = g.contacts
        #: which limited loop runs this system (`engine.sequential.sizes.LoopChoice`): the tables where they fit in
        #: cache, the tables prefetched or the lattice's row pattern where they do not, and between, the faster of
        #: two timed on the run's own steps
        self._choice = LoopChoice(self.loops, s.skips, c.pairs.nbytes + c.ends.nbytes + state.velocities.nbytes,
                                  lambda: None if self.setting in _TABLES else g.row_pattern, self.setting)
        self._live = None  # the LiveSet, built when a tracked run first needs it
        self._parallel = None if parallel else False  # the threaded chain, built when a run first asks (False: none)
        self._parallel_loop = None  # ``(loop, pattern)`` the threaded chain's blocks are built for (`parallel_chain`)
        self._own_ran = False  # whether the scheduler's own loop (`own_steps`) has run

    def tables(self) -> tuple:
        """``(scheduler state, aux, rng, counters, margin)``: what every loop takes after the chain's arrays."""
        st = self.state
        return st.scheduler, self.model.selector.aux, st.rng, st.counters, st.margin

    def chain(self):
        return self.model.chain(self.state.velocities)

    # ------------------------------------------------------------ the protocol
    def _run(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        try:
            return self._loops(max_steps, max_collisions, until_frozen)
        except Exception as exc:  # raised inside a compiled loop (a user's pick): its velocities moved, counters not
            self.state.broken = f"it stopped between two states on {type(exc).__name__}: {exc}"
            raise

    def _loops(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        if self.listeners:
            return self._run_logged(max_steps, max_collisions, until_frozen)
        chain, s, tables = self.chain(), self.model.selector, self.tables()
        if s.tracks:
            return self.loops.tracked(*chain, *tables, max_steps, max_collisions, until_frozen, *self.refresh_live(),
                                      _NO_LOG)
        plain = not until_frozen and max_collisions == NO_LIMIT
        if plain and self.own_steps is not None:
            self._own_ran = True
            return self.own_steps(*chain, *tables, max_steps)
        parallel = self.parallel_chain()
        if parallel is not None:  # its blocks read the pattern they were built for; its stretches on one
            limited, pattern = self._parallel_loop  # thread run the loop `choice` chooses
            return parallel.run(chain, pattern, limited, self._any_live, *tables, max_steps, max_collisions,
                                until_frozen, TUNED_SEGMENT if plain else self.freeze_chunk(), self.tune,
                                self._choice)
        saved = np.empty_like(self.state.scheduler)

        def call(limited, pattern, steps: int) -> int:
            return limited(*chain, pattern, *tables, steps, max_collisions, until_frozen,
                           steps if plain else self.freeze_chunk(), saved, _NO_LOG, self.tune)

        return self.choice().run(call, max_steps)

    def approaching(self) -> int:
        flags = np.empty(self.model.geometry.n_contacts, dtype=np.uint8)
        return int(self._live_flags(*self.chain(), flags))

    def resources(self) -> dict:
        """``{"kind": "cpu", "threads": k}``: the threads of the threaded chain or of the scheduler's own loop
        where one has run (else 1); where a `ThreadTuner` chose the count, the count it ran most on, and
        ``"tuned"``: ``{count: share of the work}`` (`ThreadTuner.shares`); ``"loop"``: which limited loop ran and
        what chose it (`sizes.LoopChoice.described`), and where the table loop ran, how its blocks were chosen and
        the share of its picks run without a branch (`choice.described`); ``"setting"``: ``PINNEDBALLS_LOOP`` where
        it forced a choice."""
        threads, tuner = 1, None
        if self._parallel:  # built by a run, and run by it: on its threads, or as its tuner chose
            threads, tuner = self._parallel.threads, self._parallel.tuner
        elif self._own_ran:
            threads, tuner = self.model.threads or most_threads(), getattr(self.own_steps, "tuner", None)
        shares = tuner.shares() if tuner is not None else {}
        said = {"kind": "cpu", "threads": threads}
        if shares:
            said = {"kind": "cpu", "threads": max(shares, key=shares.get),
                    "tuned": {str(count): share for count, share in shares.items()}}
        loop = {**(self._choice.described() if self._choice.ran else {}), **described(self.tune)}
        if loop:
            said["loop"] = loop
        if self.setting != "auto":
            said["setting"] = f"PINNEDBALLS_LOOP={self.setting}"
        return said

    # ------------------------------------------------------------ the loops
    def parallel_chain(self):
        """The chain on several threads where the scheduler allows it and it pays, built once; else None:
        on the xoshiro stream the regions of `engine.threads.regions` (a large system, regions with few
        crossings, narrow bands around the cuts: not a torus), on the counter stream the reservations of
        `engine.threads.reservations`."""
        if self._parallel is None:
            self._parallel = False
            m, s = self.model, self.model.selector
            g, c = m.geometry, m.geometry.contacts
            threads = most_threads() if m.threads is None else m.threads
            # built for the loop chosen now (``rows``: the blocks decode contacts from its pattern), kept for the
            # chain's life: `choice` may later prefer a loop reading no pattern
            self._parallel_loop = self.limited(logged=False)
            rows = self._parallel_loop[1] is not NO_PATTERN
            if threads > 1 and len(c) >= MIN_PARALLEL_CONTACTS and not s.tracks:
                built = None
                if s.uniform and bands_pay(c.pairs, g.n_balls, threads):
                    built = ParallelChain.build(m.collide, g.dim, c.flat, c.pairs, g.n_balls, rows, threads,
                                                tuned=m.threads is None)
                elif s.counter:
                    from .threads.reservations import ReservationChain

                    built = ReservationChain.build(m.collide, g.dim, c.flat, c.pairs, g.n_balls, rows, threads,
                                                   tuned=m.threads is None)
                self._parallel = built if built is not None else False
        return self._parallel or None

    def choice(self) -> LoopChoice:
        """Which limited loop runs this system (`engine.sequential.sizes.LoopChoice`)."""
        return self._choice

    def limited(self, logged: bool):
        """``(loop, pattern)``: the limited loop running this system now (`choice`), and the row pattern it reads
        (`engine.rows`)."""
        choice = self.choice()
        return choice.loop(choice.name, logged)

    def freeze_chunk(self) -> int:
        """Steps between two scans for the freeze in an untracked loop (`engine.sequential.loops`)."""
        return max(FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT * self.model.geometry.n_contacts)

    def refresh_live(self) -> LiveSet:
        """The live set of the current velocities (flags and ``counters[LIVE]`` recomputed)."""
        if self._live is None:
            g = self.model.geometry
            ptr, inc = incidence(g.contacts.pairs, g.n_balls)
            self._live = LiveSet(ptr, inc, np.empty(g.n_contacts, dtype=np.uint8))
        self.state.counters[LIVE] = self._live_flags(*self.chain(), self._live.flags)
        return self._live

    def _run_logged(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        """`run` telling the listeners of every collision: the engine's logging loops (sequential: the same
        bits as the others), a log of `LOG_CAPACITY` collisions at a time."""
        chain, s, loops_, tables, st = self.chain(), self.model.selector, self.loops, self.tables(), self.state
        log, taken = np.empty((LOG_CAPACITY, 2), dtype=np.int64), 0
        while True:
            before = st.collisions
            if s.tracks:
                taken += loops_.tracked_logged(*chain, *tables, max_steps - taken, max_collisions, until_frozen,
                                               *self.refresh_live(), log)
            else:
                limited, pattern = self.limited(logged=True)
                taken += limited(*chain, pattern, *tables, max_steps - taken, max_collisions, until_frozen,
                                 self.freeze_chunk(), np.empty_like(st.scheduler), log, self.tune)
            made = st.collisions - before
            if made:
                self.tell(log[:made, 0].copy(), log[:made, 1].copy())
            if made < len(log) or taken >= max_steps or st.collisions >= max_collisions:
                return taken


class DeviceBackend(Backend):
    """Floats on an NVIDIA GPU (`engine.gpu.chain.DeviceChain`): the counter stream's chain by deterministic
    reservations, with the CPU loop's bits. The velocities live on the GPU; reading them copies them
    back once after each run (then they are kept until the next run or `set_velocities`)."""

    def __init__(self, model: Model, state: ChainState, listeners: list | None = None, device=None, **options):
        super().__init__(model, state, listeners, device)
        from .gpu.chain import DeviceChain

        g = model.geometry
        pattern = g.row_pattern if g.row_shape() is not None else None
        self.chain = DeviceChain(state.velocities, g.contacts, pattern, model.masses, model.params, model.collide,
                                 state.rng[:2], **options)
        self._host = state.velocities  # the velocities as last read (None: the GPU's have moved on)

    def _run(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        if self.listeners:
            raise FieldError("device", "the collision log runs on the CPU: build the simulation with device='cpu' "
                                       "(the same bits on the counter stream)")
        st = self.state
        taken = self.chain.run(st.counters, st.rng, st.margin, max_steps, max_collisions, until_frozen)
        if taken:
            self._host = None
        return taken

    def velocities(self) -> np.ndarray:
        if self._host is None:
            self._host = self.chain.velocities()
        return self._host

    def set_velocities(self, velocities: np.ndarray) -> None:
        self.chain.set_velocities(velocities)
        self._host = self.state.velocities = np.array(velocities, dtype=np.float64)

    def approaching(self) -> int:
        return self.chain.count_live()

    def is_frozen(self) -> bool:
        return self.approaching() == 0

    def resources(self) -> dict:
        """``{"kind": "cuda", "gpu": its name, "compute_capability": ...}`` (`engine.gpu.describe`)."""
        from .gpu import describe

        return {"kind": "cuda", **describe()}
