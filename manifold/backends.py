"""Math backends for formulas written once and evaluated two ways.

A formula (such as :mod:`charts.suspension_formula`) calls ``ops.sin``, ``ops.sqrt``,
... and the arithmetic operators.  With :data:`NUMPY` it evaluates numpy arrays
(float64 or long double, any batch shape); with :class:`HeyokaOps` it builds
heyoka expressions that heyoka can differentiate and compile into Taylor
integrators and compiled functions (``cfunc``).

Complex numbers are carried as real pairs (:class:`Cx`), because heyoka
expressions are real.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .precision import unit_roundoff


class Cx:
    """A complex number as a pair of reals (numbers, numpy arrays or heyoka expressions); treat it as immutable.

    A plain class with slots, not a frozen dataclass: a start's checks build a few dozen of them on Python floats
    (:mod:`linkage.rods`), and a frozen dataclass takes 3.6x as long to make one.
    """

    __slots__ = ("re", "im")

    def __init__(self, re: Any, im: Any) -> None:
        self.re, self.im = re, im

    def __repr__(self) -> str:
        return f"Cx(re={self.re!r}, im={self.im!r})"

    def __add__(self, other: "Cx") -> "Cx":
        return Cx(self.re + other.re, self.im + other.im)

    def __sub__(self, other: "Cx") -> "Cx":
        return Cx(self.re - other.re, self.im - other.im)

    def __mul__(self, other: "Cx") -> "Cx":
        return Cx(self.re * other.re - self.im * other.im, self.re * other.im + self.im * other.re)

    def scale(self, k: Any) -> "Cx":
        """Multiply by the real ``k``."""
        return Cx(self.re * k, self.im * k)

    def conj(self) -> "Cx":
        """The complex conjugate ``re - i im``."""
        return Cx(self.re, -self.im)

    def abs2(self) -> Any:
        """``|z|^2 = re^2 + im^2`` (no square root, so smooth everywhere)."""
        return self.re * self.re + self.im * self.im

    def dot(self, other: "Cx") -> Any:
        """``Re(conj(z) w) = re re' + im im'``: the dot product of the two as plane vectors."""
        return self.re * other.re + self.im * other.im

    def cross(self, other: "Cx") -> Any:
        """``Im(conj(z) w) = re im' - im re'``: the cross product of the two as plane vectors."""
        return self.re * other.im - self.im * other.re


class NumpyOps:
    """Backend on numpy arrays (float64 or long double)."""

    sin = staticmethod(np.sin)
    cos = staticmethod(np.cos)
    sqrt = staticmethod(np.sqrt)
    atan2 = staticmethod(np.arctan2)

    @staticmethod
    def asin_clipped(x):
        """``asin`` of ``x`` clipped to ``[-1, 1]`` (rounding can push a pole configuration past 1)."""
        return np.arcsin(np.clip(x, -1, 1))

    where = staticmethod(np.where)
    abs = staticmethod(np.abs)
    minimum = staticmethod(np.minimum)
    gt = staticmethod(np.greater)
    ge = staticmethod(np.greater_equal)

    @staticmethod
    def one_minus_sin(x):
        """``1 - sin x`` without cancellation near ``x = pi/2``: ``cos^2 x / (1 + sin x)`` there."""
        s, c = np.sin(x), np.cos(x)
        return np.where(s > 0, c * c / (1 + np.abs(s)), 1 - s)

    @staticmethod
    def one_plus_sin(x):
        """``1 + sin x`` without cancellation near ``x = -pi/2``."""
        s, c = np.sin(x), np.cos(x)
        return np.where(s < 0, c * c / (1 + np.abs(s)), 1 + s)

    @staticmethod
    def sinc(x):
        """``sin(x)/x``, 1 at 0.  Exact division is accurate in floating point for ``x != 0``."""
        x = np.asarray(x)
        safe = np.where(x == 0, 1, x)
        return np.where(x == 0, 1, np.sin(safe) / safe)

    @staticmethod
    def ratio_or_zero(a, b):
        """``a / b``, and 0 where ``b == 0`` (a collapsed sub-sphere: any value is valid)."""
        b = np.asarray(b)
        safe = np.where(b == 0, 1, b)
        return np.where(b == 0, 0, a / safe)


NUMPY = NumpyOps()


def _sinc_terms(fp_type: type) -> int:
    """Number of series terms of ``sin(y)/y`` exact to ``fp_type`` for ``y`` in ``[0, pi/2]``.

    The k-th term is at most ``(pi/2)^(2k) / (2k+1)!``; we stop when it falls
    below a tenth of the machine epsilon (twice the unit roundoff).
    """
    eps = 2 * unit_roundoff(fp_type)
    k, term = 0, 1.0
    while term > 0.1 * eps:
        k += 1
        term *= (np.pi / 2) ** 2 / ((2 * k) * (2 * k + 1))
    return k + 1


class HeyokaOps:
    """Backend building heyoka expressions with constants exact in ``fp_type``.

    Parameters
    ----------
    fp_type
        ``float``, ``numpy.longdouble``, ``heyoka.real128`` or a
        :class:`manifold.precision.MultiPrecision`: the precision the
        expressions will be compiled in.  Non-integer constants are created in
        this type (heyoka turns ``x / 20.`` into ``x * 0.05`` rounded to double,
        which would cap a real128 integration at double accuracy).
    """

    def __init__(self, fp_type: type = float) -> None:
        import heyoka as hy

        self.hy = hy
        self.fp_type = fp_type
        coeffs, c = [], fp_type(1)
        for k in range(_sinc_terms(fp_type)):
            coeffs.append(c)
            c = -c / fp_type((2 * k + 2) * (2 * k + 3))  # (-1)^k / (2k+1)!, rounded in fp_type
        self.sinc_coefficients = tuple(coeffs)

    def sin(self, x):
        """``sin x`` as a heyoka expression."""
        return self.hy.sin(x)

    def cos(self, x):
        """``cos x`` as a heyoka expression."""
        return self.hy.cos(x)

    def sqrt(self, x):
        """``sqrt x`` as a heyoka expression."""
        return self.hy.sqrt(x)

    def atan2(self, y, x):
        """``atan2(y, x)``, the argument of ``x + i y`` in ``(-pi, pi]``, as a heyoka expression."""
        return self.hy.atan2(y, x)

    def _clip1(self, x):
        hy = self.hy
        return hy.select(hy.gt(x, 1.0), hy.expression(1.0), hy.select(hy.lt(x, -1.0), hy.expression(-1.0), x))

    def where(self, cond, x, y):
        """``x`` where ``cond`` holds, else ``y`` (heyoka's ``select``)."""
        return self.hy.select(cond, x, y)

    def gt(self, x, y):
        """``x > y`` as a heyoka condition (expressions have no comparison operators)."""
        return self.hy.gt(x, y)

    def ge(self, x, y):
        """``x >= y`` as a heyoka condition."""
        return self.hy.gte(x, y)

    def abs(self, x):
        """``|x| = select(x < 0, -x, x)``."""
        hy = self.hy
        return hy.select(hy.lt(x, 0.0), -x, x)

    def minimum(self, x, y):
        """``min(x, y) = select(x < y, x, y)``."""
        hy = self.hy
        return hy.select(hy.lt(x, y), x, y)

    def one_minus_sin(self, x):
        """``1 - sin x = 2 sin^2(pi/4 - x/2)``: no cancellation near ``x = pi/2``."""
        h = self.sin(self.hy.pi / 4.0 - x / 2.0)
        return 2.0 * h * h

    def one_plus_sin(self, x):
        """``1 + sin x = 2 sin^2(pi/4 + x/2)``."""
        h = self.sin(self.hy.pi / 4.0 + x / 2.0)
        return 2.0 * h * h

    def asin_clipped(self, x):
        """``asin`` of ``x`` clipped to ``[-1, 1]`` (rounding can push a pole configuration past 1)."""
        return self.hy.asin(self._clip1(x))

    def sinc(self, x):
        """``sin(x)/x = cos(x/2) S(x^2/4)``, ``S(y) = sum_k (-1)^k y^k / (2k+1)!`` (:meth:`polynomial`).

        The plain quotient is 0/0 at ``x = 0``: its Taylor coefficients lose all
        accuracy there and heyoka's step size collapses.  The even polynomial has
        no such trap.  Halving the argument (``x/2 <= pi/2`` for ``x`` in
        ``[0, pi]``) shortens the series needed for ``fp_type`` by a fifth.
        """
        h = x / 2.0
        return self.cos(h) * self.polynomial(self.sinc_coefficients, h * h)

    def polynomial(self, coeffs, y):
        """``sum_k coeffs[k] y^k`` as a sum of scaled powers ``y^(2j) = (y^j)^2``, ``y^(2j+1) = y^(2j) y``.

        In a Taylor step a product of two series costs ``O(order^2)`` and a product with a
        constant ``O(order)``: Horner's rule pays a product of series per term, the powers
        one per term with half of them squares, and :class:`~manifold.jets.JetOps` takes
        ``p``, ``p'`` and ``p''`` from the same powers.  For the ``sinc`` series (``0 <= y <= pi^2/4``,
        alternating terms summing to at least ``2/pi``) neither form loses more than a few roundings.
        """
        hy = self.hy
        powers = [None, y]
        for j in range(2, len(coeffs)):
            powers.append(powers[j // 2] * powers[j // 2] if j % 2 == 0 else powers[j - 1] * y)
        return hy.sum([hy.expression(coeffs[0])] + [hy.expression(c) * powers[k] for k, c in enumerate(coeffs) if k > 0])

    def ratio_or_zero(self, a, b):
        """``a / b``, and 0 where ``b == 0`` (a collapsed sub-sphere: any value is valid)."""
        hy = self.hy
        return hy.select(hy.eq(b, 0.0), hy.expression(0.0), a / b)
