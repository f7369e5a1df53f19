"""Waldron's double Bennett linkage (Figure 4 of [HSS]): two Bennett linkages that share the
line of one axis ``h``, welded at ``h`` (the joint at ``h`` removed), give a 6R linkage.

The paper names this linkage (Example 11, citing Dietmaier's thesis) but neither describes
its construction nor prints its bond diagram (Figure 4 is an image missing from our copy of
the text).  The expected values below are derived by hand from the construction and the
paper's statements, never read off the code:

*Bonds.*  A Bennett linkage ``(a_1, a_2, a_3, a_4)`` has two conjugate pairs of elementary
bonds, one connecting ``a_1, a_3`` and one ``a_2, a_4`` (Example 9, Figure 1(a), eq. (18)).
On the 6R curve ``t -> (A(t), B(-t))`` both Bennett curves are parametrised birationally, so
every bond of the 6R is a bond of ``A`` or of ``B`` and the local distances of links inside
one Bennett linkage are that linkage's.  ``A = (h1, h2, h3, h)``: its bonds joining ``h1, h3``
are bonds joining ``h1, h3``.  Its bonds joining ``h2, h`` have ``a_h = +-I``, hence
``b_h = -+I``: they are the bonds of ``B = (h, h4, h5, h6)`` joining ``h`` and ``h5`` too.
Cutting the two Bennett cycles at ``(h2, h)`` and at ``(h, h5)`` separates the 6R links
``{o6, o1} | {o2, o3}`` and ``{o3, o4} | {o5, o6}``: exactly the cut of the hexagon at
``h2`` and ``h5``.  So the 6R has three conjugate pairs of elementary bonds, connecting
``h1-h3``, ``h4-h6`` and ``h2-h5`` (Example 11 has four pairs: the different bond structure
of Figure 4).

*Distances* by Theorem 23 (cut at ``o_i, o_j``, count the crossing connections): all joint
lengths 1; ``d(i, i+2) = 2``; ``d(1,4) = d(2,5) = 3`` (all three cross) and ``d(3,6) = 1``
(only ``h2-h5`` crosses): the welded links ``o3, o6`` turn about ``h`` (degree one).

*Corollary 27*: joints of length one connected only to each other satisfy
``t_j = +-t_i``: ``t3 = +-t1``, ``t6 = +-t4``, ``t5 = +-t2``.

*Geometry* (Example 11's remark): the double Bennett is one of the two known families with
pairwise distinct normal distances ``a_i``, no angle zero or right, and no three consecutive
vanishing offsets; Example 12's remark ("only one vanishing offset ... no need to worry
about the double Bennett") implies more than one.  A Bennett linkage has all offsets zero,
and the 6R keeps the two triples ``(h1, h2, h3)`` and ``(h4, h5, h6)`` of consecutive
Bennett axes: ``s2 = s5 = 0`` and no other, and those triples satisfy the Bennett conditions
(Corollary 25 for the bonds ``h1-h3``, ``h4-h6``; Theorem 7.d).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy
from sympy import Rational as R

from linkage.spatial import DualQuaternion, RevoluteChain, RigidLinkageError, double_bennett
from linkage.spatial.examples import double_bennett_6r, spherical_four_bar
from linkage.spatial.synthesis import bennett_linkage

from .test_spatial_goldberg import assert_theorems_19_cd_and_23, closure_residual, offset, rational_line, skew

# Theorem 23 on the connections h1-h3, h2-h5, h4-h6 (module docstring)
D_DOUBLE_BENNETT = np.array(
    [
        [0, 1, 2, 3, 2, 1],
        [1, 0, 1, 2, 3, 2],
        [2, 1, 0, 1, 2, 1],
        [3, 2, 1, 0, 1, 2],
        [2, 3, 2, 1, 0, 1],
        [1, 2, 1, 2, 1, 0],
    ]
)
CONNECTIONS = {(1, 3): 1, (2, 5): 1, (4, 6): 1}
EXAMPLE_11_BOND_PAIRS = 4  # "We have four pairs of conjugate complex bonds" (Example 11)


def plucker(h: DualQuaternion) -> tuple[sympy.Matrix, sympy.Matrix]:
    """Unit direction ``d`` and moment ``m`` of the line ``h = d - eps m``."""
    return sympy.Matrix(h.primal[1:]), -sympy.Matrix(h.dual[1:])


def feet(h: DualQuaternion, g: DualQuaternion) -> tuple[sympy.Matrix, sympy.Matrix]:
    """The feet on ``h`` and on ``g`` of their common perpendicular (skew or intersecting lines)."""
    (d, m), (e, n) = plucker(h), plucker(g)
    x, y = d.cross(m), e.cross(n)  # the points of the lines nearest the origin
    u, v = sympy.symbols("u v")
    diff = x + u * d - y - v * e
    sol = sympy.solve([diff.dot(d), diff.dot(e)], [u, v], dict=True)
    assert len(sol) == 1, "parallel consecutive axes"
    return x + sol[0][u] * d, y + sol[0][v] * e


def denavit_hartenberg(axes) -> tuple[list, list, list]:
    """Exact ``a_i^2``, ``cos alpha_i`` (axes ``h_i``, ``h_{i+1}``) and offsets ``s_i`` on ``h_i``."""
    n = len(axes)
    a2, cosines, offsets = [], [], []
    for i in range(n):
        h, g = axes[i], axes[(i + 1) % n]
        p, q = feet(h, g)
        a2.append(sympy.simplify((p - q).dot(p - q)))
        cosines.append(sympy.simplify(plucker(h)[0].dot(plucker(g)[0])))
    for i in range(n):
        on_h_from_prev = feet(axes[i], axes[i - 1])[0]
        on_h_from_next = feet(axes[i], axes[(i + 1) % n])[0]
        offsets.append(sympy.simplify((on_h_from_next - on_h_from_prev).dot(plucker(axes[i])[0])))
    return a2, cosines, offsets


def bennett_ratio_squared(a2, cosine):
    """``(a / sin alpha)^2`` of two consecutive axes (Theorem 7.d)."""
    return sympy.simplify(a2 / (1 - cosine**2))


def random_double_bennett(rng) -> RevoluteChain:
    while True:
        h, x, y = rational_line(rng), rational_line(rng), rational_line(rng)
        if skew(h, x) and skew(h, y) and skew(x, y):
            break
    a = bennett_linkage(h, x, offset(rng))  # (h, x, p, q)
    b = bennett_linkage(h, y, offset(rng))  # (h, y, r, s)
    return double_bennett(RevoluteChain([a.axes[1], a.axes[2], a.axes[3], a.axes[0]]), b)


@pytest.fixture(scope="module")
def fixed():
    return double_bennett_6r()


def test_bond_pattern_and_distance_matrix(fixed):
    _, _, chain = fixed
    bonds = chain.bonds()
    assert len(bonds) == 2 * 3 and 2 * EXAMPLE_11_BOND_PAIRS != len(bonds)
    assert all(b.method == "exact" and b.typical and b.elementary for b in bonds)
    assert sorted(p for b in bonds for p in b.connection_numbers.items()) == sorted(list(CONNECTIONS.items()) * 2)
    for b in bonds:  # a typical bond: exactly the two connected joints at +-I
        (pair,) = b.connection_numbers
        at_i = [k + 1 for k, t in enumerate(b.joints) if abs(complex(t) ** 2 + 1) < 1e-12]
        assert at_i == list(pair)
    assert chain.connections() == CONNECTIONS
    assert np.array_equal(chain.distance_matrix(), D_DOUBLE_BENNETT)
    assert_theorems_19_cd_and_23(chain)


def test_the_bennett_linkages_have_their_own_pattern(fixed):
    a, b, _ = fixed
    d_bennett = np.array([[0, 1, 2, 1], [1, 0, 1, 2], [2, 1, 0, 1], [1, 2, 1, 0]])  # eq. (18)
    for bennett in (a, b):
        assert np.array_equal(bennett.distance_matrix(), d_bennett)
        assert bennett.connections() == {(1, 3): 1, (2, 4): 1}


def test_corollary_27_joint_pairs(fixed):
    _, _, chain = fixed
    e = chain.configuration_curve().expressions()
    for i, j in [(1, 3), (4, 6), (2, 5)]:
        assert sympy.cancel(e[j - 1] - e[i - 1]) == 0 or sympy.cancel(e[j - 1] + e[i - 1]) == 0, (i, j, e)


def test_mobile_from_the_axes_alone_and_the_same_curve(fixed):
    """Elimination from the six axes (which never sees the Bennett linkages) finds a curve, and
    every point of the glued curve lies on it."""
    _, _, chain = fixed
    alone = RevoluteChain(chain.axes)
    assert not alone.home_is_isolated() and alone.is_mobile()
    t = sympy.Symbol("t")
    ex_glued, ex_elim = chain.configuration_curve().expressions(), alone.configuration_curve().expressions()
    (param,) = [k for k, e in enumerate(ex_elim) if e == t]
    for s in (R(1, 3), R(-5, 2), R(7)):
        p = [e.subs(t, s) for e in ex_glued]
        assert p == [e.subs(t, p[param]) for e in ex_elim]
    assert closure_residual(chain, np.linspace(-3.3, 3.1, 13)) <= 1e-12


def test_denavit_hartenberg_parameters_as_the_paper_states(fixed):
    a, b, chain = fixed
    a2, cosines, offsets = denavit_hartenberg(chain.axes)
    assert len(set(a2)) == 6 and all(x != 0 for x in a2)  # pairwise distinct normal distances
    assert all(c != 0 and c**2 != 1 for c in cosines)  # no angle zero or right
    assert [k + 1 for k, s in enumerate(offsets) if s == 0] == [2, 5]
    # Corollary 25 / Theorem 7.d: the bonds h1-h3 and h4-h6 ask for Bennett triples
    for i in (0, 3):
        assert bennett_ratio_squared(a2[i], cosines[i]) == bennett_ratio_squared(a2[i + 1], cosines[i + 1])
        assert chain.coupling_space_dimension(i + 1, i + 3) == 6
    # each Bennett linkage on its own: all offsets zero (the property the 6R inherits)
    for bennett in (a, b):
        assert all(s == 0 for s in denavit_hartenberg(bennett.axes)[2])


def test_twenty_random_double_bennett_linkages():
    rng = np.random.default_rng(4)
    worst = 0.0
    for _ in range(20):
        chain = random_double_bennett(rng)
        worst = max(worst, closure_residual(chain, np.linspace(-3.3, 3.1, 9)))
        assert chain.connections() == CONNECTIONS
        assert np.array_equal(chain.distance_matrix(), D_DOUBLE_BENNETT)
        assert_theorems_19_cd_and_23(chain)
        assert not RevoluteChain(chain.axes).home_is_isolated()
        offsets = denavit_hartenberg(chain.axes)[2]
        assert offsets[1] == 0 and offsets[4] == 0
    assert worst <= 1e-12


def test_orientation_of_the_shared_axis_does_not_matter(fixed):
    a, b, chain = fixed
    flipped = RevoluteChain([-b.axes[0], *b.axes[1:]])
    again = double_bennett(a, flipped)
    assert again.axes == chain.axes
    assert again.configuration_curve().expressions() == chain.configuration_curve().expressions()


def test_refusals(fixed):
    a, b, chain = fixed
    with pytest.raises(ValueError, match="must share the axis h"):
        double_bennett(a, RevoluteChain([*b.axes[1:], b.axes[0]]))
    with pytest.raises(ValueError, match="4R RevoluteChain"):
        double_bennett(a, chain)
    moved = RevoluteChain([*b.axes[:3], DualQuaternion.from_line([1, 2, 3], [R(2, 3), R(1, 3), R(2, 3)])])
    with pytest.raises(RigidLinkageError, match="bennett_b is not a Bennett linkage: the chain is rigid"):
        double_bennett(a, moved)
    sph = spherical_four_bar()  # shares no line with a, and is not a Bennett linkage either
    with pytest.raises(ValueError, match="genus > 0"):
        double_bennett(sph, RevoluteChain([sph.axes[3], sph.axes[0], sph.axes[1], sph.axes[2]]))
