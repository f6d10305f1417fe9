"""The laws a collision rule must obey, each a check: ``check(rule)`` returns, or raises an
`AssertionError` naming the law and a pair of balls that breaks it.

Each check collides many separate pairs at once (`samples.pair_geometry`, every contact tried once by
a `Sweep`): unit vectors, velocities and masses drawn from a fixed seed, equal and unequal masses, in
flat space (``t_j = -t_i``) and, where the law holds there too, as on a curved surface (``t_j`` any
unit vector). Tolerances: one collision rounds by a few units in the last place, so energies are
compared to ``1e-12`` of the pair's energy, momenta to ``1e-12`` of ``m_i |v_i| + m_j |v_j|``,
velocities to ``1e-12`` of the pair's speeds.

A rule says it is elastic by ``exact_restitution() == 1`` (the built-in ones) or an attribute
``elastic = True``; it has an exact form when ``exact_restitution()`` is not None.
"""

from __future__ import annotations

import numpy as np

from ..geometry.lattices import HalfPlane
from ..schedulers.simple import Sweep, UniformRandomPair
from .samples import SEED, fail, pair_geometry, simulation, vector

__all__ = ["check_momentum_conserved", "check_energy_never_created", "check_energy_conserved_if_elastic",
           "check_separating_untouched", "check_swap_symmetric", "check_restitution_law",
           "check_exact_agrees", "claims_elastic", "REL"]

#: relative tolerance of one collision (see the module's docstring)
REL = 1e-12
#: pairs collided per sample
PAIRS = 64


def claims_elastic(rule) -> bool:
    """True when ``rule`` says it conserves energy (see the module's docstring)."""
    return rule.exact_restitution() == 1.0 or getattr(rule, "elastic", False) is True


def _units(rng: np.random.Generator, n: int, d: int) -> np.ndarray:
    t = rng.standard_normal((n, d))
    return t / np.linalg.norm(t, axis=1, keepdims=True)


def _samples(flat_only: bool = False):
    """``(label, t_i (P, d), t_j (P, d) or None, v (2P, d), masses (2P,) or None)``: 2-D and 3-D flat
    pairs and 3-D pairs as on a curved surface, each with equal and unequal masses."""
    rng = np.random.default_rng(SEED)
    kinds = [(2, True), (3, True)] + ([] if flat_only else [(3, False)])
    for d, flat in kinds:
        for equal in (True, False):
            t_i = _units(rng, PAIRS, d)
            t_j = None if flat else _units(rng, PAIRS, d)
            v = rng.standard_normal((2 * PAIRS, d)) * rng.choice([0.01, 1.0, 100.0], size=(2 * PAIRS, 1))
            v[rng.random(2 * PAIRS) < 0.2] = 0.0  # some balls at rest
            masses = None if equal else rng.uniform(0.1, 10.0, 2 * PAIRS)
            label = f"{d}-D {'flat' if flat else 'curved'}, {'equal' if equal else 'unequal'} masses"
            yield label, t_i, t_j, v, masses


def _collide_once(prop: str, rule, t_i, t_j, v, masses, swapped: bool = False):
    """Velocities after trying each pair's contact once, and the simulation's collision count."""
    sim = simulation(prop, pair_geometry(t_i, t_j, swapped), v, rule=rule, scheduler=Sweep(), masses=masses, seed=0)
    sim.run(steps=len(t_i), progress=False)
    return sim.velocities, sim.collisions


def _pair(v, masses, p):
    m = np.ones(2) if masses is None else masses[2 * p:2 * p + 2]
    return v[2 * p], v[2 * p + 1], m


def _example(label, t_i, t_j, v, masses, p) -> str:
    vi, vj, m = _pair(v, masses, p)
    tj = -t_i[p] if t_j is None else t_j[p]
    return (f"{label}, pair {p}: t_i = {vector(t_i[p])}, t_j = {vector(tj)}, masses {vector(m)}, "
            f"v_i = {vector(vi)}, v_j = {vector(vj)}")


def _energies(v, masses) -> np.ndarray:
    """``(P,)`` kinetic energy of each pair."""
    m = np.ones(len(v)) if masses is None else masses
    e = 0.5 * m * np.einsum("nd,nd->n", v, v)
    return e[0::2] + e[1::2]


def check_momentum_conserved(rule) -> None:
    """Flat space: ``m_i v_i + m_j v_j`` is the same after a collision, to ``1e-12`` of
    ``m_i |v_i| + m_j |v_j|``.

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    for label, t_i, t_j, v, masses in _samples(flat_only=True):
        after, _ = _collide_once("momentum conserved", rule, t_i, t_j, v, masses)
        m = np.ones(len(v)) if masses is None else masses
        p0, p1 = m[:, None] * v, m[:, None] * after
        total0, total1 = p0[0::2] + p0[1::2], p1[0::2] + p1[1::2]
        scale = np.linalg.norm(p0[0::2], axis=1) + np.linalg.norm(p0[1::2], axis=1)
        bad = np.flatnonzero(np.abs(total1 - total0).max(axis=1) > REL * scale)
        if len(bad):
            p = bad[0]
            fail("momentum conserved", f"{_example(label, t_i, t_j, v, masses, p)}: momentum {vector(total0[p])} "
                                       f"became {vector(total1[p])}")


def check_energy_never_created(rule) -> None:
    """No collision gives a pair more kinetic energy than it had (beyond ``1e-12`` of it).

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    for label, t_i, t_j, v, masses in _samples():
        after, _ = _collide_once("energy never created", rule, t_i, t_j, v, masses)
        e0, e1 = _energies(v, masses), _energies(after, masses)
        bad = np.flatnonzero(e1 > e0 * (1 + REL))
        if len(bad):
            p = bad[0]
            fail("energy never created", f"{_example(label, t_i, t_j, v, masses, p)}: energy {e0[p]:.12g} became "
                                         f"{e1[p]:.12g}")


def check_energy_conserved_if_elastic(rule) -> None:
    """A rule that says it is elastic keeps each pair's kinetic energy, to ``1e-12`` of it, in flat space
    and on a curved surface alike. (Nothing to check for a rule that does not say so.)

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    if not claims_elastic(rule):
        return
    for label, t_i, t_j, v, masses in _samples():
        after, _ = _collide_once("energy conserved (elastic)", rule, t_i, t_j, v, masses)
        e0, e1 = _energies(v, masses), _energies(after, masses)
        bad = np.flatnonzero(np.abs(e1 - e0) > REL * e0)
        if len(bad):
            p = bad[0]
            fail("energy conserved (elastic)", f"{_example(label, t_i, t_j, v, masses, p)}: energy {e0[p]:.12g} "
                                               f"became {e1[p]:.12g}")


def _closing(t_i, t_j, v) -> np.ndarray:
    """``(P,)`` closing speed ``w = v_i . t_i + v_j . t_j`` of each pair."""
    tj = -t_i if t_j is None else t_j
    return np.einsum("pd,pd->p", v[0::2], t_i) + np.einsum("pd,pd->p", v[1::2], tj)


def check_separating_untouched(rule) -> None:
    """Balls that do not approach (``w <= 0``: separating, sliding past or at rest) keep their velocities
    bit for bit, and the pick is no collision.

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    for label, t_i, t_j, v, masses in _samples():
        v = v.copy()
        w = _closing(t_i, t_j, v)
        flip = np.repeat(w > 0, 2)
        v[flip] = -v[flip]  # negating both velocities negates w exactly
        v[:8] = 0.0  # four pairs at rest (w = 0)
        after, collisions = _collide_once("separating balls untouched", rule, t_i, t_j, v, masses)
        changed = np.flatnonzero((after != v).any(axis=1))
        if len(changed) or collisions:
            p = changed[0] // 2 if len(changed) else 0
            fail("separating balls untouched", f"{_example(label, t_i, t_j, v, masses, p)} (w = "
                                               f"{_closing(t_i, t_j, v)[p]:.6g} <= 0): became "
                                               f"{vector(after[2 * p])}, {vector(after[2 * p + 1])}; "
                                               f"{collisions} collision(s) counted")


def check_swap_symmetric(rule) -> None:
    """Naming the two balls of a contact the other way round (``(j, i)`` with ``t_j, t_i``) gives the same
    velocities, to ``1e-12`` of the pair's speeds.

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    for label, t_i, t_j, v, masses in _samples():
        after, _ = _collide_once("symmetric under swapping the balls", rule, t_i, t_j, v, masses)
        swapped, _ = _collide_once("symmetric under swapping the balls", rule, t_i, t_j, v, masses, swapped=True)
        speed = np.linalg.norm(v, axis=1)
        scale = np.repeat(speed[0::2] + speed[1::2], 2)
        bad = np.flatnonzero(np.abs(swapped - after).max(axis=1) > REL * scale)
        if len(bad):
            p = bad[0] // 2
            fail("symmetric under swapping the balls", f"{_example(label, t_i, t_j, v, masses, p)}: as (i, j) "
                                                       f"{vector(after[2 * p])}, {vector(after[2 * p + 1])}; as "
                                                       f"(j, i) {vector(swapped[2 * p])}, {vector(swapped[2 * p + 1])}")


def check_restitution_law(rule) -> None:
    """A rule with an exact form (restitution ``r``) turns the closing speed ``w > 0`` of a collision into
    ``-r w``, to ``1e-12`` of the pair's speeds. (Nothing to check for a rule without one.)

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    r = rule.exact_restitution()
    if r is None:
        return
    for label, t_i, t_j, v, masses in _samples():
        after, _ = _collide_once("closing speed becomes -r w", rule, t_i, t_j, v, masses)
        w0, w1 = _closing(t_i, t_j, v), _closing(t_i, t_j, after)
        speed = np.linalg.norm(v, axis=1)
        scale = speed[0::2] + speed[1::2]
        bad = np.flatnonzero((w0 > REL * scale) & (np.abs(w1 + r * w0) > REL * scale))
        if len(bad):
            p = bad[0]
            fail("closing speed becomes -r w", f"{_example(label, t_i, t_j, v, masses, p)}: w = {w0[p]:.12g} "
                                               f"became {w1[p]:.12g}, not -{r:g} w")


def check_exact_agrees(rule) -> None:
    """A rule with an exact form runs in exact arithmetic (`Simulation` ``arithmetic="exact"``) to the
    float run's velocities: on a 3 x 4 half-plane with one boundary ball sent inward, after 3,000 steps
    on the same picks, every component within ``1e-12`` of the speed scale. (Collision counts may
    differ: the float run does not count rounding remnants, and below ``r = 1`` the exact one may go
    on colliding ever more slowly.) (Nothing to check for a rule without an exact form.)

    Parameters
    ----------
    rule : CollisionRule
        The rule checked.

    Raises
    ------
    AssertionError
        Naming the property that does not hold and a small example.
    """
    if rule.exact_restitution() is None:
        return
    g = HalfPlane(3, 4)
    v = np.zeros((g.n_balls, 2))
    v[g.boundary_center()] = (0.3, 1.0)
    prop = "float and exact arithmetic agree"
    runs = [simulation(prop, g, v, rule=rule, scheduler=UniformRandomPair(), seed=SEED, arithmetic=a)
            for a in ("float", "exact")]
    for sim in runs:
        sim.run(steps=3000, progress=False)
    f, x = runs
    gap = np.abs(f.velocities - x.velocities).max(axis=1)
    if gap.max() > REL * float(np.linalg.norm(v)):
        b = int(np.argmax(gap))
        fail(prop, f"3 x 4 half-plane, ball {g.boundary_center()} sent with {vector(v[g.boundary_center()])}, seed "
                   f"{SEED}, 3,000 steps: ball {b} has {vector(f.velocities[b])} in float and "
                   f"{vector(x.velocities[b])} exactly ({f.collisions} and {x.collisions} collisions)")
