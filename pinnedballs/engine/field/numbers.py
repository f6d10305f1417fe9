"""Exact numbers for exact collisions: multi-quadratic number fields Q(sqrt(d1), sqrt(d2), ...).

On the triangular lattice every contact normal is (+-1, 0) or (+-1/2, +-sqrt(3)/2), so velocities
that start as floats (rationals) stay in Q(sqrt 3)^2 through any number of collisions; FCC's
normals (+-1, +-1, 0)/sqrt(2) live in Q(sqrt 2), HCP's in Q(sqrt 2, sqrt 3), square and cubic
packings and collinear chains in Q. `recognise` finds the field of a geometry's unit vectors from
their floats, or says why there is none.

An element is a tuple of ``m`` rationals (``gmpy2.mpq``), its coefficients on the field's basis
``sqrt(b)`` for ``b`` in `Field.basis` (squarefree, ``basis[0] == 1``): ``(1/2, 3/4)`` in Q(sqrt 3)
is 1/2 + 3/4 sqrt(3). The basis is closed under products (sqrt(2) sqrt(3) = sqrt(6)), so sums and
products stay on it. Signs are exact: an element is zero only when every coefficient is, and a
nonzero one is evaluated at rising precision (MPFR) until its sign is certain.

gmpy2 (GMP's rationals) is used rather than python-flint: on the sums and products a collision
makes, its ``mpq`` is the faster (docs/performance.md).
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import reduce

import gmpy2
import numpy as np
from gmpy2 import mpfr, mpq

__all__ = ["Field", "FieldNumber", "recognise", "snap", "NotExact", "squarefree"]

#: the largest denominator, and the largest squarefree root, `recognise` looks for
MAX_DENOMINATOR = 1 << 12
MAX_ROOT = 1000
#: how far (in units in the last place) a float may be from the number it stands for
ULPS = 4
_ZERO = mpq(0)


class NotExact(ValueError):
    """A unit vector whose components are not ``q * sqrt(d)`` with small rational ``q`` and ``d``."""


def squarefree(n: int) -> tuple[int, int]:
    """``(s, d)`` with ``n = s^2 d`` and ``d`` squarefree (``n >= 1``)."""
    s, d, p = 1, 1, 2
    while p * p <= n:
        while n % (p * p) == 0:
            n //= p * p
            s *= p
        if n % p == 0:
            n //= p
            d *= p
        p += 1
    return s, d * n


class Field:
    """Q(sqrt(b) for b in ``basis``): ``basis`` squarefree, closed under products, ``basis[0] == 1``.

    ``times[a][b] = (c, f)``: sqrt(basis[a]) * sqrt(basis[b]) = f sqrt(basis[c]).
    """

    def __init__(self, basis: tuple[int, ...]):
        self.basis = tuple(basis)
        index = {b: k for k, b in enumerate(self.basis)}
        self.times = []
        for a in self.basis:
            row = []
            for b in self.basis:
                s, d = squarefree(a * b)
                row.append((index[d], mpq(s)))
            self.times.append(tuple(row))
        self.times = tuple(self.times)
        self._context = gmpy2.context(precision=128)
        with self._context:
            self.roots = tuple(gmpy2.sqrt(mpfr(b)) for b in self.basis)
        self.m = len(self.basis)
        self.zero = (_ZERO,) * self.m

    @classmethod
    def generated(cls, roots) -> Field:
        """The smallest such field holding ``sqrt(d)`` for every ``d`` in ``roots``."""
        basis = {1}
        for d in roots:
            basis |= {squarefree(b * d)[1] for b in basis}
        return cls(tuple(sorted(basis)))

    # ------------------------------------------------------------ elements
    def of(self, value) -> tuple:
        """The element equal to the float or rational ``value`` (a float is a rational: exactly)."""
        return (mpq(value),) + self.zero[1:]

    def add(self, x: tuple, y: tuple) -> tuple:
        return tuple(a + b for a, b in zip(x, y))

    def sub(self, x: tuple, y: tuple) -> tuple:
        return tuple(a - b for a, b in zip(x, y))

    def scale(self, x: tuple, q) -> tuple:
        """``q x`` for a rational ``q``."""
        return tuple(a * q for a in x)

    def mul(self, x: tuple, y: tuple) -> tuple:
        out = [_ZERO] * self.m
        for a, xa in enumerate(x):
            if xa:
                row = self.times[a]
                for b, yb in enumerate(y):
                    if yb:
                        c, f = row[b]
                        out[c] += xa * yb * f
        return tuple(out)

    def sign(self, x: tuple) -> int:
        """-1, 0 or 1: exact."""
        if not any(x):
            return 0
        if self.m == 1:
            return 1 if x[0] > 0 else -1
        if self.m == 2:  # a + b sqrt(d): compare a^2 with d b^2 when the signs differ
            a, b = x
            if a >= 0 and b >= 0:
                return 1
            if a <= 0 and b <= 0:
                return -1
            big = a * a - self.basis[1] * b * b
            return (1 if big > 0 else -1) * (1 if a > 0 else -1)
        precision = 128
        while True:
            with gmpy2.context(precision=precision):
                terms = [mpfr(c) * gmpy2.sqrt(mpfr(b)) for c, b in zip(x, self.basis) if c]
                total = sum(terms, mpfr(0))
                error = len(terms) * 4 * sum(abs(t) for t in terms) * mpfr(2) ** (-precision)
            if abs(total) > error:
                return 1 if total > 0 else -1
            precision *= 2

    def to_float(self, x: tuple) -> float:
        """``x`` rounded to float64 (to nearest, from a 128-bit evaluation)."""
        if not any(x[1:]):  # a rational: float() of an mpq rounds to nearest
            return float(x[0])
        with self._context:
            return float(sum((mpfr(c) * r for c, r in zip(x, self.roots) if c), mpfr(0)))

    def text(self, x: tuple) -> str:
        """``x`` written out, e.g. ``1/2 + 3/4*sqrt(3)``."""
        parts = [f"{c}" if b == 1 else f"{c}*sqrt({b})" for c, b in zip(x, self.basis) if c]
        return " + ".join(parts).replace("+ -", "- ") if parts else "0"

    def parse(self, coefficients) -> tuple:
        """The element of the coefficient strings ``coefficients`` (``["1/2", "3/4"]``)."""
        if len(coefficients) != self.m:
            raise ValueError(f"an element of {self} has {self.m} coefficients, got {len(coefficients)}")
        return tuple(mpq(c) for c in coefficients)

    def __repr__(self) -> str:
        roots = ", ".join(f"sqrt({b})" for b in self.basis[1:])
        return f"Q({roots})" if roots else "Q"


class FieldNumber:
    """An exact number: an element ``x`` of ``field``; ``+ - *`` with its kind, ints and
    rationals, comparisons, ``float()``, and its value written out by ``str()``."""

    __slots__ = ("field", "x")

    def __init__(self, field: Field, x: tuple):
        self.field, self.x = field, tuple(x)

    def _other(self, y) -> tuple:
        if isinstance(y, FieldNumber):
            if y.field.basis != self.field.basis:
                raise TypeError(f"cannot mix numbers of {self.field} and {y.field}")
            return y.x
        return self.field.of(y)

    def __add__(self, y):
        return FieldNumber(self.field, self.field.add(self.x, self._other(y)))

    __radd__ = __add__

    def __sub__(self, y):
        return FieldNumber(self.field, self.field.sub(self.x, self._other(y)))

    def __rsub__(self, y):
        return FieldNumber(self.field, self.field.sub(self._other(y), self.x))

    def __mul__(self, y):
        return FieldNumber(self.field, self.field.mul(self.x, self._other(y)))

    __rmul__ = __mul__

    def __neg__(self):
        return FieldNumber(self.field, tuple(-c for c in self.x))

    def sign(self) -> int:
        """-1, 0 or 1, exactly."""
        return self.field.sign(self.x)

    def __eq__(self, y) -> bool:
        return self.field.sign(self.field.sub(self.x, self._other(y))) == 0

    def __lt__(self, y) -> bool:
        return self.field.sign(self.field.sub(self.x, self._other(y))) < 0

    def __gt__(self, y) -> bool:
        return self.field.sign(self.field.sub(self.x, self._other(y))) > 0

    def __le__(self, y) -> bool:
        return not self > y

    def __ge__(self, y) -> bool:
        return not self < y

    def __hash__(self) -> int:
        return hash((self.field.basis, self.x))

    def __float__(self) -> float:
        return self.field.to_float(self.x)

    def __str__(self) -> str:
        return self.field.text(self.x)

    def __repr__(self) -> str:
        return f"FieldNumber({self.field.text(self.x)})"


def _component(x: float) -> tuple[Fraction, int]:
    """``(q, d)`` with ``x`` the float nearest ``q sqrt(d)`` (within `ULPS`), ``d`` squarefree;
    `NotExact` if there is none with small ``q`` and ``d``."""
    if x == 0.0:
        return Fraction(0), 1
    square = Fraction(x * x).limit_denominator(MAX_DENOMINATOR ** 2)
    s, d = squarefree(square.numerator * square.denominator)
    q = Fraction(s, square.denominator) * (1 if x > 0 else -1)
    close = abs(float(q) * math.sqrt(d) - x) <= ULPS * math.ulp(x) and d <= MAX_ROOT
    if not close or q.denominator > MAX_DENOMINATOR:
        raise NotExact(f"{x!r} is not q*sqrt(d) for a small rational q and squarefree d")
    return q, d


def _simplest(lo: Fraction, hi: Fraction) -> Fraction:
    """The rational of least denominator in ``[lo, hi]`` (``0 <= lo <= hi``), by continued fractions."""
    n = math.floor(lo)
    if n == lo or n + 1 <= hi:
        return Fraction(n if n == lo else n + 1)
    return n + 1 / _simplest(1 / (hi - n), 1 / (lo - n))


def _near(x: float, tolerance: float) -> tuple[Fraction, int]:
    """``(q, d)``: the ``q sqrt(d)`` within ``tolerance`` of ``x`` whose square has the least denominator
    (``d`` squarefree), or `NotExact` if it has no small ``q`` and ``d``."""
    lo, hi = Fraction(max(abs(x) - tolerance, 0.0)), Fraction(abs(x)) + Fraction(tolerance)
    square = _simplest(lo * lo, hi * hi)
    if square == 0:
        return Fraction(0), 1
    s, d = squarefree(square.numerator * square.denominator)
    q = Fraction(s, square.denominator) * (1 if x > 0 else -1)
    if q.denominator > MAX_DENOMINATOR or d > MAX_ROOT:
        raise NotExact(f"{x!r} is not within {tolerance:.3g} of q*sqrt(d) for a small rational q and squarefree d")
    return q, d


def recognise(units: np.ndarray, tolerance: float | None = None) -> tuple[Field, list[tuple]]:
    """The field of the unit vectors ``units (K, dim)`` and each as exact elements ``[(t_0, ..., t_dim-1)]``.

    Each component must be within `ULPS` of ``q sqrt(d)`` (within ``tolerance``, absolute, when one is
    given: the ``q sqrt(d)`` there whose square is simplest), and each vector exactly of length 1 in
    the field; otherwise `NotExact` naming the vector.
    """
    component = _component if tolerance is None else (lambda x: _near(x, tolerance))
    found = []
    for k, row in enumerate(np.asarray(units, dtype=np.float64)):
        try:
            found.append([component(float(x)) for x in row])
        except NotExact as exc:
            raise NotExact(f"unit vector {k} {tuple(row.tolist())}: {exc}") from None
    field = Field.generated(reduce(set.union, ({d for _, d in row} for row in found), set()))
    index = {b: a for a, b in enumerate(field.basis)}
    exact = []
    for k, row in enumerate(found):
        vector = []
        for q, d in row:
            element = [_ZERO] * field.m
            element[index[d]] = mpq(q.numerator, q.denominator)
            vector.append(tuple(element))
        length = reduce(field.add, (field.mul(t, t) for t in vector), field.zero)
        if length != field.of(1):
            raise NotExact(f"unit vector {k} {tuple(np.asarray(units)[k].tolist())} is not of length 1 in {field} "
                           f"(its exact length squared is {field.text(length)})")
        exact.append(tuple(vector))
    return field, exact


def snap(units: np.ndarray, tolerance: float) -> np.ndarray:
    """``units (K, dim)`` moved to the floats nearest the unit vectors of a number field within
    ``tolerance`` (absolute, on each component; `recognise`), the sign of a zero kept: floats that
    `recognise` then finds exact. `NotExact` naming the first vector with no such field."""
    units = np.asarray(units, dtype=np.float64)
    field, exact = recognise(units, tolerance)
    out = np.array([[field.to_float(t) for t in vector] for vector in exact], dtype=np.float64).reshape(units.shape)
    return np.copysign(out, units)
