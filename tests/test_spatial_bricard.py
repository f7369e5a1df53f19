"""Example 13: Bricard's plane symmetric 6R linkage from its printed axes alone.

The paper states: the configuration curve has genus one; t1 = -t5 and t2 = -t4 on the whole
curve; the bonds follow the pattern (+-i, *, *, *, -+i, *), (*, +-i, *, -+i, *, *),
(*, *, +-i, *, *, +-i), (*, *, +-i, *, *, -+i) with the * complex numbers of nonzero real
and imaginary part.  All of it is checked here on the curve that exact elimination finds.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import sympy

from linkage.spatial import RevoluteChain
from linkage.spatial.chain import distances_from_connections
from linkage.spatial.curve import W
from linkage.spatial.examples import bricard_example_13


@pytest.fixture(scope="module")
def bricard():
    return bricard_example_13()


def test_curve_from_the_axes_has_genus_one_and_the_symmetry(bricard):
    assert bricard.is_mobile()
    curve = bricard.configuration_curve()
    assert curve.genus == 1 and curve.g.degree() == 4
    g = curve.g.as_expr()
    e = curve.expressions()
    for i, j in ((0, 4), (1, 3)):  # t1 + t5 = 0 and t2 + t4 = 0 modulo w^2 = g
        num = sympy.numer(sympy.together(e[i] + e[j]))
        assert sympy.rem(sympy.Poly(sympy.expand(num), W), sympy.Poly(W**2 - g, W)).is_zero


def test_closure_traced_over_every_real_component(bricard):
    """Both branches over every interval where g >= 0 (the real components), in floats."""
    curve = bricard.configuration_curve()
    rounded = RevoluteChain([h.map(float) for h in bricard.axes])
    intervals = curve.real_intervals()
    assert len(intervals) == 3  # two ovals: one through t = inf (first and last interval)
    worst, count = 0.0, 0
    for a, b in intervals:
        lo, hi = (b - 30 if np.isinf(a) else a), (a + 30 if np.isinf(b) else b)
        ts = np.linspace(lo, hi, 41)[1:-1]
        for branch in (1, -1):
            for p in curve.real_points(ts, branch):
                if not all(np.isfinite(abs(z)) for z in p):
                    continue
                q = rounded.closure([z.real for z in p])
                worst = max(worst, max(abs(x) for x in q.coefficients[1:]) / abs(q[0]))
                count += 1
    assert count > 200 and worst <= 1e-12
    # an independent numerical solve from a nearby start lands on the traced point
    p = [z.real for z in curve(0.1, 1)]
    guess = [x + 0.05 for x in p]
    q = rounded.configuration_point(p[4], joint=5, guess=guess)
    assert np.allclose([z.real for z in q], p, rtol=1e-8)


def test_example_13_bond_pattern(bricard):
    bonds = bricard.bonds()
    patterns = set()
    for b in bonds:
        assert b.typical
        at_i = [k for k, z in enumerate(b.joints) if abs(z * z + 1) < 1e-12]
        assert len(at_i) == 2
        signs = [round(b.joints[k].imag) for k in at_i]
        kind = "same" if signs[0] == signs[1] else "opposite"
        patterns.add((tuple(k + 1 for k in at_i), kind))
        for k, z in enumerate(b.joints):  # the other entries: complex, real and imaginary parts nonzero
            if k not in at_i:
                assert abs(z.real) > 1e-6 and abs(z.imag) > 1e-6
    assert patterns == {((1, 5), "opposite"), ((2, 4), "opposite"), ((3, 6), "same"), ((3, 6), "opposite")}
    d, n = bricard.distance_matrix(), 6
    for i, j, k in itertools.combinations(range(n), 3):
        assert (d[i, j] + d[j, k] + d[i, k]) % 2 == 0 and d[i, j] + d[j, k] + d[i, k] > 0
    for i in range(n):
        assert d[(i - 1) % n, (i + 1) % n] == d[(i - 1) % n, i] + d[i, (i + 1) % n]
    assert np.array_equal(distances_from_connections(n, bricard.connections()), d)
    # genus one: no joint parametrises the curve, every joint length is at least 2
    assert min(d[(i - 1) % n, i] for i in range(n)) >= 2


def test_remark_13_no_bond_at_infinity_in_any_pose(bricard):
    """Joints 3 and 6 have length 4: a bond at infinity there is not excluded by the fibre count of
    ``tests/test_spatial_remark_13.py``, but it needs a real ``t3`` or ``t6`` at a bond (then some
    pose of the linkage puts it at ``inf``).  At every bond they are ``+-I`` or not real."""
    d, n = bricard.distance_matrix(), 6
    assert [int(d[(k - 1) % n, k]) for k in range(n)] == [2, 2, 4, 2, 2, 4]
    for b in bricard.bonds():
        assert not any(np.isinf(abs(z)) for z in b.joints)
        for z in (b.joints[2], b.joints[5]):
            assert abs(z * z + 1) < 1e-12 or abs(z.imag) > 1e-6
