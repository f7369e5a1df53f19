"""The linkages of "The Theory of Bonds" (Examples 1, 2, 3, 11, 12, 13, Figures 1(c) and 4) as
``RevoluteChain`` objects.

Examples 1-3 and 13 are given by their axes alone (the configuration curve is
computed).  Examples 11 and 12 are built as the paper describes, by factoring
quadratic motion polynomials, and carry the paper's printed configuration
curves, which the constructor checks against the closure condition exactly.
"""

from __future__ import annotations

import sympy
from sympy import Rational as R

from .chain import RevoluteChain, motion_factorization
from .synthesis import bennett_linkage, double_bennett, goldberg, linkage_from_factorizations
from .curve import T, ConfigurationCurve
from .dualquat import DualQuaternion

__all__ = [
    "bennett",
    "bricard_example_13",
    "cubic_6r",
    "double_bennett_6r",
    "example_11",
    "example_12",
    "example_11_axes",
    "goldberg_5r",
    "planar_four_bar",
    "spherical_four_bar",
]


def _line(primal, dual) -> DualQuaternion:
    """``primal`` and ``dual`` vector parts as printed in the paper (exact rationals)."""
    zero = sympy.Integer(0)
    return DualQuaternion([zero, *map(sympy.Rational, primal), zero, *map(sympy.Rational, dual)])


def bennett() -> RevoluteChain:
    """Example 1: ``h1 = i``, ``h2 = 9 eps i + j - 9 eps k``, ``h3``, ``h4`` as printed."""
    return RevoluteChain(
        [
            _line([1, 0, 0], [0, 0, 0]),
            _line([0, 1, 0], [9, 0, -9]),
            _line([-R(1, 3), -R(2, 3), R(2, 3)], [-4, 4, 2]),
            _line([R(2, 3), R(1, 3), R(2, 3)], [5, 4, -7]),
        ]
    )


def spherical_four_bar() -> RevoluteChain:
    """Example 2: ``h1 = i``, ``h2 = j``, ``h3 = k``, ``h4 = 3/5 i + 4/5 j``."""
    zero = [0, 0, 0]
    directions = ([1, 0, 0], [0, 1, 0], [0, 0, 1], [R(3, 5), R(4, 5), 0])
    return RevoluteChain([_line(d, zero) for d in directions])


def planar_four_bar() -> RevoluteChain:
    """Example 3: ``h1 = eps i + k``, ``h2 = eps j + k``, ``h3 = k``, ``h4 = eps i + 2 eps j + k``."""
    k = [0, 0, 1]
    return RevoluteChain([_line(k, [1, 0, 0]), _line(k, [0, 1, 0]), _line(k, [0, 0, 0]), _line(k, [1, 2, 0])])


def _factor(left: DualQuaternion, right: DualQuaternion, right_norm) -> tuple:
    """Refactor ``(t - left)(t - right)`` with the new right factor's norm ``t^2 + m1 t + m0``."""
    return motion_factorization((left * right, -(left + right)), right_norm)


def example_11_axes() -> list[DualQuaternion]:
    """The axes ``h1..h6`` of Example 11, by the paper's chain of factorisations.

    ``(t - h1)(t - 1 - h2) = (t - 1 - g1)(t - g2)``,
    ``(t - g2)(t - 2 - h2) = (t - 2 - h4)(t - h3)``,
    ``(t - 1 - g1)(t - 3 - h4) = (t - 3 - h6)(t - 1 - h5)``,
    with ``h1 = i`` and ``h2 = eps i + j``.
    """
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    h1 = _line([1, 0, 0], [0, 0, 0])
    h2 = _line([0, 1, 0], [1, 0, 0])
    g1, g2 = _factor(h1, one + h2, (1, 0))  # N(t - g2) = t^2 + 1
    g1 = g1 - one
    h4, h3 = _factor(g2, 2 * one + h2, (1, 0))
    h4 = h4 - 2 * one
    h6, h5 = _factor(one + g1, 3 * one + h4, (2, -2))  # N(t - 1 - h5) = t^2 - 2t + 2
    return [h1, h2, h3, h4, h5 - one, h6 - 3 * one]


def example_11() -> RevoluteChain:
    """Example 11 with its printed curve ``(t, (t^2-3t+1)/(2t-3), -t, t^2-5t+7, -t+1, -t+3)``."""
    t = T
    curve = ConfigurationCurve.rational([t, (t**2 - 3 * t + 1) / (2 * t - 3), -t, t**2 - 5 * t + 7, -t + 1, -t + 3])
    return RevoluteChain(example_11_axes(), curve=curve)


def example_12() -> RevoluteChain:
    """Example 12: ``(t + h1)(t - 3 - h6) = (t - 3 - h1')(t - h6')``, chain ``(h1', h2..h5, h6')``,
    printed curve ``(3 + t, -(t^2+3t+1)/(2t+3), t, t^2+5t+7, t+1, t)``."""
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    h1, h2, h3, h4, h5, h6 = example_11_axes()
    h1p, h6p = _factor(-h1, 3 * one + h6, (1, 0))
    t = T
    curve = ConfigurationCurve.rational([3 + t, -(t**2 + 3 * t + 1) / (2 * t + 3), t, t**2 + 5 * t + 7, t + 1, t])
    return RevoluteChain([h1p - 3 * one, h2, h3, h4, h5, h6p], curve=curve)


def bricard_example_13() -> RevoluteChain:
    """Example 13, Bricard's plane symmetric 6R linkage, from its printed axes alone.

    ``h3 = k`` and ``h6 = j`` span the symmetry plane; ``h1, h5`` and ``h2, h4`` are mirror
    images.  Its configuration curve (genus one) is computed by elimination.
    """
    k, j = _line([0, 0, 1], [0, 0, 0]), _line([0, 1, 0], [0, 0, 0])
    h1 = _line([R(4, 9), -R(7, 9), R(4, 9)], [-R(17, 27), -R(4, 27), R(10, 27)])
    h2 = _line([R(3, 7), R(2, 7), R(6, 7)], [R(32, 49), R(12, 49), -R(20, 49)])
    h4 = _line([R(3, 7), -R(2, 7), -R(6, 7)], [-R(32, 49), R(12, 49), -R(20, 49)])
    h5 = _line([R(4, 9), R(7, 9), -R(4, 9)], [R(17, 27), -R(4, 27), R(10, 27)])
    return RevoluteChain([h1, h2, k, h4, h5, j])


def goldberg_5r() -> tuple[RevoluteChain, RevoluteChain, RevoluteChain]:
    """A Goldberg 5R linkage and its two Bennett linkages (the paper gives no axes for one).

    The shared link carries ``h3`` through ``(0, 1, 2)`` with direction ``(2, -1, 2)/3`` and
    ``h6`` through ``(1, -1, 1/2)`` with direction ``(4, 1, -8)/9``; the Bennett linkages are
    those of :func:`~linkage.spatial.synthesis.bennett_linkage` with offsets ``2`` and
    ``-1/2``.  Returns ``(bennett_a, bennett_b, goldberg)`` with
    ``bennett_a = (h1, h2, h3, h6)``, ``bennett_b = (h3, h4, h5, h6)``.
    """
    h3 = DualQuaternion.from_line([0, 1, 2], [R(2, 3), R(-1, 3), R(2, 3)])
    h6 = DualQuaternion.from_line([1, -1, R(1, 2)], [R(4, 9), R(1, 9), R(-8, 9)])
    a = bennett_linkage(h3, h6, 2)  # (h3, h6, x, y)
    b = bennett_linkage(h6, h3, R(-1, 2))  # (h6, h3, p, q)
    bennett_a = RevoluteChain([a.axes[2], a.axes[3], a.axes[0], a.axes[1]])
    bennett_b = RevoluteChain([b.axes[1], b.axes[2], b.axes[3], b.axes[0]])
    return bennett_a, bennett_b, goldberg(bennett_a, bennett_b)


def cubic_6r() -> RevoluteChain:
    """A 6R linkage from two factorisations of a cubic motion polynomial (refs. [8, 10]).

    ``C = (t - h_1)(t - 1 - h_2)(t + 1 - h_3)`` with ``h_1 = i``, ``h_2 = eps i + j``,
    ``h_3`` through ``(1, 0, 2)`` with direction ``(2, 2, 1)/3``, refactored with the norm
    factors in reverse order (:func:`~linkage.spatial.synthesis.linkage_from_factorizations`).
    """
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    h1 = _line([1, 0, 0], [0, 0, 0])
    h2 = _line([0, 1, 0], [1, 0, 0])
    h3 = DualQuaternion.from_line([1, 0, 2], [R(2, 3), R(2, 3), R(1, 3)])
    factors = [h1, one + h2, -one + h3]
    return linkage_from_factorizations(factors, [(2, 2), (2, -2), (1, 0)])


def double_bennett_6r() -> tuple[RevoluteChain, RevoluteChain, RevoluteChain]:
    """Waldron's double Bennett linkage of Figure 4 (the paper gives no axes for it).

    The shared axis ``h`` passes through ``(0, 1, 2)`` with direction ``(2, -1, 2)/3``;
    ``bennett_a`` is :func:`~linkage.spatial.synthesis.bennett_linkage` of ``h`` and the
    line through ``(1, -1, 1/2)`` with direction ``(4, 1, -8)/9`` (offset ``3``), turned
    to end at ``h``; ``bennett_b`` is that of ``h`` and the line through ``(2, 0, -1)``
    with direction ``(1, 2, 2)/3`` (offset ``-1/2``).  Returns
    ``(bennett_a, bennett_b, chain)`` with ``bennett_a = (h1, h2, h3, h)``,
    ``bennett_b = (h, h4, h5, h6)`` and ``chain = double_bennett(bennett_a, bennett_b)``.
    """
    h = DualQuaternion.from_line([0, 1, 2], [R(2, 3), R(-1, 3), R(2, 3)])
    a = bennett_linkage(h, DualQuaternion.from_line([1, -1, R(1, 2)], [R(4, 9), R(1, 9), R(-8, 9)]), 3)
    b = bennett_linkage(h, DualQuaternion.from_line([2, 0, -1], [R(1, 3), R(2, 3), R(2, 3)]), R(-1, 2))
    bennett_a = RevoluteChain([a.axes[1], a.axes[2], a.axes[3], a.axes[0]])
    bennett_b = RevoluteChain(b.axes)
    return bennett_a, bennett_b, double_bennett(bennett_a, bennett_b)
