"""What an engine is (`Engine`: a name, the devices and arithmetics it runs, `Engine.supports` and `Engine.build`),
what it builds (`Backend`: the chunk protocol the run driver calls, ``run(max_steps, max_collisions,
until_frozen) -> steps taken``, and the state its arithmetic saves and restores), and what it says when it does
not run a chain (`Refusal`, raised as `Refused`). The door (`engine.door`) keeps the registered engines and
chooses among them; the built-in ones are `engine.builtin`'s, their backends `engine.backends`' and
`engine.field.backend`'s."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..util.errors import FieldError
from .chain import NO_LIMIT, ChainState, Model
from .devices import Device, as_device
from .sequential.loops import live_kernel

__all__ = ["Refusal", "Refused", "Engine", "Backend"]


@dataclass(frozen=True)
class Refusal:
    """Why an engine does not run a chain (what `Engine.supports` answers with).

    Parameters
    ----------
    field : str
        What to change: ``"device"``, ``"arithmetic"``, ``"engine"``...
    reason : str
        Why not.
    instead : str
        What runs it instead.
    needs : tuple of (str, str)
        What it would take, by the field a spec states it in (``(("scheduler", "counter"),)``: the counter
        stream), for a caller that says it in its own words.

    Examples
    --------
    >>> from pinnedballs.engine import Refusal
    >>> refusal = Refusal("device", "no GPU here", "device 'cpu' gives the same bits")
    >>> refusal.message
    "no GPU here; device 'cpu' gives the same bits"
    >>> str(refusal.error())
    "device: no GPU here; device 'cpu' gives the same bits"
    """

    field: str
    reason: str
    instead: str = ""
    needs: tuple[tuple[str, str], ...] = ()

    @property
    def message(self) -> str:
        """The reason and what runs it instead, as one line."""
        return f"{self.reason}; {self.instead}" if self.instead else self.reason

    def error(self) -> Refused:
        """The refusal as the error that says it.

        Returns
        -------
        Refused
            A `FieldError` on ``field``.
        """
        return Refused(self)


class Refused(FieldError):
    """A chain no engine runs, as the error that says so: a `FieldError` on the refusal's field.

    Parameters
    ----------
    refusal : Refusal
        Kept (``refusal``) for a caller that words it for its own input (a spec).
    """

    def __init__(self, refusal: Refusal):
        super().__init__(refusal.field, refusal.message)
        self.refusal = refusal

    def __reduce__(self):
        return type(self), (self.refusal,)


class Engine:
    """What runs chains: a name, the devices (kinds: ``"cpu"``, ``"cuda"``) and arithmetics it runs, whether it
    runs an ensemble's replicas together (``replicas``), and the two calls of the door.

    Subclass it, set the attributes, and override `supports` and `build` (docs/architecture.md shows one).

    Attributes
    ----------
    name : str
        An identifier, by which `find` and ``Simulation(..., engine=NAME)`` find it.
    devices : tuple of str
        The device kinds it runs on (``"cpu"``, ``"cuda"``).
    arithmetics : tuple of str
        The arithmetics it runs (``"float"``, ``"exact"``, ``"certified"``).
    replicas : bool
        It runs many replicas of one spec together (an ensemble's), not one simulation's chain.
    """

    name: str = ""
    devices: tuple[str, ...] = ()
    arithmetics: tuple[str, ...] = ()
    #: it runs many replicas of one spec together (an ensemble's), not one simulation's chain
    replicas: bool = False

    def supports(self, model, arithmetic: str, device: Device) -> Refusal | None:
        """Whether this engine runs a chain. Cheap: what needs a compile or a GPU is checked by `build`.

        Parameters
        ----------
        model : pinnedballs.engine.chain.Model
            What the chain is.
        arithmetic : str
            Its arithmetic.
        device : Device
            Where it would run.

        Returns
        -------
        Refusal or None
            None when this engine runs it, else why not (by default `refuse_kinds`).

        Examples
        --------
        >>> import pinnedballs as pb
        >>> from pinnedballs.engine import find
        >>> g = pb.HalfPlane(rows=2, cols=2)
        >>> model = pb.Simulation(g, [[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], seed=0).engine.model
        >>> find("sequential").supports(model, "exact", pb.CPU()).reason
        "engine 'sequential' runs float arithmetic, not exact"
        """
        return self.refuse_kinds(arithmetic, device)

    def build(self, model, state, listeners: list, device: Device, options: dict):
        """The backend running a chain (docs/architecture.md builds one).

        Parameters
        ----------
        model : pinnedballs.engine.chain.Model
            What the chain is.
        state : pinnedballs.engine.chain.ChainState
            What changes, written in place.
        listeners : list
            Told of each collision.
        device : Device
            Where it runs.
        options : dict
            The arithmetic's (`door.options`: ``arithmetic``, ``precision``, ``late_precision``).

        Returns
        -------
        Backend

        Raises
        ------
        FieldError
            Where a check only the build can make fails.
        """
        raise NotImplementedError

    def refuse_kinds(self, arithmetic: str, device: Device) -> Refusal | None:
        """The refusal of an arithmetic or a device this engine does not run at all.

        Parameters
        ----------
        arithmetic : str
            The chain's arithmetic.
        device : Device
            Where it would run.

        Returns
        -------
        Refusal or None
            None where ``device.kind`` is one of ``devices`` and ``arithmetic`` one of ``arithmetics``.
        """
        if device.kind not in self.devices:
            return Refusal("device", f"engine {self.name!r} runs on {' and '.join(self.devices)}, not {device.kind}")
        if arithmetic not in self.arithmetics:
            return Refusal("arithmetic", f"engine {self.name!r} runs {' and '.join(self.arithmetics)} arithmetic, "
                                         f"not {arithmetic}")
        return None

    def __repr__(self) -> str:
        return (f"<engine {self.name!r}: {', '.join(self.arithmetics)} on {', '.join(self.devices)}"
                f"{', replicas' if self.replicas else ''}>")


class Backend:
    """What every backend shares: the chain's ``model`` and ``state``, the listeners told of each collision
    (``listeners(steps (C,) int64, contacts (C,) int64)``, in order), the `Device` it runs on, and the protocol
    (module docstring)."""

    def __init__(self, model: Model, state: ChainState, listeners: list | None = None, device=None):
        self.model, self.state = model, state
        self.listeners = [] if listeners is None else listeners
        self.device = as_device(device)
        g = model.geometry
        self._live_flags, self._any_live = live_kernel(model.collide, g.dim, g.contacts.flat)

    def run(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        """At most ``max_steps`` steps (never past the counter's range), stopping at a total of ``max_collisions``
        collisions and, with ``until_frozen``, right after the collision that leaves no live contact. A state left
        between two states by an error inside a compiled loop (``state.broken``) cannot go on."""
        if self.state.broken:
            raise FieldError("simulation", f"cannot go on: {self.state.broken}; build it again (or load its last "
                                           f"checkpoint)")
        return self._run(min(max_steps, NO_LIMIT - self.state.steps), max_collisions, until_frozen)

    def _run(self, max_steps: int, max_collisions: int, until_frozen: bool) -> int:
        raise NotImplementedError

    def velocities(self) -> np.ndarray:
        """``(n_balls, dim) float64``: the velocities now."""
        return self.state.velocities

    def set_velocities(self, velocities: np.ndarray) -> None:
        self.state.velocities = velocities

    def approaching(self) -> int:
        """The number of live contacts."""
        return int(self.live_flags(self.velocities()).sum())

    def is_frozen(self) -> bool:
        return not self._any_live(*self.model.chain(self.velocities()))

    def live_flags(self, velocities: np.ndarray) -> np.ndarray:
        """``(E,) uint8``: the live contacts of ``velocities`` in float arithmetic (1 where a pick would collide)."""
        flags = np.empty(self.model.geometry.n_contacts, dtype=np.uint8)
        self._live_flags(*self.model.chain(velocities), flags)
        return flags

    def tell(self, steps: np.ndarray, contacts: np.ndarray) -> None:
        """Tell the listeners of collisions at ``steps`` of ``contacts``."""
        for listener in self.listeners:
            listener(steps, contacts)

    def resources(self) -> dict:
        """What this chain's runs have used so far, as a run's provenance records it (`util.provenance`):
        ``{"kind": "cpu", "threads": 1}`` here (one thread); a backend that runs elsewhere says so."""
        return {"kind": "cpu", "threads": 1}

    # ------------------------------------------------------------ its state, saved and restored
    def saved(self) -> dict:
        """The parts of a `engine.state.RunState` this backend's arithmetic keeps beyond the velocities, counters,
        stream and scheduler, as copies: in float arithmetic the closing margin (``{"margin": (4,) float64}``)."""
        return {"margin": self.state.margin.copy()}

    def restore(self, state, velocities: np.ndarray) -> None:
        """Take ``state``'s arithmetic's parts (`saved`'s), checked before anything changes, and ``velocities``
        (``(n_balls, dim)``, checked by the simulation); a `FieldError` naming the part that does not fit."""
        self.set_velocities(velocities)
