"""Examples 11 and 12 (overconstrained 6R): axes rebuilt by motion polynomial factorisation,
checked against the printed configuration curves, bond sets and the texts of the examples."""

from __future__ import annotations

import numpy as np
import pytest
import sympy

from linkage.spatial import DualQuaternion
from linkage.spatial.examples import example_11, example_12

from .test_spatial_fourbar import assert_same_bond_set, bennett, planar, spherical  # noqa: F401 (fixtures)

I = 1j


def pairs(template):
    return [tuple(template(s)) for s in (1, -1)]


# Example 11 (text): four pairs of conjugate bonds
EX11_BONDS = (
    pairs(lambda s: (3 + s * I, 6 / 13 + s * 9j / 13, -3 - s * I, s * I, -2 - s * I, -s * I))
    + pairs(lambda s: (s * I, -6 / 13 + s * 9j / 13, -s * I, 6 - s * 5j, 1 - s * I, 3 - s * I))
    + pairs(lambda s: (2 + s * I, s * I, -2 - s * I, -s * I, -1 - s * I, 1 - s * I))
    + pairs(lambda s: (1 + s * I, s * I, -1 - s * I, 2 - s * 3j, -s * I, 2 - s * I))
)
# Example 12 (text)
EX12_BONDS = (
    pairs(lambda s: (-s * I, 6 / 13 + s * 9j / 13, -3 - s * I, s * I, -2 - s * I, -3 - s * I))
    + pairs(lambda s: (3 - s * I, -6 / 13 + s * 9j / 13, -s * I, 6 - s * 5j, 1 - s * I, -s * I))
    + pairs(lambda s: (1 - s * I, s * I, -2 - s * I, -s * I, -1 - s * I, -2 - s * I))
    + pairs(lambda s: (2 - s * I, s * I, -1 - s * I, 2 - s * 3j, -s * I, -1 - s * I))
)


@pytest.fixture(scope="module")
def ex11():
    return example_11()


@pytest.fixture(scope="module")
def ex12():
    return example_12()


@pytest.mark.parametrize("name", ["ex11", "ex12"])
def test_rebuilt_axes_are_lines_and_close_the_printed_curve(name, request):
    """The constructor already checked closure exactly; here also numerically at real points."""
    chain = request.getfixturevalue(name)
    for h in chain.axes:
        assert h * h == DualQuaternion.scalar(-1)
    curve = chain.configuration_curve()
    for point in curve.real_points(np.linspace(-4.1, 4.3, 15)):
        p = chain.closure([z.real for z in point])
        assert max(abs(float(x)) for x in p.coefficients[1:]) <= 1e-10 * abs(float(p[0]))


def test_example_11_bonds(ex11):
    bonds = ex11.bonds()
    assert_same_bond_set([b.joints for b in bonds], EX11_BONDS)
    assert all(b.elementary for b in bonds)  # "All of them are elementary"


def test_example_12_bonds(ex12):
    assert_same_bond_set([b.joints for b in ex12.bonds()], EX12_BONDS)


def _dh(axes):
    """Squared distances ``a_i^2``, cosines of ``alpha_i`` (axes i, i+1) and offsets ``s_i``."""
    n = len(axes)
    d = [sympy.Matrix(h.primal[1:]) for h in axes]
    p = [d[k].cross(-sympy.Matrix(h.dual[1:])) for k, h in enumerate(axes)]  # closest points

    def foot(k, l):  # parameter along axis k of its common normal with axis l
        b, w0 = d[k].dot(d[l]), p[k] - p[l]
        return (b * d[l].dot(w0) - d[k].dot(w0)) / (1 - b**2)

    a2, cos, s = [], [], []
    for k in range(n):
        nxt, prev = (k + 1) % n, (k - 1) % n
        cross = d[k].cross(d[nxt])
        a2.append(((p[nxt] - p[k]).dot(cross)) ** 2 / cross.dot(cross))
        cos.append(d[k].dot(d[nxt]))
        s.append(foot(k, nxt) - foot(k, prev))
    return a2, cos, s


def test_example_11_geometry_as_described(ex11):
    """"the numbers a_i are pairwise distinct ... the only vanishing offsets are s2 = s3 = s5 = 0".
    The text also says no angle is a right angle, but its own h1 = i and h2 = eps i + j are
    perpendicular: alpha_1 = 90 degrees; the others are neither 0 nor 90 degrees."""
    a2, cos, s = _dh(ex11.axes)
    assert len(set(a2)) == 6
    assert [k + 1 for k in range(6) if s[k] == 0] == [2, 3, 5]
    assert cos[0] == 0 and all(x not in (0, 1, -1) for x in cos[1:])


def test_example_12_geometry_as_described(ex12):
    """"now we have only one vanishing offset s3 = 0"."""
    a2, cos, s = _dh(ex12.axes)
    assert [k + 1 for k in range(6) if s[k] == 0] == [3]
    assert all(x not in (0, 1, -1) for x in cos)


@pytest.mark.parametrize("name", ["ex11", "ex12"])
def test_theorem_19_distances_are_degrees_of_the_coupling_curves(name, request):
    """``d(i,j) = deg C_ij * deg f_ij``: on a rational curve, the degree of ``t -> F_ij(t)`` in P^7
    after removing the common factor of its 8 coordinates (and the common zero at t = inf).
    Computed globally here, compared with the sum of local distances over the bonds."""
    chain = request.getfixturevalue(name)
    curve = chain.configuration_curve()
    t = sympy.Symbol("t")
    D = chain.distance_matrix()
    n = chain.n
    for i in range(1, n + 1):
        for j in range(i + 1, n + 1):
            f = DualQuaternion.scalar(sympy.Integer(1))
            degree = 0
            for k in range(i, j):
                a, cc = curve.a[k].as_expr(), curve.c[k].as_expr()
                degree += max(sympy.degree(a, t), sympy.degree(cc, t))
                f = (f * (a - cc * chain.axes[k])).map(sympy.expand)
            coords = [x for x in f if x != 0]
            common = sympy.gcd_list(coords)
            top = max(sympy.degree(x, t) for x in coords)
            assert D[i - 1, j - 1] == int(top - sympy.degree(common, t)), (i, j)
            assert degree >= top


@pytest.mark.parametrize("name", ["ex11", "ex12", "bennett", "spherical", "planar"])
def test_theorem_23_diagram_gives_back_the_distances(name, request):
    """Cutting the bond diagram at links o_i, o_j: d(i,j) = number of lines between the parts."""
    chain = request.getfixturevalue(name)
    n, D, conn = chain.n, chain.distance_matrix(), chain.connections()
    for i in range(1, n + 1):
        for j in range(i + 1, n + 1):
            side = set(range(i + 1, j + 1))  # joints h_{i+1} .. h_j lie between o_i and o_j
            crossing = sum(k for (r, s), k in conn.items() if (r in side) != (s in side))
            assert D[i - 1, j - 1] == crossing


def test_numerical_configuration_points_lie_on_the_printed_curve(ex11):
    """Solving the closure equations for t_1 = t (Gauss-Newton from a perturbed start) gives
    the printed curve (t, (t^2-3t+1)/(2t-3), -t, t^2-5t+7, -t+1, -t+3)."""
    for t in (-2.0, 0.3, 1.1, 2.5):
        printed = (t, (t**2 - 3 * t + 1) / (2 * t - 3), -t, t**2 - 5 * t + 7, -t + 1, -t + 3)
        point = ex11.configuration_point(t, joint=1, guess=[x + 0.05 for x in printed])
        assert np.allclose(np.real(point), printed, rtol=1e-9, atol=1e-9)
        p = ex11.closure([z.real for z in point])
        assert max(abs(float(x)) for x in p.coefficients[1:]) <= 1e-9 * abs(float(p[0]))
