"""The engine's one door: engines are registered objects saying what they run, and one function chooses.

An `Engine` has a ``name``, the ``devices`` and ``arithmetics`` it runs, and answers `Engine.supports` with
None or a `Refusal` (the field to change, the reason, what runs it instead); `Engine.build` gives the backend
that runs a chain (`engine.backends`: the chunk protocol the driver calls). The built-in engines, one per room
(`engine.engines`), are registered when the door is first used, in the order it prefers them; a user's engine
comes in through `register` (docs/architecture.md), and ``Simulation(..., engine=NAME)`` forces one.

`choose` is where every chain's engine is chosen: a `Simulation`, an ensemble's replicas together
(``replicas=True``) and a check made before anything runs (`check`). Above the engine nothing compares a
device's name or matches a refusal's text: it asks the door, and prints what the door refuses as it is.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from ..util.errors import FieldError
from .devices import Device, as_device

__all__ = ["Refusal", "Refused", "Engine", "engines", "register", "unregister", "find", "choose", "check"]


@dataclass(frozen=True)
class Refusal:
    """Why an engine does not run a chain: ``field`` (what to change: ``"device"``, ``"arithmetic"``,
    ``"engine"``...), ``reason`` and ``instead`` (what runs it instead), and ``needs``: what it would take, by the
    field a spec states it in (``{"scheduler": "counter"}``: the counter stream), for a caller that says it in
    its own words."""

    field: str
    reason: str
    instead: str = ""
    needs: tuple[tuple[str, str], ...] = ()

    @property
    def message(self) -> str:
        """The reason and what runs it instead, as one line."""
        return f"{self.reason}; {self.instead}" if self.instead else self.reason

    def error(self) -> Refused:
        """The refusal as the error that says it (a `FieldError` on ``field``)."""
        return Refused(self)


class Refused(FieldError):
    """A chain no engine runs, as the error that says so: a `FieldError` on the refusal's field, its
    `Refusal` kept (``refusal``) for a caller that words it for its own input (a spec)."""

    def __init__(self, refusal: Refusal):
        super().__init__(refusal.field, refusal.message)
        self.refusal = refusal

    def __reduce__(self):
        return type(self), (self.refusal,)


class Engine:
    """What runs chains: a name, the devices (kinds: ``"cpu"``, ``"cuda"``) and arithmetics it runs, whether it
    runs an ensemble's replicas together (``replicas``), and the two calls of the door.

    Subclass it, set the attributes, and override `supports` and `build` (docs/architecture.md shows one).
    """

    name: str = ""
    devices: tuple[str, ...] = ()
    arithmetics: tuple[str, ...] = ()
    #: it runs many replicas of one spec together (an ensemble's), not one simulation's chain
    replicas: bool = False

    def supports(self, model, arithmetic: str, device: Device) -> Refusal | None:
        """None when this engine runs ``model`` (`engine.chain.Model`) in ``arithmetic`` on ``device``, else why
        not. Cheap: what needs a compile or a GPU is checked by `build`."""
        return self.refuse_kinds(arithmetic, device)

    def build(self, model, state, listeners: list, device: Device, options: dict):
        """The backend running ``model`` from ``state`` (`engine.chain.ChainState`, written in place), telling
        ``listeners`` of each collision; a `FieldError` where a check only the build can make fails."""
        raise NotImplementedError

    def refuse_kinds(self, arithmetic: str, device: Device) -> Refusal | None:
        """The refusal of an arithmetic or a device this engine does not run at all."""
        if device.kind not in self.devices:
            return Refusal("device", f"engine {self.name!r} runs on {' and '.join(self.devices)}, not {device.kind}")
        if arithmetic not in self.arithmetics:
            return Refusal("arithmetic", f"engine {self.name!r} runs {' and '.join(self.arithmetics)} arithmetic, "
                                         f"not {arithmetic}")
        return None

    def __repr__(self) -> str:
        return (f"<engine {self.name!r}: {', '.join(self.arithmetics)} on {', '.join(self.devices)}"
                f"{', replicas' if self.replicas else ''}>")


_REGISTRY: dict[str, Engine] = {}
_BUILT_IN = False


def _registry() -> dict[str, Engine]:
    """The registered engines, the built-in ones first registered on first use."""
    global _BUILT_IN
    if not _BUILT_IN:
        _BUILT_IN = True
        from .engines import BUILT_IN

        for engine in BUILT_IN:
            _REGISTRY.setdefault(engine.name, engine)
    return _REGISTRY


def engines() -> list[Engine]:
    """Every registered engine, in the order the door prefers them (a user's after the built-in ones).

    Examples
    --------
    >>> from pinnedballs.engine import engines
    >>> [e.name for e in engines()][:3]
    ['colored_sweep', 'threads', 'sequential']
    """
    return list(_registry().values())


def register(engine: Engine, *, replace: bool = False) -> Engine:
    """Add ``engine`` to the door (after those registered before it); returns it. A name already registered
    is an error unless ``replace``."""
    if not isinstance(engine, Engine):
        raise TypeError(f"engine: must be a pinnedballs.engine.Engine, got {type(engine).__name__}")
    if not (isinstance(engine.name, str) and engine.name.isidentifier()):
        raise ValueError(f"engine: its name must be an identifier, got {engine.name!r}")
    registry = _registry()
    if engine.name in registry and not replace:
        raise ValueError(f"engine: {engine.name!r} is registered already (pass replace=True to replace it)")
    registry[engine.name] = engine
    return engine


def unregister(name: str) -> None:
    """Take the engine ``name`` out of the door (a KeyError when none has it)."""
    del _registry()[name]


def find(name: str) -> Engine:
    """The registered engine ``name``; a `FieldError` on ``engine`` listing them otherwise."""
    registry = _registry()
    if name not in registry:
        raise FieldError("engine", f"no engine {name!r} is registered (registered: {', '.join(registry)})")
    return registry[name]


def _candidates(replicas: bool) -> Iterator[Engine]:
    return (e for e in _registry().values() if e.replicas == replicas)


def choose(model, arithmetic: str, device, *, engine: str | None = None, replicas: bool = False) -> Engine:
    """The engine that runs ``model`` in ``arithmetic`` on ``device`` (a `Device` or its name): ``engine``,
    named, if it does, else the first registered that does (of those running replicas together, with
    ``replicas``). A `Refused` error saying why where none does: the refusal of the first engine that runs this
    arithmetic on this device (it knows best what is missing), else that of the device itself."""
    device = as_device(device)
    if engine is not None:
        chosen = find(engine)
        if chosen.replicas != replicas:
            raise FieldError("engine", f"{engine!r} runs {'replicas together' if chosen.replicas else 'one chain'}, "
                                       f"not {'replicas together' if replicas else 'one chain'}")
        refusal = chosen.supports(model, arithmetic, device)
        if refusal is not None:
            raise refusal.error()
        return chosen
    first = None
    for candidate in _candidates(replicas):
        refusal = candidate.supports(model, arithmetic, device)
        if refusal is None:
            return candidate
        if first is None and device.kind in candidate.devices and arithmetic in candidate.arithmetics:
            first = refusal
    raise (first or _no_engine(arithmetic, device, replicas)).error()


def _no_engine(arithmetic: str, device: Device, replicas: bool) -> Refusal:
    """No engine runs ``arithmetic`` on ``device``: the arithmetics the device's engines run, and where this one
    runs instead."""
    what = "an ensemble's replicas in " if replicas else ""
    here = sorted({a for e in _candidates(replicas) if device.kind in e.devices for a in e.arithmetics},
                  key=("float", "certified", "exact").index)
    elsewhere = sorted({d for e in _candidates(False) if arithmetic in e.arithmetics for d in e.devices} -
                       {device.kind})
    instead = f"{arithmetic} arithmetic runs on the {' or the '.join(d.upper() for d in elsewhere)}"
    if replicas and arithmetic == "certified" and device.gpu:
        instead += ", or one replica a call (pinnedballs run SPEC --device cuda)"
    if not replicas and arithmetic == "exact" and "certified" in here:
        instead += " (certified arithmetic proves its decisions: arithmetic='certified')"
    return Refusal("device", f"{device.kind!r} runs {what}{' and '.join(here)} arithmetic", instead)


def check(model, arithmetic: str, device, *, replicas: bool = False, here: bool = True,
          rule=None, scheduler=None) -> Engine:
    """`choose`, and the checks its engine makes before it builds (`Engine.check`, where it has one: a GPU
    engine compiles the rule and asks for a GPU; with ``here=False`` the chain runs elsewhere, a cluster's GPUs,
    so this process needs neither). ``rule`` and ``scheduler`` name them in a message."""
    chosen = choose(model, arithmetic, device, replicas=replicas)
    prepare = getattr(chosen, "check", None)
    if prepare is not None:
        prepare(model, arithmetic, as_device(device), here=here, rule=rule, scheduler=scheduler)
    return chosen
