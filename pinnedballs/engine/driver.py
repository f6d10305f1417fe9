"""The one run driver: a simulation run in chunks to a `Stop`, its writers fired on their triggers,
its progress shown, a Ctrl-C honoured between chunks.

`drive` is what every run goes through: ``Simulation.run`` and ``run_until_frozen`` (with writers
or without), ``pinnedballs run``, ensembles and the paper's reproduction. Each chunk is one call of
the engine's loop, ``sim.engine.run(max_steps, max_collisions, until_frozen)`` (`engine.backends`); the
engine gives the same bits however a run is split into calls, so how it is chunked changes no bit.

Chunks last about `CHUNK_SECONDS`: the first is `FIRST_CHUNK` steps, each next one is sized from
the speed of the one before (at most `GROWTH` times longer), never less than `CHUNK_PER_CONTACT`
steps per contact (so per-chunk work over the contacts stays small) nor more than `CHUNK_STEPS`
(tests lower it for many small chunks), and cut short at the stop and at the next count any trigger
names. Before the first chunk, a call of no steps compiles the loop (once per process: numba caches
it on disk) and changes no bit of the state; it compiles only what a call of no steps runs: a threaded
chain (`engine.threads`) compiles its loops in the first chunks that run them.

Each pass of the loop, in this order:

0. (once, at the start) every writer whose trigger fires at the current counts records a
   snapshot (`Writer.write`);
1. if the `Stop` is reached, every writer closes the run (`Writer.finish`) and the loop ends;
2. the simulation runs one chunk;
3. every writer whose trigger fires at the new counts records a snapshot;
4. every writer may checkpoint (`Writer.after_chunk`); the progress is shown; a Ctrl-C that came
   meanwhile is handed on (`sigint`): by default it raises KeyboardInterrupt here; then
   ``after_chunk(sim)`` is called. A checkpoint is thus always of a state whose snapshots are recorded.

Ctrl-C. While the chunks run (main thread), SIGINT is held to the end of the chunk it came in
(`sigint.deferred`), so a run always stops on a state the chain passed through, whole: continuing
it gives the bits of a run never interrupted. The compiling call runs on a thread of its own
(`sigint.Deferred.aside`; on the CPU): a Ctrl-C during it stops the run at once (KeyboardInterrupt, the
state untouched), while numba, which cannot be interrupted safely, finishes the compile on that thread (the
next run waits for it). What a chunk compiles itself still holds a Ctrl-C to the chunk's end: a threaded
chain's loops (seconds, on a first run of a large system) and the logging loops. A command line ends the
process at once instead (`sigint.on_compile_interrupt`).

If anything raises on the way (Ctrl-C's KeyboardInterrupt, a writer's error, ...), every writer
already attached is told (`Writer.abort`, with the counts at which the driver last checked its
trigger) before the exception goes on: a `ResultsWriter` saves the state the simulation stopped
in, with any snapshot due at it that was not yet recorded.
"""

from __future__ import annotations

import contextlib
import time
import weakref
from collections.abc import Callable, Sequence

from ..util.errors import InternalError
from ..util.progress import Progress, shown
from ..util.sigint import Deferred, deferred
from .jit.failures import compiling
from .stop import Stop
from .triggers import Counts

__all__ = ["CHUNK_SECONDS", "FIRST_CHUNK", "GROWTH", "CHUNK_STEPS", "CHUNK_PER_CONTACT", "NO_LIMIT", "Stop",
           "Writer", "Counts", "Drive", "advance", "drive", "check_writers", "least"]

#: a chunk lasts about this many seconds: a Ctrl-C stops a run within about this long
CHUNK_SECONDS = 0.2
#: the first chunk's steps, before the speed is known
FIRST_CHUNK = 1 << 12
#: a chunk is at most this many times longer than the one before
GROWTH = 4
#: a chunk is at least this many steps per contact ...
CHUNK_PER_CONTACT = 2
#: ... and at most this many steps
CHUNK_STEPS = 1 << 62
#: no limit on a counter (the engine's counters are int64)
NO_LIMIT = 2**63 - 1


class Writer:
    """Something a run records into (``sim.run(..., writers=[...])``). Subclasses override what they need.

    Attributes
    ----------
    trigger : Trigger or None
        When `write` is called (None: never); a `pinnedballs.engine.triggers.Trigger`, or any
        object with its ``fires``, ``next_steps`` and ``next_collisions``.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> class Steps(pb.Writer):
    ...     trigger = pb.EverySteps(100)
    ...     def __init__(self):
    ...         self.seen = []
    ...     def write(self, sim):
    ...         self.seen.append(sim.steps)
    >>> g = pb.HalfPlane(rows=2, cols=2)
    >>> sim = pb.Simulation(g, [[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], seed=0)
    >>> w = Steps()
    >>> sim.run(steps=350, writers=[w]), w.seen
    (350, [100, 200, 300])
    """

    trigger = None

    def attach(self, sim) -> Counts | None:
        """The run starts: take the output, write what is static.

        Parameters
        ----------
        sim : Simulation
            The simulation run.

        Returns
        -------
        tuple of int or None
            The counts ``(steps, collisions)`` at which the trigger was already checked (a resumed or
            continued run), else None.
        """
        return None

    def write(self, sim) -> None:
        """The trigger fired at the current state.

        Parameters
        ----------
        sim : Simulation
            The simulation, at the count the trigger names.
        """

    def after_chunk(self, sim) -> None:
        """Between chunks (e.g. checkpoint when due).

        Parameters
        ----------
        sim : Simulation
            The simulation, between two chunks.
        """

    def finish(self, sim, reason: str) -> None:
        """The run reached its stop.

        Parameters
        ----------
        sim : Simulation
            The simulation, at its stop.
        reason : str
            Why it stopped (`Stop.reason`).
        """

    def abort(self, sim, checked: Counts | None) -> None:
        """The run stopped on an exception (which goes on after this): save what is consistent.

        Parameters
        ----------
        sim : Simulation
            The simulation, as the exception left it.
        checked : tuple of int or None
            The counts at which the driver last finished checking the trigger (None: never).
        """


def check_writers(writers) -> list[Writer]:
    """``writers`` as a list, each a `Writer` (a TypeError naming ``writers`` otherwise)."""
    writers = list(writers)
    for w in writers:
        if not isinstance(w, Writer):
            raise TypeError(f"writers: must be Writer objects such as ResultsWriter, got {type(w).__name__}")
    return writers


def advance(sim, steps: int, collisions: int | None = None, until_frozen: bool = False) -> bool:
    """One chunk: at most ``steps`` more steps, stopping at ``collisions`` in total if given, and at the
    exact freeze if ``until_frozen``. Returns True if it stopped because the system froze.

    The engine's loop stops early only at the collision target or, with ``until_frozen``, at the
    freeze; a chunk that ends on its last step is checked afresh (`Simulation.is_frozen`) when the
    run would otherwise end there for its steps (`_loop`), or by the next chunk, which takes no step.
    A loop that stops short otherwise broke the protocol: an `InternalError` (the run is saved "failed").
    """
    limit = NO_LIMIT if collisions is None else collisions
    taken = sim.engine.run(steps, limit, until_frozen)
    short = taken < steps and sim.collisions < limit
    if short and until_frozen and sim.is_frozen():
        return True
    if short and (until_frozen or taken == 0):
        left = steps - taken
        raise InternalError(f"the loop of engine {getattr(sim, 'engine_name', '')!r} stopped at step {sim.steps:,}, "
                            f"{left:,} step{'' if left == 1 else 's'} short of its chunk, neither frozen nor at its "
                            f"collision target (an internal failure)")
    return False


class _Chunks:
    """The steps of the next chunk, from the speed of the last (see the module's docstring)."""

    def __init__(self, n_contacts: int):
        self.least = CHUNK_PER_CONTACT * n_contacts
        self.size = max(FIRST_CHUNK, self.least)

    def next(self) -> int:
        return max(1, min(CHUNK_STEPS, self.size))

    def measured(self, asked: int, taken: int, seconds: float) -> None:
        """A chunk asked for ``asked`` steps and took ``taken`` in ``seconds``. Only a whole chunk of the
        planned size tells the speed (one cut short at a trigger, the stop or the freeze does not)."""
        if asked < self.next() or taken < asked or seconds <= 0:
            return
        self.size = int(max(self.least, min(taken * CHUNK_SECONDS / seconds, GROWTH * self.size)))


class Drive:
    """One run driven to its `Stop` with its writers, a chunk at a time: the driver's steps (module docstring)
    as an object, so that `drive` runs one simulation with them and a GPU's replicas run many at once
    (`pinnedballs.run.ensemble_gpu`: one `Drive` a replica, the chunks of all in one launch).

    ``sim`` is what the writers record and the stop reads: a `Simulation`, or anything with its ``steps``,
    ``collisions``, ``is_frozen()``, ``geometry`` and what the writers read. ``chunk``: the steps a chunk
    asks for at most (None: about `CHUNK_SECONDS`, from the speed of the chunks before). Use: `start`, then
    `next` (the limits of the next chunk, or None once the stop is reached and the writers finished), run
    the chunk, `advanced`; `abort` on an exception.
    """

    def __init__(self, sim, stop: Stop, writers: Sequence[Writer] = (), chunk: int | None = None):
        self.sim, self.stop, self.writers = sim, stop, list(writers)
        self.checked: list[Counts | None] = []
        self.triggers = [w.trigger for w in self.writers if w.trigger is not None]
        self.chunks = _Chunks(sim.geometry.n_contacts) if chunk is None else _Fixed(chunk)
        self.frozen, self.reason = False, ""

    def attach(self) -> None:
        """Attach the writers (an exception leaves the ones attached to be told by `abort`)."""
        for w in self.writers:
            self.checked.append(w.attach(self.sim))

    def start(self) -> None:
        """Step 0: the snapshots due at the counts the run starts from."""
        _fire(self.sim, self.writers, self.checked)

    def limits(self) -> tuple[int, int | None]:
        """``(steps, collisions)``: the first chunk's limits before `start` (what the compiling call runs to)."""
        return _next_chunk(self.sim, self.stop, 0, self.triggers)

    def next(self) -> tuple[int, int | None] | None:
        """The next chunk's ``(steps, collisions)`` limits, or None when the stop is reached (step 1: the
        writers then finished, `reason` says why)."""
        sim, stop = self.sim, self.stop
        reason = stop.reason(sim, self.frozen)
        if reason == stop.steps_reason and stop.until_frozen and sim.is_frozen():
            reason = stop.reason(sim, True)  # froze on the very last step
        if reason:
            for w in self.writers:
                w.finish(sim, reason)
            self.reason = reason
            return None
        return _next_chunk(sim, stop, self.chunks.next(), self.triggers)

    def advanced(self, frozen: bool, asked: int = 0, taken: int = 0, seconds: float = 0.0) -> None:
        """The chunk ran (``frozen``: it stopped at the freeze; ``asked``/``taken`` steps in ``seconds``): steps
        3 and 4 but for the progress and Ctrl-C, which are the caller's."""
        self.frozen = frozen
        self.chunks.measured(asked, taken, seconds)
        _fire(self.sim, self.writers, self.checked)  # before any checkpoint of this state
        for w in self.writers:
            w.after_chunk(self.sim)

    def abort(self) -> None:
        """Tell the writers attached that the run stopped on an exception (`_abort`)."""
        _abort(self.sim, self.writers[:len(self.checked)], self.checked)


class _Fixed:
    """Chunks of one size (`Drive`'s ``chunk``)."""

    def __init__(self, size: int):
        self.size = max(1, int(size))

    def next(self) -> int:
        return self.size

    def measured(self, asked: int, taken: int, seconds: float) -> None:
        pass


def drive(sim, stop: Stop, writers: Sequence[Writer] = (), *, after_chunk: Callable[[object], None] | None = None,
          progress: bool | None = False) -> str:
    """Run ``sim`` to ``stop``, firing ``writers``; returns the stop reason (see the module's docstring).

    ``progress`` (`pinnedballs.util.progress`): a bar over the steps, or the collisions for a
    collision target; a count of steps and collisions when the run goes until frozen (its end unknown).
    """
    shown(progress)  # a bad argument is refused before anything starts
    run = Drive(sim, stop, check_writers(writers))
    try:
        run.attach()
        _, collisions = run.limits()
        with _progress(sim, stop, progress) as bar, deferred() as held:
            _compile(sim.engine, held, NO_LIMIT if collisions is None else collisions, stop.until_frozen)
            run.start()
            while (limits := run.next()) is not None:
                steps, collisions = limits
                start, before = time.perf_counter(), sim.steps
                frozen = advance(sim, steps, collisions, stop.until_frozen)
                run.advanced(frozen, steps, sim.steps - before, time.perf_counter() - start)
                _shown(bar, sim, stop)
                held.deliver()
                if after_chunk is not None:
                    after_chunk(sim)
            _shown(bar, sim, stop)
            return run.reason
    except BaseException:
        run.abort()
        raise


#: the compiling calls each engine has made, by `_compiling_kind`: made again, they compile nothing
_compiled: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _compile(engine, held: Deferred, collisions: int, until_frozen: bool) -> None:
    """The compiling call, ``engine.run(0, collisions, until_frozen)``: aside (`Deferred.aside`, a Ctrl-C
    meanwhile stops the run at once) the first time an engine makes it, here after (a thread's start costs
    more than the call). numba's error compiling a user's rule or scheduler is raised as the one-line
    `jit.failures.CompileFailure` naming it."""
    kind = _compiling_kind(engine, collisions, until_frozen)
    made = _compiled.setdefault(engine, set())
    model = getattr(engine, "model", None)
    with compiling(model) if model is not None else contextlib.nullcontext():
        if kind in made or engine.device.gpu:  # a GPU's context belongs to the thread that made it
            engine.run(0, collisions, until_frozen)
            return
        held.aside(engine.run, 0, collisions, until_frozen)
    made.add(kind)


def _compiling_kind(engine, collisions: int, until_frozen: bool) -> tuple:
    """What picks the loops a call of the engine runs: a stop at a freeze, at a collision count, a listener."""
    return until_frozen, collisions != NO_LIMIT, bool(getattr(engine, "listeners", None))


def _progress(sim, stop: Stop, progress) -> Progress:
    if stop.collisions is not None:
        return Progress(progress, stop.collisions, "collisions", "running", sim.collisions)
    if stop.until_frozen:
        return Progress(progress, None, "steps", "until frozen", sim.steps)
    return Progress(progress, stop.steps, "steps", "running", sim.steps)


def _shown(bar: Progress, sim, stop: Stop) -> None:
    if not bar.visible:
        return
    if stop.collisions is not None:
        bar.update(sim.collisions, f"steps={sim.steps:,}")
    else:
        bar.update(sim.steps, f"collisions={sim.collisions:,}")


def _counts(sim) -> Counts:
    return sim.steps, sim.collisions


def least(*values: int | None) -> int | None:
    """The smallest of ``values`` not None, or None when all are."""
    given = [v for v in values if v is not None]
    return min(given) if given else None


def _next_chunk(sim, stop: Stop, chunk: int, triggers: list) -> tuple[int, int | None]:
    """``(steps, collisions)`` limits of the next chunk: never past the stop or a trigger's next count."""
    s, c = _counts(sim)
    step_target = least(stop.steps, *(t.next_steps(s) for t in triggers))
    steps = chunk if step_target is None else min(chunk, step_target - s)
    return steps, least(stop.collisions, *(t.next_collisions(c) for t in triggers))


def _check_missed(trigger, prev: Counts, now: Counts) -> None:
    for k, (name, nxt) in enumerate((("steps", trigger.next_steps), ("collisions", trigger.next_collisions))):
        target = nxt(prev[k])
        if target is not None and target < now[k]:
            raise RuntimeError(f"a snapshot at {name} = {target} was missed (now at {now[k]})")


def _abort(sim, writers: Sequence[Writer], checked: list) -> None:
    """Tell each writer the run stopped; the first writer's own failure (after all were told) is raised
    instead of the exception that stopped the run, which becomes its context."""
    failed = None
    for w, counts in zip(writers, checked):
        try:
            w.abort(sim, counts)
        except BaseException as exc:  # noqa: BLE001 - the others must still be told
            failed = failed or exc
    if failed is not None:
        raise failed


def _fire(sim, writers: Sequence[Writer], checked: list[Counts | None]) -> None:
    """Call `Writer.write` of each writer whose trigger fires at the current counts; ``checked``
    holds, per writer, the counts of its previous check and is updated."""
    now = _counts(sim)
    for k, w in enumerate(writers):
        prev = checked[k]
        if w.trigger is not None and prev != now:
            if prev is not None:
                _check_missed(w.trigger, prev, now)
            if w.trigger.fires(prev, now):
                w.write(sim)
        checked[k] = now
