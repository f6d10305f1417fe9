"""Collision rules: what a collision does to the two pseudo-velocities.

A contact ``(i, j)`` collides only if its balls approach: the closing speed
``w = v_i . t_i + v_j . t_j`` is positive. Then, with restitution ``r``,

    v_i -= (1 + r) m_j / (m_i + m_j) * w * t_i
    v_j -= (1 + r) m_i / (m_i + m_j) * w * t_j

For equal masses and ``r = 1`` this is the paper's exchange of the components
along the line of centres (Algorithm 1).

A rule is a Python object whose `kernel` hands the compiled loop a jitted
function ``collide(v, units, i, j, a, b, masses, params, dim, flat, write) -> bool``
and its ``params`` array. ``t_i = units[a]`` and ``t_j = units[b]``, or
``t_j = -t_i`` when ``flat`` (the same numbers: negation is exact, so flat
space skips one lookup). ``dim`` and ``flat`` are compile-time constants.

``collide`` returns True when the collision changes (with ``write``: changed)
at least one velocity component, and writes the new velocities only if
``write``. So a *collision* is a pick that changed velocities, as in the paper,
and a system is *frozen* when no pick can change anything.

A rule may instead be given by its *impulse*, ``impulse(w, i, j, masses, params) -> (c_i, c_j)``
(the kick ``v_i -= c_i t_i``, ``v_j -= c_j t_j`` of a collision closing at ``w``), its ``collide``
made by `impulse_rule` (`pinnedballs.engine.closing`): the engine then adds the threshold test and the
kick, and runs the collision without a branch where that is faster. The built-in rules are written so,
and their arithmetic lives here alone: every engine (the CPU's loops, the threads, a GPU) compiles it.

**Rounding remnants are not collisions.** In exact arithmetic (`pinnedballs.engine.field.rational`) many
closing speeds are exactly zero: a ball that handed on all of its velocity along a line of centres
is at rest along it. In float64 such a ball keeps a remnant of a few units in the last place of the
speeds that passed through it, and its contacts "approach" at ~1e-16. A remnant is small against
the system's speed scale, not against the two balls' own velocities (two balls at rest but for
their remnants close at about their own speed), so the criterion is absolute: a contact collides
only if ``w > threshold = THRESHOLD_ULPS * 2^-53 * V``, with ``V = sqrt(2 E_0 / m_mean)`` the
system's speed scale: the largest speed a ball of the mean mass can reach (with equal masses, the
largest any ball can), ``E_0`` the energy the simulation was built with. Measured
against the exact engine on the same picks (half-planes from 20x10 to 200x100, oblique and
multi-ball starts, tori of 2e6 steps; ``docs/collisions.md``): every remnant closes at most
0.7 * 2^-53 V and every genuine collision at least 26 * 2^-53 V, so 4 sits between them, and the
float engine then counts exactly the exact engine's collisions on those runs.

The engine appends the threshold to the rule's ``params`` (``params[-1]``, `remnant_threshold`);
a rule collides only when its closing speed exceeds it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np

from .engine.closing import closing_speed, impulse_rule
from .engine.jit.cache import njit_cached
from .util import checks
from .util.errors import FieldError
from .util.sums import kinetic_energy

__all__ = ["CollisionRule", "Elastic", "Restitution", "closing_speed", "remnant_threshold", "threshold",
           "THRESHOLD_ULPS", "DEFAULT_RESOLUTION", "check_resolution",
           "collide_elastic", "collide_equal", "collide_masses", "elastic_impulse", "equal_impulse", "masses_impulse",
           "impulse_rule"]

#: the remnant threshold in units of ``2^-53 V`` (see the module docstring)
THRESHOLD_ULPS = 4.0
#: the default resolution ``e``: a pick collides when its closing speed exceeds ``e V``
DEFAULT_RESOLUTION = THRESHOLD_ULPS * 2.0**-53


def threshold(velocities: np.ndarray, masses: np.ndarray, resolution: float = DEFAULT_RESOLUTION) -> float:
    """The collision criterion's threshold ``resolution * sqrt(2 E / m_mean)``: closing speeds at or below it
    do not collide.

    The default resolution, ``4 * 2^-53``, sets aside exactly the rounding remnants on every case measured
    (the module docstring); another resolution ``e`` defines a model of its own, whose counts ``N_e`` are
    those of a criterion ``w > e V``.

    Parameters
    ----------
    velocities : numpy.ndarray
        ``(n_balls, dim)`` pseudo-velocities.
    masses : numpy.ndarray
        ``(n_balls,)`` masses.
    resolution : float
        ``e``, in (0, 1).

    Returns
    -------
    float

    Examples
    --------
    >>> import numpy as np
    >>> from pinnedballs.rules import threshold
    >>> threshold(np.array([[3.0, 4.0], [0.0, 0.0]]), np.ones(2), resolution=0.01)
    0.05
    """
    energy = kinetic_energy(masses, velocities)
    return resolution * float(np.sqrt(2.0 * energy / float(masses.mean())))


def check_resolution(value) -> float:
    """``value`` (None: `DEFAULT_RESOLUTION`) as a float in (0, 1), else a `FieldError` on ``resolution``."""
    if value is None:
        return DEFAULT_RESOLUTION
    number = checks.number("resolution", value)
    if not 0.0 < number < 1.0:
        raise FieldError("resolution", f"must be a number in (0, 1): a pick collides when its closing speed exceeds "
                                       f"resolution * V (V the system's speed scale), got {value}")
    return number


@njit_cached(inline="always")
def remnant_threshold(params):
    """The engine's threshold, ``params[-1]`` (>= 0): a rule collides only if ``w`` exceeds it.

    Read it at the top of ``collide``, before any branch, and test ``w <= threshold`` once: an
    array read on an early-return path of the inlined loop keeps numba from pruning its reference
    counting, which makes the paper's chain several times slower (`benchmarks/results/measurements.md`)."""
    return params[params.shape[0] - 1]


@njit_cached(inline="always")
def elastic_impulse(w, i, j, masses, params):
    """Equal masses, elastic: the paper's exchange, ``c_i = c_j = w``."""
    return w, w


@njit_cached(inline="always")
def equal_impulse(w, i, j, masses, params):
    """Equal masses, restitution ``r``: ``c_i = c_j = w (1 + r) / 2``, ``params[0] = (1 + r) / 2``
    (1 for elastic: ``w * 1.0`` is ``w``, bit for bit, so `elastic_impulse` gives the same)."""
    c = w * params[0]
    return c, c


@njit_cached(inline="always")
def masses_impulse(w, i, j, masses, params):
    """Any masses, restitution ``r``: ``c_i = (1 + r) m_j / (m_i + m_j) w`` and ``c_j`` alike, ``params[0] = 1 + r``."""
    s = params[0] * w / (masses[i] + masses[j])
    return s * masses[j], s * masses[i]


#: the built-in rules' ``collide``, each built from its impulse (`engine.closing.impulse_rule`): every engine
#: (the CPU's loops with or without a branch, the threads, a GPU) runs this arithmetic
collide_elastic = impulse_rule(elastic_impulse)
collide_equal = impulse_rule(equal_impulse)
collide_masses = impulse_rule(masses_impulse)


class CollisionRule(ABC):
    """What a collision does. Subclasses give the compiled loop a jitted function (`kernel`).

    The module's docstring says what the function is given and returns; docs/extending.md writes one.
    """

    @abstractmethod
    def kernel(self, equal_masses: bool) -> tuple[Callable, np.ndarray]:
        """The rule's compiled collision, for the compiled loop.

        Parameters
        ----------
        equal_masses : bool
            Whether every ball has the same mass (a rule may then skip the masses).

        Returns
        -------
        collide : callable
            A jitted ``collide(v, units, i, j, a, b, masses, params, dim, flat, write) -> bool`` (or one made
            by `impulse_rule`).
        params : numpy.ndarray
            ``(p,) float64``: its parameters (the engine appends the threshold).
        """

    def exact_restitution(self) -> float | None:
        """The rule's coefficient of restitution, where exact arithmetic can run it.

        Returns
        -------
        float or None
            ``r`` when the rule is the paper's with restitution ``r`` (exact arithmetic can run it:
            `pinnedballs.engine.field.rational`), else None.
        """
        return None

    def exact_kick(self, m_i, m_j):
        """The rule's kick as an exact linear form, what exact and certified arithmetic run: a collision closing
        at ``w`` kicks ``v_i -= a_i w t_i`` and ``v_j -= a_j w t_j``.

        Parameters
        ----------
        m_i, m_j : exact rationals
            The two balls' masses, as exact numbers (``gmpy2.mpq``, ``fractions.Fraction``).

        Returns
        -------
        tuple or None
            ``(a_i, a_j)`` in the masses' type, or None where the rule has no exact form (the default: by
            `exact_restitution`, the paper's rule with restitution ``r`` taken exactly,
            ``a_i = (1 + r) m_j / (m_i + m_j)``).

        Examples
        --------
        >>> from fractions import Fraction
        >>> import pinnedballs as pb
        >>> pb.Restitution(0.5).exact_kick(Fraction(1), Fraction(3))
        (Fraction(9, 8), Fraction(3, 8))
        >>> pb.Elastic().exact_kick(Fraction(2), Fraction(2))
        (Fraction(1, 1), Fraction(1, 1))
        """
        r = self.exact_restitution()
        if r is None:
            return None
        scale = (1 + type(m_i)(r)) / (m_i + m_j)  # the float r exactly (a float is a rational)
        return scale * m_j, scale * m_i

    def to_spec(self) -> dict | None:
        """The rule as a run spec's ``"rule"``.

        A run built in Python records this spec, so that ``pb.load(dir).simulation()`` rebuilds
        the rule; a rule of your own may return ``{"kind": "python", "factory": ..., "args": ...}``.

        Returns
        -------
        dict or None
            A dict with its ``"kind"``, or None if it has none.
        """
        return None


class Restitution(CollisionRule):
    """Inelastic collisions with coefficient of restitution ``r``; momentum kept, energy never gained.

    A collision closing at ``w`` along ``t_i`` takes ``(1 + r) m_j / (m_i + m_j) w`` from ``v_i . t_i``
    and alike from ``v_j . t_j`` (the module's docstring).

    Parameters
    ----------
    r : float
        The coefficient of restitution, in [0, 1] (1: `Elastic`).

    Raises
    ------
    FieldError
        On ``r`` outside [0, 1].

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.GraphGeometry.from_positions([[0.0], [2.0]])
    >>> sim = pb.Simulation(g, [[1.0], [0.0]], rule=pb.Restitution(0.5), seed=0)
    >>> sim.run(steps=1), sim.velocities.tolist(), sim.energy()
    (1, [[0.25], [0.75]], 0.3125)
    >>> pb.Restitution(0.5).to_spec()
    {'kind': 'restitution', 'r': 0.5}
    """

    def __init__(self, r: float):
        self.r = checks.number("r", r, 0.0, 1.0, what="coefficient of restitution")

    def kernel(self, equal_masses: bool) -> tuple[Callable, np.ndarray]:
        """The paper's collision with restitution ``r`` (`CollisionRule.kernel`).

        Parameters
        ----------
        equal_masses : bool
            Whether every ball has the same mass.

        Returns
        -------
        collide : callable
            `collide_elastic` (equal masses, ``r = 1``), `collide_equal` or `collide_masses`.
        params : numpy.ndarray
            ``[(1 + r) / 2]`` for equal masses, else ``[1 + r]``.
        """
        if equal_masses:
            return collide_elastic if self.r == 1.0 else collide_equal, np.array([(1.0 + self.r) / 2.0])
        return collide_masses, np.array([1.0 + self.r])

    def exact_restitution(self) -> float:
        """The coefficient ``r`` (`CollisionRule.exact_restitution`): exact arithmetic runs every ``r``.

        Returns
        -------
        float
        """
        return self.r

    def to_spec(self) -> dict:
        """The rule as a run spec's ``"rule"`` (`CollisionRule.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "restitution", "r": r}``.
        """
        return {"kind": "restitution", "r": self.r}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.r})"

    def __eq__(self, other) -> bool:
        return type(other) is type(self) and other.r == self.r

    def __hash__(self) -> int:
        return hash((type(self), self.r))


class Elastic(Restitution):
    """Totally elastic collisions (``r = 1``): energy and momentum conserved, any masses.

    With equal masses this is the paper's exchange of the components along the line of centres
    (Algorithm 1). The default rule of a `Simulation`.

    Examples
    --------
    >>> import pinnedballs as pb
    >>> g = pb.GraphGeometry.from_positions([[0.0], [2.0]])
    >>> sim = pb.Simulation(g, [[1.0], [0.0]], rule=pb.Elastic(), seed=0)
    >>> sim.run(steps=1), sim.velocities.tolist(), sim.energy()
    (1, [[0.0], [1.0]], 0.5)
    >>> pb.Elastic().to_spec()
    {'kind': 'elastic'}
    """

    def __init__(self):
        super().__init__(1.0)

    def to_spec(self) -> dict:
        """The rule as a run spec's ``"rule"`` (`CollisionRule.to_spec`).

        Returns
        -------
        dict
            ``{"kind": "elastic"}``.
        """
        return {"kind": "elastic"}

    def __repr__(self) -> str:
        return "Elastic()"
