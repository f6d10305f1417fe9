"""What a scheduler must do, each a check: ``check(scheduler)`` returns, or raises an `AssertionError`
naming the property and a small example.

The checks run on a 4 x 3 flat torus (12 balls, 36 contacts; it never freezes) and, until frozen, on a
3 x 4 half-plane (23 contacts) with one boundary ball sent inward; everything from fixed seeds. Picks
are read through the engine's own `engine.sequential.loops.selector_picks` (what a run in exact arithmetic
follows), except for a scheduler that picks among live contacts (``selector().tracks``), whose picks
depend on the velocities: it is checked through its runs.

The law a scheduler claims (`Scheduler.law`) is tested at a stated level with a fixed seed, so the
verdict is the same on every run: ``"uniform"``: the counts of 20,000 picks over the 10 contacts of a
chain, and of the 20,000 pairs of consecutive picks over the 100 ordered pairs, pass a chi-square
test at level 1e-3; ``"sweep"``: every block of ``n_contacts`` picks from a fresh start holds each
contact once (ten sweeps); ``"uniform_chain"``: over 400 replicas the steps and the collisions until
frozen have the law of `UniformRandomPair`'s (two-sample Kolmogorov-Smirnov tests at level 1e-3).
"""

from __future__ import annotations

import numpy as np

from ..engine.sequential.loops import selector_picks
from ..engine.state import RunState
from ..engine.streams.xoshiro import seed_state
from ..geometry.graph import GraphGeometry
from ..geometry.lattices import FlatTorus, HalfPlane
from ..schedulers.base import PickOutOfRange
from ..schedulers.simple import UniformRandomPair
from .samples import SEED, fail, simulation

__all__ = ["check_scheduler_picks_in_range", "check_scheduler_same_seed_same_run", "check_scheduler_split_run",
           "check_scheduler_state_round_trip", "check_scheduler_law", "LEVEL", "LAWS"]

#: the level of the law's statistical tests
LEVEL = 1e-3
#: the laws a scheduler may claim (`Scheduler.law`)
LAWS = ("uniform", "sweep", "uniform_chain")
_PICKS = 20_000
_STEPS = 3_000


def _torus():
    g = FlatTorus(4, 3)
    return g, np.random.default_rng(SEED).standard_normal((g.n_balls, 2))


def _half_plane():
    g = HalfPlane(3, 4)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = (0.3, 1.0)
    return g, v


def _chain(n_contacts: int = 10):
    return GraphGeometry.from_positions(np.column_stack([2.0 * np.arange(n_contacts + 1)]))


def _picks(prop: str, scheduler, geometry, count: int, seed: int = SEED) -> np.ndarray | None:
    """The first ``count`` picks from a fresh state and ``seed`` (None for a scheduler that picks among
    live contacts); a pick out of range fails ``prop``."""
    try:
        sel = scheduler.selector(geometry)
    except (ValueError, TypeError) as error:
        fail(prop, f"its selector for {geometry!r} was refused: {type(error).__name__}: {error}")
    if sel.tracks:
        return None
    n = geometry.n_contacts
    out = np.empty(count, dtype=np.int64)
    try:
        selector_picks(sel.select, sel.begin)(scheduler.initial_state(n), sel.aux, seed_state(seed), n, out)
    except PickOutOfRange as error:
        fail(prop, f"on {geometry!r} ({n} contacts), seed {seed}: {error.problem}")
    bad = np.flatnonzero((out >= n) | ((out < 0) if not sel.skips else (out < -1)))
    if len(bad):
        fail(prop, f"on {geometry!r} ({n} contacts), seed {seed}: pick {bad[0]} is contact {out[bad[0]]}")
    return out


def _run(prop: str, scheduler, make, seed: int = SEED, *calls):
    """A simulation on ``make()``'s geometry and velocities, run by ``calls`` (each ``("steps", n)`` or
    ``("frozen", max_steps)``); its final state."""
    g, v = make()
    sim = simulation(prop, g, v, scheduler=scheduler, seed=seed)
    for how, n in calls:
        try:
            if how == "steps":
                sim.run(steps=n, progress=False)
            elif not sim.run_until_frozen(max_steps=n, progress=False):
                fail(prop, f"{g!r} did not freeze within {n} steps")
        except PickOutOfRange as error:
            fail(prop, f"on {g!r}: {error.problem}")
    return sim


def _differ(a: RunState, b: RunState) -> str:
    """What differs between two states, in a few words."""
    if (a.steps, a.collisions) != (b.steps, b.collisions):
        return f"{a.steps} steps, {a.collisions} collisions against {b.steps} steps, {b.collisions} collisions"
    for name in RunState.ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        if x.shape != y.shape or not np.array_equal(x, y):
            return f"{name} differ (first at {int(np.flatnonzero((x != y).ravel())[0]) if x.shape == y.shape else 0})"
    return "the exact velocities differ"


def check_scheduler_picks_in_range(scheduler) -> None:
    """Every pick names a contact, ``0 <= k < n_contacts``: 20,000 picks on the torus (a scheduler that
    picks among live contacts: the contact of every collision of a run on the half-plane until frozen).

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    prop = "picks in range"
    g, _ = _torus()
    if _picks(prop, scheduler, g, _PICKS) is not None:
        return
    sim = _run(prop, scheduler, _half_plane)
    seen: list[np.ndarray] = []
    sim.collision_listeners.append(lambda steps, contacts: seen.append(np.asarray(contacts).copy()))
    try:
        sim.run_until_frozen(max_steps=10**6, progress=False)
    except PickOutOfRange as error:
        fail(prop, f"on {sim.geometry!r}: {error.problem}")
    contacts = np.concatenate(seen) if seen else np.zeros(0, dtype=np.int64)
    bad = np.flatnonzero((contacts < 0) | (contacts >= sim.geometry.n_contacts))
    if len(bad):
        fail(prop, f"collision {bad[0]} of a half-plane run is at contact {contacts[bad[0]]} of "
                   f"{sim.geometry.n_contacts}")


def check_scheduler_same_seed_same_run(scheduler) -> None:
    """The same seed gives the same picks and the same run, bit for bit: 20,000 picks, and 3,000 steps on
    the torus (a scheduler that picks among live contacts: a run until frozen on the half-plane).

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    prop = "same seed, same run"
    g, _ = _torus()
    first, second = _picks(prop, scheduler, g, _PICKS), _picks(prop, scheduler, g, _PICKS)
    if first is not None and not np.array_equal(first, second):
        at = int(np.flatnonzero(first != second)[0])
        fail(prop, f"seed {SEED} on {g!r}: pick {at} was contact {first[at]}, then {second[at]}")
    make, calls = (_torus, [("steps", _STEPS)]) if first is not None else (_half_plane, [("frozen", 10**6)])
    a, b = (_run(prop, scheduler, make, SEED, *calls).get_state() for _ in range(2))
    if not a.identical(b):
        fail(prop, f"seed {SEED}, {calls}: {_differ(a, b)}")


def check_scheduler_split_run(scheduler) -> None:
    """A run split into calls ends on the state of one call, bit for bit: 3,000 steps on the torus as one
    call and as 1,000 + 1,999 + 1; and the half-plane until frozen as one call and after 7 steps.

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    prop = "a run split in two equals one run"
    cases = [(_torus, [("steps", _STEPS)], [("steps", 1000), ("steps", _STEPS - 1001), ("steps", 1)]),
             (_half_plane, [("frozen", 10**6)], [("steps", 7), ("frozen", 10**6)])]
    for make, whole, split in cases:
        a, b = (_run(prop, scheduler, make, SEED, *whole).get_state(),
                _run(prop, scheduler, make, SEED, *split).get_state())
        if not a.identical(b):
            fail(prop, f"{make()[0]!r}, seed {SEED}: {whole} against {split}: {_differ(a, b)}")


def check_scheduler_state_round_trip(scheduler) -> None:
    """`Simulation.get_state` then `set_state` on another simulation (other velocities, other seed)
    continues the run exactly: 1,500 + 1,500 steps on the torus; the scheduler accepts its own state
    (`Scheduler.check_state`).

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    prop = "state round trip"
    sim = _run(prop, scheduler, _torus, SEED, ("steps", 1500))
    state = sim.get_state()
    try:
        scheduler.check_state(state.scheduler_state, sim.geometry.n_contacts)
        other = simulation(prop, sim.geometry, np.ones((sim.geometry.n_balls, 2)), scheduler=scheduler, seed=SEED + 1)
        other.set_state(state)
    except (ValueError, TypeError) as error:
        fail(prop, f"after 1,500 steps on {sim.geometry!r} its own state was refused: {type(error).__name__}: {error}")
    for s in (sim, other):
        s.run(steps=1500, progress=False)
    if not sim.get_state().identical(other.get_state()):
        fail(prop, f"1,500 steps on {sim.geometry!r}, state moved to another simulation, 1,500 more: "
                   f"{_differ(sim.get_state(), other.get_state())}")


def check_scheduler_law(scheduler) -> None:
    """The law the scheduler claims (`Scheduler.law`; see the module's docstring for the tests and their
    level). Nothing to check for a scheduler that claims none.

    Parameters
    ----------
    scheduler : Scheduler
        The scheduler checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    law = getattr(scheduler, "law", None)
    if law is None:
        return
    if law not in LAWS:
        fail("the law it claims", f"law {law!r} is none of {LAWS}")
    {"uniform": _uniform, "sweep": _sweep, "uniform_chain": _uniform_chain}[law](scheduler)


def _uniform(scheduler) -> None:
    from scipy import stats

    prop = "the law it claims (uniform)"
    g = _chain()
    n = g.n_contacts
    picks = _picks(prop, scheduler, g, _PICKS)
    if picks is None:
        fail(prop, "it picks among live contacts, so its picks are not uniform over the contacts")
    counts = np.bincount(picks, minlength=n)
    p = stats.chisquare(counts).pvalue
    if p < LEVEL:
        fail(prop, f"{_PICKS} picks over the {n} contacts of a chain, seed {SEED}: counts {counts.tolist()}, "
                   f"chi-square p = {p:.3g} < {LEVEL:g}")
    pairs = np.bincount(picks[:-1] * n + picks[1:], minlength=n * n)
    p = stats.chisquare(pairs).pvalue
    if p < LEVEL:
        worst = int(np.argmax(np.abs(pairs - pairs.mean())))
        fail(prop, f"{_PICKS - 1} consecutive pairs of picks over the {n * n} ordered pairs of contacts, seed {SEED}: "
                   f"chi-square p = {p:.3g} < {LEVEL:g} (pick {worst // n} then {worst % n}: {pairs[worst]} times, "
                   f"{pairs.mean():.0f} expected)")


def _sweep(scheduler) -> None:
    prop = "the law it claims (sweep)"
    g, _ = _torus()
    n = g.n_contacts
    picks = _picks(prop, scheduler, g, 10 * n)
    if picks is None:
        fail(prop, "it picks among live contacts, so it cannot visit each contact once per sweep")
    for sweep, block in enumerate(picks.reshape(10, n)):
        counts = np.bincount(block, minlength=n)
        if not (counts == 1).all():
            k = int(np.flatnonzero(counts != 1)[0])
            fail(prop, f"sweep {sweep} of {g!r} ({n} contacts), seed {SEED}, picked contact {k} {counts[k]} times")


def _uniform_chain(scheduler, replicas: int = 400) -> None:
    from scipy import stats

    prop = "the law it claims (the uniform chain)"
    counts = {}
    for name, s in (("it", scheduler), ("UniformRandomPair", UniformRandomPair())):
        sim = _run(prop, s, _half_plane)
        start = sim.get_state()
        steps, collisions = np.empty(replicas), np.empty(replicas)
        for r in range(replicas):
            sim.set_state(start.replace(rng_state=seed_state(SEED + r)))
            sim.run_until_frozen(max_steps=10**6, progress=False)
            steps[r], collisions[r] = sim.steps, sim.collisions
        counts[name] = (steps, collisions)
    for k, what in enumerate(("steps", "collisions")):
        a, b = counts["it"][k], counts["UniformRandomPair"][k]
        p = stats.ks_2samp(a, b).pvalue
        if p < LEVEL:
            fail(prop, f"{what} until frozen on a 3 x 4 half-plane over {replicas} replicas: mean {a.mean():.4g} "
                       f"against UniformRandomPair's {b.mean():.4g}, two-sample KS p = {p:.3g} < {LEVEL:g}")
