"""Triggers: when a writer records a snapshot, as small predicates of the step and collision counters.

A trigger names the counts at which it fires: at listed step or collision counts, or
every so many (`AtSteps`, `EverySteps`, `AtCollisions`, `EveryCollisions`); ``a | b``
fires when either does. The driver cuts its chunks at the next count a trigger names
(`next_steps`, `next_collisions`), so a snapshot lands on exactly that count.

A trigger fires at a state whose counter equals one of its counts, if that counter has
moved since the state the driver checked before (``prev``; None at a fresh start).
A collision count therefore fires once, right after the collision that reaches it,
not again while later steps leave it unchanged.
"""

from __future__ import annotations

from collections.abc import Iterable

from ..util import checks

__all__ = ["Trigger", "AtSteps", "EverySteps", "AtCollisions", "EveryCollisions", "AnyOf", "Counts"]

#: ``(steps, collisions)``
Counts = tuple[int, int]


class Trigger:
    """Base of every trigger; combine with ``|`` (an `AnyOf`).

    Examples
    --------
    >>> import pinnedballs as pb
    >>> either = pb.EverySteps(100) | pb.AtCollisions([3])
    >>> either.next_steps(150), either.next_collisions(0), either.to_spec()
    (200, 3, None)
    """

    def fires(self, prev: Counts | None, now: Counts) -> bool:
        """Whether the trigger fires at ``now``.

        Parameters
        ----------
        prev : tuple of int or None
            ``(steps, collisions)`` at the driver's previous check (None: a fresh start).
        now : tuple of int
            ``(steps, collisions)`` now.

        Returns
        -------
        bool
        """
        raise NotImplementedError

    def next_steps(self, steps: int) -> int | None:
        """The smallest step count ``> steps`` at which it may fire (the driver cuts its chunk there).

        Parameters
        ----------
        steps : int
            The steps so far.

        Returns
        -------
        int or None
            None: none.
        """
        return None

    def next_collisions(self, collisions: int) -> int | None:
        """The smallest collision count ``> collisions`` at which it may fire.

        Parameters
        ----------
        collisions : int
            The collisions so far.

        Returns
        -------
        int or None
            None: none.
        """
        return None

    def to_spec(self) -> dict | None:
        """The trigger as a run spec's ``"snapshots"``.

        Returns
        -------
        dict or None
            ``{"every_steps": 1000}``, ..., or None if a spec cannot say it (an `AnyOf`).
        """
        return None

    def __or__(self, other: Trigger) -> AnyOf:
        if not isinstance(other, Trigger):
            return NotImplemented
        return AnyOf(self, other)

    def __eq__(self, other) -> bool:
        return type(self) is type(other) and vars(self) == vars(other)

    def __hash__(self) -> int:
        return hash((type(self).__name__, repr(self)))


def _counts(name: str, values: Iterable[int]) -> tuple[int, ...]:
    return tuple(sorted({checks.integer(name, v, 0) for v in values}))


class _OnCounter(Trigger):
    """Fires when one counter (0: steps, 1: collisions) reaches one of its counts."""

    counter: int

    def _targets(self, value: int) -> bool:
        raise NotImplementedError

    def _next(self, value: int) -> int | None:
        raise NotImplementedError

    def fires(self, prev: Counts | None, now: Counts) -> bool:
        """At one of its counts, if its counter has moved since ``prev`` (`Trigger.fires`).

        Parameters
        ----------
        prev : tuple of int or None
            ``(steps, collisions)`` at the driver's previous check (None: a fresh start).
        now : tuple of int
            ``(steps, collisions)`` now.

        Returns
        -------
        bool
        """
        v = now[self.counter]
        return self._targets(v) and (prev is None or prev[self.counter] < v)

    def next_steps(self, steps: int) -> int | None:
        """Its next count after ``steps``, for a trigger on the steps (`Trigger.next_steps`).

        Parameters
        ----------
        steps : int
            The steps so far.

        Returns
        -------
        int or None
        """
        return self._next(steps) if self.counter == 0 else None

    def next_collisions(self, collisions: int) -> int | None:
        """Its next count after ``collisions``, for a trigger on the collisions (`Trigger.next_collisions`).

        Parameters
        ----------
        collisions : int
            The collisions so far.

        Returns
        -------
        int or None
        """
        return self._next(collisions) if self.counter == 1 else None


class _At(_OnCounter):
    def __init__(self, counts: Iterable[int]):
        self.counts = _counts("counts", counts)

    def _targets(self, value: int) -> bool:
        return value in self.counts

    def _next(self, value: int) -> int | None:
        return next((c for c in self.counts if c > value), None)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({list(self.counts)})"


class _Every(_OnCounter):
    def __init__(self, period: int):
        self.period = checks.integer("period", period, 1)

    def _targets(self, value: int) -> bool:
        return value > 0 and value % self.period == 0

    def _next(self, value: int) -> int | None:
        return (value // self.period + 1) * self.period

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.period})"


class AtSteps(_At):
    """Fires at each of the listed step counts.

    Parameters
    ----------
    counts : iterable of int
        Step counts (>= 0), kept sorted and once each.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> t = pb.AtSteps([100, 10])
    >>> t, t.next_steps(10), t.fires(None, (10, 0)), t.to_spec()
    (AtSteps([10, 100]), 100, True, {'at_steps': [10, 100]})
    """

    counter = 0

    def to_spec(self) -> dict:
        """A run spec's ``"snapshots"`` (`Trigger.to_spec`).

        Returns
        -------
        dict
            ``{"at_steps": [...]}``.
        """
        return {"at_steps": list(self.counts)}


class AtCollisions(_At):
    """Fires right after the collision that brings the total to each listed count (0: at the start).

    Parameters
    ----------
    counts : iterable of int
        Collision counts (>= 0), kept sorted and once each.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> t = pb.AtCollisions([3])
    >>> t.fires((9, 2), (10, 3)), t.fires((10, 3), (11, 3))
    (True, False)
    """

    counter = 1

    def to_spec(self) -> dict:
        """A run spec's ``"snapshots"`` (`Trigger.to_spec`).

        Returns
        -------
        dict
            ``{"at_collisions": [...]}``.
        """
        return {"at_collisions": list(self.counts)}


class EverySteps(_Every):
    """Fires at steps ``period, 2 period, ...``.

    Parameters
    ----------
    period : int
        At least 1.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> pb.EverySteps(100).next_steps(150), pb.EverySteps(100).to_spec()
    (200, {'every_steps': 100})
    """

    counter = 0

    def to_spec(self) -> dict:
        """A run spec's ``"snapshots"`` (`Trigger.to_spec`).

        Returns
        -------
        dict
            ``{"every_steps": period}``.
        """
        return {"every_steps": self.period}


class EveryCollisions(_Every):
    """Fires right after collisions ``period, 2 period, ...``.

    Parameters
    ----------
    period : int
        At least 1.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> pb.EveryCollisions(5).next_collisions(7), pb.EveryCollisions(5).to_spec()
    (10, {'every_collisions': 5})
    """

    counter = 1

    def to_spec(self) -> dict:
        """A run spec's ``"snapshots"`` (`Trigger.to_spec`).

        Returns
        -------
        dict
            ``{"every_collisions": period}``.
        """
        return {"every_collisions": self.period}


class AnyOf(Trigger):
    """Fires when any of ``triggers`` fires."""

    def __init__(self, *triggers: Trigger):
        flat: list[Trigger] = []
        for t in triggers:
            if not isinstance(t, Trigger):
                raise TypeError(f"triggers: must be Trigger objects, got {type(t).__name__}")
            flat.extend(t.triggers if isinstance(t, AnyOf) else (t,))
        self.triggers = tuple(flat)

    def fires(self, prev: Counts | None, now: Counts) -> bool:
        return any(t.fires(prev, now) for t in self.triggers)

    def next_steps(self, steps: int) -> int | None:
        return _least(t.next_steps(steps) for t in self.triggers)

    def next_collisions(self, collisions: int) -> int | None:
        return _least(t.next_collisions(collisions) for t in self.triggers)

    def __repr__(self) -> str:
        return " | ".join(map(repr, self.triggers))


def _least(values: Iterable[int | None]) -> int | None:
    given = [v for v in values if v is not None]
    return min(given) if given else None
