"""Examples 1-9 of "The Theory of Bonds" (Bennett, spherical, planar four-bar) from their axes alone.

Every expected value below is typed in from the paper (equation numbers
given), never taken from this code's output.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy
from sympy import Rational as R

from linkage.spatial import ConfigurationCurve, DualQuaternion, RevoluteChain

I = 1j
t, w = sympy.symbols("t w")


def line(primal, dual) -> DualQuaternion:
    """``primal`` and ``dual`` vector parts, as printed in the paper."""
    return DualQuaternion([0, *primal, 0, *dual])


# Example 1: h1 = i, h2 = 9 eps i + j - 9 eps k, h3 = -(1/3 + 4 eps) i - (2/3 - 4 eps) j + (2/3 + 2 eps) k,
#            h4 = (2/3 + 5 eps) i + (1/3 + 4 eps) j + (2/3 - 7 eps) k
BENNETT = [
    line([1, 0, 0], [0, 0, 0]),
    line([0, 1, 0], [9, 0, -9]),
    line([-R(1, 3), -R(2, 3), R(2, 3)], [-4, 4, 2]),
    line([R(2, 3), R(1, 3), R(2, 3)], [5, 4, -7]),
]
# Example 2: h1 = i, h2 = j, h3 = k, h4 = 3/5 i + 4/5 j
SPHERICAL = [line([1, 0, 0], [0] * 3), line([0, 1, 0], [0] * 3), line([0, 0, 1], [0] * 3), line([R(3, 5), R(4, 5), 0], [0] * 3)]
# Example 3: h1 = eps i + k, h2 = eps j + k, h3 = k, h4 = eps i + 2 eps j + k
PLANAR = [line([0, 0, 1], [1, 0, 0]), line([0, 0, 1], [0, 1, 0]), line([0, 0, 1], [0, 0, 0]), line([0, 0, 1], [1, 2, 0])]


def both_signs(template):
    """The two bonds ``(... +-I ...)`` of a printed pair: ``template(s)`` for ``s = +1, -1``."""
    return [tuple(template(s)) for s in (1, -1)]


# eq. (9)
BENNETT_BONDS = both_signs(lambda s: (s * I, 1 + s * I, s * I, -1 - s * I)) + both_signs(
    lambda s: (-1 + s * I, s * I, -1 + s * I, -s * I)
)
# Example 2 (text)
SPHERICAL_BONDS = (
    both_signs(lambda s: (-3 * s * I, -s * I, -3, s * I))
    + both_signs(lambda s: (-s * I / 3, s * I, R(1, 3), s * I))
    + both_signs(lambda s: (-s * I, -1, s * I, 0.8 + 0.6 * s * I))
    + both_signs(lambda s: (-s * I, 1, -s * I, -0.8 + 0.6 * s * I))
)
# Example 3 (text)
PLANAR_BONDS = (
    both_signs(lambda s: (s * I, -2 + s * I, -s * I, 4 - s * I))
    + both_signs(lambda s: (2 + s * I, -s * I, -1 + 2 * s * I, s * I))
    + both_signs(lambda s: (s * I, -s * I, s * I, -s * I))
)

# eqs. (14) and (15), times 2
D_BENNETT_1 = [[0, 0, 1, 1], [0, 0, 1, 1], [1, 1, 0, 0], [1, 1, 0, 0]]  # beta' = (+-I, 1+-I, +-I, -1-+I)
D_BENNETT_2 = [[0, 1, 1, 0], [1, 0, 0, 1], [1, 0, 0, 1], [0, 1, 1, 0]]  # beta''
D_PLANAR_1 = [[0, 1, 1, 0], [1, 0, 0, 1], [1, 0, 0, 1], [0, 1, 1, 0]]  # beta' = (2+-I, -+I, -1+-2I, +-I)
D_PLANAR_2 = [[0, 0, 1, 1], [0, 0, 1, 1], [1, 1, 0, 0], [1, 1, 0, 0]]  # beta'' = (+-I, -2+-I, -+I, 4-+I)
D_PLANAR_3 = [[0, 1, 2, 1], [1, 0, 1, 2], [2, 1, 0, 1], [1, 2, 1, 0]]  # beta''' = (+-I, -+I, +-I, -+I)
# eq. (18)
D_TOTAL_BENNETT = [[0, 1, 2, 1], [1, 0, 1, 2], [2, 1, 0, 1], [1, 2, 1, 0]]
D_TOTAL_PLANAR = [[0, 2, 4, 2], [2, 0, 2, 4], [4, 2, 0, 2], [2, 4, 2, 0]]


def same_point(a, b, tol=1e-12) -> bool:
    def same(x, y):
        x, y = complex(x), complex(y)
        if np.isinf(abs(x)) or np.isinf(abs(y)):
            return np.isinf(abs(x)) and np.isinf(abs(y))
        return abs(x - y) <= tol * (1 + abs(y))

    return all(same(x, y) for x, y in zip(a, b))


def assert_same_bond_set(found, expected):
    assert len(found) == len(expected), (found, expected)
    for e in expected:
        assert sum(same_point(f, e) for f in found) == 1, f"bond {e} not found once in {found}"


def bond_at(chain, point):
    (b,) = [b for b in chain.bonds() if same_point(b.joints, point)]
    return b


@functools.lru_cache(maxsize=None)
def example_chain(name: str) -> RevoluteChain:
    """One chain per example for the whole session (bonds are cached on the chain)."""
    return RevoluteChain({"bennett": BENNETT, "spherical": SPHERICAL, "planar": PLANAR}[name])


@pytest.fixture
def bennett():
    return example_chain("bennett")


@pytest.fixture
def spherical():
    return example_chain("spherical")


@pytest.fixture
def planar():
    return example_chain("planar")


def test_axes_are_unit_lines():
    for h in BENNETT + SPHERICAL + PLANAR:
        assert h * h == DualQuaternion.scalar(-1)


# --- configuration curves -------------------------------------------------------------


def test_bennett_curve_is_eq_7_up_to_the_parameter(bennett):
    """eq. (7): ``(t - 1, t, t - 1, -t)``; ours uses ``t = t_4``, i.e. the paper's ``-t``."""
    curve = bennett.configuration_curve()
    assert curve.is_rational
    assert [sympy.simplify(e - f) for e, f in zip(curve.expressions(), (-t - 1, -t, -t - 1, t))] == [0] * 4


def test_spherical_curve_has_the_radicand_of_eq_12(spherical):
    curve = spherical.configuration_curve()
    assert sympy.expand(curve.g.as_expr() - (25 * t**4 - 14 * t**2 + 25)) == 0


def test_planar_curve_has_the_radicand_of_eq_13(planar):
    curve = planar.configuration_curve()
    assert sympy.expand(curve.g.as_expr() - (t**4 - 8 * t**3 + 2 * t**2 + 56 * t - 47)) == 0


@pytest.mark.parametrize("name", ["bennett", "spherical", "planar"])
def test_closure_along_the_real_curve(name, request):
    """At real curve points, ``prod (t_k - h_k)`` is real: vector and dual parts vanish."""
    chain = request.getfixturevalue(name)
    curve = chain.configuration_curve()
    checked = 0
    for point in curve.real_points(np.linspace(-3.3, 3.1, 23)) + curve.real_points(np.linspace(-3.3, 3.1, 23), -1):
        if not all(np.isfinite(point)):
            continue
        p = chain.closure([z.real for z in point])
        assert max(abs(x) for x in p.coefficients[1:]) <= 1e-11 * (1 + abs(p[0]))
        assert abs(p[0]) > 1e-6
        checked += 1
    assert checked >= 20


def test_printed_curves_satisfy_closure_and_a_wrong_one_is_refused():
    """eqs. (7), (12), (13) typed in from the paper pass the exact closure check; a typo does not."""
    RevoluteChain(BENNETT, curve=ConfigurationCurve.rational([t - 1, t, t - 1, -t]))
    g2 = 25 * t**4 - 14 * t**2 + 25
    sph = [(5 - 5 * t**2 + w) / (6 * t), (-5 * t**2 - 5 + w) / (8 * t), (25 * t**2 - 7 - 5 * w) / 24, t]
    RevoluteChain(SPHERICAL, curve=ConfigurationCurve.hyperelliptic(sph, g2))
    g3 = t**4 - 8 * t**3 + 2 * t**2 + 56 * t - 47
    pla = [(-(t**2) + 2 * t + 5 - w) / (2 * (t + 3)), (t**2 + 1 + w) / (4 * (2 - t)), (t**2 - 4 * t + 1 + w) / (4 * (t - 1)), t]
    RevoluteChain(PLANAR, curve=ConfigurationCurve.hyperelliptic(pla, g3))
    with pytest.raises(ValueError, match="closure"):
        RevoluteChain(BENNETT, curve=ConfigurationCurve.rational([t - 1, t, t + 1, -t]))


def test_a_rigid_chain_is_refused():
    """Moving one Bennett axis off its place leaves a rigid 4R chain: no configuration curve."""
    axes = list(BENNETT)
    axes[3] = line([R(2, 3), R(1, 3), R(2, 3)], [6, 4, -8])  # the same direction, moved
    assert axes[3] * axes[3] == DualQuaternion.scalar(-1)
    with pytest.raises(ValueError, match="rigid"):
        RevoluteChain(axes).configuration_curve()


def test_a_moving_component_with_a_fixed_joint_is_not_dropped_silently():
    """Planar kite, pivots (0,0), (2,0), (3,3), (0,2): |p1p2| = |p4p1| = 2, |p2p3| = |p3p4| = sqrt 10.

    Besides the ordinary motion it folds: link p4p1 onto p1p2 (joint 1 fixed at
    t_1 = -1), after which p2 = p4 and joints 2 and 4 turn together.  That
    component moves, so it must not be discarded as a 'fixed joint' leaving
    bonds and distances of half the curve (issue 11, review finding B).
    """
    pivots = [[0, 0, 0], [2, 0, 0], [3, 3, 0], [0, 2, 0]]
    ch = RevoluteChain([DualQuaternion.from_line(p, [0, 0, 1]) for p in pivots])
    # independent check that t_1 = -1 is a moving component: closure for several t_4
    a, b = sympy.symbols("a b")
    moving = set()
    for t4 in (0, 1, R(1, 2)):
        prod = ch.closure([-1, a, b, t4]).map(sympy.expand)
        for sol in sympy.solve(list(prod)[1:], [a, b], dict=True):
            scalar = sympy.expand(ch.closure([-1, sol[a], sol[b], t4])[0])
            assert scalar != 0
            moving.add((sol[a], t4))
    assert len(moving) == 3
    with pytest.raises(ValueError, match=r"reducible.*t_1 \+ 1 = 0 \(joint 1 fixed\)"):
        ch.configuration_curve()
    with pytest.raises(ValueError, match="reducible"):
        ch.bonds()


# --- bonds ----------------------------------------------------------------------------


def test_bennett_bonds_eq_9(bennett):
    assert_same_bond_set([b.joints for b in bennett.bonds()], BENNETT_BONDS)


def test_spherical_bonds_example_2(spherical):
    assert_same_bond_set([b.joints for b in spherical.bonds()], SPHERICAL_BONDS)


def test_planar_bonds_example_3(planar):
    assert_same_bond_set([b.joints for b in planar.bonds()], PLANAR_BONDS)


@pytest.mark.parametrize("name", ["bennett", "spherical", "planar"])
def test_theorem_10_every_bond_has_two_joints_at_plus_minus_i(name, request):
    for b in request.getfixturevalue(name).bonds():
        assert sum(abs(z * z + 1) < 1e-12 for z in b.joints) >= 2


def test_bennett_local_distances_eq_14(bennett):
    for s in (1, -1):
        assert np.array_equal(2 * bond_at(bennett, (s * I, 1 + s * I, s * I, -1 - s * I)).local_distances, D_BENNETT_1)
        assert np.array_equal(2 * bond_at(bennett, (-1 + s * I, s * I, -1 + s * I, -s * I)).local_distances, D_BENNETT_2)


def test_planar_local_distances_eq_15(planar):
    for s in (1, -1):
        assert np.array_equal(2 * bond_at(planar, (2 + s * I, -s * I, -1 + 2 * s * I, s * I)).local_distances, D_PLANAR_1)
        assert np.array_equal(2 * bond_at(planar, (s * I, -2 + s * I, -s * I, 4 - s * I)).local_distances, D_PLANAR_2)
        assert np.array_equal(2 * bond_at(planar, (s * I, -s * I, s * I, -s * I)).local_distances, D_PLANAR_3)


def test_example_6_and_7_local_values(bennett, planar):
    """Example 6: ``d(1,3) = 1/2`` at ``(-1-I, -I, -1-I, I)``; Example 7: at ``(I, -I, I, -I)``
    ``d(1,2) = 1/2, d(1,3) = 1, d(1,4) = 1/2`` and joint lengths ``b(2) = b(3) = b(4) = 1/2``."""
    assert bond_at(bennett, (-1 - I, -I, -1 - I, I)).local_distances[0, 2] == 0.5
    b = bond_at(planar, (I, -I, I, -I))
    assert list(b.local_distances[0, 1:]) == [0.5, 1.0, 0.5]
    assert b.joint_lengths[1:] == (0.5, 0.5, 0.5)


def test_total_distance_matrices_eq_18(bennett, planar):
    assert np.array_equal(bennett.distance_matrix(), D_TOTAL_BENNETT)
    assert np.array_equal(planar.distance_matrix(), D_TOTAL_PLANAR)


def test_spherical_has_the_planar_distances(spherical):
    """Example 9: Figure 1.b is also the spherical bond diagram, so by Theorem 23 the
    distance matrix is the planar one of eq. (18)."""
    assert np.array_equal(spherical.distance_matrix(), D_TOTAL_PLANAR)


def test_example_9_non_typical_bond(planar):
    """The non-typical bond connects h1 with h3 and h2 with h4 (multiplicity one), and its
    local distance matrix is the sum of the elementary bonds' matrices."""
    for s in (1, -1):
        b = bond_at(planar, (s * I, -s * I, s * I, -s * I))
        assert not b.typical and not b.elementary
        assert b.connection_numbers == {(1, 3): 1, (2, 4): 1}
        assert np.array_equal(b.local_distances, (np.array(D_PLANAR_1) + np.array(D_PLANAR_2)) / 2)
    typical = [b for b in planar.bonds() if b.typical]
    assert len(typical) == 4 and all(b.elementary for b in typical)


def test_figure_1_connections(bennett, spherical, planar):
    """Figure 1 / Example 9: Bennett one line h1-h3 and one h2-h4; four-bars two each."""
    assert bennett.connections() == {(1, 3): 1, (2, 4): 1}
    assert planar.connections() == {(1, 3): 2, (2, 4): 2}
    assert spherical.connections() == {(1, 3): 2, (2, 4): 2}


@pytest.mark.parametrize("name", ["bennett", "spherical", "planar"])
def test_theorem_17_local_pseudometric(name, request):
    """d_beta(i,i) = 0, symmetric, triangle inequality, d(i,j)+d(j,k)+d(i,k) integer."""
    for b in request.getfixturevalue(name).bonds():
        d = b.local_distances
        assert np.all(np.diag(d) == 0) and np.array_equal(d, d.T)
        for i in range(4):
            for j in range(4):
                for k in range(4):
                    assert d[i, k] <= d[i, j] + d[j, k]
                    assert (d[i, j] + d[j, k] + d[i, k]) % 1 == 0


def test_coupling_space_dimensions_theorem_7(bennett, spherical, planar):
    """Three consecutive axes: 6 for Bennett axes, 4 for concurrent ones; two axes: 4."""
    assert all(bennett.coupling_space_dimension(i, i + 2 if i < 3 else i - 2) == 6 for i in (1, 2))
    assert spherical.coupling_space_dimension(1, 3) == 4
    assert planar.coupling_space_dimension(2, 4) == 4
    assert bennett.coupling_space_dimension(1, 2) == 4
    assert bennett.coupling_space_dimension(1, 4) == 8


def test_coupling_map_is_the_relative_pose(bennett):
    """f_13 at a real point is (t2 - h2)(t3 - h3) up to scale (eq. 3 and the F_13 of Example 4)."""
    f13 = bennett.coupling_map(1, 3)
    curve = bennett.configuration_curve()
    t2, t3 = curve(0.4)[1:3]
    expected = (t2.real - BENNETT[1]) * (t3.real - BENNETT[2])
    got = f13(0.4)
    ratio = complex(got[0]) / float(expected[0])
    assert all(abs(complex(x) - ratio * float(y)) < 1e-12 for x, y in zip(got, expected))


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="4 to 7"):
        RevoluteChain(BENNETT[:3])
    with pytest.raises(ValueError, match=r"axes\[1\].*unit line"):
        RevoluteChain([BENNETT[0], line([0, 2, 0], [0, 0, 0]), *BENNETT[2:]])
    with pytest.raises(ValueError, match="same line"):
        RevoluteChain([BENNETT[0], BENNETT[0], *BENNETT[2:]])
    with pytest.raises(ValueError, match=r"i must be .* 1\.\.4"):
        RevoluteChain(BENNETT).coupling_map(0, 2)


def test_numerical_configuration_point_from_the_home_pose(bennett):
    """From the home pose t_k = inf, the solver follows the Bennett curve to t_4 = 2:
    eq. (7) with the paper's t = -2 gives (-3, -2, -3, 2)."""
    point = bennett.configuration_point(2.0)
    assert np.allclose(np.real(point), [-3, -2, -3, 2], atol=1e-9)


def test_numerical_configuration_point_refuses_a_rigid_chain():
    axes = list(BENNETT)
    axes[3] = line([R(2, 3), R(1, 3), R(2, 3)], [6, 4, -8])
    with pytest.raises(ArithmeticError, match="no configuration"):
        RevoluteChain(axes).configuration_point(2.0)
    with pytest.raises(ValueError, match=r"joint must be .* 1\.\.4"):
        RevoluteChain(BENNETT).configuration_point(2.0, joint=5)


def test_coupling_map_takes_the_limit_where_f_14_vanishes(planar):
    """Example 5: at the non-typical bond (-I, I, -I, I) the product F_14 vanishes; the coupling
    map is its limit, and f_14 = f_41^-1 is proportional to conj(t_1 - h_1) = t_1 + h_1 = -I + h_1."""
    curve = planar.configuration_curve()
    (place,) = [p for p in curve.places(1j) if same_point(p.joint_values(), (-I, I, -I, I))]
    got = planar.coupling_map(1, 4)(1j, branch=place.branch)
    expected = DualQuaternion.scalar(-I) + PLANAR[0]
    k = max(range(8), key=lambda m: abs(complex(expected[m])))
    ratio = complex(got[k]) / complex(expected[k])
    assert abs(ratio) > 1e-6
    assert all(abs(complex(x) - ratio * complex(y)) < 1e-12 * abs(ratio) for x, y in zip(got, expected))


@pytest.mark.parametrize("name", ["spherical", "planar"])
def test_exact_orders_on_the_hyperelliptic_examples_match_the_50_digit_series(name):
    """Examples 2 and 3 have rational axes: their bonds lie over t0 in Q(I), so the orders are
    exact (series over Q(I, t0, sqrt g(t0))); the forced 50-digit series must agree."""
    chain = example_chain(name)
    exact, series = chain.bonds(), chain.bonds(numeric=True)
    assert {b.method for b in exact} == {"exact"} and {b.method for b in series} == {"mpmath-50"}
    assert len(exact) == len(series)
    for b in exact:
        (twin,) = [c for c in series if same_point(c.joints, b.joints)]
        assert np.array_equal(twin.local_distances, b.local_distances) and twin.typical == b.typical


def test_spherical_bonds_at_4_5_plus_3_5_i_sit_at_branch_points():
    """g = 25t^4 - 14t^2 + 25 vanishes at t = +-4/5 +- 3/5 I: the bonds with t_4 there are at
    branch points of eq. (12), where t - t0 is not a local parameter."""
    g = lambda z: 25 * z**4 - 14 * z**2 + 25  # noqa: E731
    assert abs(g(0.8 + 0.6j)) < 1e-12
    at_branch = [b for b in example_chain("spherical").bonds() if abs(abs(b.joints[3].real) - 0.8) < 1e-12]
    assert len(at_branch) == 4 and all(b.branch == 0 for b in at_branch)


def _turned(h: DualQuaternion) -> DualQuaternion:
    """The line ``h`` turned by 45 degrees about the z axis (matrix entries sqrt(2)/2)."""
    c = sympy.sqrt(2) / 2
    m = sympy.Matrix([[c, -c, 0], [c, c, 0], [0, 0, 1]])
    p, q = m * sympy.Matrix(h.primal[1:]), m * sympy.Matrix(h.dual[1:])
    return DualQuaternion([0, *p, 0, *q])


def test_algebraic_axes_give_the_same_bonds():
    """The Bennett linkage of Example 1 moved rigidly (axes in Q(sqrt 2)): the curve eq. (7)
    still closes it exactly, and bonds and local distances are eqs. (9) and (14), from 50-digit
    series of exactly known data."""
    chain = RevoluteChain([_turned(h) for h in BENNETT], curve=ConfigurationCurve.rational([t - 1, t, t - 1, -t]))
    assert chain.data == "algebraic"
    bonds = chain.bonds()
    assert_same_bond_set([b.joints for b in bonds], BENNETT_BONDS)
    assert {b.method for b in bonds} == {"mpmath-50"}
    for b in bonds:
        expected = D_BENNETT_1 if abs(b.joints[0] ** 2 + 1) < 1e-12 else D_BENNETT_2
        assert np.array_equal(2 * b.local_distances, expected)
    assert chain.coupling_space_dimension(1, 3) == 6


def test_float_axes_close_but_refuse_bonds():
    """Rounded axes satisfy closure only to ~1e-16: configuration points and closure work,
    bonds (zero tests at 1e-30) are refused with a clear message instead of found empty."""
    chain = RevoluteChain([h.map(float) for h in BENNETT])
    assert chain.data == "float"
    point = chain.configuration_point(2.0)
    assert np.allclose(np.real(point), [-3, -2, -3, 2], atol=1e-9)
    with pytest.raises(ValueError, match="bonds need exact axes"):
        chain.bonds()
    with pytest.raises(NotImplementedError, match="rational axes"):
        chain.configuration_curve()
