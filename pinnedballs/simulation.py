"""`Simulation`: owns the velocities, the counters and the random stream; `RunState`: all of
it that changes during a run, as one record."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .engine import checks
from .engine.chain import COLLISIONS, LIVE, NO_LIMIT, STEPS, Chain, LiveSet, incidence
from .engine.driver import Stop, check_writers, drive
from .engine.errors import FieldError, FieldTypeError, check_jitted
from .engine.exact import BLOCK as EXACT_BLOCK
from .engine.exact import ExactChain
from .engine.fields import NotExact
from .engine.limits import check_speeds
from .engine.loops import FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT, LOOKAHEAD_BYTES, live_kernel, loops

#: collisions a logging loop records before handing them to the listeners
LOG_CAPACITY = 1 << 16
_NO_LOG = np.empty((0, 2), dtype=np.int64)
from .engine.random import seed_state
from .geometry.base import Geometry
from .rules import CollisionRule, Elastic, threshold
from .schedulers.base import Scheduler
from .schedulers.simple import UniformRandomPair

__all__ = ["Simulation", "RunState", "mass_array"]


@dataclass(frozen=True, eq=False)
class RunState:
    """Everything that changes during a run: enough to resume it bit for bit.

    velocities ``(n_balls, dim) float64``; steps and collisions so far; rng_state ``(4,) uint64``,
    the random stream; scheduler_state ``(L,) int64``, the scheduler's own state; exact: for a
    run in exact arithmetic, the exact velocities as ``(n_balls, dim, m)`` strings, each velocity
    component's coefficients on its number field's basis (``velocities`` are then their roundings).
    """

    velocities: np.ndarray
    steps: int
    collisions: int
    rng_state: np.ndarray
    scheduler_state: np.ndarray
    exact: np.ndarray | None = None

    #: the arrays among the fields (the rest are counts)
    ARRAYS = ("velocities", "rng_state", "scheduler_state")

    def copy(self) -> "RunState":
        """A copy whose arrays share no memory with this one's."""
        return RunState(self.velocities.copy(), self.steps, self.collisions, self.rng_state.copy(),
                        self.scheduler_state.copy(), None if self.exact is None else self.exact.copy())

    def replace(self, **changes) -> "RunState":
        """This state with the fields named in ``changes`` replaced."""
        return dataclasses.replace(self, **changes)

    def identical(self, other: "RunState") -> bool:
        """True when ``other`` is this state bit for bit (every array, dtype and count)."""
        same_exact = (self.exact is None) == (other.exact is None) and (
            self.exact is None or np.array_equal(self.exact, other.exact))
        return (self.steps, self.collisions) == (other.steps, other.collisions) and same_exact and all(
            getattr(self, name).dtype == getattr(other, name).dtype
            and np.array_equal(getattr(self, name), getattr(other, name)) for name in self.ARRAYS)


def mass_array(masses, n_balls: int) -> np.ndarray:
    """``(n_balls,)`` masses from None (all 1), one number, or an array; each finite and > 0."""
    if masses is None:
        return np.ones(n_balls)
    try:
        m = np.array(masses, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("masses", f"must be an array of numbers ({exc})") from None
    if m.ndim == 0:
        m = np.full(n_balls, float(m))
    if m.shape != (n_balls,):
        raise FieldError("masses", f"must have shape (n_balls,) = ({n_balls},), got {m.shape}")
    if not (np.isfinite(m).all() and (m > 0).all()):
        raise FieldError("masses", "must all be finite and > 0")
    return m


def _count(name: str, value) -> int:
    """A count in ``[0, 2**63 - 1]`` (the loop's counters are int64)."""
    return checks.integer(name, value, 0, NO_LIMIT)


def _sparse_copy(v: np.ndarray) -> np.ndarray:
    """A C-ordered copy of ``v`` that writes only the rows with a nonzero bit.

    Rows never written stay on the operating system's shared zero page until a
    collision writes them: a large lattice with one moving ball (the paper's
    set-up) then reads velocities from cache instead of memory.
    """
    out = np.zeros(v.shape, dtype=np.float64)
    rows = np.flatnonzero(v.view(np.uint64).any(axis=1))
    out[rows] = v[rows]
    return out


class Simulation:
    """Pinned billiard balls on ``geometry``, run by ``scheduler`` under ``rule``.

    velocities: ``(n_balls, dim)`` initial pseudo-velocities (copied).
    masses: ``(n_balls,)`` positive masses, or None for all equal.
    seed: int or ``numpy.random.SeedSequence``; seeds the simulation's one random stream.
    A contact collides only if its closing speed exceeds ``threshold`` (`pinnedballs.rules.threshold`,
    about 4 units in the last place of the largest speed the velocities given can give a ball):
    closing speeds below it are rounding remnants, which exact arithmetic shows are no approach.

    arithmetic: ``"float"`` (float64, the compiled loop) or ``"exact"``: the same chain, the same
    picks from the same stream, with every velocity exact in the number field of the contact
    normals (`pinnedballs.engine.exact`; ``velocities`` are then the exact values rounded, and
    `exact_velocities` the values themselves). Exact runs need normals in a known field (the
    triangular lattices: Q(sqrt 3); FCC: Q(sqrt 2); HCP: Q(sqrt 2, sqrt 3); chains: Q), the
    built-in rules, and a scheduler that picks without a live set.

    Each step the scheduler picks a contact; if its balls approach, the rule
    collides them. ``steps`` counts picks, ``collisions`` the picks that changed
    velocities. Same inputs and seed give bit-identical velocities and counters,
    however the run is split into calls.

    The engine's loops (`pinnedballs.engine.loops`) run the scheduler's selector on plain data
    the simulation owns: the velocities, the counters, the random stream, the scheduler's state
    and, for a selector that tracks them, the live contacts (`engine.chain.LiveSet`).
    """

    def __init__(self, geometry: Geometry, velocities, rule: CollisionRule | None = None,
                 scheduler: Scheduler | None = None, masses=None, seed=0, arithmetic: str = "float"):
        if not isinstance(geometry, Geometry):
            raise FieldTypeError("geometry", f"must be a pinnedballs Geometry, got {type(geometry).__name__}")
        rule = Elastic() if rule is None else rule
        scheduler = UniformRandomPair() if scheduler is None else scheduler
        if not isinstance(rule, CollisionRule):
            raise FieldTypeError("rule", f"must be a CollisionRule such as Elastic(), got {type(rule).__name__}")
        if not isinstance(scheduler, Scheduler):
            raise FieldTypeError("scheduler", f"must be a Scheduler such as UniformRandomPair(), "
                                              f"got {type(scheduler).__name__}")
        if geometry.n_contacts == 0:
            raise FieldError("geometry", "has no contacts, so nothing can ever collide")
        self.geometry, self.rule, self.scheduler = geometry, rule, scheduler
        self._mass_array = mass_array(masses, geometry.n_balls)
        self.masses = None if masses is None else self._mass_array
        self.velocities = self._check_velocities(velocities)
        self._collide, params = rule.kernel(bool(np.all(self._mass_array == self._mass_array[0])))
        self.threshold = threshold(self.velocities, self._mass_array)
        self._params = np.append(np.asarray(params, dtype=np.float64), self.threshold)  # params[-1]: `approaching`
        check_jitted(self._collide, "rule", f"{type(rule).__name__}.kernel()'s collide")
        self._selector = _selector(scheduler, geometry)
        s, dim, flat = self._selector, geometry.dim, geometry.contacts.flat
        self._loops = loops(self._collide, s.select, s.begin, s.changed, s.skips, dim, flat)
        self._own_steps = None if s.steps is None else s.steps(self._collide, dim, flat)
        self._live_flags, self._any_live = live_kernel(self._collide, dim, flat)
        self._sched_state = scheduler.initial_state(geometry.n_contacts)
        self._rng = seed_state(seed)
        self._counters = np.zeros(3, dtype=np.int64)
        self._live = None  # the LiveSet, built when a tracked run first needs it
        #: callables ``listener(steps (C,) int64, contacts (C,) int64)`` told of every collision, in
        #: order, in batches (`pinnedballs.run.collision_log.CollisionLog` is one); the loops that
        #: record them run a little slower
        self.collision_listeners: list = []
        self.arithmetic = checks.choice("arithmetic", arithmetic, ("float", "exact"))
        self._exact = _exact_chain(self) if self.arithmetic == "exact" else None
        if self._exact is not None:
            self.velocities = self._exact.shadow  # the exact values rounded, kept by the exact chain

    # ------------------------------------------------------------ input checks
    def _check_velocities(self, velocities) -> np.ndarray:
        g = self.geometry
        try:
            v = np.array(velocities, dtype=np.float64, order="C")
        except (TypeError, ValueError) as exc:
            raise FieldTypeError("velocities", f"must be an array of numbers ({exc})") from None
        if v.shape != (g.n_balls, g.dim):
            raise FieldError("velocities", f"must have shape (n_balls, dim) = {(g.n_balls, g.dim)}, got {v.shape}")
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if len(bad):
            raise FieldError("velocities", f"ball {bad[0]} has a NaN or infinite component ({len(bad)} ball(s) in all)")
        check_speeds(v, self._mass_array, "velocities")  # no collision can overflow float64
        return _sparse_copy(v)

    # ------------------------------------------------------------ counters
    @property
    def steps(self) -> int:
        """Contacts tried so far."""
        return int(self._counters[STEPS])

    @property
    def collisions(self) -> int:
        """Contacts tried so far that changed velocities."""
        return int(self._counters[COLLISIONS])

    # ------------------------------------------------------------ running
    def run(self, steps: int | None = None, collisions: int | None = None, *, until_frozen: bool = False,
            writers=None, progress: bool | None = None) -> int:
        """Pick ``steps`` more contacts, or run until ``collisions`` in total, whichever comes first.

        With ``until_frozen`` (implied when only ``collisions`` is given, which a frozen
        system could never reach) the run also stops right after the collision that
        leaves no live contact (see `approaching`). Returns the number of steps taken.
        ``writers`` (e.g. `ResultsWriter`) record the run, to the same final state.

        The run goes in chunks of about 0.2 s (`pinnedballs.engine.driver`), which change no bit.
        Ctrl-C stops it at the end of its chunk with KeyboardInterrupt, the simulation whole:
        continuing it gives the bits of a run never interrupted. ``progress``: a bar over the
        steps (the collisions for a collision target; a count when running until frozen):
        True shows it, False never, None where it helps (in a terminal or a notebook, once the run
        has taken 2 s; `pinnedballs.engine.progress`).
        """
        if steps is None and collisions is None:
            raise FieldError("run", "give steps= or collisions= (or use run_until_frozen)")
        if steps is not None:
            _count("steps", steps)
        if collisions is not None:
            _count("collisions", collisions)
        start = self.steps
        stop = Stop(steps=None if steps is None else min(start + steps, NO_LIMIT), collisions=collisions,
                    until_frozen=until_frozen or steps is None)
        drive(self, stop, check_writers(writers or ()), progress=progress)
        return self.steps - start

    def run_until_frozen(self, max_steps: int, *, writers=None, progress: bool | None = None) -> bool:
        """Run until no contact approaches, for at most ``max_steps`` more steps.

        Stops right after the collision that freezes the system, so ``steps`` is the
        exact step of the last collision. Returns True if frozen. Ctrl-C, ``writers`` and
        ``progress`` as for `run` (the progress is a count of steps and collisions: the end is unknown).
        """
        stop = Stop(steps=min(self.steps + _count("max_steps", max_steps), NO_LIMIT), until_frozen=True)
        return drive(self, stop, check_writers(writers or ()), progress=progress) == "frozen"

    def _run(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        """The engine's loop for these limits (see `pinnedballs.engine.loops`); the steps taken."""
        max_steps = min(max_steps, NO_LIMIT - self.steps)  # the step counter never wraps
        if self._exact is not None:
            return self._run_exact(max_steps, max_collisions, until_frozen)
        if self.collision_listeners:
            return self._run_logged(max_steps, max_collisions, until_frozen)
        chain, s, loops_ = self._chain(), self._selector, self._loops
        tables = (self._sched_state, s.aux, self._rng, self._counters)
        if s.tracks:
            return loops_.tracked(*chain, *tables, max_steps, max_collisions, until_frozen, *self._refresh_live(),
                                  _NO_LOG)
        large = chain.pairs.nbytes + chain.ends.nbytes + chain.v.nbytes > LOOKAHEAD_BYTES and not s.skips
        if not until_frozen and max_collisions == NO_LIMIT:
            plain = self._own_steps or (loops_.steps_prefetched if large else loops_.steps)
            return plain(*chain, *tables, max_steps)
        chunk = max(FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT * self.geometry.n_contacts)
        limited = loops_.limited_prefetched if large else loops_.limited
        return limited(*chain, *tables, max_steps, max_collisions, until_frozen, chunk, np.empty_like(self._sched_state),
                       _NO_LOG)

    def _run_logged(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        """`_run` telling `collision_listeners` of every collision: the engine's logging loops
        (sequential: the same bits as the others), a log of `LOG_CAPACITY` collisions at a time."""
        chain, s, loops_ = self._chain(), self._selector, self._loops
        tables = (self._sched_state, s.aux, self._rng, self._counters)
        log, taken = np.empty((LOG_CAPACITY, 2), dtype=np.int64), 0
        while True:
            before = self.collisions
            if s.tracks:
                taken += loops_.tracked_logged(*chain, *tables, max_steps - taken, max_collisions, until_frozen,
                                               *self._refresh_live(), log)
            else:
                large = chain.pairs.nbytes + chain.ends.nbytes + chain.v.nbytes > LOOKAHEAD_BYTES and not s.skips
                limited = loops_.limited_prefetched_logged if large else loops_.limited_logged
                chunk = max(FREEZE_CHUNK_MIN, FREEZE_CHUNK_PER_CONTACT * self.geometry.n_contacts)
                taken += limited(*chain, *tables, max_steps - taken, max_collisions, until_frozen, chunk,
                                 np.empty_like(self._sched_state), log)
            made = self.collisions - before
            if made:
                for listener in self.collision_listeners:
                    listener(log[:made, 0].copy(), log[:made, 1].copy())
            if made < len(log) or taken >= max_steps or self.collisions >= max_collisions:
                return taken

    def _run_exact(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        """`_run` in exact arithmetic: the compiled selector's picks in blocks, each tried exactly
        (`ExactChain.run`); a block cut short is drawn again to its end, so the stream and the
        scheduler's state are those of the float loop after the same steps."""
        ex, s, n = self._exact, self._selector, self.geometry.n_contacts
        if ex.flags is None:
            ex.count_live()
        taken, collisions = 0, self.collisions
        while taken < max_steps and collisions < max_collisions and not (until_frozen and ex.live == 0):
            block = int(min(EXACT_BLOCK, max_steps - taken))
            rng, state = self._rng.copy(), self._sched_state.copy()
            picks = np.empty(block, dtype=np.int64)
            self._loops.picks(self._sched_state, s.aux, self._rng, n, picks)
            used, made, at = ex.run(picks.tolist(), max_collisions - collisions, until_frozen)
            if made and self.collision_listeners:
                steps = self.steps + taken + 1 + np.asarray(at, dtype=np.int64)
                contacts = picks[np.asarray(at, dtype=np.int64)]
                for listener in self.collision_listeners:
                    listener(steps, contacts)
            if used < block:
                self._rng[:], self._sched_state[:] = rng, state
                self._loops.picks(self._sched_state, s.aux, self._rng, n, np.empty(used, dtype=np.int64))
            taken, collisions = taken + used, collisions + made
        ex.sync()
        self._counters[STEPS] += taken
        self._counters[COLLISIONS], self._counters[LIVE] = collisions, ex.live
        return taken

    def _chain(self) -> Chain:
        c = self.geometry.contacts
        return Chain(self.velocities, c.pairs, c.ends, c.units, self._mass_array, self._params)

    def _refresh_live(self) -> LiveSet:
        """The live set of the current velocities (flags and ``counters[LIVE]`` recomputed)."""
        if self._live is None:
            c = self.geometry.contacts
            ptr, inc = incidence(c.pairs, self.geometry.n_balls)
            self._live = LiveSet(ptr, inc, np.empty(len(c), dtype=np.uint8))
        self._counters[LIVE] = self._live_flags(*self._chain(), self._live.flags)
        return self._live

    # ------------------------------------------------------------ observables
    def approaching(self) -> int:
        """Number of live contacts: those whose balls approach, so that picking one would
        collide (0 means frozen). In float arithmetic a closing speed so small that the collision
        would change no bit of any velocity, a remnant of rounding, does not count."""
        if self._exact is not None:
            return self._exact.count_live()
        flags = np.empty(self.geometry.n_contacts, dtype=np.uint8)
        return int(self._live_flags(*self._chain(), flags))

    def is_frozen(self) -> bool:
        """True when no contact is live, so no collision can ever happen again."""
        if self._exact is not None:
            return self.approaching() == 0
        return not self._any_live(*self._chain())

    @property
    def exact_velocities(self) -> np.ndarray | None:
        """``(n_balls, dim)`` exact velocities (`pinnedballs.engine.fields.Exact` numbers) of a run in
        exact arithmetic; None in float arithmetic."""
        if self._exact is None:
            return None
        return self._exact.numbers()

    def energy(self) -> float:
        """Kinetic energy ``sum m |v|^2 / 2``."""
        return float(0.5 * np.dot(self._mass_array, np.einsum("ij,ij->i", self.velocities, self.velocities)))

    def momentum(self) -> np.ndarray:
        """``(dim,)`` total momentum ``sum m v`` (meaningful in flat space)."""
        return self._mass_array @ self.velocities

    # ------------------------------------------------------------ state for checkpoints
    def get_state(self) -> RunState:
        """Everything that changes during a run, as copies: enough to resume bit for bit."""
        exact = None if self._exact is None else self._exact.coefficients()
        return RunState(self.velocities.copy(), self.steps, self.collisions, self._rng.copy(),
                        self._sched_state.copy(), exact)

    def set_state(self, state: RunState) -> None:
        """Restore a state from `get_state` (of a simulation with the same geometry, rule and
        scheduler). Everything is checked before anything changes."""
        velocities = self._check_velocities(state.velocities)
        rng = np.asarray(state.rng_state)
        if rng.shape != (4,) or rng.dtype != np.uint64 or not rng.any():
            raise FieldError("rng_state", f"must be 4 uint64 words, not all zero, got {rng.dtype} {rng.shape}")
        sched = np.asarray(state.scheduler_state)
        if sched.dtype != np.int64:
            raise FieldError("scheduler_state", f"must be int64, got {sched.dtype}")
        self.scheduler.check_state(sched, self.geometry.n_contacts)
        flags = None
        if self._selector.tracks:
            flags = np.empty(self.geometry.n_contacts, dtype=np.uint8)
            self._live_flags(*self._chain()._replace(v=velocities), flags)
        self.scheduler.check_resume(sched, self._selector, flags)
        steps, collisions = _count("steps", state.steps), _count("collisions", state.collisions)
        if collisions > steps:
            raise FieldError("collisions", f"{collisions} is more than the {steps} steps taken")
        exact = self._exact_state(state, velocities)
        if exact is not None:
            self._exact.set_velocities(exact)
        else:
            self.velocities = velocities
        self._rng = rng.copy()
        self._sched_state = sched.copy()
        self._counters[STEPS], self._counters[COLLISIONS] = steps, collisions

    def _exact_state(self, state: RunState, velocities: np.ndarray) -> list | None:
        """The exact velocities of ``state`` for an exact simulation (None for a float one), checked:
        they parse in this geometry's field and round to ``velocities``."""
        if self._exact is None:
            return None
        if state.exact is None:
            raise FieldError("exact", "a simulation in exact arithmetic resumes only from an exact state "
                                      "(this one holds float velocities only)")
        shape = (*velocities.shape, self._exact.field.m)
        if np.shape(state.exact) != shape:
            raise FieldError("exact", f"must have shape (n_balls, dim, m) = {shape} in {self._exact.field}, "
                                      f"got {np.shape(state.exact)}")
        try:
            exact = self._exact.parse(state.exact)
        except (ValueError, TypeError, ZeroDivisionError) as exc:
            raise FieldError("exact", f"a coefficient is not a rational number ({exc})") from None
        F = self._exact.field
        rounded = np.array([[F.to_float(x) for x in row] for row in exact])
        if not np.array_equal(rounded, velocities):
            raise FieldError("exact", "the exact velocities do not round to the state's velocities")
        return exact

    def __repr__(self) -> str:
        return (f"Simulation({self.geometry!r}, rule={self.rule!r}, scheduler={self.scheduler!r}, "
                f"steps={self.steps}, collisions={self.collisions})")


def _selector(scheduler: Scheduler, geometry: Geometry):
    """The scheduler's selector on ``geometry``; a clear error for a scheduler written for the loop
    protocol before the engine owned the loop (``loops()`` and ``advance()``)."""
    if any(hasattr(scheduler, name) for name in ("advance", "loops")):
        raise FieldTypeError("scheduler", f"{type(scheduler).__name__} defines advance() or loops(), which the engine "
                                          f"no longer calls: give it kernel() (a pick) or selector() instead "
                                          f"(docs/extending.md)")
    return scheduler.selector(geometry)


def _exact_chain(sim: Simulation) -> ExactChain:
    """The `ExactChain` of ``sim``, or a `FieldError` on ``arithmetic`` saying why it cannot have one."""
    r = sim.rule.exact_restitution()
    if r is None:
        raise FieldError("arithmetic", f"exact arithmetic runs the built-in rules (Elastic, Restitution); "
                                       f"{sim.rule!r} has no exact form")
    if sim._selector.tracks:
        raise FieldError("arithmetic", f"exact arithmetic follows the picks of a scheduler that needs no live set; "
                                       f"{sim.scheduler!r} picks among live contacts in float arithmetic "
                                       f"(UniformRandomPair has the same law)")
    try:
        return ExactChain(sim.geometry, sim.velocities, sim._mass_array, r)
    except NotExact as exc:
        raise FieldError("arithmetic", f"exact arithmetic needs every contact normal in a known number field "
                                       f"(q*sqrt(d) components), and {type(sim.geometry).__name__}'s are not: "
                                       f"{exc}") from None
