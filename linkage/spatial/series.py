"""Truncated Laurent series in a local parameter ``u`` over mpmath or over an exact number field.

Used to evaluate the joint coordinates and the products ``F_ij`` of a linkage
along a *place* of its configuration curve (a branch through a point, with a
local parameter ``u``), and to read off orders of vanishing.

A series ``sum_k c_k u^(val + k) + O(u^prec)`` knows its absolute precision
``prec``: products and sums propagate it, so an order is never reported from
coefficients that were not computed.

Two coefficient fields (``Field`` objects):

* ``NUMERIC``: mpmath complex numbers at ``WORKING_DIGITS = 50`` digits.  The zero
  test is the documented threshold: a coefficient counts as zero when its
  modulus is below ``ZERO_THRESHOLD = 1e-30`` times the series' scale (the
  largest modulus among its first four computed coefficients, and at least 1).
  The 20 digits between working precision and threshold absorb cancellation in
  the products and in the roots of the bond polynomials; genuine nonzero
  coefficients of the examples are of order ``1e-3`` or larger.
* ``ExactField(K)``: elements of a sympy algebraic number field ``K`` (for
  instance ``Q(I)``); the zero test is exact.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mpmath
import sympy

__all__ = [
    "EXACT",
    "NUMERIC",
    "TERMS",
    "WORKING_DIGITS",
    "ZERO_THRESHOLD",
    "ExactField",
    "NumericField",
    "PrecisionExhausted",
    "Series",
    "polyval",
]

WORKING_DIGITS = 50
ZERO_THRESHOLD = mpmath.mpf("1e-30")
#: Terms kept by series that are not exact (square roots).  Enough for the orders met
#: here (at most 4); an order beyond the computed terms raises PrecisionExhausted, it
#: is never guessed.
TERMS = 10
#: Precision of exactly known series (polynomials): larger than any exponent met.
EXACT = 10**6


class PrecisionExhausted(ArithmeticError):
    """All computed coefficients vanish: the order is at least ``prec``."""


class NumericField:
    """mpmath complex coefficients with the thresholded zero test."""

    exact = False

    def __init__(self):
        self.zero, self.one = mpmath.mpc(0), mpmath.mpc(1)

    def convert(self, x: Any) -> Any:
        """``x`` (a number or a sympy expression) as an ``mpmath.mpc`` at the working precision."""
        if type(x) is mpmath.mpc:
            return x
        if isinstance(x, sympy.Basic):
            re, im = sympy.re(x).evalf(WORKING_DIGITS + 10), sympy.im(x).evalf(WORKING_DIGITS + 10)
            return mpmath.mpc(mpmath.mpf(re), mpmath.mpf(im))
        return mpmath.mpc(x)

    def first_nonzero(self, coeffs: Sequence[Any]) -> int | None:
        """Index of the first coefficient above ``ZERO_THRESHOLD`` times the scale of the leading four; ``None`` if none."""
        tol = ZERO_THRESHOLD * max([abs(c) for c in coeffs[:4]] + [mpmath.mpf(1)])
        return next((k for k, c in enumerate(coeffs) if abs(c) > tol), None)

    def sqrt(self, x: Any) -> Any:
        """The principal square root."""
        return mpmath.sqrt(x)

    def to_complex(self, x: Any) -> complex:
        """``x`` rounded to ``complex``."""
        return complex(x)


class ExactField:
    """Elements of a sympy algebraic field ``K`` containing ``I``; zero means zero.

    Gaussian rationals ``a + b I`` are converted by arithmetic (sympy's general
    conversion solves a field isomorphism problem each time, ~0.1 s).
    """

    exact = True

    def __init__(self, field: Any):
        self.field = field
        self.zero, self.one = field.zero, field.one
        self._i = field.from_sympy(sympy.I)

    def convert(self, x: Any) -> Any:
        """``x`` (a number or a sympy expression in ``K``) as an element of the field ``K``."""
        if isinstance(x, type(self.zero)):
            return x
        x = sympy.sympify(x)
        re, im = x.as_real_imag()
        if re.is_Rational and im.is_Rational:
            return self.field.from_sympy(re) + self.field.from_sympy(im) * self._i
        return self.field.from_sympy(x)

    def first_nonzero(self, coeffs: Sequence[Any]) -> int | None:
        """Index of the first coefficient that is exactly nonzero; ``None`` if all vanish."""
        return next((k for k, c in enumerate(coeffs) if c != self.zero), None)

    def sqrt(self, x: Any) -> Any:
        """The square root of ``x`` in ``K``; ``ArithmeticError`` if it is not in ``K``."""
        r = sympy.sqrt(self.field.to_sympy(x))
        try:
            return self.field.from_sympy(r)
        except Exception as err:  # sympy raises CoercionFailed and others
            raise ArithmeticError(f"sqrt({r}) is not in {self.field}") from err

    def to_complex(self, x: Any) -> complex:
        """``x`` rounded to ``complex`` (evaluated to ``WORKING_DIGITS`` first)."""
        return complex(sympy.N(self.field.to_sympy(x), WORKING_DIGITS))


NUMERIC = NumericField()


class Series:
    """``sum_k coeffs[k] u^(val + k) + O(u^prec)`` with coefficients in ``field``.

    Parameters
    ----------
    coeffs
        Coefficients of ``u^val, u^(val+1), ...``; entries beyond ``prec - val`` are dropped.
    val
        Exponent of the first coefficient.
    prec
        Absolute precision: terms ``u^e`` with ``e >= prec`` are unknown.
    field
        ``NUMERIC`` (default) or an ``ExactField``.
    """

    __slots__ = ("coeffs", "val", "prec", "field")

    def __init__(self, coeffs: Sequence[Any], val: int, prec: int, field: Any = NUMERIC):
        # coefficients past the stored ones (and below prec) are exactly zero
        self.coeffs = [field.convert(x) for x in list(coeffs)[: max(prec - val, 0)]]
        self.val, self.prec, self.field = val, prec, field

    @classmethod
    def exact(cls, coeffs: Sequence[Any], val: int = 0, field: Any = NUMERIC) -> Series:
        """A series known exactly (a polynomial in ``u`` times ``u^val``)."""
        return cls(coeffs, val, EXACT, field)

    def _new(self, coeffs: Sequence[Any], val: int, prec: int) -> Series:
        return Series(coeffs, val, prec, self.field)

    def _coerce(self, other: Any) -> Series:
        return other if isinstance(other, Series) else Series.exact([other], 0, self.field)

    def _end(self) -> int:
        """One past the exponent of the last stored coefficient."""
        return min(self.val + len(self.coeffs), self.prec)

    def coefficient(self, e: int) -> Any:
        """Coefficient of ``u^e`` (``e < prec``)."""
        if e >= self.prec:
            raise PrecisionExhausted(f"coefficient of u^{e} requested; series known up to O(u^{self.prec})")
        k = e - self.val
        return self.coeffs[k] if 0 <= k < len(self.coeffs) else self.field.zero

    def __add__(self, other: Any) -> Series:
        o = self._coerce(other)
        val, prec = min(self.val, o.val), min(self.prec, o.prec)
        end = min(max(self._end(), o._end()), prec)
        return self._new([self.coefficient(e) + o.coefficient(e) for e in range(val, end)], val, prec)

    __radd__ = __add__

    def __neg__(self) -> Series:
        return self._new([-c for c in self.coeffs], self.val, self.prec)

    def __sub__(self, other: Any) -> Series:
        return self + (-self._coerce(other))

    def __rsub__(self, other: Any) -> Series:
        return self._coerce(other) + (-self)

    def __mul__(self, other: Any) -> Series:
        if not isinstance(other, Series):
            c = self.field.convert(other)
            return self._new([x * c for x in self.coeffs], self.val, self.prec)
        val = self.val + other.val
        # relative precisions: the product is known to the smaller one
        prec = min(self.prec + other.val, other.prec + self.val)
        a, b = self.coeffs, other.coeffs
        n = min(prec - val, len(a) + len(b) - 1)
        zero = self.field.zero
        out = [zero] * max(n, 0)
        for i in range(min(len(a), n)):
            ai = a[i]
            if ai == zero:
                continue
            for j in range(min(len(b), n - i)):
                out[i + j] += ai * b[j]
        return self._new(out, val, prec)

    __rmul__ = __mul__

    def order(self) -> int:
        """Exponent of the first nonzero coefficient (thresholded for ``NUMERIC``).

        Raises
        ------
        PrecisionExhausted
            If every computed coefficient is zero (the series is zero as far as it is known).
        """
        k = self.field.first_nonzero(self.coeffs)
        if k is None:
            raise PrecisionExhausted(f"no nonzero coefficient up to O(u^{min(self.prec, EXACT)})")
        return self.val + k

    def normalized(self) -> Series:
        """Leading zero coefficients dropped: ``val`` becomes the order."""
        o = self.order()
        return self._new(self.coeffs[o - self.val :], o, self.prec)

    def truncated(self, prec: int) -> Series:
        """The same series known only up to ``O(u^prec)``."""
        return self._new(self.coeffs, self.val, min(prec, self.prec))

    def shift(self, e: int) -> Series:
        """Multiply by ``u^e``."""
        return self._new(self.coeffs, self.val + e, self.prec + e)

    def sqrt_unit(self, root: Any = None) -> Series:
        """The square root of a unit series (order 0, ``val`` 0), starting with ``root``.

        ``root`` is a square root of the constant term (default: the field's own,
        mpmath's principal branch for ``NUMERIC``).
        """
        if self.val != 0 or self.order() != 0:
            raise ValueError(f"sqrt_unit needs a series of order 0 with val 0; got val {self.val}")
        n = min(self.prec, TERMS)
        a = self.coeffs
        r = [self.field.sqrt(a[0]) if root is None else self.field.convert(root)]
        two_r0 = r[0] + r[0]
        for k in range(1, n):
            s = self.field.zero
            for j in range(1, k):
                s += r[j] * r[k - j]
            ak = a[k] if k < len(a) else self.field.zero
            r.append((ak - s) / two_r0)
        return self._new(r, 0, n)

    def __repr__(self) -> str:
        show = (lambda c: mpmath.nstr(c, 6)) if not self.field.exact else str
        terms = [f"({show(c)})u^{self.val + k}" for k, c in enumerate(self.coeffs[:6])]
        return "Series(" + " + ".join(terms) + f" + O(u^{self.prec}))"


def polyval(coefficients: Sequence[Any], x: Series) -> Series:
    """Horner evaluation of ``sum_k coefficients[k] x^k`` (ascending order) at a series."""
    r = Series.exact([], 0, x.field)
    for c in reversed(list(coefficients)):
        r = r * x + c
    return r
