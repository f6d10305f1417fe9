"""`Simulation`: balls on a geometry, run by a scheduler under a rule; owns the velocities, the counters
and the random stream. The one object every user meets: it stands on the geometry it is built on and the
engine's door (`engine.door`), which chooses and builds what runs its chain, and below what builds, records
and studies it (specs, results, analysis, run). (`RunState`, all of it that changes during a run as one
record, lives in `engine.state`; its name is imported here too.)"""

from __future__ import annotations

import warnings

import numpy as np

from .engine.chain import COLLISIONS, COUNTERS, NO_LIMIT, STEPS, ChainState, Model
from .engine.devices import Device, as_device
from .engine.door import choose, options
from .engine.driver import check_writers, drive
from .engine.margin import ClosingMargin, MarginWarning, new_margin
from .engine.protocol import Backend
from .engine.state import RunState, margin_problem, mass_array
from .engine.stop import Stop
from .engine.streams.philox import counter_stream
from .engine.streams.xoshiro import seed_state
from .geometry.base import Geometry
from .geometry.checks import check_contacts
from .geometry.pictures import display
from .rules import CollisionRule, Elastic, check_resolution, threshold
from .schedulers.base import Scheduler
from .schedulers.simple import UniformRandomPair
from .util import checks
from .util.errors import FieldError, FieldTypeError, check_jitted
from .util.limits import check_speeds
from .util.sigint import deferred
from .util.sums import kinetic_energy, momentum

__all__ = ["Simulation", "RunState", "mass_array", "check_velocities", "FreezeWarning"]


class FreezeWarning(UserWarning):
    """A run until frozen stopped at its step cap on a system that can never freeze (a torus: see
    `Simulation.run_until_frozen`)."""


def _recorded_seed(seed) -> int | np.random.SeedSequence:
    """The seed a simulation records (`Simulation.seed`): what repeats its stream, as an int when one does."""
    if seed is None:
        return np.random.SeedSequence().entropy  # fresh entropy, as numpy.random.default_rng() draws it
    seed = checks.seed("seed", seed)
    if isinstance(seed, np.random.SeedSequence) and isinstance(seed.entropy, int) and not seed.spawn_key \
            and seed.pool_size == _DEFAULT_POOL_SIZE:
        return seed.entropy  # SeedSequence(entropy) gives the same stream
    return seed


_DEFAULT_POOL_SIZE = np.random.SeedSequence(0).pool_size


def _count(name: str, value) -> int:
    """A count in ``[0, 2**63 - 1]`` (the loop's counters are int64)."""
    return checks.integer(name, value, 0, NO_LIMIT)


def _sparse_copy(v: np.ndarray) -> np.ndarray:
    """A C-ordered copy of ``v`` writing only the rows with a nonzero bit: rows never written stay on the
    operating system's shared zero page until a collision writes them, so a large lattice with one moving
    ball (the paper's set-up) reads velocities from cache instead of memory."""
    out = np.zeros(v.shape, dtype=np.float64)
    rows = np.flatnonzero(v.view(np.uint64).any(axis=1))
    out[rows] = v[rows]
    return out


def check_velocities(geometry: Geometry, masses: np.ndarray, velocities) -> np.ndarray:
    """``velocities`` for ``geometry`` as a simulation takes them: ``(n_balls, dim)`` finite float64s that no
    collision can carry past float64's range (with ``masses (n_balls,)``), copied (`_sparse_copy`); else a
    `FieldError` naming ``velocities`` and what is wrong."""
    g = geometry
    try:
        v = np.array(velocities, dtype=np.float64, order="C")
    except (TypeError, ValueError) as exc:
        raise FieldTypeError("velocities", f"must be an array of numbers ({exc})") from None
    if v.shape != (g.n_balls, g.dim):
        raise FieldError("velocities", f"must have shape (n_balls, dim) = {(g.n_balls, g.dim)}, got {v.shape}")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if len(bad):
        raise FieldError("velocities", f"ball {bad[0]} has a NaN or infinite component ({len(bad)} ball(s) in all)")
    check_speeds(v, masses, "velocities")  # no collision can overflow float64
    return _sparse_copy(v)


class Simulation:
    """Pinned billiard balls on ``geometry``, run by ``scheduler`` under ``rule``.

    Each step the scheduler picks a contact; if its balls approach, the rule collides them. `steps` counts
    picks, `collisions` the picks that changed velocities. Same inputs and seed give bit-identical
    velocities and counters, however the run is split into calls.

    Parameters
    ----------
    geometry : Geometry
        Where the balls sit and which of them touch.
    velocities : array_like
        ``(n_balls, dim)`` initial pseudo-velocities (copied).
    rule : CollisionRule, optional
        What a collision does; `Elastic` by default.
    scheduler : Scheduler, optional
        Which contact is tried next; `UniformRandomPair` by default.
    masses : array_like or float, optional
        ``(n_balls,)`` positive masses (one number: all alike), or None for all equal.
    seed : int or numpy.random.SeedSequence, optional
        Seeds the one random stream. As in numpy, None (the default) draws fresh entropy from the operating
        system, so two simulations made alike without a seed are independent; `seed` records it (an int).
    arithmetic : {"float", "exact", "certified"}
        ``"float"``: float64, the compiled loop. ``"exact"``: the same chain and picks, every velocity exact
        in the number field of the contact normals (`velocities` its values rounded, `exact_velocities` the
        values); ``"certified"``: fixed point at ``precision`` bits, every decision proved equal to exact
        arithmetic's, so the counts and steps are exact (`error_bound`). What each needs and what it costs:
        docs/collisions.md.
    resolution : float, optional
        The criterion's ``e`` in (0, 1): a contact collides only if its closing speed exceeds ``threshold =
        e V`` (`pinnedballs.rules.threshold`, ``V`` the largest speed the velocities given can give a ball of
        the mean mass). None: ``4 * 2^-53`` (4 units in the last place of ``V``), which sets aside rounding
        remnants, which exact arithmetic shows are no approach; another ``e`` is a model of its own (counts
        ``N_e``). `closing_margin` says how near the threshold the picks came; a float run at the default
        that ends frozen with a thin margin says so once (`engine.margin.MarginWarning`).
    precision : int, optional
        Certified arithmetic's bits per coefficient (default 768).
    late_precision : int, optional
        Certified arithmetic's bits (at most ``precision``; None: none) once the first wave has passed (no
        ball at rest, hardly any still exact), at a step that depends on the state alone; behind the wave
        the paper's half-plane runs about twice as fast at 256 bits (docs/collisions.md).
    device : Device or {"cpu", "cuda"}
        ``pb.CPU()`` (or ``"cpu"``, the default) or ``pb.CUDA()`` (``"cuda"``): an NVIDIA GPU (``python3 -m
        pip install ".[cuda]"``) runs float arithmetic with any rule, a user's too, and certified arithmetic,
        on ``UniformRandomPair(stream="counter")``, with the CPU's bits (docs/gpu.md). Its state stays on
        the GPU between runs; reading `velocities` copies them back.
    engine : str, optional
        A registered engine's name (`pinnedballs.engine.engines()`) to force; None: the door chooses, by the
        arithmetic and the device, what runs the chain (plain data: `engine`).

    Attributes
    ----------
    seed : int or numpy.random.SeedSequence
        The seed used (the entropy drawn when none was given).
    resolution, threshold : float
        The criterion's ``e`` and ``e V``.
    engine_name : str
        The registered engine running the chain.
    collision_listeners : list
        Told of every collision (`pinnedballs.CollisionLog` is one).

    Raises
    ------
    FieldError
        On the argument that is wrong (a `FieldTypeError` for one of another type, a scheduler of the old loop
        protocol too), as ``geometry`` without sound contacts or ``velocities`` of another shape, not finite
        or too fast for float64 (docs/model.md).
    pinnedballs.engine.Refused
        Where no engine runs the chain in this arithmetic on this device.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> g = pb.HalfPlane(rows=4, cols=6)
    >>> v = np.zeros((g.n_balls, 2))
    >>> v[g.boundary_center()] = [0.0, 1.0]
    >>> sim = pb.Simulation(g, v, seed=1)
    >>> sim.run_until_frozen(max_steps=100_000), sim.steps, sim.collisions, round(sim.energy(), 12)
    (True, 556, 50, 0.5)
    """

    def __init__(self, geometry: Geometry, velocities, rule: CollisionRule | None = None,
                 scheduler: Scheduler | None = None, masses=None, seed=None, arithmetic: str = "float",
                 resolution: float | None = None, precision: int | None = None, late_precision: int | None = None,
                 device: str | Device = "cpu", engine: str | None = None):
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
        with deferred():  # compiles the check on a first call: a Ctrl-C waits for numba (see `util.sigint`)
            check_contacts(geometry)  # indices in range, unit vectors, directions: the loops trust them
        self.geometry, self.rule, self.scheduler = geometry, rule, scheduler
        self._masses = mass_array(masses, geometry.n_balls)
        self.masses = None if masses is None else self._masses
        v = check_velocities(geometry, self._masses, velocities)
        collide, params = rule.kernel(bool(np.all(self._masses == self._masses[0])))
        #: the collision criterion's resolution ``e``: a pick collides when its closing speed exceeds ``e V``
        self.resolution = check_resolution(resolution)
        self._default_resolution = resolution is None  # a chosen resolution is the model: no warning
        self.threshold = threshold(v, self._masses, self.resolution)
        check_jitted(collide, "rule", f"{type(rule).__name__}.kernel()'s collide")
        selector = _selector(scheduler, geometry)
        #: the seed used: the int given, the entropy drawn when none was (an int), or the SeedSequence
        #: given when its entropy alone would not repeat it (a spawned one); ``Simulation(..., seed=sim.seed)``
        #: repeats the run
        self.seed = _recorded_seed(seed)
        rng = seed_state(self.seed)
        if selector.counter:  # the counter stream: its key, and no pick drawn yet
            rng = counter_stream(rng)
        #: whether a float run that ends frozen with a thin closing margin says so, once (`warn_if_thin`);
        #: an ensemble says it once for all its replicas instead
        self.warns_thin_margin = True
        #: callables ``listener(steps (C,) int64, contacts (C,) int64)`` told of every collision, in
        #: order, in batches (`pinnedballs.run.collision_log.CollisionLog` is one); the loops that
        #: record them run a little slower
        self.collision_listeners: list = []
        given = options(arithmetic, precision, late_precision)  # checked
        self.arithmetic = given["arithmetic"]
        #: where the chain runs: a `pinnedballs.CPU` or `pinnedballs.CUDA` (given as one, or as "cpu" or "cuda");
        #: information about a run, not part of its model (the same bits on either)
        self.device = as_device(device)
        threads = getattr(scheduler, "threads", None)
        model = Model(geometry, self._masses, collide,
                      np.append(np.asarray(params, dtype=np.float64), self.threshold),  # params[-1]: the threshold
                      selector, getattr(self.device, "threads", None) if threads is None else threads, rule, scheduler)
        state = ChainState(v, np.zeros(COUNTERS, dtype=np.int64), rng, scheduler.initial_state(geometry.n_contacts),
                           new_margin())  # the margin: every pick's closing speed against the threshold
        chosen = choose(model, self.arithmetic, self.device, engine=engine)
        self._engine = chosen.build(model, state, self.collision_listeners, self.device, given)
        #: the registered engine running the chain (`pinnedballs.engine.engines()`), by name
        self.engine_name = chosen.name

    # ------------------------------------------------------------ the engine
    @property
    def engine(self) -> Backend:
        """What runs the chain (`pinnedballs.engine.backends`): its ``model`` and ``state`` (plain data,
        `engine.chain.Model` and `engine.chain.ChainState`), and the chunk protocol the run driver calls."""
        return self._engine

    @property
    def _field(self):
        """The chain of exact or certified arithmetic (None in float arithmetic)."""
        return self._engine.state.field_chain

    # ------------------------------------------------------------ state
    @property
    def velocities(self) -> np.ndarray:
        """``(n_balls, dim) float64``: the velocities now (in exact or certified arithmetic, the exact
        values rounded, brought up to date when read: a run in chunks rounds only once at its end)."""
        return self._engine.velocities()

    @velocities.setter
    def velocities(self, value: np.ndarray) -> None:
        self._engine.set_velocities(value)

    # ------------------------------------------------------------ counters
    @property
    def steps(self) -> int:
        """Contacts tried so far."""
        return self._engine.state.steps

    @property
    def collisions(self) -> int:
        """Contacts tried so far that changed velocities."""
        return self._engine.state.collisions

    # ------------------------------------------------------------ running
    def run(self, steps: int | None = None, collisions: int | None = None, *, until_frozen: bool = False,
            writers=None, progress: bool | None = None) -> int:
        """Pick ``steps`` more contacts, or run until ``collisions`` in total, whichever comes first.

        The run goes in chunks of about 0.2 s (`pinnedballs.engine.driver`), which change no bit.

        Parameters
        ----------
        steps, collisions : int, optional
            More steps; collisions in total (one of the two at least).
        until_frozen : bool
            Also stop right after the collision that leaves no live contact (see `approaching`); implied when
            only ``collisions`` is given, which a frozen system could never reach.
        writers : list of Writer, optional
            Record the run (e.g. `ResultsWriter`), to the same final state.
        progress : bool or None
            A bar over the steps (the collisions for a collision target; a count until frozen): True shows
            it, False never, None where it helps (in a terminal or a notebook, once the run has taken 2 s).

        Returns
        -------
        int
            The steps taken.

        Raises
        ------
        FieldError
            On ``run`` without ``steps`` or ``collisions``, or on a count out of range.
        KeyboardInterrupt
            On Ctrl-C, at the end of its chunk, the simulation whole: going on gives the bits of one run.
        pinnedballs.engine.field.fixed.UncertifiedDecision
            A decision certified arithmetic cannot prove (a ValueError).

        Examples
        --------
        >>> import pinnedballs as pb
        >>> sim = pb.Simulation(pb.HalfPlane(rows=2, cols=2), [[0, 1.0], [0, 0], [0, 0], [0, 0]], seed=0)
        >>> sim.run(collisions=1), sim.run(steps=10), sim.collisions, sim.is_frozen()
        (3, 10, 2, True)
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
        self.warn_if_thin(drive(self, stop, check_writers(writers or ()), progress=progress))
        return self.steps - start

    def run_until_frozen(self, max_steps: int, *, writers=None, progress: bool | None = None) -> bool:
        """Run until no contact approaches, for at most ``max_steps`` more steps.

        Stops right after the collision that freezes the system, so ``steps`` is the
        exact step of the last collision. Ctrl-C as for `run`.

        Parameters
        ----------
        max_steps : int
            The step cap.
        writers : list of Writer, optional
            As for `run`.
        progress : bool or None
            As for `run` (a count of steps and collisions: the end is unknown).

        Returns
        -------
        bool
            True if frozen; False at the step cap.

        Warns
        -----
        FreezeWarning
            One line, at the step cap, where the system can never freeze (a torus: `docs/model.md`).

        """
        stop = Stop(steps=min(self.steps + _count("max_steps", max_steps), NO_LIMIT), until_frozen=True)
        reason = drive(self, stop, check_writers(writers or ()), progress=progress)
        self.warn_if_thin(reason)
        frozen = reason == "frozen"
        why = None if frozen or not max_steps else self.never_freezes()  # 0 steps: a warm-up, nothing to say
        if why:
            warnings.warn(f"run_until_frozen: not frozen after {max_steps:,} steps, and never will be: {why}; "
                          "use run(steps=...)", FreezeWarning, stacklevel=_outside_the_package())
        return frozen

    def never_freezes(self) -> str | None:
        """Why this system, not frozen, can never freeze (docs/model.md: a torus never freezes).

        Its contacts all on closed rows (`Contacts.closed_rows`), frozen means every closing speed 0, while in
        exact arithmetic each collision leaves its contact separating (any ``r > 0``); in float64 at the
        default resolution, on a `Geometry.rigid` torus, elastic collisions keep the energy above that of
        the one common velocity that is frozen.

        Returns
        -------
        str or None
            The reason, or None where that is not certain.
        """
        r = self.rule.exact_restitution()
        exact = self.arithmetic == "exact"
        if r is None or r <= 0 or not (exact or (r == 1.0 and self._default_resolution and self.geometry.rigid)):
            return None
        if not self.geometry.contacts.closed_rows:
            return None
        if exact:
            return ("on a torus (every contact on a closed row of balls) a frozen state has every closing speed 0, "
                    "and in exact arithmetic each collision leaves its contact separating")
        return ("on a torus (every contact on a closed row of balls) only equal velocities are frozen, and "
                "elastic collisions keep the energy above theirs")

    # ------------------------------------------------------------ observables
    def approaching(self) -> int:
        """The number of live contacts (0: frozen): those whose balls approach, so that picking one would
        collide. In float arithmetic a closing speed so small that the collision would change no bit of any
        velocity, a remnant of rounding, does not count.

        Returns
        -------
        int
        """
        return self._engine.approaching()

    def is_frozen(self) -> bool:
        """Whether no contact is live, so that no collision can ever happen again.

        Returns
        -------
        bool
        """
        return self._engine.is_frozen()

    def closing_margin(self) -> ClosingMargin:
        """How near the collision criterion this run's picks came. In exact arithmetic every sign is exact;
        the margin is then the float criterion's on the same picks, unknown (None) until the exact engine keeps it.

        Returns
        -------
        pinnedballs.engine.margin.ClosingMargin
            The smallest closing speed counted as a collision and the largest positive one set aside, in
            units of ``threshold``, and the picks within a factor 10^4 of it on each side.
        """
        return ClosingMargin.of(self._engine.state.margin, self.threshold, self.resolution)

    def warn_if_thin(self, reason: str) -> None:
        """Say once, as a one-line `MarginWarning` about the caller's line, that this float run's count
        depends on its criterion, where the count is the observable: a run that ended frozen.

        Parameters
        ----------
        reason : str
            Why the run stopped (`Stop.reason`): only ``"frozen"`` may warn.
        """
        if reason != "frozen" or not self.warns_thin_margin or self._field is not None or not self._default_resolution:
            return
        margin = self.closing_margin()
        if margin.thin:
            self.warns_thin_margin = False
            exact = self.rule.exact_restitution() is not None and not self._engine.model.selector.tracks
            warnings.warn(margin.warning(exact), MarginWarning, stacklevel=_outside_the_package())

    @property
    def exact_velocities(self) -> np.ndarray | None:
        """``(n_balls, dim)`` exact velocities (`pinnedballs.engine.field.numbers.FieldNumber` numbers) of a run in
        exact arithmetic; None in float or certified arithmetic."""
        if self._field is None or self.arithmetic != "exact":
            return None
        return self._field.numbers()

    @property
    def error_bound(self) -> tuple[float, float] | None:
        """A run in certified arithmetic: ``(G, largest)``, bounds on how far its velocities (before
        rounding to floats) are from exact arithmetic's: ``G`` on the whole error vector, ``largest``
        on any one ball's (0: all exact). None in other arithmetics."""
        return self._field.error_bound if self.arithmetic == "certified" else None

    @property
    def smallest_exact_collision(self) -> float | None:
        """Exact or certified arithmetic (fixed-point engine): the smallest closing speed counted as a collision,
        in thresholds (`threshold`); None otherwise, before one, or where unknown. A certified run's covers the
        whole run, resumed or not (its state keeps it: `CertifiedState.margin`), and is unknown after a resume
        from a state that did not keep it (a results file written before); an exact run's covers the picks
        since the simulation was built."""
        field = self._field
        margin = getattr(field, "margin", None)
        if margin is None or not getattr(field, "margin_kept", True) or not np.isfinite(margin[0]):
            return None
        return float(margin[0] / self.threshold)

    def energy(self) -> float:
        """The kinetic energy ``sum m |v|^2 / 2``.

        Returns
        -------
        float
        """
        return kinetic_energy(self._masses, self.velocities)

    def momentum(self) -> np.ndarray:
        """The total momentum ``sum m v``, ``(dim,)`` (meaningful in flat space).

        Returns
        -------
        numpy.ndarray
        """
        return momentum(self._masses, self.velocities)

    # ------------------------------------------------------------ state for checkpoints
    def get_state(self) -> RunState:
        """Everything that changes during a run, as copies: enough to resume bit for bit (the closing
        margin too: a float run's as ``margin``, a certified run's decisions' in ``certified``; none is kept
        in exact arithmetic). What the arithmetic keeps beyond the velocities is its engine's to say
        (`engine.protocol.Backend.saved`).

        Returns
        -------
        RunState
        """
        st = self._engine.state
        return RunState(self.velocities.copy(), self.steps, self.collisions, st.rng.copy(), st.scheduler.copy(),
                        **self._engine.saved())

    def set_state(self, state: RunState) -> None:
        """Restore a state from `get_state` (of a simulation with the same geometry, rule and scheduler).

        Everything is checked before anything changes. A state without a margin (one written before runs
        kept it) starts the margin afresh: it then covers the picks from here on.

        Parameters
        ----------
        state : RunState
            The state.

        Raises
        ------
        FieldTypeError
            On ``state`` that is not a `RunState`.
        FieldError
            Naming the part that does not fit (``velocities``, ``rng_state``, ``margin``...).
        """
        if not isinstance(state, RunState):
            raise FieldTypeError("state", f"must be a RunState (what get_state gives), got {type(state).__name__}")
        velocities = check_velocities(self.geometry, self._masses, state.velocities)
        rng = np.asarray(state.rng_state)
        if rng.shape != (4,) or rng.dtype != np.uint64 or not rng.any():
            raise FieldError("rng_state", f"must be 4 uint64 words, not all zero, got {rng.dtype} {rng.shape}")
        sched = np.asarray(state.scheduler_state)
        if sched.dtype != np.int64:
            raise FieldError("scheduler_state", f"must be int64, got {sched.dtype}")
        self.scheduler.check_state(sched, self.geometry.n_contacts)
        selector = self._engine.model.selector
        flags = self._engine.live_flags(velocities) if selector.tracks else None
        self.scheduler.check_resume(sched, selector, flags)
        steps, collisions = _count("steps", state.steps), _count("collisions", state.collisions)
        if collisions > steps:
            raise FieldError("collisions", f"{collisions} is more than the {steps} steps taken")
        if state.margin is not None and (problem := margin_problem(state.margin)) is not None:
            raise FieldError("margin", problem)
        self._engine.restore(state, velocities)  # the arithmetic's own parts, checked there first
        st = self._engine.state
        st.rng, st.scheduler = rng.copy(), sched.copy()
        st.counters[STEPS], st.counters[COLLISIONS] = steps, collisions
        st.margin[:] = new_margin() if state.margin is None else state.margin

    def plot(self, what: str = "state", ax=None, title: str | None = None):
        """A figure of the current state, as a run's figures draw it (`pinnedballs.plot.run.plot_simulation`).

        Parameters
        ----------
        what : str
            ``"state"``: the state in the geometry's own view (arrows, or a field above 5,000 balls);
            ``"energy"``: the energy by distance from the boundary (a geometry with one); ``"height"``: by
            height (flat 3-D); ``"histograms"``: the velocity components. (`Results.plot` draws a run's
            snapshots too.)
        ax : matplotlib.axes.Axes, optional
            Draw into these axes; else a new figure. (``sim.plot(ax)``, the axes first, draws the state.)
        title : str, optional
            The figure's title; by default the counts it is after.

        Returns
        -------
        matplotlib.figure.Figure

        Raises
        ------
        ValueError
            ``what`` is not a figure of this simulation (the message lists those it has).
        TypeError
            ``what`` is not a name (nor axes).
        """
        if not isinstance(what, str) and ax is None and hasattr(what, "set_title"):  # plot(ax): before ``what``
            what, ax = "state", what
        return display().simulation_figure(self, what, ax=ax, title=title)

    def _repr_html_(self) -> str:  # notebooks: the counters beside the picture of the state
        shown = display()
        return shown.simulation_html(self, shown.simulation_png(self))

    def _repr_png_(self) -> bytes | None:
        return display().simulation_png(self)

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:  # the picture drawn once for both
        shown = display()
        return shown.mimebundle(self, shown.simulation_html, shown.simulation_png, include, exclude)

    def __repr__(self) -> str:
        return (f"Simulation({self.geometry!r}, rule={self.rule!r}, scheduler={self.scheduler!r}, "
                f"steps={self.steps}, collisions={self.collisions})")


def _outside_the_package() -> int:
    """The ``stacklevel`` of the first caller outside pinnedballs: where a warning is about."""
    import os
    import sys
    from pathlib import Path

    # the package's root (this module lives at its top): the driver (engine/) calls back into it on the way
    package, frame, level = str(Path(__file__).resolve().parent) + os.sep, sys._getframe(1), 1
    while frame is not None and str(Path(frame.f_code.co_filename).resolve()).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def _selector(scheduler: Scheduler, geometry: Geometry):
    """The scheduler's selector on ``geometry``; a clear error for a scheduler written for the loop
    protocol before the engine owned the loop (``loops()`` and ``advance()``)."""
    if any(hasattr(scheduler, name) for name in ("advance", "loops")):
        raise FieldTypeError("scheduler", f"{type(scheduler).__name__} defines advance() or loops(), which the engine "
                                          f"no longer calls: give it kernel() (a pick) or selector() instead "
                                          f"(docs/extending.md)")
    return scheduler.selector(geometry)
