"""The engine's one door: engines are registered objects saying what they run, and one function chooses.

An `Engine` has a ``name``, the ``devices`` and ``arithmetics`` it runs, and answers `Engine.supports` with
None or a `Refusal` (the field to change, the reason, what runs it instead); `Engine.build` gives the backend
that runs a chain (`engine.backends`: the chunk protocol the driver calls). The built-in engines, one per room
(`engine.builtin`), are registered when the door is first used, in the order it prefers them; a user's engine
comes in through `register` (docs/architecture.md), and ``Simulation(..., engine=NAME)`` forces one.

`choose` is where every chain's engine is chosen: a `Simulation`, an ensemble's replicas together
(``replicas=True``) and a check made before anything runs (`check`). Above the engine nothing compares a
device's name or matches a refusal's text: it asks the door, and prints what the door refuses as it is.
"""

from __future__ import annotations

from collections.abc import Iterator

from ..util.errors import FieldError
from .devices import Device, as_device
from .protocol import Engine, Refusal

__all__ = ["engines", "register", "unregister", "find", "choose", "check", "options", "ready", "simulated",
           "ARITHMETICS"]

#: the arithmetics a chain runs in (`Simulation`'s ``arithmetic``)
ARITHMETICS = ("float", "exact", "certified")


_REGISTRY: dict[str, Engine] = {}
_BUILT_IN = False


def _registry() -> dict[str, Engine]:
    """The registered engines, the built-in ones first registered on first use."""
    global _BUILT_IN
    if not _BUILT_IN:
        _BUILT_IN = True
        from .builtin import BUILT_IN

        for engine in BUILT_IN:
            _REGISTRY.setdefault(engine.name, engine)
    return _REGISTRY


def engines() -> list[Engine]:
    """Every registered engine, in the order the door prefers them (a user's after the built-in ones).

    Returns
    -------
    list of Engine
        Each with its ``name``, ``devices``, ``arithmetics`` and `Engine.supports`.

    Examples
    --------
    >>> from pinnedballs.engine import engines
    >>> [e.name for e in engines()][:3]
    ['colored_sweep', 'threads', 'sequential']
    """
    return list(_registry().values())


def register(engine: Engine, *, replace: bool = False) -> Engine:
    """Add ``engine`` to the door, after those registered before it (docs/architecture.md).

    Parameters
    ----------
    engine : Engine
        The engine; its ``name`` an identifier.
    replace : bool
        Replace the engine registered under its name already.

    Returns
    -------
    Engine
        ``engine``.

    Raises
    ------
    TypeError
        If ``engine`` is not an `Engine`.
    ValueError
        If its name is not an identifier, or is registered already (without ``replace``).

    Examples
    --------
    >>> from pinnedballs.engine import Engine, engines, register, unregister
    >>> class Mine(Engine):
    ...     name, devices, arithmetics = "mine", ("cpu",), ("float",)
    >>> register(Mine())
    <engine 'mine': float on cpu>
    >>> [e.name for e in engines()][-1]
    'mine'
    >>> unregister("mine")
    """
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
    """Take an engine out of the door.

    Parameters
    ----------
    name : str
        The engine's name.

    Raises
    ------
    KeyError
        When no engine has it.
    """
    del _registry()[name]


def find(name: str) -> Engine:
    """The registered engine of a name.

    Parameters
    ----------
    name : str
        The engine's name.

    Returns
    -------
    Engine

    Raises
    ------
    FieldError
        On ``engine``, listing the registered ones, where none has it.

    Examples
    --------
    >>> from pinnedballs.engine import find
    >>> find("sequential")
    <engine 'sequential': float on cpu>
    """
    registry = _registry()
    if name not in registry:
        raise FieldError("engine", f"no engine {name!r} is registered (registered: {', '.join(registry)})")
    return registry[name]


def _candidates(replicas: bool) -> Iterator[Engine]:
    return (e for e in _registry().values() if e.replicas == replicas)


def choose(model, arithmetic: str, device, *, engine: str | None = None, replicas: bool = False) -> Engine:
    """The engine that runs ``model`` in ``arithmetic`` on ``device``: the one place an engine is chosen.

    Parameters
    ----------
    model : pinnedballs.engine.chain.Model
        What the chain is (a simulation's ``sim.engine.model``).
    arithmetic : {"float", "exact", "certified"}
        The chain's arithmetic.
    device : Device or str
        A `Device` or its name.
    engine : str, optional
        An engine's name: that one, if it runs the chain.
    replicas : bool
        Choose among the engines that run an ensemble's replicas together.

    Returns
    -------
    Engine
        ``engine``, named, if it runs the chain, else the first registered that does.

    Raises
    ------
    Refused
        Saying why where none does: the refusal of the first engine that runs this arithmetic on this device
        (it knows best what is missing), else that of the device itself; or the named engine's.
    FieldError
        On ``engine``: no engine of that name, or one that runs replicas where one chain is asked for (or the
        other way round).

    Examples
    --------
    >>> import pinnedballs as pb
    >>> from pinnedballs.engine import choose
    >>> g = pb.HalfPlane(rows=2, cols=2)
    >>> model = pb.Simulation(g, [[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], seed=0).engine.model
    >>> choose(model, "certified", "cpu").name
    'field'
    >>> choose(model, "float", "cuda")
    Traceback (most recent call last):
    ...
    pinnedballs.engine.protocol.Refused: device: 'cuda' runs UniformRandomPair(stream='counter') ...
    """
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
    """`choose`, and the checks its engine makes before it builds, before anything runs.

    ``Engine.check``, where the engine has one: a GPU engine compiles the rule and asks for a GPU.

    Parameters
    ----------
    model : pinnedballs.engine.chain.Model
        What the chain is.
    arithmetic : {"float", "exact", "certified"}
        The chain's arithmetic.
    device : Device or str
        A `Device` or its name.
    replicas : bool
        As for `choose`.
    here : bool
        False: the chain runs elsewhere, a cluster's GPUs, so this process needs neither.
    rule, scheduler : optional
        Named in a message.

    Returns
    -------
    Engine
        The engine `choose` chooses.

    Raises
    ------
    Refused
        As for `choose`.
    FieldError
        Where the engine's checks fail (`pinnedballs.GPUUnavailable`: no numba-cuda or no GPU).
    """
    chosen = choose(model, arithmetic, device, replicas=replicas)
    prepare = getattr(chosen, "check", None)
    if prepare is not None:
        prepare(model, arithmetic, as_device(device), here=here, rule=rule, scheduler=scheduler)
    return chosen


def options(arithmetic: str, precision=None, late_precision=None) -> dict:
    """What the engines are given beside a chain, checked: its ``arithmetic`` (one of `ARITHMETICS`) and
    certified arithmetic's ``precision`` and ``late_precision`` (bits: `engine.field.arithmetic.check_precisions`,
    a `FieldError` naming the one that is wrong, or given to another arithmetic)."""
    from ..util import checks
    from .field.arithmetic import check_precisions

    arithmetic = checks.choice("arithmetic", arithmetic, ARITHMETICS)
    precision, late_precision = check_precisions(arithmetic, precision, late_precision)
    return {"arithmetic": arithmetic, "precision": precision, "late_precision": late_precision}


def ready(device) -> None:
    """Nothing where ``device`` (a `Device` or its name) is here; else its one-line refusal: a GPU needs numba-cuda
    and a GPU it sees, or its simulator (`pinnedballs.GPUUnavailable` saying which is missing)."""
    if as_device(device).gpu:
        from .gpu import load

        load()


def simulated(device) -> bool:
    """Whether chains on ``device`` (a `Device` or its name) run under numba-cuda's simulator
    (``NUMBA_ENABLE_CUDASIM=1``: the kernels as Python threads on the CPU), not on a GPU."""
    if not as_device(device).gpu:
        return False
    from .gpu.compile import SIMULATED

    return bool(SIMULATED)
