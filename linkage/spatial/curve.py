"""Configuration curves ``t_k = (a_k(t) + b_k(t) w) / c_k(t)``, ``w^2 = g(t)``, and their places.

A configuration curve of a closed nR chain is stored in the normal form of
the bond-theory paper (eqs. 7, 12, 13): one real parameter ``t``, an optional
square root ``w`` of a squarefree polynomial ``g`` (``g = None``: the curve is
rational, ``w`` does not occur) and for each joint ``k`` three polynomials
``a_k, b_k, c_k`` in ``Q[t]`` without common factor.

*Places.*  Orders of vanishing are taken at places of the curve (points of its
normalisation): a point ``t0`` (or ``t0 = inf``) together with a branch of
``w`` and a local parameter ``u``:

* ``g(t0) != 0``: two places, ``t = t0 + u``, ``w = +-sqrt(g(t0 + u))``;
* ``g(t0) = 0`` (a branch point): one place, ``t = t0 + u^2``,
  ``w = u sqrt(g(t0 + u^2) / u^2)`` -- here ``t - t0`` is *not* a local parameter;
* ``t0 = inf``: ``t = 1/u`` and ``w = u^-m sqrt(u^2m g(1/u))`` with ``2m >= deg g``,
  a branch point again when ``deg g`` is odd.

The joint coordinates at a place are the homogeneous pairs
``(a_k + b_k w, c_k)`` as series in ``u``, divided by ``u^min(order)``: a 0/0
base point of the formula is resolved into its limit along the curve instead
of being read as ``t_k = 0/0``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import mpmath
import sympy

from .series import NUMERIC, TERMS, WORKING_DIGITS, ExactField, PrecisionExhausted, Series, polyval

__all__ = ["EXACT_ROOT_DEGREE", "ConfigurationCurve", "Place", "to_mpc"]

T = sympy.Symbol("t")
W = sympy.Symbol("w")
INF = complex("inf")


#: Largest degree of an irreducible factor whose roots are taken exactly (radicals).
EXACT_ROOT_DEGREE = 2


def to_mpc(x: Any) -> mpmath.mpc:
    """A sympy number (exact or float), Python or mpmath number as an mpmath complex."""
    return NUMERIC.convert(x)


def _poly(expr: Any) -> sympy.Poly:
    return sympy.Poly(sympy.expand(expr), T, domain="QQ")


def _ascending(p: sympy.Poly, field: Any = NUMERIC) -> list:
    """Coefficients of ``p`` in ascending order, in ``field``."""
    return [field.convert(c) for c in reversed(p.all_coeffs())]


@dataclass(frozen=True)
class Place:
    """A place of the configuration curve: parameter value, branch, local series.

    Attributes
    ----------
    t0
        The parameter value (complex, or ``inf``).
    branch
        ``+1`` / ``-1`` for the sign of ``w`` (``sqrt`` taken by mpmath's principal
        branch at ``g(t0)``), ``0`` at a branch point or on a rational curve.
    joints
        For each joint the pair ``(numerator, denominator)`` of series in ``u``,
        normalised so that not both vanish at ``u = 0``.
    """

    t0: complex
    branch: int
    joints: tuple

    def joint_values(self) -> tuple:
        """The joint coordinates ``t_k`` at the place (``inf`` where the denominator vanishes)."""
        out = []
        for num, den in self.joints:
            d, n = den.coefficient(0), num.coefficient(0)
            if den.field.exact:
                out.append(INF if d == den.field.zero else den.field.to_complex(n / d))
                continue
            tol = mpmath.mpf("1e-30") * max(abs(n), abs(d), 1)
            # parts below the zero threshold relative to |t_k| are rounding noise: chop them
            value = INF if abs(d) <= tol else mpmath.chop(n / d, mpmath.mpf("1e-30") * max(1, abs(n / d)))
            out.append(complex(value))
        return tuple(out)

    @property
    def exact(self) -> bool:
        """Whether the series have exact coefficients (an algebraic number field)."""
        return self.joints[0][1].field.exact


class ConfigurationCurve:
    """``t_k = (a_k(t) + b_k(t) w) / c_k(t)``, ``w^2 = g(t)`` (or rational: ``g = None``).

    Build one with :meth:`rational` or :meth:`hyperelliptic` from formulas such
    as the paper's, or get one from ``RevoluteChain.configuration_curve()``.

    Parameters
    ----------
    numerators, wnumerators, denominators
        ``a_k``, ``b_k``, ``c_k`` as sympy polynomials (or expressions) in ``t``.
    g
        Squarefree polynomial under the square root, or ``None``.
    """

    def __init__(self, numerators: Sequence, wnumerators: Sequence, denominators: Sequence, g: Any = None):
        if not (len(numerators) == len(wnumerators) == len(denominators)):
            raise ValueError("numerators, wnumerators and denominators must have one entry per joint")
        self.g = None if g is None else _poly(g)
        if self.g is not None:
            if self.g.degree() < 1:
                raise ValueError(f"g must be a non-constant polynomial in t; got {g}")
            if sympy.degree(sympy.gcd(self.g, self.g.diff(T)), T) > 0:
                raise ValueError(f"g must be squarefree (a square factor belongs in b_k); got {g}")
        a = [_poly(x) for x in numerators]
        b = [_poly(x) for x in wnumerators]
        c = [_poly(x) for x in denominators]
        for k in range(len(a)):
            common = sympy.gcd(sympy.gcd(a[k], b[k]), c[k])
            if not common.is_zero and common.degree() > 0:
                a[k], b[k], c[k] = (sympy.div(p, common)[0] for p in (a[k], b[k], c[k]))
            if c[k].is_zero and a[k].is_zero and b[k].is_zero:
                raise ValueError(f"joint {k + 1}: numerator and denominator are both zero")
            if self.g is None and not b[k].is_zero:
                raise ValueError(f"joint {k + 1}: a rational curve has no w term")
        self.a, self.b, self.c = a, b, c

    # construction ----------------------------------------------------------------
    @classmethod
    def rational(cls, joints: Sequence[Any], t: sympy.Symbol = T) -> ConfigurationCurve:
        """From rational functions ``t_k(t)`` (sympy expressions in ``t``)."""
        nums, dens = [], []
        for e in joints:
            n, d = sympy.fraction(sympy.cancel(sympy.together(sympy.sympify(e).subs(t, T))))
            nums.append(n)
            dens.append(d)
        return cls(nums, [0] * len(nums), dens, None)

    @classmethod
    def hyperelliptic(
        cls, joints: Sequence[Any], g: Any, t: sympy.Symbol = T, w: sympy.Symbol = W
    ) -> ConfigurationCurve:
        """From expressions ``t_k(t, w)`` with ``w^2 = g(t)``.

        Each expression is brought to ``(a + b w) / c`` by reducing ``w^2 -> g`` and
        multiplying numerator and denominator by the conjugate ``d0 - d1 w``.
        """
        gt = sympy.expand(sympy.sympify(g).subs(t, T))
        # make g squarefree: g = s^2 g0, w = s w0
        content, factors = sympy.sqf_list(gt, T)
        s, g0 = sympy.Integer(1), sympy.Integer(content)
        for f, mult in factors:
            s *= f ** (mult // 2)
            g0 *= f ** (mult % 2)
        a_s, b_s, c_s = [], [], []
        for e in joints:
            e = sympy.together(sympy.sympify(e).subs({t: T, w: W * s}))
            n, d = sympy.fraction(e)
            n0, n1 = _split_w(n, g0)
            d0, d1 = _split_w(d, g0)
            a_s.append(sympy.expand(n0 * d0 - n1 * d1 * g0))
            b_s.append(sympy.expand(n1 * d0 - n0 * d1))
            c_s.append(sympy.expand(d0**2 - d1**2 * g0))
        if sympy.Poly(g0, T).degree() < 1:
            # g was a square: the curve is rational (two components for the two signs)
            raise ValueError(
                f"g = {g} is a perfect square: the curve is reducible, give its components as rational curves"
            )
        return cls(a_s, b_s, c_s, g0)

    # evaluation --------------------------------------------------------------------
    @property
    def n(self) -> int:
        """Number of joints ``n`` (coordinates ``t_1 .. t_n``)."""
        return len(self.a)

    @property
    def is_rational(self) -> bool:
        """True for a rational curve (no square root ``w = sqrt(g(t))``)."""
        return self.g is None

    @property
    def genus(self) -> int:
        """The genus of the model ``w^2 = g(t)``: ``0`` if rational, else ``(deg g - 1) // 2``.

        ``g`` is squarefree, so ``w^2 = g(t)`` is a smooth hyperelliptic model of genus
        ``ceil(deg g / 2) - 1``.  It is the genus of the configuration curve when ``t``
        and ``w`` are rational functions of the joint values, as for the curves computed
        by elimination: ``t`` is a joint, and ``w = (c_k t_k - a_k) / b_k`` for a joint
        with ``b_k != 0``.
        """
        return 0 if self.g is None else (self.g.degree() - 1) // 2

    def expressions(self) -> tuple:
        """The joint coordinates as sympy expressions in ``t`` (and ``w``)."""
        return tuple(
            sympy.factor((a.as_expr() + b.as_expr() * W) / c.as_expr()) for a, b, c in zip(self.a, self.b, self.c)
        )

    def __call__(self, t: Any, branch: int = 1) -> tuple:
        """Naive evaluation of ``(t_1, ..., t_n)`` at a real or complex ``t`` (complex128).

        ``w = branch * sqrt(g(t))``.  A 0/0 base point gives ``nan``; use
        :meth:`places` there.
        """
        if branch not in (1, -1):
            raise ValueError(f"branch must be +1 or -1; got {branch!r}")
        t = complex(t)
        w = 0j if self.g is None else branch * complex(mpmath.sqrt(_eval(self.g, t)))
        out = []
        for a, b, c in zip(self.a, self.b, self.c):
            num, den = _eval(a, t) + _eval(b, t) * w, _eval(c, t)
            out.append(INF if den == 0 and num != 0 else (complex("nan") if den == 0 else num / den))
        return tuple(out)

    def real_intervals(self) -> list[tuple[float, float]]:
        """Parameter intervals over which the curve is real: ``g(t) >= 0`` (all of R if rational).

        Endpoints are the real roots of ``g`` (floats, ``+-inf`` for unbounded intervals).
        Over each interval the two branches ``w = +-sqrt(g)`` join at the roots, so every
        real component of the curve is traced by both branches over one or more of
        these intervals.
        """
        if self.g is None:
            return [(-float("inf"), float("inf"))]
        roots = sorted(float(r) for r in sympy.real_roots(self.g))
        edges = [-float("inf"), *roots, float("inf")]
        out = []
        for a, b in zip(edges[:-1], edges[1:]):
            if math.isinf(a) and math.isinf(b):
                mid = 0.0
            elif math.isinf(a):
                mid = b - 1
            elif math.isinf(b):
                mid = a + 1
            else:
                mid = (a + b) / 2
            if float(_eval(self.g, mid).real) > 0:
                out.append((a, b))
        return out

    def real_points(self, ts: Sequence[float], branch: int = 1) -> list:
        """Joint tuples at the real parameters ``ts`` where ``g(t) >= 0`` (all of them if rational)."""
        return [self(t, branch) for t in ts if self.g is None or float(_eval(self.g, t).real) >= 0]

    # places --------------------------------------------------------------------------
    def bond_candidates(self) -> list:
        """Parameter values where some ``t_k^2 + 1`` vanishes, or ``inf`` (50-digit roots).

        See :meth:`bond_candidate_factors`; this returns only the values.
        """
        return [z for z, _ in self.bond_candidate_factors()]

    def bond_candidate_factors(self) -> list[tuple]:
        """Pairs ``(t0, m)``: candidate parameter values and their irreducible factor over Q.

        For each joint, ``N_k = ((a_k + b_k w)^2 + c_k^2)((a_k - b_k w)^2 + c_k^2)``
        with ``w^2 = g`` is a polynomial in ``t``; its roots (50 digits), split into
        irreducible factors ``m`` over Q first so that each root is simple, and
        ``(inf, None)``.  0/0 base points are among them and are sorted out at the places.
        """
        found: list = []
        for a, b, c in zip(self.a, self.b, self.c):
            if self.g is None:
                nk = a**2 + c**2
            else:
                big_a = a**2 + b**2 * self.g + c**2
                big_b = 2 * a * b
                nk = big_a**2 - big_b**2 * self.g
            for factor, _ in nk.factor_list()[1]:
                for r in factor.nroots(n=WORKING_DIGITS, maxsteps=500):
                    z = to_mpc(r)
                    if all(abs(z - y) > mpmath.mpf("1e-25") * max(1, abs(z)) for y, _ in found):
                        found.append((z, factor))
        return found + [(INF, None)]

    def places(self, t0: Any) -> list[Place]:
        """The places over ``t0`` (a number or ``inf``) with 50-digit series, see the module docstring."""
        with mpmath.workdps(WORKING_DIGITS):
            if _is_inf(t0):
                return [self._place_at(INF, s, NUMERIC, None) for s in self._branches_at_infinity()]
            t0 = to_mpc(t0)
            if self.g is None:
                return [self._place_at(t0, 0, NUMERIC, None)]
            g0 = polyval(_ascending(self.g), Series.exact([t0])).coefficient(0)
            if _vanishes(g0, self.g, t0):
                return [self._place_at(t0, 0, NUMERIC, None)]
            return [self._place_at(t0, s, NUMERIC, None) for s in (1, -1)]

    def exact_place(self, place: Place, factor: sympy.Poly | None) -> Place | None:
        """The same place with exact series over an algebraic number field, if one is cheap.

        ``factor`` is the irreducible polynomial over Q with root ``place.t0``
        (``None`` for ``t0 = inf``).  The field is ``Q(I, t0, r)`` with ``r`` the
        square root that starts ``w`` at the place (of ``g(t0)``, of ``g'(t0)`` at a
        branch point, of the leading coefficient of ``g`` at ``inf``), chosen to
        match the numeric place's branch.  Returns ``None`` (keep the 50-digit
        place) when ``t0`` is a root of a factor of degree above
        ``EXACT_ROOT_DEGREE``, where radicals and primitive elements get expensive.
        """
        if place.t0 != INF and (factor is None or factor.degree() > EXACT_ROOT_DEGREE):
            return None
        t0 = None
        if place.t0 != INF and factor is not None:  # a finite place has its factor (checked above)
            t0 = min(sympy.roots(factor.as_expr(), T), key=lambda r: abs(complex(sympy.N(r, 30)) - place.t0))
        gens = [sympy.I] + ([] if t0 is None or _gaussian(t0) else [t0])
        root = None
        if self.g is not None:
            if t0 is None:
                radicand = self.g.LC()
            else:
                g0 = sympy.expand(self.g.as_expr().subs(T, t0))
                is_branch = sympy.simplify(g0) == 0
                if is_branch != (place.branch == 0):
                    return None  # the numeric and exact views disagree: keep the numeric one
                radicand = sympy.expand(self.g.diff(T).as_expr().subs(T, t0)) if is_branch else g0
            root = sympy.sqrt(radicand)
            principal = mpmath.sqrt(to_mpc(radicand))
            if abs(complex(sympy.N(root, 30)) - complex(principal)) > abs(complex(sympy.N(root, 30)) + complex(principal)):
                root = -root
            if not _gaussian(root):
                gens.append(root)
        field = _exact_field(tuple(gens))
        t0k = None if t0 is None else field.convert(t0)
        return self._place_at(INF if t0 is None else t0k, place.branch, field, None if root is None else field.convert(root))

    def _branches_at_infinity(self) -> tuple:
        if self.g is None or self.g.degree() % 2:
            return (0,)
        return (1, -1)

    def _place_at(self, t0: Any, branch: int, field: Any, root: Any) -> Place:
        """One place: ``t0`` in ``field`` (or ``INF``), ``branch`` as in :class:`Place`.

        ``root`` starts the square root series (``None``: the field's principal root).
        """
        g = None if self.g is None else _ascending(self.g, field)
        if _is_inf(t0):
            if g is None:
                return self._place(INF, 0, Series.exact([1], -1, field), None)
            deg = len(g) - 1
            m = (deg + 1) // 2
            rev = list(reversed(g))  # g~(u) = u^deg g(1/u), ascending; g~(0) = lc(g) != 0
            if deg % 2 == 0:  # t = 1/u, w = u^-m sqrt(g~(u)): two places
                wser = Series(rev, 0, TERMS, field).sqrt_unit(root).shift(-m) * branch
                return self._place(INF, branch, Series.exact([1], -1, field), wser)
            # odd degree, a branch point: u = v^2, w = u^-m sqrt(u g~(u)) = v^(1-2m) sqrt(g~(v^2))
            h = polyval(rev, Series.exact([0, 0, 1], 0, field))
            wser = Series(h.coeffs, 0, TERMS, field).sqrt_unit(root).shift(1 - 2 * m)
            return self._place(INF, 0, Series.exact([1], -2, field), wser)
        if g is None:
            return self._place(t0, 0, Series.exact([t0, 1], 0, field), None)
        if branch == 0:  # branch point: t = t0 + u^2, g(t0 + u^2) = u^2 h(u), w = u sqrt(h)
            tser = Series.exact([t0, 0, 1], 0, field)
            h = polyval(g, tser)
            h = Series(h.coeffs[2:], 0, TERMS, field)
            return self._place(t0, 0, tser, h.sqrt_unit(root).shift(1))
        tser = Series.exact([t0, 1], 0, field)
        wser = Series(polyval(g, tser).coeffs, 0, TERMS, field).sqrt_unit(root) * branch
        return self._place(t0, branch, tser, wser)

    def _place(self, t0: Any, branch: int, tser: Series, wser: Series | None) -> Place:
        field = tser.field
        joints = []
        for a, b, c in zip(self.a, self.b, self.c):
            # an identically zero numerator or denominator is the exact zero series: a
            # Horner zero would carry a spurious negative val at t = inf and cost precision
            num = Series.exact([], 0, field) if a.is_zero else polyval(_ascending(a, field), tser)
            if wser is not None and not b.is_zero:
                num = num + polyval(_ascending(b, field), tser) * wser
            den = Series.exact([], 0, field) if c.is_zero else polyval(_ascending(c, field), tser)
            orders = [s.order() for s in (num, den) if _known_nonzero(s)]
            if not orders:
                raise PrecisionExhausted(f"joint coordinates vanish to all computed orders at t = {t0}")
            o = min(orders)
            joints.append(tuple(s.shift(-o).normalized() if _known_nonzero(s) else s.shift(-o) for s in (num, den)))
        value = INF if _is_inf(t0) else field.to_complex(t0)
        return Place(value, branch, tuple(joints))


def _gaussian(x: Any) -> bool:
    """``x`` is in ``Q(I)`` (then it needs no generator of its own)."""
    re, im = sympy.sympify(x).as_real_imag()
    return bool(re.is_Rational and im.is_Rational)


@functools.lru_cache(maxsize=64)
def _exact_field(gens: tuple) -> ExactField:
    """``Q(gens)``, cached: conjugate bonds and repeated calls share the primitive element."""
    return ExactField(sympy.QQ.algebraic_field(*gens))


def _is_inf(t0: Any) -> bool:
    return isinstance(t0, (complex, float)) and mpmath.isinf(abs(t0))


def _known_nonzero(s: Series) -> bool:
    try:
        s.order()
    except PrecisionExhausted:
        return False
    return True


def _vanishes(value: Any, g: sympy.Poly, t0: Any) -> bool:
    scale = max([abs(x) for x in _ascending(g)] + [1]) * max(1, abs(t0)) ** g.degree()
    return abs(value) <= mpmath.mpf("1e-30") * scale


def _eval(p: sympy.Poly, t: complex) -> complex:
    r = 0j
    for c in p.all_coeffs():
        r = r * t + complex(c)
    return r


def _split_w(expr: Any, g0: Any) -> tuple:
    """``expr(t, w) = p0(t) + p1(t) w`` modulo ``w^2 = g0``."""
    p = sympy.Poly(sympy.expand(expr), W)
    p0, p1 = sympy.Integer(0), sympy.Integer(0)
    for (k,), coeff in p.terms():
        term = coeff * g0 ** (k // 2)
        if k % 2:
            p1 += term
        else:
            p0 += term
    return sympy.expand(p0), sympy.expand(p1)
