"""The conformance battery every engine passes (`check_engine`): an engine registered at the door
(`pinnedballs.engine.register`), built-in or a user's, runs small systems it supports with the bits of the
engine it stands in for, however a run is split, to a collision count or to the freeze, and refuses in one
line what it does not run.

Each check is a function of the engine (an `Engine`, or a registered engine's name) that raises an
`AssertionError` naming the property, the engine and the system where it breaks. The systems are `SYSTEMS`:
small half-planes from one moving ball (on the xoshiro stream and the counter stream, in float, exact and
certified arithmetic) and a small torus from Gaussian velocities (never frozen). A check runs on the systems
the engine supports on its first device (`Engine.supports`); the reference is ``"sequential"``'s run in float
arithmetic, ``"field"``'s in exact and certified arithmetic (those two are checked against the plain-Python
twin of the chain, in the project's own tests).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from ..engine import door
from ..engine.devices import Device, as_device
from ..engine.protocol import Engine, Refused
from ..geometry.lattices import FlatTorus, HalfPlane
from ..schedulers import ColoredSweep, UniformRandomPair
from ..simulation import Simulation

__all__ = ["SYSTEMS", "LARGE_SYSTEMS", "System", "ENGINE_CHECKS", "check_engine", "engine_checks_for", "systems_for",
           "check_engine_split_runs", "check_engine_collision_target", "check_engine_until_frozen",
           "check_engine_resume", "check_engine_agrees_with_reference", "check_engine_refuses", "check_engine_replicas",
           "REPLICAS_CHECKS"]

#: the engine a check compares with, by arithmetic
REFERENCE = {"float": "sequential", "exact": "field", "certified": "field"}


@dataclass(frozen=True)
class System:
    """A small system an engine is run on: its ``name``, a ``build() -> (geometry, velocities, scheduler)``
    (fresh each call: schedulers hold no state, but a check must not share one run's arrays with another),
    its ``arithmetic``, whether it freezes (``freezes``, within ``max_steps``) and the steps of a short run
    (``steps``), and the devices it runs on (``devices``: a large system on the CPU alone, which numba-cuda's
    simulator would take hours over)."""

    name: str
    build: Callable
    arithmetic: str = "float"
    freezes: bool = True
    steps: int = 700
    max_steps: int = 10**6
    devices: tuple[str, ...] = ("cpu", "cuda")

    def simulation(self, engine: str | None, device: Device, seed: int = 11) -> Simulation:
        """The system's simulation on ``engine`` (None: the door's choice) and ``device``."""
        return self.simulations(engine, device, [seed])[0]

    def simulations(self, engine: str | None, device: Device, seeds: list[int]) -> list[Simulation]:
        """Simulations of the system on one geometry, one a seed (replicas)."""
        g, v, scheduler = self.build()
        sims = [Simulation(g, v, scheduler=scheduler, seed=seed, arithmetic=self.arithmetic, device=device,
                           engine=engine) for seed in seeds]
        for sim in sims:
            sim.warns_thin_margin = False  # a check compares counts; the margin is compared, not told
        return sims


def _half_plane(stream: str, length: int = 12, depth: int = 6) -> Callable:
    def build():
        g = HalfPlane.from_size(length, depth)
        v = np.zeros((g.n_balls, 2))
        v[g.boundary_center()] = [0.3, np.sqrt(200.0)]
        return g, v, UniformRandomPair(stream=stream)

    return build


def _torus(scheduler: Callable) -> Callable:
    def build():
        g = FlatTorus(6, 6)
        v = np.random.default_rng(3).normal(size=(g.n_balls, 2))
        return g, v, scheduler()

    return build


#: the systems the checks run on (each engine those it supports)
SYSTEMS = (
    System("half_plane/xoshiro", _half_plane("xoshiro")),
    System("half_plane/counter", _half_plane("counter")),
    System("half_plane/xoshiro/exact", _half_plane("xoshiro"), "exact"),
    System("half_plane/counter/certified", _half_plane("counter"), "certified"),
    System("torus/counter", _torus(lambda: UniformRandomPair(stream="counter")), freezes=False, steps=400),
    System("torus/colored_sweep", _torus(ColoredSweep), freezes=False, steps=400),
)
#: the systems ``large=True`` adds: large enough for threads to pay (`engine.threads.regions.MIN_PARALLEL_CONTACTS`,
#: so the threaded chains run), run by compiled loops in a second or two (on the CPU alone: numba-cuda's simulator
#: would take hours)
LARGE_SYSTEMS = (
    System("half_plane_large/xoshiro", _half_plane("xoshiro", 400, 200), steps=300_000, max_steps=10**9,
           devices=("cpu",)),
    System("half_plane_large/counter", _half_plane("counter", 400, 200), steps=300_000, max_steps=10**9,
           devices=("cpu",)),
)


def _engine(engine: Engine | str) -> Engine:
    if isinstance(engine, str):
        return door.find(engine)
    if not isinstance(engine, Engine):
        raise TypeError(f"engine: must be a pinnedballs.engine.Engine or a registered engine's name, "
                        f"got {type(engine).__name__}")
    return engine


@contextlib.contextmanager
def _at_the_door(engine: Engine) -> Iterator[str]:
    """``engine``'s name, with ``engine`` registered meanwhile (taken out again if it was not)."""
    registered = {e.name: e for e in door.engines()}
    if type(registered.get(engine.name)) is type(engine):  # it, or another of its kind under its name
        yield engine.name
        return
    if engine.name in registered:
        raise ValueError(f"engine: another engine is registered as {engine.name!r}")
    door.register(engine)
    try:
        yield engine.name
    finally:
        door.unregister(engine.name)


def _device(engine: Engine) -> Device:
    return as_device(engine.devices[0])


def _model(system: System):
    """The system's chain as the door sees it, built on the CPU by the door's own choice."""
    return system.simulation(None, as_device("cpu")).engine.model


def systems_for(engine: Engine | str, large: bool = False) -> list[System]:
    """The `SYSTEMS` (and with ``large`` the `LARGE_SYSTEMS`) ``engine`` runs on its first device."""
    engine = _engine(engine)
    device = _device(engine)
    return [s for s in (*SYSTEMS, *(LARGE_SYSTEMS if large else ())) if device.kind in s.devices
            and engine.supports(_model(s), s.arithmetic, device) is None]


def _say(check: str, engine: Engine, system: System, what: str) -> str:
    return f"{check}: engine {engine.name!r} on {system.name}: {what}"


def _same(a: Simulation, b: Simulation) -> str:
    """What differs between two simulations' states ("" when none): velocities, counters, stream, margin."""
    sa, sb = a.get_state(), b.get_state()
    if sa.identical(sb):
        return ""
    parts = [name for name in ("velocities", "rng_state", "scheduler_state")
             if not np.array_equal(getattr(sa, name), getattr(sb, name))]
    if (sa.steps, sa.collisions) != (sb.steps, sb.collisions):
        parts.append(f"counts {sa.steps} steps, {sa.collisions} collisions against {sb.steps}, {sb.collisions}")
    if not ((sa.margin is None) == (sb.margin is None) and (sa.margin is None or np.array_equal(sa.margin, sb.margin))):
        parts.append("closing margin")
    return ", ".join(parts) or "certified or exact state"


def _runs(engine: Engine, large: bool) -> Iterator[tuple[str, System]]:
    """``(name, system)`` for each system ``engine`` runs, the engine at the door meanwhile."""
    with _at_the_door(engine) as name:
        for system in systems_for(engine, large):
            yield name, system


def check_engine_split_runs(engine: Engine | str, large: bool = False) -> None:
    """A run split into calls (1, 2, many steps; a collision target between) ends on the bits of one call.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    engine = _engine(engine)
    for name, s in _runs(engine, large):
        whole, split = s.simulation(name, _device(engine)), s.simulation(name, _device(engine))
        whole.run(steps=s.steps)
        for steps in (1, 2, 97, s.steps // 3):
            split.run(steps=steps)
        split.run(collisions=split.collisions + 3)
        split.run(steps=max(0, s.steps - split.steps))  # (a broken collision target may have run past them)
        differ = _same(split, whole)
        assert not differ, _say("check_engine_split_runs", engine, s,
                                f"a run split into calls ends otherwise than one call: {differ}")


def check_engine_collision_target(engine: Engine | str, large: bool = False) -> None:
    """``run(collisions=c)`` stops right after the ``c``-th collision, on the reference engine's step.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    engine = _engine(engine)
    for name, s in _runs(engine, large):
        sim, ref = s.simulation(name, _device(engine)), s.simulation(REFERENCE[s.arithmetic], as_device("cpu"))
        for target in (1, 5, 23):
            sim.run(collisions=target)
            ref.run(collisions=target)
            differ = _same(sim, ref)
            assert sim.collisions == target and not differ, _say(
                "check_engine_collision_target", engine, s, f"run(collisions={target}) stopped at {sim.steps} steps, "
                f"{sim.collisions} collisions; the reference at {ref.steps}, {ref.collisions} ({differ or 'no other'} "
                f"differences)")


def check_engine_until_frozen(engine: Engine | str, large: bool = False) -> None:
    """A run until frozen stops right after its last collision (the reference's step), frozen; one more run
    takes no step.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    engine = _engine(engine)
    for name, s in _runs(engine, large):
        if not s.freezes:
            continue
        sim, ref = s.simulation(name, _device(engine)), s.simulation(REFERENCE[s.arithmetic], as_device("cpu"))
        frozen = sim.run_until_frozen(max_steps=s.max_steps)
        ref.run_until_frozen(max_steps=s.max_steps)
        steps = sim.steps
        again = sim.run_until_frozen(max_steps=s.max_steps)
        differ = _same(sim, ref)
        assert frozen and again and sim.steps == steps and sim.is_frozen() and not differ, _say(
            "check_engine_until_frozen", engine, s, f"frozen {frozen} at {steps} steps ({sim.steps} after another "
            f"run), the reference at {ref.steps}; {differ or 'the same state'}")


def check_engine_resume(engine: Engine | str, large: bool = False) -> None:
    """A state saved mid-run (`Simulation.get_state`), restored into a new simulation on the engine, continues
    on the bits of the unbroken run.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    engine = _engine(engine)
    for name, s in _runs(engine, large):
        whole, first = s.simulation(name, _device(engine)), s.simulation(name, _device(engine))
        whole.run(steps=2 * s.steps)
        first.run(steps=s.steps)
        second = s.simulation(name, _device(engine), seed=12345)  # another stream, restored below
        second.set_state(first.get_state())
        second.run(steps=s.steps)
        differ = _same(second, whole) or ("" if second.closing_margin() == whole.closing_margin() else
                                          "closing margin")
        assert not differ, _say("check_engine_resume", engine, s, f"a run resumed from a saved state ends otherwise: "
                                                                  f"{differ}")


def check_engine_agrees_with_reference(engine: Engine | str, large: bool = False) -> None:
    """The bits of the reference engine (``"sequential"`` for floats, ``"field"`` for exact and certified
    arithmetic) on every system: velocities, counters, stream, scheduler and closing margin.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    engine = _engine(engine)
    for name, s in _runs(engine, large):
        sim, ref = s.simulation(name, _device(engine)), s.simulation(REFERENCE[s.arithmetic], as_device("cpu"))
        sim.run(steps=s.steps)
        ref.run(steps=s.steps)
        differ = _same(sim, ref)
        assert not differ, _say("check_engine_agrees_with_reference", engine, s,
                                f"not the bits of {REFERENCE[s.arithmetic]!r}: {differ}")
        assert sim.closing_margin() == ref.closing_margin(), _say("check_engine_agrees_with_reference", engine, s,
                                                                  "another closing margin than the reference's")


def check_engine_refuses(engine: Engine | str, large: bool = False) -> None:
    """A system the engine does not run, forced on it, is refused before anything runs: one line on a field,
    the engine's `Refusal`.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    engine = _engine(engine)
    with _at_the_door(engine) as name:
        device = _device(engine)
        refused = [s for s in SYSTEMS if device.kind in s.devices and s not in systems_for(engine)]  # small: cheap
        for s in refused:
            try:
                s.simulation(name, _device(engine))
            except Refused as exc:
                assert exc.refusal.field and "\n" not in str(exc), _say(
                    "check_engine_refuses", engine, s, f"a refusal of more than one line, or on no field: {exc!r}")
            else:
                raise AssertionError(_say("check_engine_refuses", engine, s, "built a simulation of a system its "
                                                                             "supports() refuses"))


def check_engine_replicas(engine: Engine | str, large: bool = False) -> None:
    """An engine of replicas (``engine.replicas``) runs simulations of one system together (`run.ensemble_gpu.
    run_replicas`) to steps, a collision count and the freeze, each then in the state of the same simulation run
    alone on the reference engine, and going on from there with its bits.

    Parameters
    ----------
    engine : Engine or str
        The engine checked, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (as for `check_engine`).

    Raises
    ------
    AssertionError
        Naming the property that does not hold and the engine and the system.
    """
    from ..engine.stop import Stop
    from ..run.ensemble_gpu import run_replicas

    engine = _engine(engine)
    with _at_the_door(engine) as name:
        for s in SYSTEMS:
            if engine.supports(_model(s), s.arithmetic, _device(engine)) is not None:
                continue
            mine = s.simulations(None, as_device("cpu"), [0, 1, 2])
            ref = s.simulations(REFERENCE[s.arithmetic], as_device("cpu"), [0, 1, 2])
            last = s.max_steps if s.freezes else 2 * s.steps  # to the freeze, where there is one
            stops = [Stop(steps=s.steps), Stop(collisions=9, until_frozen=True),
                     Stop(steps=last, until_frozen=s.freezes)]
            run_replicas(mine, stops, engine=name)
            ref[0].run(steps=s.steps)
            ref[1].run(collisions=9)
            ref[2].run(steps=last, until_frozen=s.freezes)
            for r, (a, b) in enumerate(zip(mine, ref)):
                differ = _same(a, b)
                assert not differ, _say("check_engine_replicas", engine, s, f"replica {r} ({stops[r]}) ends "
                                                                           f"otherwise than alone: {differ}")
                a.run(steps=s.steps)
                b.run(steps=s.steps)
                differ = _same(a, b)
                assert not differ, _say("check_engine_replicas", engine, s, f"replica {r} goes on otherwise than "
                                                                           f"the simulation alone: {differ}")


#: every engine check, in the order they run
ENGINE_CHECKS = (check_engine_refuses, check_engine_agrees_with_reference, check_engine_split_runs,
                 check_engine_collision_target, check_engine_until_frozen, check_engine_resume)
#: the checks of an engine of replicas
REPLICAS_CHECKS = (check_engine_replicas,)


def engine_checks_for(engine: Engine | str) -> list[Callable]:
    """The checks that apply to ``engine``, in the order they run.

    Parameters
    ----------
    engine : Engine or str
        The engine, or a registered engine's name.

    Returns
    -------
    list of callable
        All of `ENGINE_CHECKS`, but the comparison with the reference for a reference engine itself
        (``"sequential"``, ``"field"``); for an engine of replicas, `REPLICAS_CHECKS`.

    Examples
    --------
    >>> from pinnedballs.testing import engine_checks_for
    >>> [c.__name__ for c in engine_checks_for("sequential")][:2]
    ['check_engine_refuses', 'check_engine_split_runs']
    """
    engine = _engine(engine)
    if engine.replicas:
        return list(REPLICAS_CHECKS)
    return [c for c in ENGINE_CHECKS
            if not (c is check_engine_agrees_with_reference and engine.name in REFERENCE.values())]


def check_engine(engine: Engine | str, large: bool = False) -> None:
    """Run every engine check on ``engine`` (an `Engine`, registered or not, or a registered engine's name); the
    first that fails raises its `AssertionError`, naming the property, the engine and the system.

    Parameters
    ----------
    engine : Engine or str
        The engine, or a registered engine's name.
    large : bool
        Also the `LARGE_SYSTEMS` (half-planes of 69,000 contacts, to the freeze: seconds for a compiled engine,
        where an engine that only pays on large systems, as threads do, runs its own loops).

    Raises
    ------
    AssertionError
        The first check that fails, naming the property, the engine and the system.

    Examples
    --------
    >>> from pinnedballs.testing import check_engine
    >>> check_engine("sequential")
    """
    for check in engine_checks_for(engine):
        check(engine, large)
