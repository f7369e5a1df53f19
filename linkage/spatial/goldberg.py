"""Bennett linkages by factorisation and Goldberg's 5R linkage composed from two of them.

[HSS] Section 4: every non-degenerate closed 5R linkage is a *Goldberg linkage*: two
Bennett linkages ``(h_1, h_2, h_3, h_6)`` and ``(h_3, h_4, h_5, h_6)`` that share the
link carrying the axes ``h_3`` and ``h_6`` are composed, and the joint at ``h_6`` is
removed.  On configurations this reads (with ``a_k``, ``b_k`` the joint values of the two
Bennett linkages)

    (a_1 - h_1)(a_2 - h_2) ~ (a_6 + h_6)(a_3 + h_3),   (b_4 - h_4)(b_5 - h_5) ~ (b_3 + h_3)(b_6 + h_6),

so the 5R product ``(a_1 - h_1)(a_2 - h_2)(tau - h_3)(b_4 - h_4)(b_5 - h_5)`` is real when
``tau - h_3 ~ (a_3 - h_3)(b_3 - h_3)`` (the two rotations about ``h_3`` add up:
``tau = (a_3 b_3 - 1) / (a_3 + b_3)``) and ``b_6 = -a_6`` (then
``(a_6 + h_6)(-a_6 + h_6) = -(a_6^2 + 1)``).  The removed joint's ``a_6`` is the
curve's parameter.
"""

from __future__ import annotations

from typing import Any

import sympy

from .chain import RevoluteChain, motion_factorization
from .curve import T, ConfigurationCurve
from .dualquat import DualQuaternion

__all__ = ["bennett_linkage", "goldberg"]


def bennett_linkage(h1: DualQuaternion, h2: DualQuaternion, offset: Any) -> RevoluteChain:
    """The Bennett linkage ``(h_1, h_2, h_3, h_4)`` with two given consecutive axes.

    Factorises the quadratic motion polynomial ``(t - h_1)(t - offset - h_2)`` the other
    way round, ``(t - offset - k_1)(t - k_2)`` with ``N(t - k_2) = t^2 + 1`` ([HSS]
    Example 11, refs. [8, 10]); then ``(t - h_1)(t - offset - h_2)`` times the conjugate
    of ``(t - offset - k_1)(t - k_2)`` is real, the closure of the chain
    ``(h_1, h_2, -k_2, -k_1)`` at ``(t, t - offset, -t, offset - t)``.  Every Bennett
    linkage through the link ``(h_1, h_2)`` arises for one real ``offset != 0``.

    Raises
    ------
    ValueError
        If ``offset`` is zero (the factorisation is then the trivial one) or the two axes
        are concurrent (a planar or spherical pair admits no Bennett linkage).
    """
    if offset == 0:
        raise ValueError("offset must be a nonzero real number (offset 0 gives back the same factors)")
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    c = sympy.nsimplify(offset) if not isinstance(offset, float) else offset
    g1, k2 = motion_factorization((h1 * (c * one + h2), -(h1 + c * one + h2)), (1, 0))
    return RevoluteChain([h1, h2, -k2, -(g1 - c * one)])


def goldberg(bennett_a: RevoluteChain, bennett_b: RevoluteChain) -> RevoluteChain:
    """Goldberg's 5R linkage ``(h_1, h_2, h_3, h_4, h_5)`` from two Bennett linkages.

    Parameters
    ----------
    bennett_a
        ``(h_1, h_2, h_3, h_6)``, a Bennett linkage with rational axes.
    bennett_b
        ``(h_3', h_4, h_5, h_6')`` with ``h_3' = +-h_3`` and ``h_6' = +-h_6`` (the same lines:
        the two linkages share the link carrying ``h_3`` and ``h_6``).

    Returns
    -------
    RevoluteChain
        The 5R chain with the configuration curve composed as in the module docstring,
        parametrised by the removed joint ``t = a_6``; the constructor checks the closure
        condition on it exactly.

    Raises
    ------
    ValueError
        If either chain is not a 4R chain with a rational configuration curve (a Bennett
        linkage), or the shared axes are not the same lines.
    """
    for name, chain in (("bennett_a", bennett_a), ("bennett_b", bennett_b)):
        if not isinstance(chain, RevoluteChain) or chain.n != 4:
            raise ValueError(f"{name} must be a 4R RevoluteChain (a Bennett linkage); got {chain!r}")
    h1, h2, h3, h6 = bennett_a.axes
    b_axes = list(bennett_b.axes)
    for k, (mine, shared, label) in enumerate(((b_axes[0], h3, "h3"), (b_axes[3], h6, "h6"))):
        if mine == -shared:
            b_axes[3 * k] = shared  # the same line, oriented as in bennett_a (joint value changes sign)
        elif mine != shared:
            raise ValueError(
                f"bennett_b must share the axis {label} with bennett_a: bennett_b.axes[{3 * k}] = {mine} "
                f"is not +-{shared}"
            )
    b_chain = bennett_b if b_axes == list(bennett_b.axes) else RevoluteChain(b_axes)
    curves = []
    for name, chain in (("bennett_a", bennett_a), ("bennett_b", b_chain)):
        curve = chain.configuration_curve()
        if not curve.is_rational:
            raise ValueError(f"{name} has a curve of genus > 0: it is a planar or spherical 4R, not a Bennett linkage")
        curves.append([sympy.cancel(e) for e in curve.expressions()])  # parameter t = joint 4
    a1, a2, a3, _ = curves[0]
    b3, b4, b5, _ = (sympy.cancel(e.subs(T, -T)) for e in curves[1])  # b_6 = -a_6 = -t
    tau = sympy.cancel((a3 * b3 - 1) / (a3 + b3))
    return RevoluteChain([h1, h2, h3, b_axes[1], b_axes[2]], curve=ConfigurationCurve.rational([a1, a2, tau, b4, b5]))
