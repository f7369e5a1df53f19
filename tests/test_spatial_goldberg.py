"""Goldberg's 5R linkage from two Bennett linkages ([HSS] Section 4, Examples 8 and 10),
random Bennett and Goldberg linkages against Theorems 19 and 23, and rigid random chains.

Eq. (18) and Example 10 are typed in from the paper.  The paper numbers the Goldberg
linkage of Figure 1(c) with the joint of length two first; ``goldberg`` follows the
numbering of Theorem 34 (two Bennetts sharing h3 and h6, h6 removed: the double joint is
h3), so the paper's joint k is joint k + 2 (mod 5) here.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import sympy
from sympy import Rational as R

from linkage.spatial import DualQuaternion, RevoluteChain
from linkage.spatial.chain import RigidLinkageError, distances_from_connections
from linkage.spatial.elimination import candidate_curves_5r
from linkage.spatial.examples import goldberg_5r
from linkage.spatial.synthesis import bennett_linkage, goldberg, goldberg_decomposition

# eq. (18), the Goldberg linkage (Figure 1(c) numbering)
D18 = np.array([[0, 1, 2, 3, 2], [1, 0, 1, 2, 3], [2, 1, 0, 1, 2], [3, 2, 1, 0, 1], [2, 3, 2, 1, 0]])
D18_BENNETT = np.array([[0, 1, 2, 1], [1, 0, 1, 2], [2, 1, 0, 1], [1, 2, 1, 0]])
SHIFT = 2  # paper joint k = joint k + 2 here


def paper_numbering(d):
    idx = [(k + SHIFT) % 5 for k in range(5)]
    return d[np.ix_(idx, idx)]


def rational_line(rng) -> DualQuaternion:
    """Unit direction by inverse stereographic projection of a rational (u, v); integer point."""
    u, v = (R(int(a), int(b)) for a, b in zip(rng.integers(-6, 7, 2), rng.integers(1, 5, 2)))
    q = 1 + u**2 + v**2
    return DualQuaternion.from_line([R(int(x)) for x in rng.integers(-3, 4, 3)], [2 * u / q, 2 * v / q, (1 - u**2 - v**2) / q])


def skew(a: DualQuaternion, b: DualQuaternion) -> bool:
    """Neither parallel nor intersecting (reciprocal product of the Pluecker coordinates != 0)."""
    da, db = np.array(a.primal[1:], dtype=float), np.array(b.primal[1:], dtype=float)
    ma, mb = np.array(a.dual[1:], dtype=float), np.array(b.dual[1:], dtype=float)
    return np.linalg.norm(np.cross(da, db)) > 0.05 and abs(da @ mb + db @ ma) > 0.05


def skew_pair(rng):
    while True:
        a, b = rational_line(rng), rational_line(rng)
        if skew(a, b):
            return a, b


def offset(rng):
    return R(int(rng.choice([-3, -2, -1, 1, 2, 3])), int(rng.integers(1, 4)))


def goldberg_from_link(h3, h6, c_a, c_b) -> tuple:
    """Two Bennett linkages on the link (h3, h6): (h1, h2, h3, h6) and (h3, h4, h5, h6)."""
    a = bennett_linkage(h3, h6, c_a)  # (h3, h6, x, y)
    b = bennett_linkage(h6, h3, c_b)  # (h6, h3, p, q)
    a = RevoluteChain([a.axes[2], a.axes[3], a.axes[0], a.axes[1]])
    b = RevoluteChain([b.axes[1], b.axes[2], b.axes[3], b.axes[0]])
    return a, b, goldberg(a, b)


def closure_residual(chain, ts) -> float:
    """Largest relative residual of the closure along real curve points, in float arithmetic."""
    rounded = RevoluteChain([h.map(float) for h in chain.axes])
    worst = 0.0
    for p in chain.configuration_curve().real_points(ts):
        if not all(np.isfinite(abs(z)) for z in p):
            continue
        q = rounded.closure([z.real for z in p])
        worst = max(worst, max(abs(x) for x in q.coefficients[1:]) / abs(q[0]))
    return worst


def assert_theorems_19_cd_and_23(chain):
    d, n = chain.distance_matrix(), chain.n
    for i, j, k in itertools.combinations(range(n), 3):
        s = d[i, j] + d[j, k] + d[i, k]
        assert s > 0 and s == int(s) and int(s) % 2 == 0
    b = [d[(i - 1) % n, i] for i in range(n)]
    for i in range(n):
        assert d[(i - 1) % n, (i + 1) % n] == b[i] + b[(i + 1) % n]
    assert np.array_equal(distances_from_connections(n, chain.connections()), d)


@pytest.fixture(scope="module")
def fixed_goldberg():
    return goldberg_5r()


def test_example_8_eq_18_and_example_10(fixed_goldberg):
    a, b, g = fixed_goldberg
    assert np.array_equal(a.distance_matrix(), D18_BENNETT) and np.array_equal(b.distance_matrix(), D18_BENNETT)
    d = g.distance_matrix()
    assert np.array_equal(paper_numbering(d), D18)
    assert all(bond.method == "exact" and bond.elementary for bond in g.bonds())
    # Example 10: cut the diagram at o3 and o5 (paper numbering); exactly two connections cross,
    # h1-h4 and h2-h5, so d(3, 5) = 2
    conn = {tuple(sorted(((i - 1 - SHIFT) % 5 + 1, (j - 1 - SHIFT) % 5 + 1))): k for (i, j), k in g.connections().items()}
    side = {4, 5}  # joints between o3 and o5
    crossing = sorted(key for key in conn if (key[0] in side) != (key[1] in side))
    assert crossing == [(1, 4), (2, 5)] and sum(conn[k] for k in crossing) == 2 == paper_numbering(d)[2, 4]
    # the joint of length two (Lemma 32): h3 of Theorem 34, connected twice
    assert [d[(i - 1) % 5, i] for i in range(5)] == [1, 1, 2, 1, 1]


def test_goldberg_curve_agrees_with_elimination_from_the_axes_alone(fixed_goldberg):
    """The composed curve and the 5R elimination (which never sees the Bennett linkages) give
    the same configurations: every point of one closes the chain and lies on the other."""
    _, _, g = fixed_goldberg
    alone = RevoluteChain(g.axes)
    assert alone.is_mobile()
    eliminated = alone.configuration_curve()
    composed = g.configuration_curve()
    t = sympy.Symbol("t")
    ex_c, ex_e = composed.expressions(), eliminated.expressions()
    (param,) = [k for k, e in enumerate(ex_e) if e == t]  # the joint that parametrises the eliminated curve
    for s in (R(1, 3), R(-5, 2), R(7)):
        p = [e.subs(t, s) for e in ex_c]
        q = [e.subs(t, p[param]) for e in ex_e]
        assert p == q
    assert np.array_equal(alone.distance_matrix(), g.distance_matrix())


def test_goldberg_refuses_chains_that_do_not_share_the_link(fixed_goldberg):
    a, b, _ = fixed_goldberg
    other = RevoluteChain([b.axes[1], b.axes[2], b.axes[3], b.axes[0]])
    with pytest.raises(ValueError, match="must share the axis h3"):
        goldberg(a, other)
    with pytest.raises(ValueError, match="4R RevoluteChain"):
        goldberg(a, fixed_goldberg[2])
    with pytest.raises(ValueError, match="offset must be a nonzero"):
        bennett_linkage(a.axes[0], a.axes[1], 0)


def test_twenty_random_bennett_linkages():
    rng = np.random.default_rng(20)
    worst = 0.0
    for _ in range(20):
        h1, h2 = skew_pair(rng)
        chain = bennett_linkage(h1, h2, offset(rng))
        worst = max(worst, closure_residual(chain, np.linspace(-3.3, 3.1, 9)))
        assert np.array_equal(chain.distance_matrix(), D18_BENNETT)
        assert_theorems_19_cd_and_23(chain)
        assert chain.is_mobile()
    assert worst <= 1e-12


def test_twenty_random_goldberg_linkages():
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(20):
        h3, h6 = skew_pair(rng)
        c_a, c_b = offset(rng), offset(rng)
        while c_b == c_a:
            c_b = offset(rng)
        _, _, g = goldberg_from_link(h3, h6, c_a, c_b)
        worst = max(worst, closure_residual(g, np.linspace(-3.3, 3.1, 9)))
        assert np.array_equal(paper_numbering(g.distance_matrix()), D18)
        assert_theorems_19_cd_and_23(g)
        assert g.is_mobile() and RevoluteChain(g.axes).home_is_isolated() is False
    assert worst <= 1e-12


@pytest.mark.parametrize("n", [5, 6])
def test_twenty_random_chains_are_rigid(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        chain = RevoluteChain([rational_line(rng) for _ in range(n)])
        assert chain.is_mobile() is False
        with pytest.raises(RigidLinkageError, match="rigid"):
            chain.configuration_curve()


def test_random_5r_rigid_by_elimination_too():
    """Independent of the home-pose argument: the elimination finds no curve component."""
    rng = np.random.default_rng(55)
    for _ in range(3):
        axes = [rational_line(rng) for _ in range(5)]
        for curve in candidate_curves_5r(axes):
            with pytest.raises(ValueError, match="closure"):
                RevoluteChain(axes, curve=curve)


def test_rigid_linkage_error_is_a_value_error_and_moved_bennett_is_rigid():
    from .test_spatial_fourbar import BENNETT, line

    assert issubclass(RigidLinkageError, ValueError)
    axes = list(BENNETT)
    axes[3] = line([R(2, 3), R(1, 3), R(2, 3)], [6, 4, -8])
    chain = RevoluteChain(axes)
    assert chain.is_mobile() is False
    assert RevoluteChain(BENNETT).is_mobile() is True


def scrambled_goldberg(rng):
    """A random mobile 5R not in Goldberg's form: a random Goldberg linkage moved to another
    configuration (its axes where that configuration puts them), displaced rigidly, renumbered
    cyclically and possibly reversed.  Returns the axes and the position of the double joint."""
    h3, h6 = skew_pair(rng)
    c_a, c_b = offset(rng), offset(rng)
    while c_b == c_a:
        c_b = offset(rng)
    _, _, g = goldberg_from_link(h3, h6, c_a, c_b)
    t = sympy.Symbol("t")
    expr = g.configuration_curve().expressions()
    for t0 in (R(1, 2), R(-2, 3), R(5, 4), R(3), R(-7, 5)):
        joints = [e.subs(t, t0) for e in expr]
        if all(j.is_finite for j in joints):
            break
    pose = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    moved = [g.axes[0]]
    for k in range(1, 5):
        pose = pose * (joints[k - 1] - g.axes[k - 1])
        moved.append((pose * g.axes[k] * pose.inverse()).map(sympy.simplify))
    r = [R(int(x)) for x in rng.integers(-3, 4, 4)]
    r[0] += 5  # a nonzero rotation quaternion
    v = [R(int(x)) for x in rng.integers(-3, 4, 3)]
    sigma = DualQuaternion([*r, 0, 0, 0, 0]) * DualQuaternion([1, 0, 0, 0, 0, *(-x / 2 for x in v)])
    placed = [(sigma * h * sigma.inverse()).map(sympy.simplify) for h in moved]
    shift = int(rng.integers(5))
    order = [(shift + k) % 5 for k in range(5)]
    if rng.integers(2):
        order = order[::-1]
    return [placed[k] for k in order], order.index(2)


def _karger_check(rng):
    axes, double = scrambled_goldberg(rng)
    chain = RevoluteChain(axes)
    assert chain.is_mobile()
    a, b = goldberg_decomposition(chain)
    assert a.axes[2] == axes[double] and b.axes[0] == axes[double]
    assert np.array_equal(a.distance_matrix(), D18_BENNETT) and np.array_equal(b.distance_matrix(), D18_BENNETT)
    g = goldberg(a, b)
    assert list(g.axes) == [axes[(double + k) % 5] for k in (-2, -1, 0, 1, 2)]


def test_karger_classification_on_random_mobile_5r():
    """Theorem 34: a mobile 5R is a Goldberg linkage; its two Bennett linkages are found from
    the axes alone (3 random chains here, 20 in the slow study)."""
    rng = np.random.default_rng(34)
    for _ in range(3):
        _karger_check(rng)


@pytest.mark.slow
def test_karger_classification_on_twenty_random_mobile_5r():
    rng = np.random.default_rng(3434)
    for _ in range(20):
        _karger_check(rng)


def test_goldberg_decomposition_refuses_rigid_and_non_5r_chains(fixed_goldberg):
    a, _, _ = fixed_goldberg
    with pytest.raises(ValueError, match="5R RevoluteChain"):
        goldberg_decomposition(a)
    rng = np.random.default_rng(1)
    with pytest.raises(RigidLinkageError):
        goldberg_decomposition(RevoluteChain([rational_line(rng) for _ in range(5)]))


def coupling_degree_and_span(chain, i, j):
    """Degree of the polynomial map t -> F_ij (coordinates freed of their gcd) and the dimension
    of the linear span of its image, computed from the rational curve alone (no bonds)."""
    t = sympy.Symbol("t")
    curve = chain.configuration_curve()
    f = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    for k in [(i + s) % chain.n for s in range((j - i) % chain.n)]:  # joints i+1..j, 0-based
        f = (f * (curve.a[k].as_expr() - curve.c[k].as_expr() * chain.axes[k])).map(sympy.expand)
    polys = [sympy.Poly(c, t) for c in f if c != 0]
    g = polys[0]
    for p in polys[1:]:
        g = sympy.gcd(g, p)
    reduced = [sympy.div(p, g)[0] for p in polys]
    degree = max(p.degree() for p in reduced)
    samples = sympy.Matrix([[p.eval(s) for p in reduced] for s in range(-4, 5)])
    return degree, samples.rank()


def test_section_4_coupling_curves_are_conics_and_twisted_cubics(fixed_goldberg):
    """Theorem 33 with Theorem 19 (a) checked independently of the bonds: on the rational curve
    (a birational parametrisation) deg C_ij deg f_ij is the degree of t -> F_ij; the coupling
    curves of non-adjacent links have degree 2 (spanning a plane: conics) or 3 (spanning a 3-space:
    twisted cubics), and neighbouring links move on lines."""
    _, _, g = fixed_goldberg
    d = g.distance_matrix()
    kinds = []
    for i, j in itertools.combinations(range(1, 6), 2):
        degree, span = coupling_degree_and_span(g, i, j)
        assert degree == d[i - 1, j - 1]
        if (j - i) % 5 in (1, 4):
            assert span == 2  # a rotation about the common axis: a line (twice round at the double joint)
        else:
            assert (degree, span) in ((2, 3), (3, 4))
            kinds.append(degree)
    assert sorted(kinds) == [2, 2, 2, 3, 3]


@pytest.mark.parametrize("name", ["bennett", "example_11", "example_12"])
def test_theorem_19_a_by_the_degree_of_the_coupling_map(name):
    """d(i, j) from the bonds equals the degree of t -> F_ij on the rational curve."""
    from linkage.spatial import examples

    chain = {"bennett": examples.bennett, "example_11": examples.example_11, "example_12": examples.example_12}[name]()
    d = chain.distance_matrix()
    for i, j in itertools.combinations(range(1, chain.n + 1), 2):
        assert coupling_degree_and_span(chain, i, j)[0] == d[i - 1, j - 1]


def test_mobility_of_a_7r_chain_and_what_is_not_decided():
    """Six independent screws of seven joints: a smooth curve through the home pose (mobile); the
    elimination stops at six joints, and float axes with dependent screws are not judged."""
    rng = np.random.default_rng(77)
    chain = RevoluteChain([rational_line(rng) for _ in range(7)])
    assert chain.is_mobile() is True and chain.home_is_isolated() is False
    with pytest.raises(NotImplementedError, match="n = 4, 5, 6"):
        chain.configuration_curve()
    a, b, g = goldberg_5r()
    rounded = RevoluteChain([h.map(float) for h in g.axes])
    with pytest.raises(NotImplementedError, match="mobility of this 5R chain"):
        rounded.is_mobile()
