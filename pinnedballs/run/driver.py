"""The one run driver: a simulation run in chunks to a `Stop`, its writers fired on their triggers.

`drive` is what ``Simulation.run(..., writers=...)``, ``pinnedballs run``, ensembles and
the paper's reproduction all use. Each pass of its loop, in this order:

0. (once, at the start) every writer whose trigger fires at the current counts records a
   snapshot (`Writer.write`);
1. if the `Stop` is reached, every writer closes the run (`Writer.finish`) and the loop ends;
2. the simulation runs one chunk: at most ``max(CHUNK_STEPS, CHUNK_PER_CONTACT * n_contacts)``
   steps, cut short at the stop and at the next count any trigger names;
3. every writer whose trigger fires at the new counts records a snapshot;
4. every writer may checkpoint (`Writer.after_chunk`), then ``after_chunk(sim)`` is called.
   A checkpoint is thus always of a state whose snapshots are recorded.

If anything raises on the way (Ctrl-C's KeyboardInterrupt, a writer's error, ...), every writer
already attached is told (`Writer.abort`, with the counts at which the driver last checked its
trigger) before the exception goes on: a `ResultsWriter` saves the state the simulation stopped
in. The compiled loop changes the state only inside one call, so the state is always one the
chain passed through; a snapshot due at it that was not yet recorded is recorded by the writer.

The engine carries all state, so the result is bit-identical however the run is split:
a driven run ends on exactly the state of the plain ``sim.run(steps=, collisions=)`` or
``sim.run_until_frozen(max_steps=)``.
"""

from __future__ import annotations

from typing import Callable, Sequence

from ..engine.stop import Stop
from ..engine.triggers import Counts, Trigger

__all__ = ["CHUNK_STEPS", "CHUNK_PER_CONTACT", "Writer", "advance", "drive", "drive_run"]

#: a chunk is at least this many steps ...
CHUNK_STEPS = 1 << 20
#: ... and at least this many per contact (so per-chunk O(contacts) work stays small)
CHUNK_PER_CONTACT = 2


class Writer:
    """Something a run records into. Subclasses override what they need.

    ``trigger``: when `write` is called (None: never).
    """

    trigger: Trigger | None = None

    def attach(self, sim) -> Counts | None:
        """The run starts (take the output, write what is static). Returns the counts at which
        the trigger was already checked (a resumed or continued run), else None."""
        return None

    def write(self, sim) -> None:
        """The trigger fired at the current state."""

    def after_chunk(self, sim) -> None:
        """Between chunks (e.g. checkpoint when due)."""

    def finish(self, sim, reason: str) -> None:
        """The run reached its stop for ``reason``."""

    def abort(self, sim, checked: Counts | None) -> None:
        """The run stopped on an exception (which goes on after this): save what is consistent.
        ``checked``: the counts at which the driver last finished checking the trigger (None: never)."""


def advance(sim, steps: int, collisions: int | None = None, until_frozen: bool = False) -> bool:
    """Run at most ``steps`` more steps, stopping at ``collisions`` in total if given, and
    at the exact freeze if ``until_frozen``. Returns True if it stopped because the system froze.
    """
    sim.run(steps=steps, collisions=collisions, until_frozen=until_frozen)
    return until_frozen and sim.is_frozen()


def _counts(sim) -> Counts:
    return sim.steps, sim.collisions


def _least(*values: int | None) -> int | None:
    given = [v for v in values if v is not None]
    return min(given) if given else None


def _next_chunk(sim, stop: Stop, chunk: int, triggers: list[Trigger]) -> tuple[int, int | None]:
    """``(steps, collisions)`` limits of the next chunk: never past the stop or a trigger's next count."""
    s, c = _counts(sim)
    step_target = _least(stop.steps, *(t.next_steps(s) for t in triggers))
    steps = chunk if step_target is None else min(chunk, step_target - s)
    return steps, _least(stop.collisions, *(t.next_collisions(c) for t in triggers))


def _check_missed(trigger: Trigger, prev: Counts, now: Counts) -> None:
    for k, (name, nxt) in enumerate((("steps", trigger.next_steps), ("collisions", trigger.next_collisions))):
        target = nxt(prev[k])
        if target is not None and target < now[k]:
            raise RuntimeError(f"a snapshot at {name} = {target} was missed (now at {now[k]})")


def drive(sim, stop: Stop, writers: Sequence[Writer] = (), *,
          after_chunk: Callable[[object], None] | None = None) -> str:
    """Run ``sim`` to ``stop``, firing ``writers``; returns the stop reason (see the module's docstring)."""
    chunk = max(CHUNK_STEPS, CHUNK_PER_CONTACT * sim.geometry.n_contacts)
    checked: list[Counts | None] = []
    try:
        for w in writers:
            checked.append(w.attach(sim))
        return _loop(sim, stop, writers, checked, chunk, after_chunk)
    except BaseException:
        _abort(sim, writers[:len(checked)], checked)
        raise


def _loop(sim, stop: Stop, writers: Sequence[Writer], checked: list, chunk: int, after_chunk) -> str:
    triggers = [w.trigger for w in writers if w.trigger is not None]
    frozen = False
    _fire(sim, writers, checked)
    while True:
        reason = stop.reason(sim, frozen)
        if reason:
            for w in writers:
                w.finish(sim, reason)
            return reason
        steps, collisions = _next_chunk(sim, stop, chunk, triggers)
        frozen = advance(sim, steps, collisions, stop.until_frozen)
        _fire(sim, writers, checked)  # before any checkpoint of this state
        for w in writers:
            w.after_chunk(sim)
        if after_chunk is not None:
            after_chunk(sim)


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


def drive_run(sim, steps: int | None, collisions: int | None, until_frozen: bool, writers: Sequence[Writer]) -> int:
    """``sim.run(steps=, collisions=, until_frozen=)`` through `drive` with ``writers``; the steps taken."""
    writers = list(writers)
    for w in writers:
        if not isinstance(w, Writer):
            raise TypeError(f"writers: must be Writer objects such as ResultsWriter, got {type(w).__name__}")
    start = sim.steps
    stop = Stop(steps=None if steps is None else start + steps, collisions=collisions,
                until_frozen=until_frozen or steps is None)
    drive(sim, stop, writers)
    return sim.steps - start
