"""A component survives being written down: as its run spec (`to_spec`, through JSON and the spec's
`build`) and as a pickle (what ensembles on other processes and Dask workers receive). Each is a
check: ``check(component)`` returns, or raises an `AssertionError` saying what came back different.

"The same" is what a run sees: a geometry's positions and contact tables bit for bit (and its spec
again); a rule's compiled function and parameters, for equal and unequal masses; a scheduler equal
of its class (from a pickle: equal to it, `Scheduler.__eq__`) that gives the same 2,000 steps on the
torus, bit for bit.
"""

from __future__ import annotations

import json
import pickle

import numpy as np

from ..geometry.lattices import FlatTorus
from ..specs.run import parse_spec
from .samples import SEED, fail, simulation

__all__ = ["check_geometry_spec_round_trip", "check_geometry_pickles", "check_rule_spec_round_trip",
           "check_rule_pickles", "check_scheduler_spec_round_trip", "check_scheduler_pickles"]

_TORUS = {"kind": "flat_torus", "rows": 4, "cols": 3}


def _from_spec(prop: str, slot: str, spec: dict):
    """The component a run spec's ``slot`` builds from ``spec``, through JSON."""
    run = {"geometry": _TORUS, "initial": {"kind": "gaussian", "energy": 1.0}, "stop": {"steps": 1}}
    try:
        text = json.dumps(spec)
    except (TypeError, ValueError) as error:
        fail(prop, f"to_spec() gave {spec!r}, which is not JSON ({error})")
    try:
        return getattr(parse_spec({**run, slot: json.loads(text)}), slot).build()
    except (ValueError, TypeError) as error:
        fail(prop, f"to_spec() gave {spec!r}, which does not build: {type(error).__name__}: {error}")


def _pickled(prop: str, component):
    try:
        return pickle.loads(pickle.dumps(component))
    except Exception as error:  # noqa: BLE001 - whatever pickle raises is the finding
        fail(prop, f"{component!r} does not pickle: {type(error).__name__}: {error}")


def _same_geometry(prop: str, a, b) -> None:
    if type(a) is not type(b):
        fail(prop, f"a {type(a).__name__} came back as a {type(b).__name__}")
    if not np.array_equal(np.asarray(a.positions), np.asarray(b.positions)):
        fail(prop, "the positions came back different")
    ca, cb = a.contacts, b.contacts
    for name in ("pairs", "ends", "units"):
        x, y = getattr(ca, name), getattr(cb, name)
        if x.dtype != y.dtype or not np.array_equal(x, y):
            fail(prop, f"the contact table {name} came back different ({x.dtype} {x.shape} against {y.dtype} "
                       f"{y.shape})")
    if a.to_spec() != b.to_spec():
        fail(prop, f"its spec {a.to_spec()!r} came back as {b.to_spec()!r}")


def check_geometry_spec_round_trip(geometry) -> None:
    """``geometry.to_spec()``, through JSON and the spec's ``build``, gives the same geometry. (Nothing
    to check for a geometry without a spec.)

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    spec = geometry.to_spec()
    if spec is not None:
        _same_geometry("spec round trip", geometry, _from_spec("spec round trip", "geometry", spec))


def check_geometry_pickles(geometry) -> None:
    """A pickled geometry comes back the same.

    Parameters
    ----------
    geometry : Geometry
        The geometry checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    _same_geometry("pickles", geometry, _pickled("pickles", geometry))


def _same_rule(prop: str, a, b) -> None:
    if type(a) is not type(b):
        fail(prop, f"{a!r} came back as a {type(b).__name__}")
    for equal in (True, False):
        (fa, pa), (fb, pb) = a.kernel(equal), b.kernel(equal)
        if fa is not fb or not np.array_equal(np.asarray(pa), np.asarray(pb)):
            fail(prop, f"{a!r} came back as {b!r}: kernel({equal}) gives {getattr(fb, '__name__', fb)} with "
                       f"params {np.asarray(pb).tolist()}, not {getattr(fa, '__name__', fa)} with "
                       f"{np.asarray(pa).tolist()}")


def check_rule_spec_round_trip(rule) -> None:
    """``rule.to_spec()``, through JSON and the spec's ``build``, gives a rule with the same compiled
    function and parameters. (Nothing to check for a rule without a spec.)

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    spec = rule.to_spec()
    if spec is not None:
        _same_rule("spec round trip", rule, _from_spec("spec round trip", "rule", spec))


def check_rule_pickles(rule) -> None:
    """A pickled rule comes back with the same compiled function and parameters.

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    _same_rule("pickles", rule, _pickled("pickles", rule))


def _same_scheduler(prop: str, a, b, equal: bool) -> None:
    if type(a) is not type(b) or (equal and not a == b):
        fail(prop, f"{a!r} came back as {b!r}, not equal to it")
    g = FlatTorus(4, 3)
    v = np.random.default_rng(SEED).standard_normal((g.n_balls, 2))
    runs = [simulation(prop, g, v, scheduler=s, seed=SEED) for s in (a, b)]
    for sim in runs:
        sim.run(steps=2000, progress=False)
    if not runs[0].get_state().identical(runs[1].get_state()):
        fail(prop, f"{a!r} and what came back run 2,000 steps on {g!r} (seed {SEED}) differently")


def check_scheduler_spec_round_trip(scheduler) -> None:
    """``scheduler.to_spec()``, through JSON and the spec's ``build``, gives a scheduler of its class that
    runs the same (a spec need not keep what changes no bit, such as a number of threads). (Nothing to
    check for a scheduler without a spec.)

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    spec = scheduler.to_spec()
    if spec is not None:
        _same_scheduler("spec round trip", scheduler, _from_spec("spec round trip", "scheduler", spec), equal=False)


def check_scheduler_pickles(scheduler) -> None:
    """A pickled scheduler comes back equal and runs the same.

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    _same_scheduler("pickles", scheduler, _pickled("pickles", scheduler), equal=True)
