"""Configuration curves of closed 5R chains by exact elimination over the rationals.

The closure condition ``(t_1 - h_1) ... (t_5 - h_5)`` real and nonzero ([HSS] eq. 1) is
the coupling equality for the links ``o_5`` and ``o_2``:

    (t_1 - h_1)(t_2 - h_2)  ~  Z = (t_5 + h_5)(t_4 + h_4)(t_3 + h_3),

so ``Z`` lies in the coupling space ``L_12 = span(1, h_1, h_2, h_1 h_2)`` and its coordinates
``alpha`` there satisfy ``alpha_0 alpha_3 = alpha_1 alpha_2`` (then ``t_1 = -alpha_2/alpha_3``,
``t_2 = -alpha_1/alpha_3``).  ``Z = A t_3 + A h_3`` with ``A = (t_5 + h_5)(t_4 + h_4)`` is
linear in ``t_3``: with ``P`` the projection onto the complement of ``L_12``, a ``t_3``
exists where the vectors ``P A`` and ``P A h_3`` are parallel, i.e. where all their 2 x 2
minors vanish.  These are polynomials of bidegree at most ``(2, 2)`` in ``(t_4, t_5)``;
their gcd over Q holds every curve component of the configuration set, projected to the
``(t_4, t_5)`` plane.  Each irreducible factor is parametrised (rationally when it is
linear in one variable, else by ``w = sqrt(discriminant)``) and kept only if the closure
condition holds on it identically (exact check by the chain's constructor), which discards
the spurious factors (``t_k^2 + 1``, the locus where ``P A = P A h_3 = 0``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import sympy

from .curve import T, W, ConfigurationCurve
from .dualquat import DualQuaternion

__all__ = [
    "ReducibleCurveError",
    "RigidLinkageError",
    "UnparametrisedComponentError",
    "candidate_curves_5r",
    "candidate_curves_6r",
]


class RigidLinkageError(ValueError):
    """The chain is rigid: its closure equations have no curve of solutions."""


class ReducibleCurveError(ValueError):
    """The configuration curve has several components; pass ``curve=`` to study one of them."""


def candidate_curves_5r(axes: Sequence[DualQuaternion]) -> list[ConfigurationCurve]:
    """Curves in the normal form of :class:`ConfigurationCurve`, one per component candidate.

    The parameter is ``t_4`` where a component is linear in ``t_5`` (then it is rational),
    else ``t_5``.  A factor for which no candidate can be built (a fixed joint 4 or 5, a
    degenerate formula) is screened numerically: skipped when the closure fails at generic
    points over it (spurious, e.g. ``t_k^2 + 1``), refused with ``NotImplementedError`` when
    it holds there (a genuine component this parametrisation cannot represent).

    ``axes`` are five rational unit lines.  The candidates still have to pass the exact
    closure check (``RevoluteChain(axes, curve=...)``).
    """
    h1, h2, h3, h4, h5 = axes
    y, x = sympy.symbols("y x")  # t_4, t_5
    one = sympy.Integer(1)
    basis = sympy.Matrix([list(v) for v in (DualQuaternion.scalar(one), h1, h2, h1 * h2)]).T
    if basis.rank() != 4:
        raise ValueError("axes 1 and 2 span less than a 4-dimensional coupling space (equal lines?)")
    coords = (basis.T * basis).inv() * basis.T
    a = sympy.Matrix(list(((x + h5) * (y + h4)).map(sympy.expand)))
    b = sympy.Matrix(list(((x + h5) * (y + h4) * h3).map(sympy.expand)))
    pa = (a - basis * (coords * a)).applyfunc(sympy.expand)
    pb = (b - basis * (coords * b)).applyfunc(sympy.expand)
    minors = [sympy.expand(pa[k] * pb[m] - pa[m] * pb[k]) for k in range(8) for m in range(k + 1, 8)]
    minors = [e for e in minors if e != 0]
    if not minors:
        raise ValueError("P A and P A h_3 are parallel for all t_4, t_5: a degenerate chain (two-dimensional motion?)")
    g = minors[0]
    for e in minors[1:]:
        g = sympy.gcd(g, e)
        if g.is_number:
            return []
    curves = []
    for f, _ in sympy.factor_list(g, y, x)[1]:
        dy, dx = sympy.degree(f, y), sympy.degree(f, x)
        if dy == 0 or dx == 0:
            _refuse_if_closing(
                _closes_somewhere_5r(f, y, x, axes, coords),
                f"a component with joint {5 if dy == 0 else 4} fixed ({f} = 0), which cannot be parametrised by "
                "the other joint",
                f,
                (y, x),
            )
            continue  # spurious (t_k = +-I, where the product has zero norm, and the like)
        # parametrise by the joint in which f is linear if there is one (a rational curve), else by t_5
        solved, param = (x, y) if dx == 1 else (y, x)
        poly = sympy.Poly(f.subs(param, T), solved)
        if poly.degree() == 1:
            c1, c0 = poly.all_coeffs()
            value = -c0 / c1
            g_w = None
        else:  # the minors have degree <= 2 in each variable
            ca, cb, cc = poly.all_coeffs()
            g_w = sympy.expand(cb**2 - 4 * ca * cc)
            value = (-cb + W) / (2 * ca)
        t4, t5 = (value, T) if solved == y else (T, value)
        pa_s, pb_s = pa.subs({y: t4, x: t5}), pb.subs({y: t4, x: t5})
        k = next((k for k in range(8) if sympy.simplify(pa_s[k]) != 0), None)
        if k is None:
            _refuse_if_closing(
                _closes_somewhere_5r(f, y, x, axes, coords), f"the component {f} = 0 (P A vanishes on it)", f, (y, x)
            )
            continue
        t3 = sympy.together(-pb_s[k] / pa_s[k])
        z = a.subs({y: t4, x: t5}) * t3 + b.subs({y: t4, x: t5})
        alpha = coords * z
        # alpha ~ (t1 t2, -t2, -t1, 1); alpha_3 = 0 where t1 or t2 rests at inf, and then
        # t1 = -alpha_0/alpha_1, t2 = -alpha_0/alpha_2 hold instead
        if sympy.cancel(alpha[3]) == 0:
            t1, t2 = sympy.together(-alpha[0] / alpha[1]), sympy.together(-alpha[0] / alpha[2])
        else:
            t1, t2 = sympy.together(-alpha[2] / alpha[3]), sympy.together(-alpha[1] / alpha[3])
        joints = [t1, t2, t3, t4, t5]
        try:
            if g_w is None:
                curves.append(ConfigurationCurve.rational([sympy.cancel(e) for e in joints]))
            else:
                curves.append(ConfigurationCurve.hyperelliptic(joints, g_w))
        except (ValueError, ZeroDivisionError) as err:
            _refuse_if_closing(_closes_somewhere_5r(f, y, x, axes, coords), f"the component {f} = 0 ({err})", f, (y, x))
            continue  # a degenerate formula on a spurious factor
    return curves


def candidate_curves_6r(axes: Sequence[DualQuaternion]) -> list[ConfigurationCurve]:
    """Curve candidates of a closed 6R chain with rational axes, parameter ``t_6`` or ``t_5``.

    The closure is the coupling equality ``(t_1 - h_1)(t_2 - h_2)(t_3 - h_3) ~ Z`` with
    ``Z = (t_6 + h_6)(t_5 + h_5)(t_4 + h_4)``.  Writing ``U = (t_6 + h_6)(t_5 + h_5)``,

        Z (t_3 + h_3) = U t_4 t_3 + U h_4 t_3 + U h_3 t_4 + U h_4 h_3

    must lie in ``L_12``: with ``N`` (4 x 8) the equations of ``L_12``, the 4 x 4 matrix
    ``M = N [U, U h_4, U h_3, U h_4 h_3]`` (entries bilinear in ``t_5, t_6``) has the null
    vector ``(t_3 t_4, t_3, t_4, 1)``, so ``det M = 0``: a polynomial of bidegree at most
    ``(4, 4)`` whose factors over Q hold the projections of all curve components to the
    ``(t_5, t_6)`` plane.  A factor of degree at most 2 in one of the two variables is
    parametrised by the other (``w`` = square root of the discriminant when the degree
    is 2); the null vector (a column of the adjugate) gives ``t_3, t_4``, and the
    coordinates of ``Z (t_3 + h_3)`` in ``L_12`` give ``t_1, t_2``.  Candidates must still
    pass the exact closure check.

    On a component where ``t_3`` or ``t_4`` stays at ``inf`` (the joint at rest) the last
    entry of the null vector vanishes, and ``t_3 = v_0/v_2``, ``t_4 = v_0/v_1`` hold instead.
    A component on which ``t_5`` or ``t_6`` stays at ``inf`` lies over a line at infinity of
    the ``(t_5, t_6)`` plane and is not seen here; ``RevoluteChain`` numbers the joints
    cyclically from another joint to find it.

    Raises
    ------
    NotImplementedError
        For a factor on which the closure holds (a numerical screen at generic points
        tells such a component from a spurious factor, which is skipped) but that gives
        no candidate: degree above 2 in both ``t_5`` and ``t_6`` (a double cover of
        neither line), a fixed ``t_5`` or ``t_6``, or ``M`` of rank 2 or less all along it.
    """
    h1, h2, h3, h4, h5, h6 = axes
    x, y = sympy.symbols("x y")  # t_5, t_6
    one = sympy.Integer(1)
    basis = sympy.Matrix([list(v) for v in (DualQuaternion.scalar(one), h1, h2, h1 * h2)]).T
    if basis.rank() != 4:
        raise ValueError("axes 1 and 2 span less than a 4-dimensional coupling space (equal lines?)")
    normals = sympy.Matrix.hstack(*basis.T.nullspace()).T  # 4 x 8: N v = 0 iff v in L_12
    coords = (basis.T * basis).inv() * basis.T
    u = ((y + h6) * (x + h5)).map(sympy.expand)
    cols = [u, u * h4, u * h3, u * h4 * h3]
    m = (normals * sympy.Matrix([list(c.map(sympy.expand)) for c in cols]).T).applyfunc(sympy.expand)
    det = sympy.expand(m.det(method="berkowitz"))
    if det == 0:
        raise ValueError("det M vanishes identically: a degenerate 6R chain (axes 1, 2 or 4, 5, 6 special)")
    curves = []
    for f, _ in sympy.factor_list(det, x, y)[1]:
        dx, dy = sympy.degree(f, x), sympy.degree(f, y)
        if dx == 0 or dy == 0 or min(dx, dy) > 2:
            what = (
                f"a component with joint {6 if dx == 0 else 5} fixed ({f} = 0)"
                if dx == 0 or dy == 0
                else f"a component of degree {dx} in t_5 and {dy} in t_6, a double cover of neither joint's line"
            )
            _refuse_if_closing(_closes_somewhere(f, x, y, m, coords, axes), what, f, (x, y))
            continue  # spurious: the closure fails at generic points over this factor
        solved, param = (x, y) if dx <= dy else (y, x)
        poly = sympy.Poly(f.subs(param, T), solved)
        if poly.degree() == 1:
            c1, c0 = poly.all_coeffs()
            num, den, g0 = -c0, c1, None  # solved = num / den
        else:
            ca, cb, cc = poly.all_coeffs()
            s, g0 = _square_free(sympy.expand(cb**2 - 4 * ca * cc))
            num, den = -cb + s * W, 2 * ca  # solved = (-b + sqrt(disc)) / (2a), sqrt(disc) = s w
        field = _QuadraticField(g0)
        # the null vector of M: a column of the adjugate, polynomials in (x, y) first
        adjugate = m.adjugate(method="berkowitz")
        column = next((adjugate.col(k) for k in range(4) if not _vanishes_on(adjugate.col(k), f, x, y)), None)
        if column is None:  # M has a null space of dimension 2 or more all along f = 0
            _refuse_if_closing(
                _closes_somewhere(f, x, y, m, coords, axes), f"the component {f} = 0 (M has rank 2 or less on it)", f, (x, y)
            )
            continue
        v = field.homogenised(list(column), solved, param, num, den)
        # v ~ (t3 t4, t3, t4, 1): t3 = v1/v3 = v0/v2, t4 = v2/v3 = v0/v1; v3 = 0 on the component
        # when t3 or t4 stays at inf (the identity) there, and then the other quotients hold
        pair3, pair4 = ((v[0], v[2]), (v[0], v[1])) if field.reduce(v[3]).is_zero else ((v[1], v[3]), (v[2], v[3]))
        t3, t4 = field.ratio(*pair3), field.ratio(*pair4)
        # Z (t_3 + h_3) with every t_k = n_k / d_k replaced by n_k + d_k h_k (a projective point)
        pair5 = (T, one) if solved == y else (num, den)
        pair6 = (T, one) if solved == x else (num, den)
        z = DualQuaternion.scalar(field.poly(1), field.poly(0))
        for n_, d_, h in ((pair6[0], pair6[1], h6), (pair5[0], pair5[1], h5), (*pair4, h4), (*pair3, h3)):
            n_, d_ = field.poly(n_), field.poly(d_)
            factor = DualQuaternion([n_ if k == 0 else field.poly(0) for k in range(8)]) + h.map(field.poly) * d_
            z = (z * factor).map(field.reduce)
        alpha = [sum((coords[r, c] * z[c] for c in range(8)), field.poly(0)) for r in range(4)]
        # alpha ~ (t1 t2, -t2, -t1, 1): where t1 or t2 rests at inf, alpha_3 = 0 and the other quotients hold
        if field.reduce(alpha[3]).is_zero:
            t1, t2 = field.ratio(-alpha[0], alpha[1]), field.ratio(-alpha[0], alpha[2])
        else:
            t1, t2 = field.ratio(-alpha[2], alpha[3]), field.ratio(-alpha[1], alpha[3])
        t5 = (T, one) if solved == y else field.ratio(num, den)
        t6 = (T, one) if solved == x else field.ratio(num, den)
        joints = [t1, t2, t3, t4, t5, t6]
        try:
            curves.append(field.curve(joints))
        except (ValueError, ZeroDivisionError) as err:
            _refuse_if_closing(_closes_somewhere(f, x, y, m, coords, axes), f"the component {f} = 0 ({err})", f, (x, y))
            continue
    return curves


class UnparametrisedComponentError(NotImplementedError):
    """A curve component of the configuration set that the elimination cannot parametrise.

    ``factor`` is its equation in the last two joint coordinates, the sympy symbols
    ``variables = (t_{n-1}, t_n)``.
    """

    def __init__(self, message: str, factor: Any, variables: tuple):
        super().__init__(message)
        self.factor = factor
        self.variables = variables


def _refuse_if_closing(closes: bool, what: str, factor: Any, variables: tuple) -> None:
    """Raise for a factor that carries configurations but no candidate."""
    if closes:
        raise UnparametrisedComponentError(
            f"the configuration set has {what}; it cannot be parametrised here: pass curve= with a parametrisation",
            factor,
            variables,
        )


def _screen_points(f, a, b):
    """Complex points ``(a, b)`` on ``f(a, b) = 0`` over three generic values of one variable."""
    generic = (sympy.Rational(3141, 10000), sympy.Rational(-12718, 10000), sympy.Rational(22361, 10000))
    free, other = (a, b) if sympy.degree(f, a) > 0 else (b, a)  # solve for a variable f contains
    for value in generic:
        g = sympy.Poly(f.subs(other, value), free)
        if g.degree() < 1:
            continue
        for root in np.roots([complex(c) for c in g.all_coeffs()]):
            yield (root, float(value)) if free == a else (float(value), root)


def _closure_holds(joints: list, axes: Sequence[DualQuaternion]) -> bool:
    """The product is a nonzero scalar to ``1e-8`` of its size (a genuine configuration)."""
    prod = DualQuaternion.scalar(1.0 + 0j)
    for t, h in zip(joints, axes):
        if not np.isinf(abs(t)):  # t = inf: the identity, factor 1
            prod = prod * (t - h.map(complex))
    size = max(abs(c) for c in prod)
    return bool(max(abs(c) for c in prod.coefficients[1:]) <= 1e-8 * size and abs(prod[0]) > 1e-8 * size)


def _closes_somewhere_5r(f, y, x, axes: Sequence[DualQuaternion], coords: sympy.Matrix) -> bool:
    """Whether the closure holds at generic complex points over ``f(t_4, t_5) = 0`` (5R).

    ``t_3`` solves ``A t_3 + A h_3 in L_12`` in the least-squares sense, ``L_12`` gives
    ``t_1, t_2``.  A genuine component closes to rounding; a spurious factor misses by
    order one.  Used only to tell the two apart where no candidate curve could be built.
    """
    h = [c.map(complex) for c in axes]
    cf = np.array(coords.evalf(), dtype=complex)
    basis = np.linalg.pinv(cf)  # 8 x 4, columns 1, h1, h2, h1 h2
    for t4, t5 in _screen_points(f, y, x):
        a = np.array(list((t5 + h[4]) * (t4 + h[3])), dtype=complex)
        b = np.array(list((t5 + h[4]) * (t4 + h[3]) * h[2]), dtype=complex)
        pa, pb = a - basis @ (cf @ a), b - basis @ (cf @ b)
        if np.linalg.norm(pa) < 1e-12 * np.linalg.norm(a):
            continue
        t3 = -np.vdot(pa, pb) / np.vdot(pa, pa)
        alpha = cf @ (a * t3 + b)
        if _closure_holds([*_first_two_joints(alpha), t3, t4, t5], axes):
            return True
    return False


def _closes_somewhere(f, x, y, m: sympy.Matrix, coords: sympy.Matrix, axes: Sequence[DualQuaternion]) -> bool:
    """Whether the closure holds at generic complex points over ``f(t_5, t_6) = 0`` (6R).

    At each point the null vectors of ``M`` of the form ``(t_3 t_4, t_3, t_4, 1)`` (up to
    scale, so ``t_3`` or ``t_4`` may be ``inf``) give ``t_3, t_4``, and ``L_12`` gives
    ``t_1, t_2``; a genuine component closes to rounding (``1e-8``), a spurious factor
    misses by order one.  Used only to tell the two apart where no candidate curve could
    be built.
    """
    h = [a.map(complex) for a in axes]
    coords_f = np.array(coords.evalf(), dtype=complex)
    for t5, t6 in _screen_points(f, x, y):
        mm = np.array(m.subs({x: t5, y: t6}).evalf(), dtype=complex)
        for v in _segre_null_vectors(mm):
            z = (t6 + h[5]) * (t5 + h[4])
            # the factors (t_4 + h_4), (t_3 + h_3) as homogeneous pairs: (v2 + v3 h4), (v1 + v3 h3),
            # or (v0 + v1 h4), (v0 + v2 h3) where v3 = 0 (a joint at inf)
            pair4, pair3 = ((v[2], v[3]), (v[1], v[3])) if abs(v[3]) > 1e-9 else ((v[0], v[1]), (v[0], v[2]))
            z = z * (pair4[0] + pair4[1] * h[3]) * (pair3[0] + pair3[1] * h[2])
            alpha = coords_f @ np.array(list(z), dtype=complex)
            joints = [*_first_two_joints(alpha), _quotient(*pair3), _quotient(*pair4), t5, t6]
            if _closure_holds(joints, axes):
                return True
    return False


def _segre_null_vectors(mm: np.ndarray) -> list[np.ndarray]:
    """Unit null vectors ``v`` of the 4 x 4 matrix ``mm`` with ``v0 v3 = v1 v2`` (to rounding).

    A one-dimensional null space gives its vector; a two-dimensional one ``span(p, q)`` the
    (at most two) vectors ``p + s q`` (or ``q``) on the quadric ``v0 v3 = v1 v2``.
    """
    _, sv, vh = np.linalg.svd(mm)
    if sv[-1] > 1e-8 * sv[0]:
        return []
    if sv[-2] > 1e-8 * sv[0]:
        return [vh[-1].conj()]
    p, q = vh[-1].conj(), vh[-2].conj()

    def segre(a, b):  # the bilinear form of v0 v3 - v1 v2, symmetrised
        return (a[0] * b[3] + a[3] * b[0] - a[1] * b[2] - a[2] * b[1]) / 2

    roots = np.roots([segre(q, q), 2 * segre(p, q), segre(p, p)])  # in s, for p + s q
    out = [p + s * q for s in roots]
    if abs(segre(q, q)) < 1e-12:  # a root at s = inf
        out.append(q)
    return [v / np.linalg.norm(v) for v in out]


def _first_two_joints(alpha: np.ndarray) -> list[complex]:
    """``t_1, t_2`` from the coordinates ``alpha ~ (t1 t2, -t2, -t1, 1)`` in ``L_12`` (``inf`` allowed)."""
    if abs(alpha[3]) > 1e-9 * np.max(np.abs(alpha)):
        return [-alpha[2] / alpha[3], -alpha[1] / alpha[3]]
    return [_quotient(-alpha[0], alpha[1]), _quotient(-alpha[0], alpha[2])]


def _quotient(num: complex, den: complex) -> complex:
    """``num / den``, ``inf`` for a vanishing denominator (the joint at the identity)."""
    return complex("inf") if abs(den) <= 1e-12 * max(abs(num), 1e-300) else num / den


def _vanishes_on(column: sympy.Matrix, f, x, y) -> bool:
    """Every entry of ``column`` is divisible by the irreducible ``f``."""
    return all(sympy.rem(sympy.Poly(e, x, y), sympy.Poly(f, x, y)).is_zero for e in column)


def _square_free(g):
    """``(s, g0)`` with ``g = s^2 g0``, ``g0`` squarefree."""
    content, factors = sympy.sqf_list(g, T)
    s, g0 = sympy.Integer(1), sympy.Integer(content)
    for fac, mult in factors:
        s *= fac ** (mult // 2)
        g0 *= fac ** (mult % 2)
    return sympy.expand(s), sympy.expand(g0)


class _QuadraticField:
    """Arithmetic in ``Q(t)[w] / (w^2 - g0)`` on sympy ``Poly`` objects in ``(w, t)``.

    ``g0 = None``: no ``w``, plain ``Q[t]``.  Elements are polynomials reduced to degree
    at most one in ``w``; quotients are kept as pairs (numerator, denominator).
    """

    def __init__(self, g0):
        self.g0 = g0
        self.modulus = None if g0 is None else sympy.Poly(W**2 - g0, W, T, domain="QQ")

    def poly(self, e) -> sympy.Poly:
        return e if isinstance(e, sympy.Poly) else sympy.Poly(e, W, T, domain="QQ")

    def reduce(self, e) -> sympy.Poly:
        p = self.poly(e)
        if self.modulus is None or p.degree(W) < 2:
            return p
        return p.rem(self.modulus)

    def homogenised(self, polys: list, solved, param, num, den) -> list:
        """``den^K P(num/den, t)`` for each ``P(solved, param)``, one ``K`` (the largest degree) for all."""
        ps = [sympy.Poly(sympy.expand(p).subs(param, T), solved) for p in polys]
        k = max(p.degree() for p in ps)
        num_p, den_p = self.poly(num), self.poly(den)
        powers_n = [self.poly(1)]
        for _ in range(k):
            powers_n.append(self.reduce(powers_n[-1] * num_p))
        powers_d = [self.poly(1)]
        for _ in range(k):
            powers_d.append(powers_d[-1] * den_p)
        out = []
        for p in ps:
            acc = self.poly(0)
            for (i,), c in p.terms():
                acc = acc + self.poly(c) * powers_n[i] * powers_d[k - i]
            out.append(self.reduce(acc))
        return out

    def split(self, p) -> tuple:
        """``(p0, p1)`` with ``p = p0 + p1 w`` (expressions in ``t``)."""
        p0, p1 = sympy.Integer(0), sympy.Integer(0)
        for (i, j), c in self.poly(p).terms():
            if i == 0:
                p0 += c * T**j
            else:
                p1 += c * T**j
        return p0, p1

    def ratio(self, p, q) -> tuple:
        """``p / q`` as ``(a + b w, c)`` with ``a, b, c`` polynomials in ``t`` (conjugate of ``q``)."""
        p, q = self.reduce(p), self.reduce(q)
        if self.g0 is None:
            return (p.as_expr(), q.as_expr())
        q0, q1 = self.split(q)
        conj = self.poly(q0 - q1 * W)
        den = self.poly(q0**2 - q1**2 * self.g0)
        return (self.reduce(p * conj).as_expr(), den.as_expr())

    def curve(self, joints: list) -> ConfigurationCurve:
        nums, wnums, dens = [], [], []
        for n_, d_ in joints:
            a, b = self.split(n_)
            nums.append(a)
            wnums.append(b)
            dens.append(sympy.expand(d_))
        return ConfigurationCurve(nums, wnums, dens, self.g0)
