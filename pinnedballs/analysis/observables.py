"""Observables: plain functions of a state (NumPy arrays in, numbers out), and the one registry of
observables by name that writers and specs record on each snapshot.

A state is ``velocities (n_balls, dim)`` and optional ``masses (n_balls,)``
(None means all masses 1). Contacts come as ``pairs (n_contacts, 2)`` and the
unit vectors ``t_i, t_j (n_contacts, dim)`` at each end, as a geometry's
``contacts`` holds them. Fractions of a zero energy are NaN, as are
correlations of a constant sample.

By name (`OBSERVABLES`): writers and specs select observables by name; each is measured on every
snapshot and stored as one column (``(F,)`` for a number, ``(F, *shape)`` for an array). The
built-ins: ``steps``, ``collisions`` (the counters, always recorded); ``energy``; ``momentum``
``(dim,)`` (meaningful in flat space); ``approaching`` (the number of live contacts, 0: frozen).
Add your own with `register_observable` (``fn(sim) -> number or array``, which must not change ``sim``).

Loading this module loads no engine and no scipy (a spec's observables are checked by name alone); each
function imports what it measures with.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..geometry.rows import boundary_rows
from ..util.sums import dot, momentum

if TYPE_CHECKING:
    from ..geometry.base import Geometry

__all__ = [
    "energy_per_ball", "total_energy", "total_momentum",
    "boundary_rows", "energy_profile", "boundary_share", "far_shares", "outward_energy_fraction",
    "Histogram", "component_histogram", "normality_tests", "ad_critical_5pct",
    "line_of_centres_components", "line_of_centres_correlation", "xy_correlation",
    "closing_speeds", "approaching_fraction", "summary",
    "OBSERVABLES", "DEFAULT", "ALWAYS", "register_observable", "check_names", "measure",
]

#: outward normal of `HalfPlane`'s boundary (its balls sit at y >= 0)
HALF_PLANE_OUTWARD = (0.0, -1.0)


# ---------------------------------------------------------------- input checks

def _array(name: str, value, ndim: int) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be an array of numbers ({exc})") from None
    if a.ndim != ndim:
        shape = "(n_balls, dim)" if ndim == 2 else "(n,)"
        raise ValueError(f"{name}: must have shape {shape}, got {a.shape}")
    return a


def _masses(masses, n: int) -> np.ndarray:
    """``(n,)`` masses from None, a number or an array, checked as the engine does (`engine.state.mass_array`)."""
    from ..engine.state import mass_array

    return mass_array(masses, n)


def _velocities(velocities) -> np.ndarray:
    v = _array("velocities", velocities, 2)
    if v.shape[1] < 1:
        raise ValueError(f"velocities: must have shape (n_balls, dim) with dim >= 1, got {v.shape}")
    return v


def _distances(distances, n: int) -> np.ndarray:
    d = _array("distances", distances, 1)
    if d.shape != (n,):
        raise ValueError(f"distances: must have shape (n_balls,) = ({n},), got {d.shape}")
    return d


def _contacts(velocities, pairs, t_i, t_j) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    v = _velocities(velocities)
    p = np.asarray(pairs)
    if p.ndim != 2 or p.shape[1] != 2 or not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"pairs: must be an integer array of shape (n_contacts, 2), got {p.dtype} {p.shape}")
    if p.size and (p.min() < 0 or p.max() >= len(v)):
        raise ValueError(f"pairs: ball indices must be in [0, {len(v)}), got [{p.min()}, {p.max()}]")
    ends = []
    for name, t in (("t_i", t_i), ("t_j", t_j)):
        t = _array(name, t, 2)
        if t.shape != (len(p), v.shape[1]):
            raise ValueError(f"{name}: must have shape (n_contacts, dim) = {(len(p), v.shape[1])}, got {t.shape}")
        ends.append(t)
    return v, p, ends[0], ends[1]


def _fraction(part: float, whole: float) -> float:
    return float(part / whole) if whole > 0 else float("nan")


def _pearson(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of two ``(n,)`` samples; NaN if either is constant or n < 2."""
    if len(a) < 2:
        return float("nan")
    a, b = a - a.mean(), b - b.mean()
    denominator = np.sqrt(dot(a, a) * dot(b, b))
    return float(dot(a, b) / denominator) if denominator > 0 else float("nan")


# ---------------------------------------------------------------- energy and momentum

def energy_per_ball(velocities, masses=None) -> np.ndarray:
    """``(n_balls,)`` kinetic energy ``m |v|^2 / 2`` of each ball."""
    v = _velocities(velocities)
    return 0.5 * _masses(masses, len(v)) * np.einsum("ij,ij->i", v, v)


def total_energy(velocities, masses=None) -> float:
    """Kinetic energy ``sum m |v|^2 / 2``."""
    return float(energy_per_ball(velocities, masses).sum())


def total_momentum(velocities, masses=None) -> np.ndarray:
    """``(dim,)`` momentum ``sum m v`` (meaningful in flat space only)."""
    v = _velocities(velocities)
    return momentum(_masses(masses, len(v)), v)


# ---------------------------------------------------------------- energy against distance from the boundary

def energy_profile(distances, velocities, masses=None, bin_width: float | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Share of the energy at each distance from the boundary (the paper's Figures 3 and 4).

    distances: ``(n_balls,)`` from the boundary (a geometry's ``boundary.distance``).
    Default: one bin per lattice row (see `boundary_rows`), centre = the row's
    distance, so ``centres[0]`` is the boundary row. With ``bin_width``: bins
    ``[k w, (k+1) w)`` from 0 up to the largest distance, centres at their middles,
    empty bins included. Returns ``centres (n_bins,)`` and ``fraction (n_bins,)``
    (sums to 1; NaN if the energy is 0).
    """
    e = energy_per_ball(velocities, masses)
    d = _distances(distances, len(e))
    if bin_width is None:
        index, centres = boundary_rows(d)
    else:
        if not bin_width > 0:
            raise ValueError(f"bin_width: must be > 0, got {bin_width}")
        if len(d) and d.min() < 0:
            raise ValueError(f"distances: must be >= 0 with bin_width, got min {d.min()}")
        index = np.floor(d / bin_width).astype(np.int64)
        centres = (np.arange(index.max() + 1 if len(d) else 0) + 0.5) * bin_width
    energy = np.bincount(index, weights=e, minlength=len(centres))
    total = energy.sum()
    fraction = energy / total if total > 0 else np.full(len(centres), np.nan)
    return centres, fraction


def boundary_share(distances, velocities, masses=None) -> float:
    """Share of the energy held by the boundary row (the row nearest the boundary)."""
    e = energy_per_ball(velocities, masses)
    row, _ = boundary_rows(_distances(distances, len(e)))
    return _fraction(e[row == 0].sum(), e.sum())


def far_shares(distances, velocities, masses=None) -> dict[str, float]:
    """Energy far from the boundary: ``far_half_share`` (balls beyond half the largest distance)
    and ``far_row_share`` (the row farthest from the boundary).

    distances: ``(n_balls,)`` from the boundary; velocities: ``(n_balls, dim)``. NaN if the energy is 0.
    """
    d = np.asarray(distances, dtype=np.float64)
    e = energy_per_ball(velocities, masses)
    row, _ = boundary_rows(d)
    total = e.sum()
    if not total > 0:
        return {"far_half_share": math.nan, "far_row_share": math.nan}
    return {"far_half_share": float(e[d > 0.5 * d.max()].sum() / total),
            "far_row_share": float(e[row == row.max()].sum() / total)}


def outward_energy_fraction(velocities, outward=HALF_PLANE_OUTWARD, masses=None) -> float:
    """Share of these balls' energy held by balls moving outward (``v . outward > 0``).

    velocities: ``(n, dim)``, typically the boundary row's; outward: ``(dim,)``
    direction out of the system (default ``(0, -1)``, `HalfPlane`'s), or ``(n, dim)``
    one per ball (a geometry's ``boundary.outward``).
    """
    v = _velocities(velocities)
    n = np.asarray(outward, dtype=np.float64)
    if n.shape not in ((v.shape[1],), v.shape) or not (np.linalg.norm(n, axis=-1) > 0).all():
        raise ValueError(f"outward: must be nonzero, of shape ({v.shape[1]},) or {v.shape}, got shape {n.shape}")
    e = energy_per_ball(v, masses)
    return _fraction(e[np.einsum("nd,nd->n", v, np.broadcast_to(n, v.shape)) > 0].sum(), e.sum())


# ---------------------------------------------------------------- velocity components

class Histogram(NamedTuple):
    """A histogram of normalised values and the normal distribution fitted to them."""

    counts: np.ndarray  #: ``(n_bins,)`` int
    edges: np.ndarray   #: ``(n_bins + 1,)``
    mean: float         #: fitted normal, on the normalised scale
    std: float          #: fitted normal (maximum likelihood, ``ddof=0``), on the normalised scale
    scale: float        #: the values were divided by this


def _bin_edges(bin_width: float, span) -> np.ndarray:
    lo, hi = (float(s) for s in span)
    if not (bin_width > 0 and hi > lo):
        raise ValueError(f"bin_width, span: need bin_width > 0 and span[0] < span[1], got {bin_width}, {span}")
    n_bins = int(np.ceil((hi - lo) / bin_width - 1e-9))
    if abs(n_bins * bin_width - (hi - lo)) <= 1e-9 * (hi - lo):
        return np.linspace(lo, hi, n_bins + 1)
    return lo + bin_width * np.arange(n_bins + 1)


def component_histogram(values, bin_width: float = 0.025, span=(-1.0, 1.0), normalise: bool = True,
                        scale: float | None = None) -> Histogram:
    """Histogram of velocity components as in the paper's Figure 6.

    values: ``(n,)`` e.g. ``velocities[:, 0]``. With ``normalise``, values are
    divided by ``scale`` (default: their largest absolute value, so they fill
    ``[-1, 1]``; left as they are if all are 0) before binning into bins of
    ``bin_width`` from ``span[0]``. Values outside the bins are not counted.
    """
    x = _array("values", values, 1)
    if normalise:
        if scale is None:
            scale = float(np.abs(x).max()) if len(x) else 0.0
        scale = scale if scale > 0 else 1.0
    else:
        scale = 1.0
    x = x / scale
    counts, edges = np.histogram(x, bins=_bin_edges(bin_width, span))
    mean, std = (float(x.mean()), float(x.std())) if len(x) else (float("nan"), float("nan"))
    return Histogram(counts, edges, mean, std, float(scale))


def ad_critical_5pct(n: int) -> float:
    """5 % critical value of Anderson–Darling for a normal with fitted mean and variance.

    Stephens (1974), as tabulated by ``scipy.stats.anderson``: ``0.752 / (1 + 0.75/n + 2.25/n^2)``.
    """
    return 0.752 / (1.0 + 0.75 / n + 2.25 / n**2)


def _ad_statistic(x: np.ndarray) -> float:
    from scipy import stats

    try:  # scipy >= 1.17 asks for a p-value method; the statistic is the same
        return float(stats.anderson(x, dist="norm", method="interpolate").statistic)
    except TypeError:
        return float(stats.anderson(x, dist="norm").statistic)


def normality_tests(values) -> dict[str, float]:
    """Tests of ``values (n,)`` against the normal distribution fitted to them.

    ``ks_statistic, ks_pvalue``: Kolmogorov–Smirnov against ``N(mean, std)``
    fitted to the same data; fitting makes the p-value conservative (too large:
    Lilliefors' test would reject more often). ``ad_statistic`` and
    ``ad_critical_5pct``: Anderson–Darling for a normal with fitted parameters;
    normality is rejected at 5 % when the statistic exceeds the critical value.
    Also ``n``, ``mean``, ``std`` (``ddof=0``).
    """
    x = _array("values", values, 1)
    if len(x) < 8:
        raise ValueError(f"values: need at least 8 values for normality tests, got {len(x)}")
    mean, std = float(x.mean()), float(x.std())
    if not std > 0:
        raise ValueError("values: all equal, so no normal distribution can be fitted")
    from scipy import stats

    ks = stats.kstest(x, "norm", args=(mean, std))
    return {
        "n": float(len(x)), "mean": mean, "std": std,
        "ks_statistic": float(ks.statistic), "ks_pvalue": float(ks.pvalue),
        "ad_statistic": _ad_statistic(x), "ad_critical_5pct": ad_critical_5pct(len(x)),
    }


# ---------------------------------------------------------------- contacts

def line_of_centres_components(velocities, pairs, t_i, t_j) -> tuple[np.ndarray, np.ndarray]:
    """``(n_contacts,)`` components ``u = v_i . t_i`` and ``u' = -v_j . t_j`` of each contact.

    Both are measured along the line of centres in the direction from ``i`` to
    ``j`` (in flat space ``-t_j = t_i``), so an elastic collision of equal masses
    swaps them, and the closing speed is ``w = u - u'``.
    """
    v, p, ti, tj = _contacts(velocities, pairs, t_i, t_j)
    return np.einsum("kd,kd->k", v[p[:, 0]], ti), -np.einsum("kd,kd->k", v[p[:, 1]], tj)


def line_of_centres_correlation(velocities, pairs, t_i, t_j) -> float:
    """Pearson correlation of ``u`` and ``u'`` over all contacts (the paper's Figure 7).

    See `line_of_centres_components` for the convention. Reversing a contact
    maps ``(u, u')`` to ``(-u', -u)``: the products ``u u'`` are unchanged, so the
    orientation of contacts matters only through the means and variances.
    """
    u, u_prime = line_of_centres_components(velocities, pairs, t_i, t_j)
    return _pearson(u, u_prime)


def xy_correlation(velocities) -> float:
    """Pearson correlation of the x- and y-components over all balls (the paper's Figure 8)."""
    v = _velocities(velocities)
    if v.shape[1] < 2:
        raise ValueError(f"velocities: need dim >= 2 for an x-y correlation, got shape {v.shape}")
    return _pearson(v[:, 0], v[:, 1])


def closing_speeds(velocities, pairs, t_i, t_j) -> np.ndarray:
    """``(n_contacts,)`` closing speed ``w = v_i . t_i + v_j . t_j``; positive means approaching."""
    v, p, ti, tj = _contacts(velocities, pairs, t_i, t_j)
    return np.einsum("kd,kd->k", v[p[:, 0]], ti) + np.einsum("kd,kd->k", v[p[:, 1]], tj)


def approaching_fraction(velocities, pairs, t_i, t_j) -> float:
    """Fraction of contacts whose balls approach (closing speed ``w > 0``), the physical
    definition. It can stay slightly above 0 in a frozen state: after inelastic collisions
    rounding leaves closing speeds of ~1e-17 whose collision would change no bit of any
    velocity. The engine's `Simulation.approaching` counts only contacts whose pick would
    change something, and that is what decides frozen."""
    w = closing_speeds(velocities, pairs, t_i, t_j)
    return float(np.mean(w > 0)) if len(w) else float("nan")


# ---------------------------------------------------------------- one table row

def summary(velocities, geometry: Geometry, masses=None) -> dict[str, float]:
    """The scalars above for one state on ``geometry``, for tables.

    Keys: ``energy``, ``momentum_x``, ``momentum_y``, ... (one per component;
    flat space only: left out when ``geometry.curved``), ``approaching_fraction``,
    ``line_of_centres_correlation``, ``xy_correlation`` (dim >= 2) and, on a
    geometry with a ``boundary``, ``boundary_share`` and ``boundary_outward_fraction``
    (share of the boundary row's energy moving along ``boundary.outward``).
    """
    from ..geometry.base import Geometry

    if not isinstance(geometry, Geometry):
        raise TypeError(f"geometry: must be a pinnedballs Geometry, got {type(geometry).__name__}")
    v = _velocities(velocities)
    if v.shape != (geometry.n_balls, geometry.dim):
        raise ValueError(f"velocities: must have shape (n_balls, dim) = {(geometry.n_balls, geometry.dim)}, "
                         f"got {v.shape}")
    m = _masses(masses, len(v))
    c = geometry.contacts
    contacts = (c.pairs, c.t_i, c.t_j)
    out = {"energy": total_energy(v, m)}
    axes = "xyz" if v.shape[1] <= 3 else [str(k) for k in range(v.shape[1])]
    if not geometry.curved:  # on a curved surface velocities live in different tangent planes
        out.update({f"momentum_{a}": float(p) for a, p in zip(axes, total_momentum(v, m))})
    out["approaching_fraction"] = approaching_fraction(v, *contacts)
    out["line_of_centres_correlation"] = line_of_centres_correlation(v, *contacts)
    if v.shape[1] >= 2:
        out["xy_correlation"] = xy_correlation(v)
    boundary = geometry.boundary
    if boundary is not None:
        row, _ = boundary_rows(boundary.distance)
        out["boundary_share"] = boundary_share(boundary.distance, v, m)
        out["boundary_outward_fraction"] = outward_energy_fraction(v[row == 0], boundary.outward[row == 0],
                                                                   m[row == 0])
    return out


# ---------------------------------------------------------------- observables by name

#: ``name -> fn(sim)``; use `register_observable` to add to it
OBSERVABLES: dict[str, Callable] = {
    "steps": lambda sim: sim.steps,
    "collisions": lambda sim: sim.collisions,
    "energy": lambda sim: sim.energy(),
    "momentum": lambda sim: np.asarray(sim.momentum(), dtype=np.float64),
    "approaching": lambda sim: sim.approaching(),
}
#: recorded on every snapshot whatever is selected
ALWAYS = ("steps", "collisions")
#: what writers and specs record unless told otherwise
DEFAULT = ("steps", "collisions", "energy", "momentum", "approaching")
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def register_observable(name: str, fn: Callable, *, replace: bool = False) -> Callable:
    """Register an observable: a spec's ``"observables"`` and an ensemble's table may then name it.

    Parameters
    ----------
    name : str
        An identifier (letters, digits, _), not a built-in counter.
    fn : callable
        ``fn(sim) -> number or array`` of a `Simulation`'s current state.
    replace : bool
        Replace an observable registered under ``name`` already.

    Returns
    -------
    callable
        ``fn``.

    Raises
    ------
    ValueError
        On ``name``: not an identifier, registered already (without ``replace``), or a built-in counter.
    TypeError
        On ``fn`` that is not callable.

    Examples
    --------
    >>> import numpy as np
    >>> import pinnedballs as pb
    >>> from pinnedballs.analysis.observables import OBSERVABLES
    >>> def top_speed(sim):
    ...     return float(np.linalg.norm(sim.velocities, axis=1).max())
    >>> pb.register_observable("top_speed", top_speed, replace=True) is top_speed
    True
    >>> g = pb.HalfPlane(rows=2, cols=2)
    >>> OBSERVABLES["top_speed"](pb.Simulation(g, [[0, 3], [0, 4], [0, 0], [0, 0]], seed=0))
    4.0
    """
    if not isinstance(name, str) or not _NAME.fullmatch(name):
        raise ValueError(f"name: must be an identifier (letters, digits, _), got {name!r}")
    if not callable(fn):
        raise TypeError(f"fn: must be callable, got {type(fn).__name__}")
    if name in OBSERVABLES and not replace:
        raise ValueError(f"name: {name!r} is already registered (pass replace=True to replace it)")
    if name in ALWAYS:
        raise ValueError(f"name: {name!r} is a built-in counter and cannot be replaced")
    OBSERVABLES[name] = fn
    return fn


def check_names(names, field: str = "observables") -> tuple[str, ...]:
    """``ALWAYS`` followed by ``names`` (registered, without repeats), or a ValueError naming ``field``."""
    if isinstance(names, str) or not all(isinstance(n, str) for n in names):
        raise TypeError(f"{field}: must be a list of observable names, got {names!r}")
    for n in names:
        if n not in OBSERVABLES:
            raise ValueError(f"{field}: unknown observable {n!r} (known: {', '.join(OBSERVABLES)})")
    return tuple(dict.fromkeys((*ALWAYS, *names)))


def measure(sim, names) -> dict[str, np.ndarray]:
    """``{name: value}`` of the observables ``names`` on ``sim``'s current state, as numpy values."""
    return {n: np.asarray(OBSERVABLES[n](sim)) for n in names}
