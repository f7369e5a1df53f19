"""Generic rational spherical four-bars outside the paper (issue 11, review finding A).

Expected values come from the paper, not from this code's output:

* Example 2: a spherical four-bar has two conjugate pairs of bonds with
  ``t_1^2 + 1 = t_3^2 + 1 = 0`` and two with ``t_2^2 + 1 = t_4^2 + 1 = 0``:
  8 bonds, all typical, each joining 1-3 or 2-4.
* Example 9 / Figure 1.b: the spherical four-bar has the planar four-bar's bond
  diagram (two elementary bonds of the spherical one coincide in the planar
  one), so its connections are ``{(1, 3): 2, (2, 4): 2}`` and, by Theorem 23,
  its total distance matrix is the planar one of eq. (18).
* Theorem 10 / Lemma 22: every bond has at least two joints at ``+-I``;
  connection numbers come in conjugate pairs.

These linkages used to lose bonds silently (2, 4 and 0 of 8, labelled exact):
unnormalised joint pairs of size ``1e23`` made a 50-digit rounding residual
look nonzero against the absolute-looking ``1e-30`` threshold.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy
import pytest
from sympy import Rational as R

from linkage.spatial import DualQuaternion, RevoluteChain
from linkage.spatial.curve import T, W

# eq. (18), second matrix: the planar (and spherical) four-bar
PLANAR_D = np.array([[0, 2, 4, 2], [2, 0, 2, 4], [4, 2, 0, 2], [2, 4, 2, 0]])


def stereographic(x, y):
    """Inverse stereographic projection of ``(x, y)``: a rational unit vector."""
    x, y = R(x), R(y)
    q = x * x + y * y + 1
    return [2 * x / q, 2 * y / q, (x * x + y * y - 1) / q]


CASES = {
    "pythagorean": [[R(3, 5), R(4, 5), 0], [0, R(5, 13), R(12, 13)], [0, 0, 1], [R(2, 7), R(3, 7), R(6, 7)]],
    "mixed": [[1, 0, 0], [0, R(5, 13), R(12, 13)], [R(2, 7), R(-3, 7), R(6, 7)], [R(8, 9), R(1, 9), R(4, 9)]],
    "stereographic": [
        stereographic(0, 0),
        stereographic(R(1, 2), R(1, 3)),
        stereographic(2, R(-1, 5)),
        stereographic(R(-3, 2), 1),
    ],
}


@functools.lru_cache(maxsize=None)
def chain(name: str) -> RevoluteChain:
    return RevoluteChain([DualQuaternion.from_line([0, 0, 0], d) for d in CASES[name]])


def _check_example_2_structure(bonds):
    assert len(bonds) == 8
    pairs = []
    for b in bonds:
        at_i = tuple(k + 1 for k, z in enumerate(b.joints) if z != complex("inf") and abs(z * z + 1) < 1e-20)
        pairs.append(at_i)
        assert b.typical
    assert sorted(pairs) == [(1, 3)] * 4 + [(2, 4)] * 4


@pytest.mark.parametrize("name", sorted(CASES))
def test_generic_spherical_four_bar_has_eight_bonds_and_the_planar_distances(name):
    ch = chain(name)
    bonds = ch.bonds()
    _check_example_2_structure(bonds)
    assert {b.method for b in bonds} == {"exact"}
    np.testing.assert_array_equal(ch.distance_matrix(), PLANAR_D)
    assert ch.connections() == {(1, 3): 2, (2, 4): 2}


@pytest.mark.parametrize("name", ["pythagorean", "stereographic"])
def test_generic_spherical_four_bar_50_digit_series_agree(name):
    """The numeric path alone (normalised joint pairs) finds the same 8 bonds."""
    ch = chain(name)
    bonds = ch.bonds(numeric=True)
    _check_example_2_structure(bonds)
    assert {b.method for b in bonds} == {"mpmath-50"}
    np.testing.assert_array_equal(sum(b.local_distances for b in bonds), PLANAR_D)


def test_a_bond_checked_in_exact_arithmetic_is_reported():
    """An exact zero of ``F`` on the curve (sympy, independent of the series code) is a reported bond.

    Stereographic linkage, ``t = -4/5 - 173/85 I`` on the branch where ``w = -sqrt(g(t))``:
    the joints are ``(-I, 276/245 + 451/245 I, -I, t)`` and ``F_04 = 0`` exactly.
    """
    ch = chain("stereographic")
    curve = ch.configuration_curve()
    t0 = -R(4, 5) - R(173, 85) * sympy.I
    w0 = -sympy.sqrt(sympy.expand(curve.g.as_expr().subs(T, t0)))
    joints = [sympy.simplify(sympy.radsimp(sympy.expand(e.subs({T: t0, W: w0})))) for e in curve.expressions()]
    assert joints == [-sympy.I, R(276, 245) + R(451, 245) * sympy.I, -sympy.I, t0]
    assert all(sympy.simplify(sympy.expand(e)) == 0 for e in ch.closure(joints))
    expected = tuple(complex(z) for z in joints)
    hits = [b for b in ch.bonds() if max(abs(x - y) for x, y in zip(b.joints, expected)) < 1e-12]
    assert len(hits) == 1 and hits[0].method == "exact"
    assert hits[0].connection_numbers == {(1, 3): 1}
