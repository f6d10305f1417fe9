"""Coefficients that stay 0: the grading of a state in ``Q(sqrt d)`` that the fixed-point chain keeps.

In ``Q(sqrt d)`` every coefficient is of one of two kinds, rational (coefficient 0) or a rational times
``sqrt d`` (coefficient 1). Where each component ``d`` of every velocity is of one kind, its parity ``p_d``,
and each line's unit vector has components of one kind ``pi_{l,d}`` with ``p_d + pi_{l,d}`` (mod 2) the same
``g_l`` for every component the line has, a closing speed along ``l`` is of kind ``g_l`` alone, and a collision
keeps every parity: the other coefficient of each component is 0 for ever. The triangular lattice (unit
vectors ``(1, 0)``, ``(1/2, +-sqrt 3 / 2)``) from one ball moving along an axis is so graded, ``x`` in
``sqrt 3 Q`` and ``y`` in ``Q`` (or the reverse), and half its coefficients are 0 throughout a run.

`graded` drops from the kernels' tables (`fixed_kernels.Tables`) the terms that read or write those zeros, and
records the parities (``parity``), so that a collision neither computes nor loads them (the shadows read one
coefficient a component). Every value is the same, bit for bit: only terms that are exactly 0 are dropped.
"""

from __future__ import annotations

import itertools

import numpy as np

from .fixed_kernels import Tables

__all__ = ["parities", "graded", "tables_for"]


def _kinds(tables: Tables) -> np.ndarray:
    """``(L, dim)``: the kind of each line's component, 0 (rational) or 1 (times ``sqrt d``), -1 where it is 0,
    -2 where it has both (no grading); from the exchange's terms, ``kterms[l, d, 0]`` listing ``(s, f)``, the
    coefficient 0 of ``omega u_l``'s component ``d`` taking ``f omega[s]``: ``s = 0`` for a rational ``u``."""
    L, dim = tables.kcount.shape[:2]
    kinds = np.full((L, dim), -1, dtype=np.int64)
    for line in range(L):
        for d in range(dim):
            sources = {int(tables.kterms[line, d, 0, t, 0]) for t in range(tables.kcount[line, d, 0])}
            kinds[line, d] = -1 if not sources else sources.pop() if len(sources) == 1 else -2
    return kinds


def parities(tables: Tables, X: np.ndarray) -> np.ndarray | None:
    """``(dim,)``: the parity of each component that grades the state ``X`` ``(n, dim, m, P)`` under the lines of
    ``tables`` (module docstring), the first in the order of `itertools.product` where several do; None where none
    does (or the field is ``Q``: nothing to drop)."""
    dim, m = X.shape[1], X.shape[2]
    if m != 2:
        return None
    kinds = _kinds(tables)
    if (kinds == -2).any():
        return None
    nonzero = X.any(axis=(0, 3))  # (dim, m): a coefficient that is not 0 in some ball
    for p in itertools.product((0, 1), repeat=dim):
        if any(nonzero[d, 1 - p[d]] for d in range(dim)):
            continue
        if all(len({(p[d] + k) % 2 for d, k in enumerate(row) if k >= 0}) <= 1 for row in kinds):
            return np.array(p, dtype=np.int64)
    return None


def graded(tables: Tables, parity: np.ndarray) -> Tables:
    """``tables`` without the terms that read or write a coefficient ``parity`` (`parities`) makes 0: a closing
    speed's coefficients other than ``g_l`` and its terms reading a component's other coefficient; an exchange's
    components' other coefficients and its terms reading ``omega``'s other."""
    kinds = _kinds(tables)
    wterms, wcount = np.zeros_like(tables.wterms), np.zeros_like(tables.wcount)
    kterms, kcount = np.zeros_like(tables.kterms), np.zeros_like(tables.kcount)
    for line, row in enumerate(kinds):
        g = next(((int(parity[d]) + int(k)) % 2 for d, k in enumerate(row) if k >= 0), 0)
        terms = tables.wterms[line, g, :tables.wcount[line, g]]  # (d, s, f): keep s = p_d
        wcount[line, g] = _keep(wterms[line, g], terms[terms[:, 1] == parity[terms[:, 0]]])
        for d in range(len(parity)):
            c = int(parity[d])
            terms = tables.kterms[line, d, c, :tables.kcount[line, d, c]]  # (s, f): keep s = g
            kcount[line, d, c] = _keep(kterms[line, d, c], terms[terms[:, 0] == g])
    t = tables
    return Tables(t.pairs, t.ls, t.uf, t.usum, t.e, wterms, wcount, kterms, kcount, t.coef, t.root, t.emax, t.rmax,
                  np.ascontiguousarray(parity, dtype=np.int64))


def _keep(out: np.ndarray, terms: np.ndarray) -> int:
    """``terms`` written to the front of ``out``: their number."""
    out[:len(terms)] = terms
    return len(terms)


def tables_for(tables: Tables, X: np.ndarray) -> Tables:
    """``tables`` `graded` for the state ``X`` where it is graded (`parities`), else ``tables`` themselves."""
    parity = parities(tables, X)
    return tables if parity is None else graded(tables, parity)
