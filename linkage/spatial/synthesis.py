"""Mobile chains built from motion polynomials: Bennett and 2d-R linkages, Goldberg's 5R,
Waldron's double Bennett 6R.

*Factorisation linkages* (refs. [8, 10] of [HSS]): a motion polynomial ``C`` of degree
``d`` factors as ``(t - g_1) ... (t - g_d)`` for every ordering of its norm's quadratic
factors.  Two factorisations ``C = (t - g_1)...(t - g_d) = (t - k_1)...(t - k_d)`` close a
chain: ``C conj(C)`` is real, and ``conj(t - k) = (t - c) + h`` for ``k = c + r h``
(``h`` a unit line), so the ``2d`` axes ``(h_{g_1}, ..., h_{g_d}, h_{k_d}, ..., h_{k_1})``
move with the joint values ``((t - c_{g_1})/r_{g_1}, ..., (c_{k_1} - t)/r_{k_1})``: a
Bennett linkage for ``d = 2``, a 6R linkage for ``d = 3``.

*Goldberg's 5R linkage*.
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

*Waldron's double Bennett linkage* (named, not described, in [HSS] Example 11, which
cites Dietmaier's thesis, ref. [5]; the construction is Waldron's hybrid of the
mechanism literature).  Two Bennett linkages ``(h_1, h_2, h_3, h)`` and
``(h, h_4, h_5, h_6)`` share the *line* of one axis ``h`` (not a link); at ``h`` the
two links of the first linkage are welded to those of the second
(``(h_3, h) + (h, h_4)`` and ``(h_6, h) + (h, h_1)``), which removes the joint ``h``
and leaves the 6R chain ``(h_1, ..., h_6)``.  With ``a_k``, ``b_k`` the joint values of
the two Bennett linkages, closure of each gives

    (a_1 - h_1)(a_2 - h_2)(a_3 - h_3) ~ (a_h + h),   (b_4 - h_4)(b_5 - h_5)(b_6 - h_6) ~ (b_h + h),

and ``(a_h + h)(b_h + h) = a_h b_h - 1 + (a_h + b_h) h`` is real exactly when
``b_h = -a_h``: then the welded links ``o_3`` and ``o_6`` turn about ``h`` relative to
each other by the same rotation ``~ (a_h - h)`` through either Bennett linkage.  The
curve is the pair of Bennett curves glued along ``b_h = -a_h``, parametrised by
``t = a_h``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import sympy

from .chain import RevoluteChain
from .curve import T, ConfigurationCurve
from .dualquat import DualQuaternion, is_inexact
from .factorization import motion_factorization, polynomial_product

__all__ = ["bennett_linkage", "double_bennett", "goldberg", "goldberg_decomposition", "linkage_from_factorizations"]


def linkage_from_factorizations(
    factors: Sequence[DualQuaternion], norm_factors: Sequence[Sequence[Any]]
) -> RevoluteChain:
    """The closed ``2d``-R chain of two factorisations of one motion polynomial.

    Parameters
    ----------
    factors
        ``(g_1, ..., g_d)``, rotation quaternions: ``C = (t - g_1) ... (t - g_d)``.
    norm_factors
        The ordering ``[(m0_1, m1_1), ..., (m0_d, m1_d)]`` of the second factorisation
        ``C = (t - k_1) ... (t - k_d)``, ``N(t - k_j) = t^2 + m1_j t + m0_j`` (see
        :func:`motion_factorization`).

    Returns
    -------
    RevoluteChain
        Axes ``(h_{g_1}, ..., h_{g_d}, h_{k_d}, ..., h_{k_1})`` with the rational curve of
        the module docstring (checked against the closure condition exactly by the
        constructor).
    """
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    polynomial = polynomial_product(*[[-g, one] for g in factors])
    ks = motion_factorization(polynomial[:-1], norm_factors=norm_factors)
    axes, joints = [], []
    exact = not any(is_inexact(x) for g in factors for x in g)
    for g, sign in [(g, 1) for g in factors] + [(k, -1) for k in reversed(ks)]:
        c = g[0]
        r2 = g.quadratic_form() - c * c  # N(t - g) = (t - c)^2 + r^2
        r = sympy.sqrt(r2) if exact else float(r2) ** 0.5
        if r == 0:
            raise ValueError(f"factor {g} is not a rotation (its vector part has zero norm)")
        axes.append(((g - c) * (1 / r)).map(sympy.simplify) if exact else (g - c) * (1 / r))
        joints.append(sign * (T - c) / r)
    return RevoluteChain(axes, curve=ConfigurationCurve.rational(joints))


def bennett_linkage(h1: DualQuaternion, h2: DualQuaternion, offset: Any) -> RevoluteChain:
    """The Bennett linkage ``(h_1, h_2, h_3, h_4)`` with two given consecutive axes.

    The factorisation linkage (:func:`linkage_from_factorizations`) of
    ``(t - h_1)(t - offset - h_2)`` with the norm factors swapped: the second
    factorisation is ``(t - offset - k_1)(t - k_2)``, and the chain is
    ``(h_1, h_2, -k_2, -k_1)`` with joint values ``(t, t - offset, -t, offset - t)``.
    Every Bennett linkage through the link ``(h_1, h_2)`` arises for one real
    ``offset != 0``.

    Raises
    ------
    ValueError
        If ``offset`` is zero (the factorisation is then the trivial one) or the
        factorisation is non-generic (e.g. concurrent axes).
    """
    if offset == 0:
        raise ValueError("offset must be a nonzero real number (offset 0 gives back the same factors)")
    c = offset if is_inexact(offset) else sympy.sympify(offset)  # a float stays a float: no guessed rational
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    return linkage_from_factorizations([h1, c * one + h2], [(c * c + 1, -2 * c), (1, 0)])


def _check_four_revolute(**chains: RevoluteChain) -> None:
    """``ValueError`` naming the first argument that is not a 4R :class:`RevoluteChain`."""
    for name, chain in chains.items():
        if not isinstance(chain, RevoluteChain) or chain.n != 4:
            raise ValueError(f"{name} must be a 4R RevoluteChain (a Bennett linkage); got {chain!r}")


def _bennett_expressions(name: str, curve: ConfigurationCurve) -> list:
    """The joint values along a Bennett linkage's configuration ``curve`` (argument ``name``), cancelled, as
    functions of joint 4; ``ValueError`` for a curve of genus > 0 (a planar or spherical 4R)."""
    if not curve.is_rational:
        raise ValueError(f"{name} has a curve of genus > 0: it is a planar or spherical 4R, not a Bennett linkage")
    return [sympy.cancel(e) for e in curve.expressions()]


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
    _check_four_revolute(bennett_a=bennett_a, bennett_b=bennett_b)
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
    curves = [_bennett_expressions(name, chain.configuration_curve())
              for name, chain in (("bennett_a", bennett_a), ("bennett_b", b_chain))]
    a1, a2, a3, _ = curves[0]
    b3, b4, b5, _ = (sympy.cancel(e.subs(T, -T)) for e in curves[1])  # b_6 = -a_6 = -t
    tau = sympy.cancel((a3 * b3 - 1) / (a3 + b3))
    return RevoluteChain([h1, h2, h3, b_axes[1], b_axes[2]], curve=ConfigurationCurve.rational([a1, a2, tau, b4, b5]))


def double_bennett(bennett_a: RevoluteChain, bennett_b: RevoluteChain) -> RevoluteChain:
    """Waldron's double Bennett 6R linkage ``(h_1, ..., h_6)`` from two Bennett linkages.

    Parameters
    ----------
    bennett_a
        ``(h_1, h_2, h_3, h)``, a Bennett linkage with rational axes.
    bennett_b
        ``(h', h_4, h_5, h_6)`` with ``h' = +-h`` (the same line: the two linkages share
        the axis ``h``, and at ``h`` their links are welded together).

    Returns
    -------
    RevoluteChain
        The 6R chain with the configuration curve of the module docstring,
        ``t_1, t_2, t_3`` those of ``bennett_a`` and ``t_4, t_5, t_6`` those of
        ``bennett_b``, glued along ``b_h = -a_h = -t``; the constructor checks the
        closure condition on it exactly.

    Raises
    ------
    ValueError
        If either chain is not a 4R chain with a rational configuration curve (a Bennett
        linkage; ``RigidLinkageError`` for a rigid one), the axes ``bennett_a.axes[3]`` and
        ``bennett_b.axes[0]`` are not the same line, or the 6R chain has two equal
        consecutive axes (``h_3 = +-h_4`` or ``h_6 = +-h_1``).
    """
    _check_four_revolute(bennett_a=bennett_a, bennett_b=bennett_b)
    h1, h2, h3, h = bennett_a.axes
    if bennett_b.axes[0] != h and bennett_b.axes[0] != -h:
        raise ValueError(
            f"bennett_b must share the axis h = bennett_a.axes[3] = {h}: bennett_b.axes[0] = {bennett_b.axes[0]} "
            f"is not +-h"
        )
    h4, h5, h6 = bennett_b.axes[1:]
    # Both relabelled with the shared axis last (h oriented as in bennett_a), so that the
    # elimination parametrises each curve by the joint at h: t = a_h, t = b_h.
    curves = []
    for name, axes in (("bennett_a", [h1, h2, h3, h]), ("bennett_b", [h4, h5, h6, h])):
        try:
            curve = RevoluteChain(axes).configuration_curve()
        except ValueError as err:  # rigid or reducible: the same error type, naming the argument
            raise type(err)(f"{name} is not a Bennett linkage: {err}") from err
        curves.append(_bennett_expressions(name, curve))
    a1, a2, a3, _ = curves[0]
    b4, b5, b6 = (sympy.cancel(e.subs(T, -T)) for e in curves[1][:3])  # b_h = -a_h = -t
    return RevoluteChain([h1, h2, h3, h4, h5, h6], curve=ConfigurationCurve.rational([a1, a2, a3, b4, b5, b6]))


def goldberg_decomposition(chain: RevoluteChain) -> tuple[RevoluteChain, RevoluteChain]:
    """The two Bennett linkages of a mobile 5R chain: Karger's classification, executed.

    [HSS] Section 4: a non-degenerate 5R linkage has exactly one joint of length two
    (Lemma 32), say ``h_m``; its neighbours ``h_{m-1}, h_{m-2}`` have length one, so
    ``t_{m-2}`` and ``t_{m-1}`` are Moebius functions of each other on the curve, and the
    relative motion ``F = (s - h_{m-2})(t_{m-1}(s) - h_{m-1})`` is a quadratic motion
    polynomial in ``s = t_{m-2}`` (made monic on the right by a constant rotation about
    ``h_{m-1}``).  Its second factorisation ``(s - k_1)(s - k_2)`` (norm factors swapped)
    has ``k_2`` about ``h_m`` and ``k_1`` about the axis ``h_6`` of Theorem 34's proof.

    Returns
    -------
    (bennett_a, bennett_b)
        ``(h_{m-2}, h_{m-1}, h_m, h_6)`` and ``(h_m, h_{m+1}, h_{m+2}, h_6)`` (indices mod 5),
        so that ``goldberg(bennett_a, bennett_b)`` is the chain relabelled to start at
        ``h_{m-2}``.  Both are checked to be Bennett linkages (mobile 4R chains with a
        rational curve), and ``goldberg`` checks that their composition closes the chain.

    Raises
    ------
    ValueError
        For a chain that is not 5R, a rigid one (``RigidLinkageError``), a degenerate one
        (joint lengths not ``(2, 1, 1, 1, 1)`` up to rotation, a curve of positive genus),
        or when the construction does not give back the axis ``h_m`` or a Bennett
        linkage (not a Goldberg linkage).
    """
    if not isinstance(chain, RevoluteChain) or chain.n != 5:
        raise ValueError(f"chain must be a 5R RevoluteChain; got {chain!r}")
    curve = chain.configuration_curve()
    d = chain.distance_matrix()
    lengths = [int(d[(i - 1) % 5, i]) for i in range(5)]
    if sorted(lengths) != [1, 1, 1, 1, 2] or not curve.is_rational:
        raise ValueError(
            f"a degenerate 5R chain: joint lengths {lengths} (Lemma 32: one joint of length 2, four of length 1), "
            f"curve genus {curve.genus}"
        )
    m = lengths.index(2)  # 0-based index of the double joint
    order = [(m + k) % 5 for k in (-2, -1, 0, 1, 2)]
    h1, h2, h3, h4, h5 = (chain.axes[k] for k in order)
    e = curve.expressions()
    r1, r2 = sympy.cancel(e[order[0]]), sympy.cancel(e[order[1]])
    s = sympy.Symbol("s")
    t_of_s = sympy.solve(sympy.Eq(r1, s), T)
    if len(t_of_s) != 1:
        raise ValueError(f"joint {order[0] + 1} does not parametrise the curve (t = {t_of_s}): not a Goldberg linkage")
    num, den = sympy.fraction(sympy.cancel(r2.subs(T, t_of_s[0])))
    p, q = sympy.Poly(num, s).all_coeffs() if sympy.degree(num, s) == 1 else (sympy.Integer(0), num)
    u, v = sympy.Poly(den, s).all_coeffs() if sympy.degree(den, s) == 1 else (sympy.Integer(0), den)
    one = DualQuaternion.scalar(sympy.Integer(1), sympy.Integer(0))
    # (s - h1)((p s + q) - (u s + v) h2) = (s - h1)(s - g2) rho, rho = p - u h2 commuting with g2
    rho = p * one - u * h2
    g2 = (-(rho.inverse() * (q * one - v * h2))).map(sympy.simplify)
    poly = polynomial_product([-h1, one], [-g2, one])
    k1, k2 = motion_factorization(poly[:-1], norm_factors=[(g2.quadratic_form(), -2 * g2[0]), (1, 0)])
    axes = []
    for k in (k1, k2):
        r = sympy.sqrt(sympy.nsimplify(k.quadratic_form() - k[0] ** 2))
        axes.append(((k - k[0]) * (1 / r)).map(sympy.simplify))
    h6, h3_found = axes
    if h3_found != h3 and h3_found != -h3:
        raise ValueError(f"the second factorisation turns about {h3_found}, not about h_m = {h3}: not a Goldberg linkage")
    bennett_a, bennett_b = RevoluteChain([h1, h2, h3, h6]), RevoluteChain([h3, h4, h5, h6])
    for name, b in (("bennett_a", bennett_a), ("bennett_b", bennett_b)):
        if not b.is_mobile() or not b.configuration_curve().is_rational:
            raise ValueError(f"{name} = {b.axes} is not a Bennett linkage: not a Goldberg linkage")
    goldberg(bennett_a, bennett_b)  # checks that the composed curve closes the chain
    return bennett_a, bennett_b
