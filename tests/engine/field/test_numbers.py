"""Exact numbers: multi-quadratic fields, exact signs and roundings, and the fields of the lattices' normals."""

from __future__ import annotations

import functools
import math
from fractions import Fraction

import gmpy2
import numpy as np
import pytest
from gmpy2 import mpfr, mpq
from hypothesis import given, settings
from hypothesis import strategies as st

import pinnedballs as pb
from pinnedballs.engine.field.numbers import Field, FieldNumber, NotExact, recognise, snap, squarefree


def value(field: Field, x: tuple, bits: int = 2000) -> mpfr:
    """``x`` evaluated with ``bits`` of precision (far more than any case here needs)."""
    with gmpy2.context(precision=bits):
        return sum((mpfr(c) * gmpy2.sqrt(mpfr(b)) for c, b in zip(x, field.basis)), mpfr(0))


def test_squarefree_splits_off_the_largest_square():
    assert [squarefree(n) for n in (1, 2, 3, 4, 12, 18, 72, 97, 360)] == \
        [(1, 1), (1, 2), (1, 3), (2, 1), (2, 3), (3, 2), (6, 2), (1, 97), (6, 10)]


def test_the_field_of_two_roots_holds_their_product():
    field = Field.generated({2, 3})
    assert field.basis == (1, 2, 3, 6) and repr(field) == "Q(sqrt(2), sqrt(3), sqrt(6))"
    r2, r3, r6 = (tuple(mpq(int(k == i)) for k in range(4)) for i in (1, 2, 3))
    assert field.mul(r2, r3) == r6                                  # sqrt 2 sqrt 3 = sqrt 6
    assert field.mul(r6, r2) == tuple(mpq(x) for x in (0, 0, 2, 0))  # sqrt 6 sqrt 2 = 2 sqrt 3
    assert field.mul(r6, r6) == field.of(6)


rationals = st.fractions(min_value=-50, max_value=50, max_denominator=1000).map(
    lambda f: mpq(f.numerator, f.denominator))


@settings(max_examples=300, deadline=None, derandomize=True)
@given(st.sampled_from([(1,), (1, 3), (1, 2), (1, 2, 3, 6)]).flatmap(
    lambda basis: st.tuples(st.just(basis), st.lists(rationals, min_size=len(basis), max_size=len(basis)))))
def test_signs_and_roundings_are_those_of_the_true_value(case):
    basis, coefficients = case
    field = Field(basis)
    x = tuple(coefficients)
    true = value(field, x)
    assert field.sign(x) == (0 if true == 0 else 1 if true > 0 else -1)
    assert field.to_float(x) == float(true)  # rounded to nearest


def test_signs_are_exact_where_floats_cannot_tell():
    """Convergents of sqrt 3 and sqrt 2 make a + b sqrt d within 1e-30 of zero, and sums of
    four roots cancel to 1e-25: far below what float64 resolves, never a wrong sign."""
    q3 = Field((1, 3))
    for p, q in ((1351, 780), (70226, 40545), (978122, 564719), (13623482, 7865521)):
        x = (mpq(p), mpq(-q))  # p - q sqrt 3: the sign alternates with the convergent
        assert q3.sign(x) == (1 if p * p > 3 * q * q else -1)
        assert q3.sign((-x[0], -x[1])) == -q3.sign(x)
    q236 = Field((1, 2, 3, 6))
    close = (mpq(5, 1), mpq(-1, 1), mpq(-1, 1), mpq(-1, 1))  # 5 - sqrt 2 - sqrt 3 - sqrt 6 = -0.596...
    assert q236.sign(close) == -1 and q236.sign(q236.zero) == 0
    tiny = (mpq(3363, 1), mpq(-2378, 1), mpq(0), mpq(0))  # 3363 - 2378 sqrt 2 = 1.5e-4 ... then squared
    assert q236.sign(q236.mul(tiny, tiny)) == 1
    assert q236.sign(q236.sub(q236.mul(tiny, tiny), q236.mul(tiny, tiny))) == 0


def test_exact_numbers_compute_and_print():
    field = Field((1, 3))
    half_root3 = FieldNumber(field, (mpq(0), mpq(1, 2)))
    assert str(half_root3 * half_root3) == "3/4" and half_root3 * half_root3 == Fraction(3, 4)
    assert str(1 - half_root3) == "1 - 1/2*sqrt(3)"
    assert float(1 - half_root3) == float(value(field, (mpq(1), mpq(-1, 2))))
    assert half_root3 > 0.866 and half_root3 < 0.8661 and (-half_root3).sign() == -1
    with pytest.raises(TypeError, match=r"cannot mix numbers of Q\(sqrt\(3\)\) and Q\(sqrt\(2\)\)"):
        half_root3 + FieldNumber(Field((1, 2)), (mpq(0), mpq(1)))


@pytest.mark.parametrize("geometry, basis", [
    (pb.HalfPlane(4, 5), (1, 3)),
    (pb.HalfPlane(5, 4, orientation="across"), (1, 3)),
    (pb.FlatTorus(4, 4), (1, 3)),
    (pb.FCC(3, 3, 3), (1, 2)),
    (pb.HCP(3, 3, 3), (1, 2, 3, 6)),
    (pb.GraphGeometry.from_positions(np.column_stack([2.0 * np.arange(5), np.zeros(5)])), (1,)),
    (pb.GraphGeometry.from_positions([[0, 0], [2, 0], [1, 3**0.5], [3, 3**0.5]]), (1, 3)),
])
def test_the_normals_of_the_lattices_lie_in_their_fields_exactly(geometry, basis):
    units = geometry.contacts.units
    field, exact = recognise(units)
    assert field.basis == basis
    for row, t in zip(units, exact):
        assert functools.reduce(field.add, (field.mul(x, x) for x in t)) == field.of(1)
        assert np.allclose([field.to_float(x) for x in t], row, rtol=0, atol=4e-16)


@pytest.mark.parametrize("geometry, words", [
    (pb.Sphere.geodesic(2), "unit vector 0 (0.9510565162951536, 0.30901699437494745): 0.9510565162951536 is not "
                            "q*sqrt(d)"),
    (pb.HyperbolicPlane(7, 2), "is not q*sqrt(d) for a small rational q and squarefree d"),
    (pb.GraphGeometry.from_positions([[0.0, 0.0], [2 * math.cos(1.0), 2 * math.sin(1.0)]]), "is not q*sqrt(d)"),
])
def test_normals_in_no_known_field_are_named(geometry, words):
    with pytest.raises(NotExact) as info:
        recognise(geometry.contacts.units)
    assert words in str(info.value)


def test_a_rational_normal_is_exact():
    """(3/5, 4/5): a 3-4-5 triangle's line of centres is rational."""
    field, exact = recognise(pb.GraphGeometry.from_positions([[0.0, 0.0], [1.2, 1.6]]).contacts.units)
    assert field.basis == (1,) and [str(c) for x in exact[0] for c in x] == ["3/5", "4/5"]


def test_snapping_finds_the_field_within_a_tolerance_and_keeps_signs():
    """(-0.5000000000000006, 0.8660254037844384), networkx's honeycomb, is 5 ulps from -1/2: beyond
    `recognise`'s 4, within a tolerance; it snaps to the floats of (-1/2, sqrt(3)/2), a zero keeps its sign,
    (0.6, 0.8000001) is (3/5, 4/5) within 1e-6 and a vector of no field is named."""
    units = np.array([[-0.5000000000000006, 0.8660254037844384], [-1e-17, -1.0], [0.7071067811865, 0.7071067811866]])
    with pytest.raises(NotExact, match=r"^unit vector 0 \(-0\.5000000000000006, "):
        recognise(units)
    out = snap(units, 1e-12)
    assert out.tolist() == [[-0.5, math.sqrt(3) / 2], [-0.0, -1.0], [math.sqrt(0.5), math.sqrt(0.5)]]
    assert np.signbit(out[1, 0]) and recognise(out)[0].basis == (1, 2, 3, 6)
    assert snap(np.array([[0.6, 0.8000001]]), 1e-6).tolist() == [[0.6, 0.8]]
    with pytest.raises(NotExact, match=r"^unit vector 0 \(0\.6, 0\.8000001\): 0\.8000001 is not within 1e-12 of "
                                       r"q\*sqrt\(d\) for a small rational q and squarefree d$"):
        snap(np.array([[0.6, 0.8000001]]), 1e-12)
    with pytest.raises(NotExact, match=r"is not of length 1 in Q"):  # (1/2, 1/2): each a field's, not a unit
        snap(np.array([[0.5000000001, 0.5]]), 1e-6)
