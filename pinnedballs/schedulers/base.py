"""The base of every scheduler: what it gives the engine, and what it checks before resuming.

A scheduler says which contact the engine tries next. The simple kind gives one jitted
function, its `kernel`: ``pick(state, rng, n_contacts) -> (k, rng)``, with ``state`` its own
``int64`` array (from `initial_state`) and ``rng`` the simulation's random stream as a 4-tuple
of uint64 words (`pinnedballs.engine.streams.xoshiro`), advanced only through that module's functions.
The engine wraps it (`engine.sequential.loops.pick_selector`) and owns the loop, its stop conditions, its
counters and freeze detection (`pinnedballs.engine.sequential.loops`).

A scheduler that picks in another way gives a whole `engine.sequential.loops.Selector` (`selector`): a
``select`` that may jump over picks (`RejectionFree`), functions that prepare its tables from
``state`` or hear of live contacts, and, if it must, its own loop for plain steps
(`ColoredSweep`, which runs a colour class in parallel). Either way everything that changes lives
in ``state`` and ``rng``, so a checkpoint of the two resumes it exactly; `check_state` (and
`check_resume`) refuse a state it cannot resume from.
"""

from __future__ import annotations

import functools
import re
from abc import ABC
from collections.abc import Callable

import numpy as np
from numba import njit

from ..engine.sequential.loops import Selector, pick_selector
from ..util.errors import FieldError, FieldTypeError, check_jitted

__all__ = ["Scheduler", "check_pick", "PickOutOfRange"]

#: what a pick must return, said in the errors
PICK_RETURNS = "(k, rng): the contact's index (an integer) and the random stream (the 4-tuple of uint64 it was given)"


# an ABC like CollisionRule and Geometry, but with no abstract method: a scheduler defines kernel() or selector()
class Scheduler(ABC):  # noqa: B024
    """Chooses which contact the engine tries next: a `kernel` pick, or a whole `selector`.

    The module's docstring says what each gives the engine; docs/extending.md writes one.

    Attributes
    ----------
    law : str or None
        The law of its picks, which `pinnedballs.testing.check_scheduler_law` tests: ``"uniform"``
        (each pick uniform over the contacts, independent of the others), ``"sweep"`` (every contact once
        in each sweep of ``n_contacts`` picks), ``"uniform_chain"`` (the paper's uniform chain without its
        rejected picks: the same law of steps, collisions and velocities), or None (none claimed).
    """

    law: str | None = None

    def kernel(self) -> Callable:
        """The scheduler's pick, for a scheduler that picks one contact a step.

        Returns
        -------
        callable
            The jitted ``pick(state, rng, n_contacts) -> (k, rng)``.

        Raises
        ------
        FieldTypeError
            On ``scheduler``, where the scheduler defines neither this nor `selector`.
        """
        raise FieldTypeError("scheduler", f"{type(self).__name__} must define kernel() (a pick function) "
                                          f"or selector()")

    def selector(self, geometry) -> Selector:
        """What the engine runs for this scheduler on ``geometry``; built once per `Simulation`.

        Parameters
        ----------
        geometry : Geometry
            The geometry the simulation is built on.

        Returns
        -------
        pinnedballs.engine.selector.Selector
            By default `kernel`'s pick, one contact per step (a user's pick checked first, and its contact
            at every step).

        Raises
        ------
        FieldTypeError
            On ``scheduler``, where the pick is not jitted, does not compile for the engine's arguments or
            returns something other than ``(k, rng)``.
        """
        pick = check_jitted(self.kernel(), "scheduler", f"{type(self).__name__}.kernel()'s pick")
        if not (getattr(pick, "__module__", None) or "").startswith("pinnedballs."):
            name = f"{type(self).__name__}.kernel()'s pick {getattr(pick, '__name__', pick)!r}"
            check_pick(pick, name, self.initial_state(geometry.n_contacts), geometry.n_contacts)
            pick = checked_pick(pick, name)  # a user's pick: its contact is checked at every step
        return pick_selector(pick)

    # an optional hook, empty on purpose: nothing to check by default
    def check_resume(self, state: np.ndarray, selector: Selector, flags: np.ndarray | None) -> None:  # noqa: B027
        """Check that a state fits what it resumes on. Nothing to check for a ``pick`` scheduler.

        Parameters
        ----------
        state : numpy.ndarray
            ``int64``: the scheduler's state, already through `check_state`.
        selector : pinnedballs.engine.selector.Selector
            The selector it resumes with (its tables).
        flags : numpy.ndarray or None
            ``(E,) bool``: for a selector that tracks live contacts, the live contacts of the velocities it
            is restored with; else None.

        Raises
        ------
        FieldError
            On ``scheduler_state``, where ``state`` does not fit the tables or the live contacts.
        """

    def initial_state(self, n_contacts: int) -> np.ndarray:
        """The state a run starts from.

        Parameters
        ----------
        n_contacts : int
            The geometry's contacts.

        Returns
        -------
        numpy.ndarray
            ``int64``; ``(1,)`` zeros unless the scheduler keeps more.
        """
        return np.zeros(1, dtype=np.int64)

    def check_state(self, state: np.ndarray, n_contacts: int) -> None:
        """Check that ``state`` is one this scheduler can resume from.

        The compiled loop indexes with it unchecked, so a corrupt checkpoint must stop here.

        Parameters
        ----------
        state : numpy.ndarray
            ``int64``: a saved state (`Simulation.get_state`'s ``scheduler_state``).
        n_contacts : int
            The geometry's contacts.

        Raises
        ------
        FieldError
            On ``scheduler_state`` (a ValueError), unless it has `initial_state`'s shape and fits the scheduler.
        """
        expected = self.initial_state(n_contacts).shape
        if state.shape != expected:
            raise FieldError("scheduler_state", f"must have shape {expected} for {self!r}, got {state.shape}")

    def to_spec(self) -> dict | None:
        """The scheduler as a run spec's ``"scheduler"``.

        A run built in Python records this spec, so that ``pb.load(dir).simulation()``
        rebuilds the scheduler; one of your own may return ``{"kind": "python", "factory": ..., "args": ...}``.

        Returns
        -------
        dict or None
            A dict with its ``"kind"``, or None if it has none.
        """
        return None

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"

    def __eq__(self, other) -> bool:
        """Same class and same parameters (attributes, arrays compared element by element)."""
        if type(other) is not type(self) or vars(other).keys() != vars(self).keys():
            return False
        return all(np.array_equal(value, vars(other)[key]) for key, value in vars(self).items())

    def __hash__(self) -> int:
        return hash(type(self))


class PickOutOfRange(FieldError):
    """A scheduler's pick named a contact that does not exist (raised from the compiled loop)."""

    def __init__(self, name: str, k: int, n_contacts: int):
        self.name, self.k, self.n_contacts = name, int(k), int(n_contacts)
        super().__init__("scheduler", f"{name} picked contact {self.k}, but there are {self.n_contacts} contacts "
                                      f"(0 to {self.n_contacts - 1})")

    def __reduce__(self):
        return type(self), (self.name, self.k, self.n_contacts)


@functools.cache  # one wrapper per pick: the engine's compiled loops are cached per selector
def checked_pick(pick: Callable, name: str) -> Callable:
    """``pick`` with its contact checked: `PickOutOfRange` naming ``name`` (raised from compiled code, so
    the run stops there) unless ``0 <= k < n_contacts``. For a user's pick: the compiled loop indexes
    the contact tables with ``k`` unchecked. (``name`` is a constant of the compiled code, and part of
    its cache key, `engine.jit.cache`.)"""

    @njit(inline="always")
    def checked(state, rng, n_contacts):
        k, rng = pick(state, rng, n_contacts)
        signed = np.int64(k)  # a huge unsigned k shows as the negative number it usually is
        if signed < 0 or signed >= n_contacts:
            raise PickOutOfRange(name, signed, n_contacts)
        return k, rng

    return checked


def check_pick(pick: Callable, name: str, state: np.ndarray, n_contacts: int) -> None:
    """Raise a `FieldTypeError` on ``scheduler``, naming ``name``, unless ``pick(state, rng, n_contacts)``
    compiles for the engine's argument types and returns `PICK_RETURNS` (the loop would otherwise fail
    with numba's TypingError from deep inside the engine). With ``NUMBA_DISABLE_JIT=1`` the pick is
    called once, on copies, and its result checked."""
    from numba import config, types
    from numba.core.errors import TypingError

    from ..engine.streams.xoshiro import load, seed_state

    if config.DISABLE_JIT:
        try:
            out = pick(state.copy(), load(seed_state(0)), n_contacts)
        except Exception as error:
            raise FieldTypeError("scheduler",
                                 f"{name} failed on a fresh state: {type(error).__name__}: {error}") from None
        if (isinstance(out, tuple) and len(out) == 2 and isinstance(out[0], (int, np.integer))
                and isinstance(out[1], tuple) and len(out[1]) == 4):
            return
        raise FieldTypeError("scheduler", f"{name} must return {PICK_RETURNS}; it returned {out!r}")
    rng = types.UniTuple(types.uint64, 4)
    signature = (types.Array(types.int64, 1, "C"), rng, types.int64)
    try:
        pick.compile(signature)
    except TypingError as error:
        lines = [line.strip() for line in re.sub(r"\x1b\[[0-9;]*m", "", str(error)).splitlines()]
        said = " ".join(line for line in lines[1:4] if line) or lines[0]
        raise FieldTypeError("scheduler", f"{name} does not compile for (state: int64 array, rng: 4-tuple of "
                                          f"uint64, n_contacts: int64): {said}") from None
    returned = pick.overloads[signature].signature.return_type
    if not (isinstance(returned, types.BaseTuple) and len(returned) == 2 and isinstance(returned[0], types.Integer)
            and returned[1] == rng):
        raise FieldTypeError("scheduler", f"{name} must return {PICK_RETURNS}; it returns {returned}")
