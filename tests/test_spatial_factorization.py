"""Motion polynomial factorisation of any degree (refs. [8, 10] of the bond paper): products of
rotations refactored in every order reproduce the polynomial, exactly over Q or to 1e-12 in
floats; the excluded cases are refused by name; two factorisations close a 6R linkage."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import sympy

from linkage.spatial import DualQuaternion, MotionFactorizationError, linkage_from_factorizations, motion_factorization
from linkage.spatial.chain import distances_from_connections
from linkage.spatial.factorization import norm_polynomial, polynomial_product

from .test_spatial_goldberg import rational_line

ONE = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))


def rotations(rng, d, exact=True):
    """``t - c_k - h_k`` with random lines ``h_k`` and distinct offsets ``c_k``."""
    offsets = rng.choice(np.arange(-4, 5), size=d, replace=False)
    lines = [rational_line(rng) for _ in range(d)]
    if exact:
        return [int(c) * ONE + h for c, h in zip(offsets, lines)], [int(c) for c in offsets]
    fl = DualQuaternion.scalar(1.0, 0.0)
    return [float(c) * fl + h.map(float) for c, h in zip(offsets, lines)], [float(c) for c in offsets]


def poly(gs):
    one = DualQuaternion.scalar(gs[0][0] * 0 + 1, gs[0][0] * 0)
    return polynomial_product(*[[-g, one] for g in gs])


@pytest.mark.parametrize("d", [3, 4])
def test_exact_refactorisation_in_every_order_reproduces_the_polynomial(d):
    rng = np.random.default_rng(d)
    gs, offsets = rotations(rng, d)
    c = poly(gs)
    norms = [(o * o + 1, -2 * o) for o in offsets]
    for order in itertools.permutations(range(d)):
        found = motion_factorization(c[:-1], norm_factors=[norms[k] for k in order])
        for g, k in zip(found, order):
            assert (1 - g).is_rotation()
            assert sympy.expand((g - offsets[k]).quadratic_form()) == 1  # a unit line plus the offset
        product = poly(list(found))
        assert all(sympy.simplify(x - y) == 0 for a, b in zip(product, c) for x, y in zip(a, b))
        if order == tuple(range(d)):  # the factorisation of an ordering is unique
            assert all(sympy.simplify(x - y) == 0 for a, b in zip(found, gs) for x, y in zip(a, b))


@pytest.mark.parametrize("d", [3, 4])
def test_float_refactorisation_to_1e_12(d):
    rng = np.random.default_rng(10 + d)
    worst = 0.0
    for _ in range(5):
        gs, offsets = rotations(rng, d, exact=False)
        c = poly(gs)
        order = list(rng.permutation(d))
        norms = [(offsets[k] ** 2 + 1, -2 * offsets[k]) for k in order]
        found = motion_factorization(c[:-1], norm_factors=norms)
        product = poly(list(found))
        scale = max(abs(x) for a in c for x in a)
        worst = max(worst, max(abs(x - y) for a, b in zip(product, c) for x, y in zip(a, b)) / scale)
        default = motion_factorization(c[:-1])  # norm factors from its roots
        product = poly(list(default))
        worst = max(worst, max(abs(x - y) for a, b in zip(product, c) for x, y in zip(a, b)) / scale)
    assert worst <= 1e-12


def test_default_norm_factors_over_q_and_the_quadratic_form_kept():
    rng = np.random.default_rng(7)
    gs, _ = rotations(rng, 3)
    c = poly(gs)
    found = motion_factorization(c[:-1])
    assert all(sympy.simplify(x - y) == 0 for a, b in zip(poly(list(found)), c) for x, y in zip(a, b))
    primal, dual = norm_polynomial(c)
    assert all(sympy.simplify(x) == 0 for x in dual)
    # the quadratic form of the old interface: right_norm = the last factor's norm
    h1, h2 = rational_line(rng), rational_line(rng)
    q = poly([h1, 2 * ONE + h2])
    g1, g2 = motion_factorization(q[:-1], (1, 0))
    assert sympy.expand(g2.quadratic_form()) == 1 and sympy.simplify(g2[0]) == 0


def test_excluded_cases_are_refused_by_name():
    rng = np.random.default_rng(3)
    h = rational_line(rng)
    g = 2 * ONE + h
    # a real polynomial factor in the primal part: (t^2 + 1)(t - g)
    real = [DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0)), ONE * 0, ONE]
    c = polynomial_product(real, [-g, ONE])
    with pytest.raises(MotionFactorizationError, match="real polynomial factor"):
        motion_factorization(c[:-1])
    # not on the Study quadric
    screw = DualQuaternion([0, 1, 0, 0, 1, 0, 0, 0])
    with pytest.raises(MotionFactorizationError, match="not a motion polynomial"):
        motion_factorization([screw])
    gs, offsets = rotations(rng, 3)
    c = poly(gs)
    with pytest.raises(MotionFactorizationError, match="multiply to"):
        motion_factorization(c[:-1], norm_factors=[(5, 0), (1, 0), (2, 0)])
    with pytest.raises(MotionFactorizationError, match="real roots"):
        motion_factorization(c[:-1], norm_factors=[(-1, 0), (1, 0), (2, 0)])
    with pytest.raises(MotionFactorizationError, match="d = 3"):
        motion_factorization(c[:-1], norm_factors=[(1, 0)])
    assert issubclass(MotionFactorizationError, ValueError)


def test_a_6r_linkage_from_two_factorisations_of_a_cubic():
    """(t - g1)(t - g2)(t - g3) = (t - k1)(t - k2)(t - k3) with the norm factors reversed closes
    the 6R chain (h_g1, h_g2, h_g3, h_k3, h_k2, h_k1); its bonds satisfy Theorems 19 and 23."""
    rng = np.random.default_rng(11)
    gs, offsets = rotations(rng, 3)
    chain = linkage_from_factorizations(gs, [(o * o + 1, -2 * o) for o in reversed(offsets)])
    assert chain.n == 6 and chain.is_mobile()
    d = chain.distance_matrix()
    n = 6
    for i, j, k in itertools.combinations(range(n), 3):
        assert (d[i, j] + d[j, k] + d[i, k]) % 2 == 0 and d[i, j] + d[j, k] + d[i, k] > 0
    for i in range(n):
        assert d[(i - 1) % n, (i + 1) % n] == d[(i - 1) % n, i] + d[i, (i + 1) % n]
    assert np.array_equal(distances_from_connections(n, chain.connections()), d)
    # every joint is linear in t: all joint lengths are 1 (Definition 18)
    assert [d[(i - 1) % n, i] for i in range(n)] == [1] * 6
