"""Truncated Laurent series in a local parameter ``u``, mpmath coefficients.

Used to evaluate the joint coordinates and the products ``F_ij`` of a linkage
along a *place* of its configuration curve (a branch through a point, with a
local parameter ``u``), and to read off orders of vanishing.

A series ``sum_k c_k u^(val + k) + O(u^prec)`` knows its absolute precision
``prec``: products and sums propagate it, so an order is never reported from
coefficients that were not computed.

Zero test (the documented threshold).  Coefficients are computed with
``mpmath.mp.dps = WORKING_DIGITS = 50``.  A coefficient counts as zero when its
modulus is below ``ZERO_THRESHOLD = 1e-30`` times the series' scale (the largest
modulus among its first four computed coefficients, and at least 1).  The 20
digits between working precision and threshold absorb cancellation in the
products and in the roots of the bond polynomials; genuine nonzero
coefficients of the examples are of order ``1e-3`` or larger.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import mpmath

__all__ = ["EXACT", "TERMS", "WORKING_DIGITS", "ZERO_THRESHOLD", "PrecisionExhausted", "Series", "polyval"]

WORKING_DIGITS = 50
ZERO_THRESHOLD = mpmath.mpf("1e-30")
#: Terms kept by series that are not exact (square roots, reciprocals).
TERMS = 16
#: Precision of exactly known series (polynomials): larger than any exponent met.
EXACT = 10**6


class PrecisionExhausted(ArithmeticError):
    """All computed coefficients vanish: the order is at least ``prec``."""


class Series:
    """``sum_k coeffs[k] u^(val + k) + O(u^prec)`` with mpmath complex coefficients.

    Parameters
    ----------
    coeffs
        Coefficients of ``u^val, u^(val+1), ...``; entries beyond ``prec - val`` are dropped.
    val
        Exponent of the first coefficient.
    prec
        Absolute precision: terms ``u^e`` with ``e >= prec`` are unknown.
    """

    __slots__ = ("coeffs", "val", "prec")

    def __init__(self, coeffs: Sequence[Any], val: int, prec: int):
        # coefficients past the stored ones (and below prec) are exactly zero
        mpc = mpmath.mpc
        self.coeffs = [x if type(x) is mpc else mpc(x) for x in list(coeffs)[: max(prec - val, 0)]]
        self.val, self.prec = val, prec

    @classmethod
    def exact(cls, coeffs: Sequence[Any], val: int = 0) -> Series:
        """A series known exactly (a polynomial in ``u`` times ``u^val``)."""
        return cls(coeffs, val, EXACT)

    def _coerce(self, other: Any) -> Series:
        return other if isinstance(other, Series) else Series.exact([other])

    def _end(self) -> int:
        """One past the exponent of the last stored coefficient."""
        return min(self.val + len(self.coeffs), self.prec)

    def coefficient(self, e: int) -> Any:
        """Coefficient of ``u^e`` (``e < prec``)."""
        if e >= self.prec:
            raise PrecisionExhausted(f"coefficient of u^{e} requested; series known up to O(u^{self.prec})")
        k = e - self.val
        return self.coeffs[k] if 0 <= k < len(self.coeffs) else mpmath.mpc(0)

    def __add__(self, other: Any) -> Series:
        o = self._coerce(other)
        val, prec = min(self.val, o.val), min(self.prec, o.prec)
        end = min(max(self._end(), o._end()), prec)
        return Series([self.coefficient(e) + o.coefficient(e) for e in range(val, end)], val, prec)

    __radd__ = __add__

    def __neg__(self) -> Series:
        return Series([-c for c in self.coeffs], self.val, self.prec)

    def __sub__(self, other: Any) -> Series:
        return self + (-self._coerce(other))

    def __rsub__(self, other: Any) -> Series:
        return self._coerce(other) + (-self)

    def __mul__(self, other: Any) -> Series:
        if not isinstance(other, Series):
            return Series([c * other for c in self.coeffs], self.val, self.prec)
        val = self.val + other.val
        # relative precisions: the product is known to the smaller one
        prec = min(self.prec + other.val, other.prec + self.val)
        a, b = self.coeffs, other.coeffs
        n = min(prec - val, len(a) + len(b) - 1)
        out = [mpmath.mpc(0)] * max(n, 0)
        for i in range(min(len(a), n)):
            ai = a[i]
            if ai == 0:
                continue
            for j in range(min(len(b), n - i)):
                out[i + j] += ai * b[j]
        return Series(out, val, prec)

    __rmul__ = __mul__

    def __pow__(self, k: int) -> Series:
        if not isinstance(k, int) or k < 0:
            raise ValueError(f"power must be a non-negative integer; got {k!r}")
        r = Series.exact([1])
        for _ in range(k):
            r = r * self
        return r

    def scale(self) -> Any:
        return max([abs(c) for c in self.coeffs[:4]] + [mpmath.mpf(1)])

    def order(self) -> int:
        """Exponent of the first coefficient above the zero threshold.

        Raises
        ------
        PrecisionExhausted
            If every computed coefficient is below the threshold (the series is
            zero as far as it is known).
        """
        tol = ZERO_THRESHOLD * self.scale()
        for k, c in enumerate(self.coeffs):
            if abs(c) > tol:
                return self.val + k
        raise PrecisionExhausted(f"no coefficient above {mpmath.nstr(tol, 3)} up to O(u^{min(self.prec, EXACT)})")

    def normalized(self) -> Series:
        """Leading coefficients below the zero threshold dropped: ``val`` becomes the order."""
        o = self.order()
        return Series(self.coeffs[o - self.val :], o, self.prec)

    def truncated(self, prec: int) -> Series:
        """The same series known only up to ``O(u^prec)``."""
        return Series(self.coeffs, self.val, min(prec, self.prec))

    def shift(self, e: int) -> Series:
        """Multiply by ``u^e``."""
        return Series(self.coeffs, self.val + e, self.prec + e)

    def leading(self) -> Any:
        """The coefficient of ``u^order``."""
        return self.coefficient(self.order())

    def reciprocal_unit(self) -> Series:
        """``1/s`` for a series of order 0 (a unit), by the usual recurrence."""
        if self.order() != 0 or self.val != 0:
            raise ValueError(f"reciprocal_unit needs a series of order 0 with val 0; got order {self.order()}")
        n = min(self.prec, TERMS)
        a = self.coeffs
        inv = [1 / a[0]]
        for k in range(1, n):
            s = sum((a[j] * inv[k - j] for j in range(1, min(k, len(a) - 1) + 1)), mpmath.mpc(0))
            inv.append(-s / a[0])
        return Series(inv, 0, n)

    def sqrt_unit(self) -> Series:
        """The square root with ``sqrt(c_0)`` (mpmath's principal branch) of a unit series."""
        if self.order() != 0 or self.val != 0:
            raise ValueError(f"sqrt_unit needs a series of order 0 with val 0; got order {self.order()}")
        n = min(self.prec, TERMS)
        a = self.coeffs
        r = [mpmath.sqrt(a[0])]
        for k in range(1, n):
            s = sum((r[j] * r[k - j] for j in range(1, k)), mpmath.mpc(0))
            ak = a[k] if k < len(a) else mpmath.mpc(0)
            r.append((ak - s) / (2 * r[0]))
        return Series(r, 0, n)

    def __repr__(self) -> str:
        terms = [f"({mpmath.nstr(c, 6)})u^{self.val + k}" for k, c in enumerate(self.coeffs[:6])]
        return "Series(" + " + ".join(terms) + f" + O(u^{self.prec}))"


def polyval(coefficients: Sequence[Any], x: Series) -> Series:
    """Horner evaluation of ``sum_k coefficients[k] x^k`` (ascending order) at a series."""
    r = Series.exact([0])
    for c in reversed(list(coefficients)):
        r = r * x + c
    return r
