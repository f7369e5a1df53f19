"""The statements of "The Theory of Bonds" as executable checks over every example linkage.

Section 1 (rotation/translation test, the exceptional 3-space E), Section 2 (coupling
variety X, the coupling equality, form (4) of G_ij), Corollary 12, Theorem 19 (c), (d),
Theorem 23, Corollaries 24-27 and the misprint of Example 4.  Expected values are the
paper's statements or computed here by independent means, never read off this library.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import numpy as np
import pytest
import sympy
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage.spatial import DualQuaternion, RevoluteChain
from linkage.spatial.chain import distances_from_connections
from linkage.spatial.coupling import coupling_variety_parameters, pose_product
from linkage.spatial.examples import example_11, example_12

from .test_spatial_fourbar import BENNETT, example_chain

EXAMPLES = ["bennett", "spherical", "planar", "example_11", "example_12"]


def chain_of(name):
    if name in ("bennett", "spherical", "planar"):
        return example_chain(name)
    return {"example_11": _ex11, "example_12": _ex12}[name]()


_cache: dict = {}


def _ex11():
    return _cache.setdefault("11", example_11())


def _ex12():
    return _cache.setdefault("12", example_12())


# --- Section 1: rotations, translations, E -----------------------------------------------

coordinate = st.floats(-3, 3, allow_nan=False)


@st.composite
def unit_lines(draw):
    d = np.array([draw(coordinate) for _ in range(3)])
    if np.linalg.norm(d) < 0.1:
        d = np.array([0.0, 0.0, 1.0])
    d = d / np.linalg.norm(d)
    x = [draw(coordinate) for _ in range(3)]
    return DualQuaternion.from_line(x, list(d)), np.array(x), d


def _vec(v, eps=False):
    v = [float(c) for c in v]
    return DualQuaternion([0.0, 0.0, 0.0, 0.0, 0.0, *v]) if eps else DualQuaternion([0.0, *v, 0.0, 0.0, 0.0, 0.0])


@settings(max_examples=30, deadline=None)
@given(unit_lines(), st.floats(-5, 5, allow_nan=False), st.floats(0.2, 2))
def test_rotation_test_by_norm_and_trace(line, t, s):
    """A rotation t - h passes the test and fixes its axis; a proper screw (a rotation followed by
    a slide along the axis) fails it: its trace has a dual part."""
    h, x, d = line
    rot = t - h
    assert rot.is_rotation() and not rot.is_translation() and not rot.in_exceptional_space()
    for lam in (-1.0, 0.5, 2.0):  # independent: points of the axis stay where they are
        assert np.allclose(rot.act(x + lam * d), x + lam * d, atol=1e-9)
    slide = DualQuaternion.scalar(1.0) - _vec(s * d / 2, eps=True)  # translation by s d
    assert np.allclose(slide.act([0.0, 0.0, 0.0]), s * d)
    screw = rot * slide
    assert abs(screw.norm().dual) < 1e-9  # a displacement: on the Study quadric
    assert abs(screw.trace().dual) > 1e-6
    assert not screw.is_rotation() and not screw.is_translation()


@settings(max_examples=30, deadline=None)
@given(st.lists(coordinate, min_size=3, max_size=3), st.floats(0.1, 3))
def test_translation_test_and_the_lines_through_one_that_meet_E(v, s):
    """``1 + s e`` with ``e`` in E (zero primal part, vectorial dual part) is a translation, the
    paper's 'lines on S through 1 that meet E'; a dual scalar part leaves S."""
    e = _vec(v, eps=True)
    assert e.in_exceptional_space() or all(c == 0 for c in v)
    assert e.study_condition() == 0  # E lies in the Study quadric
    one = DualQuaternion.scalar(1.0)
    tr = one + s * e
    if any(v):
        assert tr.is_translation() and not tr.is_rotation()
        assert np.allclose(tr.act([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0]) - 2 * s * np.array(v))
        off_s = tr + DualQuaternion([0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0])
        assert abs(off_s.study_condition()) > 0.1
        assert not off_s.is_translation() and not off_s.is_rotation()


def test_points_of_E_are_no_displacements_and_zero_is_refused():
    e = DualQuaternion([0, 0, 0, 0, 0, 1, 2, 3])
    assert e.in_exceptional_space() and not e.is_rotation() and not e.is_translation()
    with pytest.raises(ValueError, match="zero dual quaternion"):
        DualQuaternion([0] * 8).is_rotation()


def test_exact_rotation_test_on_the_bennett_axes():
    """Exact data are judged exactly: every joint of Example 1 at t = 2/3 is a rotation; the
    product of two joints about skew axes is not (a screw, trace with dual part)."""
    third = sympy.Rational(2, 3)
    for h in BENNETT:
        assert (third - h).is_rotation()
    product = (third - BENNETT[0]) * (third - BENNETT[1])
    assert product.trace().dual != 0 and not product.is_rotation()


# --- Section 2: coupling varieties, the coupling equality, form (4) -------------------------


def _pairs(n):
    return [(i, j) for i in range(1, n + 1) for j in range(1, n + 1) if i != j]


def _proportional(a, b, tol=1e-9):
    m = np.array([list(a), list(b)], dtype=complex)
    s = np.linalg.svd(m, compute_uv=False)
    return s[1] <= tol * s[0]


@pytest.mark.parametrize("name", ["bennett", "example_11", "example_12"])
def test_form_4_and_the_coupling_equality_along_the_curve(name):
    """F_ij is proportional to G_ij (eq. 4) at real configurations, and the pose lies in both
    coupling varieties X_{i+1..j} and X_{i,i-1..j+1} (the coupling equality), with the very
    joint values of the configuration (up to the sign of the backward ones)."""
    chain = chain_of(name)
    curve = chain.configuration_curve()
    points = [p for p in curve.real_points([-1.7, 0.35, 2.9]) if all(np.isfinite(abs(z)) for z in p)]
    assert points
    checked = 0
    for p in points:
        p = [z.real for z in p]
        for i, j in _pairs(chain.n):
            f, g = chain.relative_pose(i, j, p), chain.relative_pose_backward(i, j, p)
            assert _proportional(f, g)
            forward, backward = chain.coupling_varieties(i, j)
            if len(forward) > 3 or len(backward) > 3:
                continue
            tf = coupling_variety_parameters(f, forward)
            tb = coupling_variety_parameters(f, backward)
            m = len(forward)
            assert tf is not None and np.allclose(tf, [p[(i + s) % chain.n] for s in range(m)], rtol=1e-7)
            assert tb is not None and np.allclose(tb, [-p[(i - 1 - s) % chain.n] for s in range(len(backward))], rtol=1e-7)
            checked += 1
    assert checked > 0


def test_a_generic_point_of_one_coupling_variety_misses_the_other():
    """The coupling equality is an intersection: a point of X_{2,3,4} made of arbitrary joint
    values is not on X_{1,6,5} of Example 11 (exactly), while a configuration is."""
    chain = chain_of("example_11")
    forward, backward = chain.coupling_varieties(1, 4)
    assert len(forward) == len(backward) == 3
    x = pose_product(forward, [sympy.Rational(3, 10), 2, -1])
    assert coupling_variety_parameters(x, forward) == (sympy.Rational(3, 10), 2, -1)
    assert coupling_variety_parameters(x, backward) is None
    t = sympy.Rational(1, 2)
    p = [e.subs(sympy.Symbol("t"), t) for e in chain.configuration_curve().expressions()]
    f = chain.relative_pose(1, 4, p)
    assert coupling_variety_parameters(f, backward) == tuple(-p[k] for k in (0, 5, 4))


def test_coupling_variety_refuses_what_it_cannot_decide():
    """Parallel axes span a 4-dimensional subalgebra, so X_{1,2,3} = X_{1,2} of the planar
    four-bar: no single joint value belongs to a point, and the library says so."""
    planar = example_chain("planar")
    with pytest.raises(NotImplementedError, match="every value of the last joint"):
        coupling_variety_parameters(pose_product(planar.axes[:3], [1, 2, 3]), planar.axes[:3])
    h = example_chain("bennett").axes
    with pytest.raises(ValueError, match="nonzero"):
        coupling_variety_parameters(DualQuaternion([0] * 8), h[:2])
    x = pose_product(list(h) + [h[0]], [1, 2, 3, 4, 5])
    with pytest.raises(NotImplementedError, match="every value of the last joint"):
        coupling_variety_parameters(x, list(h) + [h[0]])


# --- Example 4: the misprint in F_13 ---------------------------------------------------------


def test_example_4_misprint_in_the_eps_k_coefficient_of_F13():
    """F_13(t) = (t - h2)(t - 1 - h3) for Example 1.  By hand, with h = p + eps q (p, q vectors):
    (t - p2 - eps q2)(t - 1 - p3 - eps q3) has the eps-part
    -t q3 - (t - 1) q2 + p2 q3 + q2 p3, and for vectors a b = -a.b + a x b.  The eps k
    coefficient is therefore -2t + 9(t - 1) + (p2 x q3)_z + (q2 x p3)_z = 7t - 9 + 4 - 6 = 7t - 11.
    The paper prints -t(2/3 + 7 eps) + 1/3 - 11 eps, i.e. -7t - 11: a misprint (the primal k
    part -2/3 t + 1/3 is right)."""
    p2, q2 = np.array([0, 1, 0], dtype=object), np.array([9, 0, -9], dtype=object)
    p3 = np.array([Fraction(-1, 3), Fraction(-2, 3), Fraction(2, 3)], dtype=object)
    q3 = np.array([-4, 4, 2], dtype=object)

    def eps_k(t):
        vec = -t * q3 - (t - 1) * q2 + np.cross(p2, q3) + np.cross(q2, p3)
        scal = -(p2 @ q3) - (q2 @ p3)
        return vec[2], scal

    assert [eps_k(t)[0] for t in (0, 1)] == [-11, -4]  # 7t - 11
    printed = [-7 * t - 11 for t in (0, 1)]
    assert [eps_k(t)[0] for t in (0, 1)] != printed
    # the library's product agrees with the hand computation, exactly, as a polynomial in t
    t = sympy.Symbol("t")
    h2, h3 = (h.map(sympy.Rational) for h in BENNETT[1:3])
    f13 = ((t - h2) * (t - 1 - h3)).map(sympy.expand)
    assert f13[7] == 7 * t - 11
    assert f13[3] == -sympy.Rational(2, 3) * t + sympy.Rational(1, 3)
    assert f13[4] == 5 and eps_k(0)[1] == 5  # the printed eps part of the scalar, 5 eps


# --- Corollary 12, Theorem 19, Theorem 23, Corollaries 24-27 --------------------------------


def _bonds(name):
    return chain_of(name).bonds()


@pytest.mark.parametrize("name", EXAMPLES)
def test_corollary_12_at_typical_bonds(name):
    """At a typical bond with t_i^2 + 1 = t_j^2 + 1 = 0 (i < j): F_{i-1,j} = F_{j-1,n+i} = 0."""
    chain = chain_of(name)
    rounded = RevoluteChain([h.map(float) for h in chain.axes])  # complex128 products, not sympy ones
    typical = [b for b in _bonds(name) if b.typical]
    assert typical or name == "planar"  # Example 3 has two non-typical pairs, and typical ones
    for b in typical:
        i, j = [k + 1 for k, z in enumerate(b.joints) if np.isfinite(abs(z)) and abs(z * z + 1) < 1e-9]
        scale = np.prod([1 + abs(z) for z in b.joints if np.isfinite(abs(z))])
        for f in (rounded.relative_pose((i - 2) % chain.n + 1, j, b.joints), rounded.relative_pose(j - 1, i, b.joints)):
            assert max(abs(complex(c)) for c in f) <= 1e-10 * scale
        # the full loop vanishes too (the bond's definition); a product leaving out joint j need not
        assert max(abs(complex(c)) for c in rounded.closure(b.joints)) <= 1e-10 * scale


@pytest.mark.parametrize("name", EXAMPLES)
def test_theorem_19_c_and_d(name):
    """(c) d(i,j) + d(j,k) + d(i,k) is a positive even integer for distinct i, j, k;
    (d) d(i-1, i+1) = b(i) + b(i+1)."""
    chain = chain_of(name)
    d, n = chain.distance_matrix(), chain.n
    for i, j, k in itertools.combinations(range(n), 3):
        s = d[i, j] + d[j, k] + d[i, k]
        assert s > 0 and s == int(s) and int(s) % 2 == 0
    b = [d[(i - 1) % n, i] for i in range(n)]  # b(i+1) = d(i, i+1), 0-based
    for i in range(n):
        assert d[(i - 1) % n, (i + 1) % n] == b[i] + b[(i + 1) % n]


@pytest.mark.parametrize("name", EXAMPLES)
def test_theorem_23_distances_from_the_bond_diagram(name):
    chain = chain_of(name)
    assert np.array_equal(distances_from_connections(chain.n, chain.connections()), chain.distance_matrix())


def test_theorem_23_reading_by_hand():
    """Figure 1(a): the Bennett diagram connects h1-h3 and h2-h4; cutting at o1, o3 separates
    {h2, h3} from {h4, h1}: both connections cross, d(1, 3) = 2; cutting at o1, o2 only h2-h4."""
    d = distances_from_connections(4, {(1, 3): 1, (2, 4): 1})
    assert d[0, 2] == 2 and d[0, 1] == 1
    with pytest.raises(ValueError, match="connections must map pairs"):
        distances_from_connections(4, {(3, 1): 1})


@pytest.mark.parametrize("name", EXAMPLES)
def test_corollaries_24_and_25(name):
    """24: d(i, i+3) < b(i+1) + b(i+2) + b(i+3) implies l_{i+1,i+2,i+3} <= 6.
    25: a bond connecting h_i with h_{i+2} makes l_{i,i+1,i+2} <= 6."""
    chain = chain_of(name)
    d, n = chain.distance_matrix(), chain.n
    applied = 0
    for i in range(1, n + 1):
        a, b1, b2, b3 = (i - 1) % n, i % n, (i + 1) % n, (i + 2) % n
        if d[a, b3] < d[a, b1] + d[b1, b2] + d[b2, b3]:
            assert chain.coupling_space_dimension(i % n + 1, (i + 2) % n + 1) <= 6
            applied += 1
    for bond in chain.bonds():
        for (i, j), k in bond.connection_numbers.items():
            if k > 0 and (j - i) % n in (2, n - 2):
                first = i if (j - i) % n == 2 else j
                assert chain.coupling_space_dimension(first, (first + 1) % n + 1) <= 6
                applied += 1
    assert applied > 0 or n > 4


@pytest.mark.parametrize("name", ["bennett", "example_11", "example_12"])
def test_corollaries_26_and_27_on_the_rational_examples(name):
    """26: b(i) = 1 (joint i connected once, to one joint) means t_i parametrises the curve: on
    these rational curves t_i is a Moebius function of the parameter (degree b(i) in general).
    27: two joints of length 1 connected once to each other and to nothing else: t_i = +-t_j."""
    chain = chain_of(name)
    d, n = chain.distance_matrix(), chain.n
    conn = chain.connections()
    curve = chain.configuration_curve()
    lengths = [d[(i - 1) % n, i] for i in range(n)]
    for k in range(n):
        assert max(curve.a[k].degree(), curve.c[k].degree()) == lengths[k]
    partners = {i: [p for key, m in conn.items() for p in key if i in key and p != i] for i in range(1, n + 1)}
    expr = curve.expressions()
    pairs = [
        (i, j)
        for (i, j), m in conn.items()
        if m == 1 and lengths[i - 1] == lengths[j - 1] == 1 and partners[i] == [j] and partners[j] == [i]
    ]
    for i, j in pairs:
        assert sympy.simplify(expr[i - 1] - expr[j - 1]) == 0 or sympy.simplify(expr[i - 1] + expr[j - 1]) == 0
    if name == "bennett":
        assert pairs == [(1, 3), (2, 4)]
