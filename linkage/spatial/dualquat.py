"""Dual quaternions with coefficients in any commutative number type.

A dual quaternion is ``h = p + eps q`` with quaternions ``p`` (primal) and ``q``
(dual) and ``eps^2 = 0``.  It is stored as the 8 coefficients over the basis

    (1, i, j, k, eps, eps i, eps j, eps k).

The coefficients may be Python floats or complex numbers, mpmath numbers, sympy
expressions or any other objects with commutative ``+``, ``-`` and ``*`` (the
power series of :mod:`linkage.spatial.series` included).  A *complex*
coefficient never mixes with the quaternion units: ``DualQuaternion.scalar(1j)``
is the complex unit ``I`` times the quaternion ``1``, and ``I - i`` is a nonzero
dual quaternion (a zero divisor: ``(I - i)(I + i) = I^2 + 1 = 0``), exactly as in
Hegedüs, Schicho, Schröcker, "The Theory of Bonds", Section 3.1.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import sympy

__all__ = ["DualNumber", "DualQuaternion", "FLOAT_TOL", "is_inexact"]

#: Zero test of the motion-type predicates for float coefficients, relative to the largest
#: coefficient (exact coefficients are tested exactly).
FLOAT_TOL = 1e-12


class DualNumber(NamedTuple):
    """``primal + eps dual`` with ``eps^2 = 0`` (the value of a norm)."""

    primal: Any
    dual: Any


def _qmul(a: Sequence, b: Sequence) -> tuple:
    """Hamilton product of two quaternions given as 4 coefficients ``(1, i, j, k)``."""
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = b
    return (
        a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3,
        a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2,
        a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1,
        a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0,
    )


def _require_zero(value: Any, message: str) -> None:
    """Raise ``ValueError(message)`` if ``value`` is a number that is not 0 (to 1e-12 for floats).

    Symbolic values (sympy expressions with free symbols) are not judged.
    """
    if getattr(value, "free_symbols", None):
        return
    try:
        size = abs(complex(value))
    except (TypeError, ValueError):
        return
    if size > 1e-12:
        raise ValueError(f"{message} (off by {size:.3g})")


class DualQuaternion:
    """An element of ``DH = H + eps H`` (``eps^2 = 0``), 8 coefficients.

    Parameters
    ----------
    coefficients
        Eight numbers ``(h0, ..., h7)`` over ``(1, i, j, k, eps, eps i, eps j, eps k)``.

    Notes
    -----
    * Product: ``(p + eps q)(r + eps s) = pr + eps (ps + qr)`` with Hamilton's
      ``i^2 = j^2 = k^2 = ijk = -1``.
    * Conjugate: the vector part is negated, ``conj(p + eps q) = conj(p) + eps conj(q)``.
    * Norm: ``N(h) = h conj(h) = p conj(p) + eps (p conj(q) + q conj(p))``, a dual
      number; the Study condition is that its dual part vanishes.
    * ``Q(h) = h0^2 + h1^2 + h2^2 + h3^2``, the primal part of the norm, is the
      complex *bilinear* square (no complex conjugation).
    * A line through point ``x`` with unit direction ``d`` is
      ``h = d + eps (d x x) = d - eps m`` with the Plücker moment ``m = x x d``;
      then ``h^2 = -1`` and ``t - h`` is the rotation about the line; with
      ``t = cot(phi/2)`` it is proportional to ``cos(phi/2) - sin(phi/2) h``, the
      turn by ``phi`` in the negative sense about ``h``.  ``t = inf`` is the identity.
    """

    __slots__ = ("_c",)

    def __init__(self, coefficients: Sequence[Any]):
        c = tuple(coefficients)
        if len(c) != 8:
            raise ValueError(
                f"coefficients must have exactly 8 entries (1, i, j, k, eps, eps i, eps j, eps k); got {len(c)}"
            )
        self._c = c

    # construction -------------------------------------------------------------
    @classmethod
    def scalar(cls, a: Any, zero: Any = 0) -> DualQuaternion:
        """The scalar ``a`` (``a`` times the quaternion 1)."""
        return cls((a, zero, zero, zero, zero, zero, zero, zero))

    @classmethod
    def from_quaternions(cls, primal: Sequence[Any], dual: Sequence[Any]) -> DualQuaternion:
        """``primal + eps dual`` from two 4-sequences ``(1, i, j, k)``."""
        if len(primal) != 4 or len(dual) != 4:
            raise ValueError(f"primal and dual must have 4 entries each; got {len(primal)} and {len(dual)}")
        return cls(tuple(primal) + tuple(dual))

    @classmethod
    def from_plucker(cls, direction: Sequence[Any], moment: Sequence[Any]) -> DualQuaternion:
        """The line with Plücker coordinates ``(d, m)`` as ``d - eps m``.

        ``d`` must be a unit vector and ``m`` orthogonal to it (normalised Plücker
        coordinates); then the result squares to ``-1``.
        """
        if len(direction) != 3 or len(moment) != 3:
            raise ValueError(f"direction and moment must be 3-vectors; got lengths {len(direction)}, {len(moment)}")
        d0, d1, d2 = direction
        m0, m1, m2 = moment
        _require_zero(d0 * d0 + d1 * d1 + d2 * d2 - 1, f"direction {tuple(direction)} must be a unit vector")
        _require_zero(d0 * m0 + d1 * m1 + d2 * m2, f"moment {tuple(moment)} must be orthogonal to the direction")
        return cls((0 * d0, d0, d1, d2, 0 * d0, -m0, -m1, -m2))

    @classmethod
    def from_line(cls, point: Sequence[Any], direction: Sequence[Any]) -> DualQuaternion:
        """The line through ``point`` with unit ``direction``: ``d - eps (point x d)``."""
        if len(point) != 3 or len(direction) != 3:
            raise ValueError(f"point and direction must be 3-vectors; got lengths {len(point)}, {len(direction)}")
        x0, x1, x2 = point
        d0, d1, d2 = direction
        moment = (x1 * d2 - x2 * d1, x2 * d0 - x0 * d2, x0 * d1 - x1 * d0)
        return cls.from_plucker(direction, moment)

    # access ---------------------------------------------------------------------
    @property
    def coefficients(self) -> tuple:
        """The 8 coefficients over ``(1, i, j, k, eps, eps i, eps j, eps k)``."""
        return self._c

    @property
    def primal(self) -> tuple:
        """The primal part: the coefficients of ``(1, i, j, k)``."""
        return self._c[:4]

    @property
    def dual(self) -> tuple:
        """The dual part: the coefficients of ``(eps, eps i, eps j, eps k)``."""
        return self._c[4:]

    def __iter__(self):
        return iter(self._c)

    def __getitem__(self, k: int) -> Any:
        return self._c[k]

    def map(self, f) -> DualQuaternion:
        """Apply ``f`` to every coefficient (e.g. ``sympy.expand``, ``mpmath.mpf``)."""
        return DualQuaternion(tuple(f(x) for x in self._c))

    # algebra --------------------------------------------------------------------
    def _coerce(self, other: Any) -> DualQuaternion:
        if isinstance(other, DualQuaternion):
            return other
        return DualQuaternion.scalar(other, 0 * other)

    def __add__(self, other: Any) -> DualQuaternion:
        o = self._coerce(other)
        return DualQuaternion(tuple(a + b for a, b in zip(self._c, o._c)))

    __radd__ = __add__

    def __neg__(self) -> DualQuaternion:
        return DualQuaternion(tuple(-a for a in self._c))

    def __sub__(self, other: Any) -> DualQuaternion:
        return self + (-self._coerce(other))

    def __rsub__(self, other: Any) -> DualQuaternion:
        return self._coerce(other) + (-self)

    def __mul__(self, other: Any) -> DualQuaternion:
        if not isinstance(other, DualQuaternion):
            return DualQuaternion(tuple(a * other for a in self._c))
        p, q = self._c[:4], self._c[4:]
        r, s = other._c[:4], other._c[4:]
        ps, qr = _qmul(p, s), _qmul(q, r)
        return DualQuaternion(_qmul(p, r) + tuple(x + y for x, y in zip(ps, qr)))

    def __rmul__(self, other: Any) -> DualQuaternion:
        # a scalar on the left commutes with everything
        return DualQuaternion(tuple(other * a for a in self._c))

    def conjugate(self) -> DualQuaternion:
        """``conj(h)``: the vector parts (primal and dual) change sign."""
        c = self._c
        return DualQuaternion((c[0], -c[1], -c[2], -c[3], c[4], -c[5], -c[6], -c[7]))

    def norm(self) -> DualNumber:
        """``N(h) = h conj(h) = |p|^2 + eps 2 <p, q>`` (bilinear, not Hermitian)."""
        c = self._c
        return DualNumber(
            c[0] * c[0] + c[1] * c[1] + c[2] * c[2] + c[3] * c[3],
            2 * (c[0] * c[4] + c[1] * c[5] + c[2] * c[6] + c[3] * c[7]),
        )

    def quadratic_form(self) -> Any:
        """``Q(h) = h0^2 + h1^2 + h2^2 + h3^2``, the primal part of ``N(h)``."""
        return self.norm().primal

    def trace(self) -> DualNumber:
        """``h + conj(h) = 2 h0 + eps 2 h4``: twice the scalar part, a dual number."""
        c = self._c
        return DualNumber(2 * c[0], 2 * c[4])

    def in_exceptional_space(self) -> bool:
        """``h`` lies in the exceptional 3-space ``E``: its primal part is zero.

        [HSS] Section 1: ``E`` (projectively a 3-space in ``P^7``) lies in the Study
        quadric ``S``; ``S - E`` is the group ``SE(3)``.  Coefficients are compared
        with zero exactly, floats to ``FLOAT_TOL`` times the largest coefficient.
        """
        return all(_negligible(x, self._c) for x in self._c[:4])

    def is_rotation(self) -> bool:
        """``h`` represents a rotation ([HSS] Section 1).

        A nonzero dual quaternion represents a rotation if and only if its norm
        and its trace are *strictly real* (their dual parts vanish) and its primal
        vectorial part is nonzero.  Points of ``E`` (zero primal part) are no
        displacements and give ``False``.
        """
        return self._norm_and_trace_real() and not all(_negligible(x, self._c) for x in self._c[1:4])

    def is_translation(self) -> bool:
        """``h`` represents a translation (the identity included) ([HSS] Section 1).

        A nonzero dual quaternion represents a translation if and only if its
        norm and its trace are strictly real and its primal vectorial part is zero;
        then ``h`` is proportional to ``1 + eps v`` with ``v`` vectorial, the
        translation by ``-2 v``.
        """
        return self._norm_and_trace_real() and all(_negligible(x, self._c) for x in self._c[1:4])

    def _norm_and_trace_real(self) -> bool:
        if all(_negligible(x, self._c) for x in self._c):
            raise ValueError("the zero dual quaternion represents no displacement")
        if self.in_exceptional_space():
            return False
        return _negligible(self.study_condition(), [x * y for x in self._c for y in self._c]) and _negligible(
            self._c[4], self._c
        )

    def study_condition(self) -> Any:
        """``h0 h4 + h1 h5 + h2 h6 + h3 h7``: zero iff ``h`` lies on the Study quadric."""
        c = self._c
        return c[0] * c[4] + c[1] * c[5] + c[2] * c[6] + c[3] * c[7]

    def inverse(self) -> DualQuaternion:
        """``h^-1 = conj(h) / N(h)`` with ``1/(a + eps b) = 1/a - eps b/a^2``.

        Raises ``ZeroDivisionError`` when the primal part of the norm is zero.
        """
        a, b = self.norm()
        inv_a = 1 / a
        conj = self.conjugate()
        p, q = conj._c[:4], conj._c[4:]
        return DualQuaternion(
            tuple(x * inv_a for x in p) + tuple(y * inv_a - x * b * inv_a * inv_a for x, y in zip(p, q))
        )

    def act(self, point: Sequence[Any]) -> tuple:
        """The displacement ``v -> (p v conj(p) + p conj(q) - q conj(p)) / (p conj(p))``.

        ``point`` is a 3-vector ``v`` (read as the pure quaternion ``v1 i + v2 j + v3 k``).
        Meaningful for ``h`` on the Study quadric with ``p conj(p) != 0``.
        """
        if len(point) != 3:
            raise ValueError(f"point must be a 3-vector; got length {len(point)}")
        p, q = self._c[:4], self._c[4:]
        pc = (p[0], -p[1], -p[2], -p[3])
        qc = (q[0], -q[1], -q[2], -q[3])
        v = (0 * point[0], point[0], point[1], point[2])
        pvp = _qmul(_qmul(p, v), pc)
        pq = _qmul(p, qc)
        qp = _qmul(q, pc)
        n = p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]
        return tuple((pvp[k] + pq[k] - qp[k]) / n for k in (1, 2, 3))

    def __eq__(self, other: object) -> bool:
        if isinstance(other, DualQuaternion):
            return all(a == b for a, b in zip(self._c, other._c))
        return NotImplemented

    def __repr__(self) -> str:
        names = ("", "i", "j", "k", "eps", "eps*i", "eps*j", "eps*k")
        terms = [f"({c})" + (f"*{n}" if n else "") for c, n in zip(self._c, names) if not _is_literal_zero(c)]
        return "DualQuaternion(" + (" + ".join(terms) if terms else "0") + ")"


def is_inexact(x: Any) -> bool:
    """``x`` is a rounded number: a Python, numpy or mpmath float, or a sympy expression with a Float."""
    if isinstance(x, (float, complex)) or type(x).__module__.startswith(("numpy", "mpmath")):
        return True
    has = getattr(x, "has", None)
    return has is not None and bool(has(sympy.Float))


def _negligible(x: Any, scale: Sequence[Any]) -> bool:
    """``x`` is zero: exactly for exact numbers, to ``FLOAT_TOL * max |scale|`` for rounded ones."""
    if is_inexact(x) or any(is_inexact(y) for y in scale):
        return abs(complex(x)) <= FLOAT_TOL * max(abs(complex(y)) for y in scale)
    return bool(sympy.simplify(x) == 0)


def _is_literal_zero(x: Any) -> bool:
    try:
        return bool(x == 0)
    except TypeError:
        return False
