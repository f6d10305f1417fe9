"""Power laws: the exponent of ``mean ~ C balls^a``, by weighted least squares on logarithms, and the local
exponents between consecutive sizes."""

from __future__ import annotations

import math

import numpy as np


def fit_exponent(balls, means, standard_errors) -> dict[str, float]:
    """Fit ``log mean = log C + a log balls``, each point weighted by ``1 / sigma^2``.

    ``balls``, ``means``, ``standard_errors``: ``(k,)`` with k >= 2 sizes; a point's
    ``sigma`` is its relative standard error ``standard_error / mean`` (the error of
    ``log mean``). A zero standard error (all replicas equal, or one replica) takes
    the smallest positive one; with none positive, every point weighs the same.
    Returns ``exponent``, ``exponent_se``, ``prefactor`` (C), ``chi2_per_dof`` and ``points``.
    ``exponent_se`` is the slope's standard error from the weights, scaled by
    ``sqrt(chi2_per_dof)`` when the points scatter more than their errors say (never scaled down).
    """
    x = np.log(_positive("balls", balls))
    y = np.log(_positive("means", means))
    se = np.asarray(standard_errors, dtype=np.float64)
    if se.shape != x.shape or x.ndim != 1:
        raise ValueError(f"balls, means, standard_errors: must be 1-D of one length, got {x.shape}, {y.shape}, "
                         f"{se.shape}")
    if len(x) < 2 or np.ptp(x) == 0:
        raise ValueError(f"balls: need at least two different sizes, got {np.exp(x).tolist()}")
    if not (np.isfinite(se).all() and (se >= 0).all()):
        raise ValueError(f"standard_errors: must be finite and >= 0, got {se.tolist()}")
    sigma = se / np.exp(y)
    positive = sigma[sigma > 0]
    sigma = np.where(sigma > 0, sigma, positive.min() if len(positive) else 1.0)
    w = 1.0 / sigma**2
    xm = np.sum(w * x) / np.sum(w)
    sxx = np.sum(w * (x - xm) ** 2)
    slope = np.sum(w * (x - xm) * y) / sxx
    intercept = np.sum(w * y) / np.sum(w) - slope * xm
    dof = len(x) - 2
    chi2 = float(np.sum(w * (y - intercept - slope * x) ** 2) / dof) if dof > 0 else math.nan
    scale = math.sqrt(chi2) if len(positive) and dof > 0 and chi2 > 1 else 1.0
    if not len(positive):  # no errors given: the scatter about the line is the error
        scale = math.sqrt(chi2) if dof > 0 else math.nan
    return {"exponent": float(slope), "exponent_se": float(scale / math.sqrt(sxx)),
            "prefactor": float(math.exp(intercept)), "chi2_per_dof": chi2, "points": int(len(x))}


def local_exponents(balls, means, standard_errors) -> dict[str, list[float]]:
    """The slope of ``log mean`` against ``log balls`` between consecutive sizes (``(k,)`` each, in order of
    size), each with its standard error (``se / mean`` is the error of a log; two sizes' errors add in quadrature).

    Returns ``local_exponents`` and ``local_exponents_se`` (``(k - 1,)``) and ``local_at`` (the geometric mean
    of the two sizes of each).
    """
    n = np.log(np.asarray(balls, dtype=np.float64))
    y = np.log(np.asarray(means, dtype=np.float64))
    e = np.asarray(standard_errors, dtype=np.float64) / np.asarray(means, dtype=np.float64)
    slope = np.diff(y) / np.diff(n)
    se = np.sqrt(e[1:] ** 2 + e[:-1] ** 2) / np.diff(n)
    return {"local_exponents": slope.tolist(), "local_exponents_se": se.tolist(),
            "local_at": np.sqrt(np.exp(n[1:] + n[:-1])).tolist()}


def _positive(name: str, values) -> np.ndarray:
    a = np.asarray(values, dtype=np.float64)
    if not (np.isfinite(a).all() and (a > 0).all()):
        raise ValueError(f"{name}: must be finite and > 0, got {a.tolist()}")
    return a
