"""Second-order jets along a velocity: forward-mode derivatives as heyoka expressions.

A :class:`Jet` carries a quantity ``f(a)`` with its partials ``df/da_i`` and its
first and second derivatives along a curve with ``a' = c`` and ``a'' = 0``::

    d1 = sum_i f_i c^i,        d2 = sum_ij f_ij c^i c^j.

Pushing jets through a chart formula gives ``z``, ``J`` and the geodesic term
``sum z_ab c^a c^b`` in one forward sweep whose size grows like the formula's,
instead of differentiating the expanded expression twice.  Zeros are kept as
the Python number 0 so that no expression is built for them.
"""

from __future__ import annotations

from typing import Any


def _is_zero(x: Any) -> bool:
    return isinstance(x, (int, float)) and x == 0


def _mul(x: Any, y: Any) -> Any:
    return 0 if _is_zero(x) or _is_zero(y) else x * y


def _add(*xs: Any) -> Any:
    out = 0
    for x in xs:
        if not _is_zero(x):
            out = x if _is_zero(out) else out + x
    return out


def _neg(x: Any) -> Any:
    return 0 if _is_zero(x) else -x


class Jet:
    """Value, gradient (list of length k), first and second derivative along ``c``."""

    __slots__ = ("v", "g", "d1", "d2")

    def __init__(self, v: Any, g: list, d1: Any, d2: Any) -> None:
        self.v, self.g, self.d1, self.d2 = v, g, d1, d2

    @classmethod
    def variable(cls, a: Any, c: Any, i: int, k: int) -> "Jet":
        """The ``i``-th of ``k`` coordinates, moving with velocity ``c``."""
        return cls(a, [1 if j == i else 0 for j in range(k)], c, 0)

    def _chain(self, f: Any, f1: Any, f2: Any) -> "Jet":
        """``F(self)`` given ``F``, ``F'`` and ``F''`` at the value."""
        return Jet(f, [_mul(f1, gi) for gi in self.g], _mul(f1, self.d1),
                   _add(_mul(f2, _mul(self.d1, self.d1)), _mul(f1, self.d2)))

    def __add__(self, o: Any) -> "Jet":
        if not isinstance(o, Jet):
            return Jet(_add(self.v, o), self.g, self.d1, self.d2)
        return Jet(_add(self.v, o.v), [_add(x, y) for x, y in zip(self.g, o.g)], _add(self.d1, o.d1), _add(self.d2, o.d2))

    # the reflected operators keep the plain operand on the left, as plain code builds it: heyoka's common
    # subexpressions are structural, and ``v * o`` beside a plain ``o * v`` was computed twice
    def __radd__(self, o: Any) -> "Jet":
        return Jet(_add(o, self.v), self.g, self.d1, self.d2)

    def __neg__(self) -> "Jet":
        return Jet(_neg(self.v), [_neg(x) for x in self.g], _neg(self.d1), _neg(self.d2))

    def __sub__(self, o: Any) -> "Jet":
        return self + (-o)

    def __rsub__(self, o: Any) -> "Jet":
        return (-self) + o

    def __mul__(self, o: Any) -> "Jet":
        if not isinstance(o, Jet):
            return Jet(_mul(self.v, o), [_mul(x, o) for x in self.g], _mul(self.d1, o), _mul(self.d2, o))
        if o is self:  # a square by the chain rule: k + 3 products of series instead of 2k + 6
            return self._chain(_mul(self.v, self.v), _mul(2.0, self.v), 2.0)
        return Jet(
            _mul(self.v, o.v),
            [_add(_mul(x, o.v), _mul(self.v, y)) for x, y in zip(self.g, o.g)],
            _add(_mul(self.d1, o.v), _mul(self.v, o.d1)),
            _add(_mul(self.d2, o.v), _mul(2.0, _mul(self.d1, o.d1)), _mul(self.v, o.d2)),
        )

    def __rmul__(self, o: Any) -> "Jet":
        return Jet(_mul(o, self.v), [_mul(o, x) for x in self.g], _mul(o, self.d1), _mul(o, self.d2))

    def reciprocal(self) -> "Jet":
        """``1/x``: derivatives ``-1/x^2`` and ``2/x^3``."""
        r = 1.0 / self.v
        r2 = r * r
        return self._chain(r, -r2, 2.0 * r2 * r)

    def __truediv__(self, o: Any) -> "Jet":
        if not isinstance(o, Jet):
            return self * (1.0 / o)
        return self * o.reciprocal()

    def __rtruediv__(self, o: Any) -> "Jet":
        return self.reciprocal() * o


class JetOps:
    """Math backend on jets, over a base backend for the values (e.g. :class:`manifold.backends.HeyokaOps`).

    Provides ``sin``, ``cos``, ``sqrt``, ``atan2``; formulas built from these and
    arithmetic (the base backend's ``sinc`` and ``one_minus_sin`` among them,
    when they are written that way) run on jets unchanged.
    """

    def __init__(self, base: Any) -> None:
        self.base = base

    def sin(self, x: Any) -> Any:
        """``sin x``; on a jet by the chain rule with ``sin' = cos``, ``sin'' = -sin``."""
        if not isinstance(x, Jet):
            return self.base.sin(x)
        s, c = self.base.sin(x.v), self.base.cos(x.v)
        return x._chain(s, c, -s)

    def cos(self, x: Any) -> Any:
        """``cos x``; on a jet by the chain rule with ``cos' = -sin``, ``cos'' = -cos``."""
        if not isinstance(x, Jet):
            return self.base.cos(x)
        s, c = self.base.sin(x.v), self.base.cos(x.v)
        return x._chain(c, -s, -c)

    def sqrt(self, x: Any) -> Any:
        """``sqrt x``; on a jet with ``r = sqrt x``, ``r' = 1/(2r)``, ``r'' = -r'/(2x)``."""
        if not isinstance(x, Jet):
            return self.base.sqrt(x)
        r = self.base.sqrt(x.v)
        f1 = 0.5 / r
        return x._chain(r, f1, -0.5 * f1 / x.v)

    def atan2(self, y: Any, x: Any) -> Any:
        """``atan2(y, x)``: ``theta' = (x y' - y x') / r^2`` and its derivative."""
        if not isinstance(y, Jet) and not isinstance(x, Jet):
            return self.base.atan2(y, x)
        y = y if isinstance(y, Jet) else Jet(y, [0] * len(x.g), 0, 0)
        x = x if isinstance(x, Jet) else Jet(x, [0] * len(y.g), 0, 0)
        inv_r2 = 1.0 / (x.v * x.v + y.v * y.v)
        grad = [_mul(inv_r2, _add(_mul(x.v, yi), _neg(_mul(y.v, xi)))) for xi, yi in zip(x.g, y.g)]
        w = _add(_mul(x.v, y.d1), _neg(_mul(y.v, x.d1)))  # x y' - y x'
        d1 = _mul(inv_r2, w)
        rr = _add(_mul(x.v, x.d1), _mul(y.v, y.d1))  # (r^2)' / 2
        d2 = _add(_mul(inv_r2, _add(_mul(x.v, y.d2), _neg(_mul(y.v, x.d2)))), _mul(-2.0, _mul(_mul(d1, inv_r2), rr)))
        return Jet(self.base.atan2(y.v, x.v), grad, d1, d2)

    def polynomial(self, coeffs: Any, y: Any) -> Any:
        """``p(y) = sum_k coeffs[k] y^k`` from three polynomials on the value: ``p``, ``p'``, ``p''``.

        A polynomial run on jets would multiply jets at every term (``2k + 6``
        products of series for ``k`` parameters, each costing heyoka ``O(order)``
        per Taylor order); the chain rule needs the base backend's three
        polynomials, which on heyoka share the powers of ``y``.
        """
        if not isinstance(y, Jet):
            return self.base.polynomial(coeffs, y)
        d1 = [k * c for k, c in enumerate(coeffs)][1:]  # exact multiples, rounded once in the coefficients' type
        d2 = [k * c for k, c in enumerate(d1)][1:]
        p = self.base.polynomial
        return y._chain(p(coeffs, y.v), p(d1, y.v) if d1 else 0, p(d2, y.v) if d2 else 0)

    def __getattr__(self, name: str) -> Any:
        """Everything else from the base backend; its methods (``sinc``, ``one_minus_sin``, ...) are
        rebound to this backend so that their ``self.sin``/``self.cos`` act on jets."""
        attr = getattr(self.base, name)
        return attr.__func__.__get__(self) if hasattr(attr, "__func__") else attr
