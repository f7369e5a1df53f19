"""Random rational Bennett linkages (built by motion polynomial factorisation) have the bond
structure the paper proves for every Bennett linkage: eq. (18), Figure 1.a, Theorem 17."""

from __future__ import annotations

import numpy as np
import sympy
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from linkage.spatial import DualQuaternion, RevoluteChain, motion_factorization

rationals = st.fractions(min_value=-3, max_value=3, max_denominator=5).map(sympy.Rational)


@st.composite
def rational_lines(draw) -> DualQuaternion:
    """Unit direction by inverse stereographic projection of a rational (u, v); rational point."""
    u, v = draw(rationals), draw(rationals)
    q = 1 + u**2 + v**2
    d = [2 * u / q, 2 * v / q, (1 - u**2 - v**2) / q]
    return DualQuaternion.from_line([draw(rationals) for _ in range(3)], d)


@settings(max_examples=6, deadline=None)
@given(rational_lines(), rational_lines(), rationals)
def test_random_bennett_linkage(h1, h2, a):
    d1, d2 = np.array(h1.primal[1:], dtype=float), np.array(h2.primal[1:], dtype=float)
    cross = np.cross(d1, d2)
    assume(np.linalg.norm(cross) > 1e-3 and a != 0)
    foot = lambda h: np.cross(np.array(h.primal[1:], dtype=float), -np.array(h.dual[1:], dtype=float))  # noqa: E731
    assume(abs((foot(h2) - foot(h1)) @ cross) > 1e-3)  # skew axes
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    # (t - h1)(t - a - h2) = (t - a - k1)(t - k2) with N(t - k2) = t^2 + 1
    g1, k2 = motion_factorization(((h1 * (a * one + h2)), -(h1 + a * one + h2)), (1, 0))
    k1 = g1 - a * one
    chain = RevoluteChain([h1, h2, -k2, -k1])
    curve = chain.configuration_curve()
    assert curve.is_rational
    bonds = chain.bonds()
    assert len(bonds) == 4 and all(b.typical for b in bonds)
    assert np.array_equal(chain.distance_matrix(), [[0, 1, 2, 1], [1, 0, 1, 2], [2, 1, 0, 1], [1, 2, 1, 0]])
    assert chain.connections() == {(1, 3): 1, (2, 4): 1}
    assert chain.coupling_space_dimension(1, 3) == 6  # Theorem 7.d
    for t in (-1.3, 0.4, 2.2):
        p = chain.closure([z.real for z in curve(t)])
        assert max(abs(float(x)) for x in p.coefficients[1:]) <= 1e-9 * abs(float(p[0]))
