"""Factorisation of motion polynomials of any degree into rotation factors ([HSS] refs. [8, 10]).

A *motion polynomial* is ``C(t) = t^d + c_{d-1} t^{d-1} + ... + c_0`` with dual quaternion
coefficients whose norm polynomial ``N(t) = C(t) conj(C)(t)`` is real (no dual part: the
curve lies on the Study quadric).  Hegedüs, Schicho and Schröcker ("Factorization of
rational curves in the Study quadric and revolute linkages", Mech. Mach. Theory 69, 2013)
show: if the primal part of ``C`` has no real polynomial factor, then for every ordering
``M_1, ..., M_d`` of the monic quadratic real factors of ``N`` there is exactly one
factorisation

    C = (t - g_1)(t - g_2) ... (t - g_d),     N(t - g_k) = M_k,

and each ``t - g_k`` is a rotation.  It is found from the right: divide ``C = Q M_d + R``
(``M_d`` real, so it commutes), ``R = r_1 t + r_0``; the common right zero of ``C`` and
``M_d`` is ``g_d = -r_1^-1 r_0``, then ``C = C' (t - g_d)`` and one continues with ``C'``.

The cases the algorithm excludes are refused by name (``MotionFactorizationError``):
a norm with a dual part, a primal part with a real polynomial factor, a remainder whose
leading coefficient ``r_1`` is not invertible, norm factors that do not multiply to the
norm or have real roots, and a right zero that does not divide.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import sympy

from .dualquat import DualQuaternion, is_inexact

__all__ = ["MotionFactorizationError", "motion_factorization", "norm_polynomial", "polynomial_product"]

#: Relative tolerance of the zero tests with float coefficients.
FACTOR_TOL = 1e-9


class MotionFactorizationError(ValueError):
    """The motion polynomial is one of the non-generic cases the factorisation excludes."""


def polynomial_product(*factors: Sequence[DualQuaternion]) -> list[DualQuaternion]:
    """Product of polynomials given by ascending coefficient lists (non-commutative, in order)."""
    out = list(factors[0])
    for f in factors[1:]:
        r = [DualQuaternion.scalar(0 * _unit(out[0]))] * (len(out) + len(f) - 1)
        for i, a in enumerate(out):
            for j, b in enumerate(f):
                r[i + j] = r[i + j] + a * b
        out = r
    return out


def norm_polynomial(coefficients: Sequence[DualQuaternion]) -> tuple[list, list]:
    """``C conj(C)`` for ``C = sum c_k t^k`` (ascending): its primal and dual scalar coefficients.

    Returns ``(primal, dual)``, ascending; for a motion polynomial the dual list is zero
    and the vector parts vanish identically.
    """
    prod = polynomial_product(list(coefficients), [c.conjugate() for c in coefficients])
    return [c[0] for c in prod], [c[4] for c in prod]


def motion_factorization(
    polynomial: Sequence[DualQuaternion],
    right_norm: Sequence[Any] | None = None,
    norm_factors: Sequence[Sequence[Any]] | None = None,
) -> tuple:
    """Factor a monic motion polynomial ``C = t^d + c_{d-1} t^{d-1} + ... + c_0`` into rotations.

    Parameters
    ----------
    polynomial
        ``(c_0, ..., c_{d-1})``, the dual quaternion coefficients below the leading ``1``.
    right_norm
        ``(m0, m1)``: the norm ``t^2 + m1 t + m0`` of the *last* factor ``t - g_d`` (the
        form used for quadratics, ``d = 2``).  Ignored when ``norm_factors`` is given.
    norm_factors
        ``[(m0_1, m1_1), ..., (m0_d, m1_d)]``: ``N(t - g_k) = t^2 + m1_k t + m0_k`` for all
        ``k``, left to right; their product must be the norm polynomial.  Default: the
        factors of the norm over Q in sympy's order (exact coefficients; every factor
        must have degree 2 there) or from its roots (float coefficients).

    Returns
    -------
    (g_1, ..., g_d)
        With ``C = (t - g_1) ... (t - g_d)``; exact for exact data (the product
        reproduces ``C`` exactly), else to rounding.

    Raises
    ------
    MotionFactorizationError
        (a ``ValueError``) for the non-generic cases, each named in the message.
    """
    coeffs = [_coerce(c) for c in polynomial]
    d = len(coeffs)
    if d < 1:
        raise ValueError("polynomial must have at least one coefficient (degree >= 1)")
    exact = not any(is_inexact(x) for c in coeffs for x in c)
    one = DualQuaternion.scalar(sympy.Integer(1) if exact else 1.0, sympy.Integer(0) if exact else 0.0)
    full = coeffs + [one]
    primal, dual = norm_polynomial(full)
    scale = max(abs(complex(x)) for x in primal)
    if not all(_zero(x, exact, scale) for x in dual):
        raise MotionFactorizationError(
            f"not a motion polynomial: the norm C conj(C) has the dual part {dual} (the curve leaves the Study quadric)"
        )
    _refuse_real_primal_factor(full, exact)
    if norm_factors is None:
        if right_norm is not None and d == 2:
            norm_factors = [_quotient(primal, right_norm, exact), tuple(right_norm)]
        else:
            norm_factors = _norm_factors(primal, exact)
    factors = [tuple(_as_number(m, exact) for m in f) for f in norm_factors]
    if len(factors) != d:
        raise MotionFactorizationError(f"norm_factors must have d = {d} quadratic factors; got {len(factors)}")
    for m0, m1 in factors:
        if not (m1 * m1 - 4 * m0 < 0):
            raise MotionFactorizationError(
                f"norm factor t^2 + {m1} t + {m0} has real roots: rotations have positive definite quadratic norms"
            )
    check = [sympy.Integer(1) if exact else 1.0]
    for m0, m1 in factors:
        check = _real_product(check, [m0, m1, 1])
    if not all(_zero(a - b, exact, scale) for a, b in zip(check, primal)):
        raise MotionFactorizationError(f"norm_factors multiply to {check}, not to the norm polynomial {primal}")
    out = []
    rest = full
    for m0, m1 in reversed(factors):
        g = _right_zero(rest, m0, m1, exact, scale)
        rest = _right_divide(rest, g, exact, scale)
        out.append(g)
    return tuple(reversed(out))


def _right_zero(c: list, m0: Any, m1: Any, exact: bool, scale: float) -> DualQuaternion:
    """``g`` with ``C(t) = C'(t) (t - g)`` and ``N(t - g) = t^2 + m1 t + m0``: ``-r_1^-1 r_0``."""
    rem = list(c)
    for k in range(len(rem) - 1, 1, -1):  # divide by the real monic M = t^2 + m1 t + m0
        q = rem[k]
        rem[k] = rem[k] - q
        rem[k - 1] = rem[k - 1] - q * m1
        rem[k - 2] = rem[k - 2] - q * m0
    r0, r1 = rem[0], rem[1]
    if _zero(r1.quadratic_form(), exact, scale):
        raise MotionFactorizationError(
            f"the remainder of C modulo t^2 + {m1} t + {m0} has the non-invertible leading coefficient "
            f"{r1} (its primal part has zero norm): a non-generic motion polynomial, excluded by the algorithm"
        )
    g = -(r1.inverse() * r0)
    return g.map(sympy.simplify) if exact else g


def _right_divide(c: list, g: DualQuaternion, exact: bool, scale: float) -> list:
    """``C'`` with ``C = C' (t - g)``; refuses a nonzero remainder."""
    d = len(c) - 1
    q = [c[d]] * d  # q_{d-1} = c_d; the lower ones are overwritten from the top down
    for i in range(d - 1, 0, -1):
        q[i - 1] = c[i] + q[i] * g
    remainder = c[0] + q[0] * g
    if exact:
        remainder = remainder.map(sympy.simplify)
    if not all(_zero(x, exact, scale) for x in remainder):
        raise MotionFactorizationError(f"t - g does not divide C from the right (remainder {remainder})")
    return [x.map(sympy.expand) if exact else x for x in q]


def _refuse_real_primal_factor(full: list, exact: bool) -> None:
    """The primal part ``sum p_k t^k`` must have no real polynomial factor (refs. [8, 10])."""
    t = sympy.Symbol("t")
    if exact:
        polys = [sympy.Poly(sum((c[m] * t**k for k, c in enumerate(full)), sympy.Integer(0)), t) for m in range(4)]
        g = polys[0]
        for p in polys[1:]:
            g = sympy.gcd(g, p)
        if g.degree() > 0:
            raise MotionFactorizationError(
                f"the primal part has the real polynomial factor {g.as_expr()}: a non-generic motion polynomial, "
                "excluded by the algorithm (factor it out first)"
            )
        return
    # floats: a common complex root of the four primal coefficient polynomials
    first = np.array([complex(c[0]) for c in reversed(full)])
    for z in np.roots(first) if len(first) > 1 else []:
        vals = [abs(sum(complex(c[m]) * z**k for k, c in enumerate(full))) for m in range(4)]
        size = sum(abs(complex(c[m])) * abs(z) ** k for k, c in enumerate(full) for m in range(4))
        if max(vals) <= FACTOR_TOL * size:
            raise MotionFactorizationError(
                f"the primal part vanishes at t = {z:.6g} in all four coordinates: it has a real polynomial "
                "factor, a non-generic motion polynomial excluded by the algorithm"
            )


def _norm_factors(primal: list, exact: bool) -> list:
    if exact:
        t = sympy.Symbol("t")
        poly = sympy.Poly(sum((c * t**k for k, c in enumerate(primal)), sympy.Integer(0)), t)
        out = []
        for f, mult in poly.factor_list()[1]:
            if f.degree() != 2:
                raise MotionFactorizationError(
                    f"the norm polynomial has the factor {f.as_expr()} of degree {f.degree()} over Q: its real "
                    "quadratic factors are irrational; pass norm_factors (e.g. as floats)"
                )
            lc = f.LC()
            c2, c1, c0 = (x / lc for x in f.all_coeffs())
            out += [(c0, c1)] * mult
        return out
    roots = np.roots([complex(x).real for x in reversed(primal)])
    upper = sorted((z for z in roots if z.imag > 0), key=lambda z: (z.real, z.imag))
    if 2 * len(upper) != len(roots):
        raise MotionFactorizationError(f"the norm polynomial has real roots {roots}: not the norm of rotations")
    return [(abs(z) ** 2, -2 * z.real) for z in upper]


def _quotient(primal: list, right: Sequence[Any], exact: bool) -> tuple:
    """``(m0, m1)`` of the quadratic ``N / (t^2 + right[1] t + right[0])`` (``N`` quartic)."""
    m0, m1 = (_as_number(x, exact) for x in right)
    n0, n1, n2, n3, _ = primal
    q1 = n3 - m1
    q0 = n2 - m0 - q1 * m1
    return q0, q1


def _real_product(a: list, b: list) -> list:
    out = [0 * a[0]] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] = out[i + j] + x * y
    return out


def _coerce(c: Any) -> DualQuaternion:
    if not isinstance(c, DualQuaternion):
        raise ValueError(f"polynomial coefficients must be DualQuaternion; got {c!r}")
    return c


def _unit(c: DualQuaternion) -> Any:
    return c[0] * 0 + 1


def _as_number(x: Any, exact: bool) -> Any:
    if exact and not is_inexact(x):
        return sympy.nsimplify(x)
    return float(x)


def _zero(x: Any, exact: bool, scale: float) -> bool:
    if exact and not is_inexact(x):
        return sympy.simplify(x) == 0
    return abs(complex(x)) <= FACTOR_TOL * max(scale, 1.0)
