"""Configuration curves of 6R chains from their axes alone, against the curves the paper prints
for Examples 11 and 12 (found there by motion polynomial factorisation, not by elimination)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy

import linkage.spatial.chain
from linkage.spatial import ConfigurationCurve, DualQuaternion, RevoluteChain
from linkage.spatial.elimination import UnparametrisedComponentError, candidate_curves_5r
from linkage.spatial.examples import example_11_axes, example_12, goldberg_5r

s = sympy.Symbol("s")
# Example 11, printed with parameter s
EX11 = [s, (s**2 - 3 * s + 1) / (2 * s - 3), -s, s**2 - 5 * s + 7, -s + 1, -s + 3]
# Example 12, printed
EX12 = [3 + s, -(s**2 + 3 * s + 1) / (2 * s + 3), s, s**2 + 5 * s + 7, s + 1, s]


def _same_curve(found, printed):
    """The eliminated curve is parametrised by t = t6; the printed one by s with t6 = t6(s)
    (linear in both examples), so substitute t = t6(s) and compare as rational functions."""
    t = sympy.Symbol("t")
    return all(sympy.simplify(f.subs(t, printed[5]) - p) == 0 for f, p in zip(found.expressions(), printed))


def test_example_11_curve_by_elimination_is_the_printed_one():
    chain = RevoluteChain(example_11_axes())
    curve = chain.configuration_curve()
    assert curve.is_rational and curve.genus == 0
    assert _same_curve(curve, EX11)


def test_example_12_curve_by_elimination_is_the_printed_one():
    chain = RevoluteChain(example_12().axes)
    assert _same_curve(chain.configuration_curve(), EX12)


# A 6R that moves as a Goldberg 5R while its extra joint stays at the identity (t_k = inf all
# along): the extra axis e is welded in anywhere.  At joints 3 and 4 the eliminant's null vector
# (t3 t4, t3, t4, 1) has last entry 0 there, at joints 1 and 2 the coordinates
# (t1 t2, -t2, -t1, 1) in L_12 do; at joints 5 and 6 the component lies over a line at
# infinity of the (t5, t6) plane.  All of them used to come out as "rigid".
EXTRA_AXIS = DualQuaternion.from_line([1, 2, -1], [sympy.Rational(2, 7), sympy.Rational(3, 7), sympy.Rational(6, 7)])


def goldberg_with_a_resting_joint(k: int) -> tuple[RevoluteChain, RevoluteChain]:
    """``(goldberg, chain)``: the Goldberg 5R and the 6R with ``EXTRA_AXIS`` as joint ``k``."""
    goldberg = goldberg_5r()[2]
    axes = list(goldberg.axes)
    axes.insert(k - 1, EXTRA_AXIS)
    return goldberg, RevoluteChain(axes)


def check_goldberg_motion_with_joint_k_at_rest(goldberg, chain, k):
    assert not chain.home_is_isolated() and chain.is_mobile()
    curve = chain.configuration_curve()
    # joint k at the identity all along: denominator zero, numerator not
    assert curve.c[k - 1].is_zero and not (curve.a[k - 1].is_zero and curve.b[k - 1].is_zero)
    # the other joints move as the Goldberg linkage: their curve closes the 5R exactly
    rest = [i for i in range(6) if i != k - 1]
    g = None if curve.g is None else curve.g.as_expr()
    five = ConfigurationCurve([curve.a[i].as_expr() for i in rest], [curve.b[i].as_expr() for i in rest],
                              [curve.c[i].as_expr() for i in rest], g)
    RevoluteChain(goldberg.axes, curve=five)  # raises unless the closure holds identically
    # traced in floats over real parameters, with joint k at the identity
    rounded = RevoluteChain([h.map(float) for h in chain.axes])
    for p in curve.real_points(np.linspace(-3.1, 2.9, 13)):
        if all(np.isfinite(abs(z)) for i, z in enumerate(p) if i != k - 1):
            q = rounded.closure([z.real if i != k - 1 else z for i, z in enumerate(p)])
            assert max(abs(x) for x in q.coefficients[1:]) <= 1e-12 * abs(q[0])


def test_a_joint_at_rest_in_the_middle_of_the_eliminated_joints():
    goldberg, chain = goldberg_with_a_resting_joint(3)
    check_goldberg_motion_with_joint_k_at_rest(goldberg, chain, 3)


def test_a_joint_at_rest_among_the_last_two_is_found_by_renumbering():
    """Joint 5 at rest: no component in the (t5, t6) plane; numbered from joint 2 the resting
    joint is the fourth and the elimination finds the curve."""
    goldberg, chain = goldberg_with_a_resting_joint(5)
    check_goldberg_motion_with_joint_k_at_rest(goldberg, chain, 5)


@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 2, 4, 6])
def test_a_joint_at_rest_anywhere(k):
    goldberg, chain = goldberg_with_a_resting_joint(k)
    check_goldberg_motion_with_joint_k_at_rest(goldberg, chain, k)


@pytest.mark.parametrize("consistent", [True, False])
def test_a_component_refused_in_one_numbering_must_lie_on_the_curve_found_in_another(consistent, monkeypatch):
    """The elimination of the Goldberg 5R as numbered is made to refuse a component: if its
    equation in (t4, t5) holds on the curve found from joint 2 on, that curve stands; if not, the
    chain refuses rather than return part of the configuration set."""
    goldberg = goldberg_5r()[2]
    y, x = sympy.symbols("y x")  # t_4, t_5, as in candidate_curves_5r
    e = goldberg.configuration_curve().expressions()
    t = sympy.Symbol("t")
    (n4, d4), (n5, d5) = (sympy.fraction(sympy.cancel(e[k])) for k in (3, 4))
    relation = sympy.resultant(sympy.expand(n4 - y * d4), sympy.expand(n5 - x * d5), t)
    assert sympy.degree(relation, x) > 0 and sympy.degree(relation, y) > 0
    factor = relation if consistent else x - y - 7

    def refusing_as_numbered(axes):
        if tuple(axes) == goldberg.axes:
            raise UnparametrisedComponentError("the configuration set has a component (made up)", factor, (y, x))
        return candidate_curves_5r(axes)

    monkeypatch.setattr(linkage.spatial.chain, "candidate_curves_5r", refusing_as_numbered)
    chain = RevoluteChain(goldberg.axes)
    if consistent:
        RevoluteChain(goldberg.axes, curve=chain.configuration_curve())
    else:
        with pytest.raises(NotImplementedError, match="does not contain that component"):
            chain.configuration_curve()
