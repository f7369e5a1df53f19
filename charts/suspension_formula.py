"""The iterated-suspension chart of a closed chain, written once for any backend.

A chain of ``m`` links ``l_1 .. l_m`` from ``0`` to a real base ``D`` that is the
dominant side of the polygon ``(l_1, ..., l_m, D)`` (``R_m - 2 mu_m < D < R_m``,
``R_m = l_1 + ... + l_m``, ``mu_m = min(l_1 .. l_m)``: the configuration space is
the sphere ``S^(m-2)``) has parameters ``a = (phi_m, ..., phi_4, t)`` (latitudes
first, the circle angle last; ``m - 2`` of them).  Level ``m >= 4`` ("peel the
last link")::

    alpha_m = acos((D^2 + l_m^2 - R_{m-1}^2) / (2 D l_m)),   theta = alpha_m sin(phi_m)
    p_{m-1} = D - l_m e^{i theta},   d = |p_{m-1}|,    phat = p_{m-1} / d

``|p_{m-1}| = R_{m-1}`` at ``theta = +-alpha_m``, and the inner chain of ``m-1``
links from 0 to ``d`` has ``d`` dominant again (``d >= D - l_m > R_{m-1} - 2 mu_m``,
and ``mu_m <= mu_{m-1}``); it gives the remaining hinges, rotated by ``phat``.
Circle level ``m = 3`` with ``s = sin t``::

    theta = alpha s,  p_2 = D - l_3 e^{i theta},  d = |p_2|
    nu    = alpha cos(t) sqrt(D l_3 sinc(alpha (1+s)/2) sinc(alpha (1-s)/2))
    p_1   = p_2 (x + i y) / d,   x = (d^2 + l_1^2 - l_2^2) / (2d),   y = nu sqrt(d^2 - (l_1 - l_2)^2) / (2d)

``nu^2 = (l_1 + l_2)^2 - d^2``, so ``x^2 + y^2 = l_1^2``, and ``y`` is the signed
elbow height (sign of ``cos t``), smooth across ``t = +-pi/2``.  Level ``m = 2``
is ``S^0``: ``p_1 = x + i sheet y`` with the same ``x``, ``y >= 0`` at ``d = D``.
Unit rods (every ``l_k = 1``) reduce to ``x = d/2``, ``y = nu/2``.

Lengths are :class:`Rods`: the Python integer 1 for unit rods, so that every
sum and difference of lengths below is an exact integer and the unit-rod
expressions are as short as before; or numbers, arrays or heyoka runtime
parameters for any lengths (one compiled family then serves every length
vector of a given ``n``).

Functions here take and return lists of scalars (numpy arrays or heyoka
expressions) and :class:`~manifold.backends.Cx` pairs; they know nothing of
rod relabelings, batching or validation (see :mod:`charts.suspension`).
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction
from typing import Any

from manifold.backends import Cx


def is_zero(x: Any) -> bool:
    """Whether ``x`` is a Python number equal to 0 (a length sum that folds away for unit rods)."""
    return isinstance(x, (int, float)) and x == 0


def is_one(x: Any) -> bool:
    """Whether ``x`` is a Python number equal to 1 (a unit rod)."""
    return isinstance(x, (int, float)) and x == 1


def plus(x: Any, y: Any) -> Any:
    """``x + y``, dropping a Python zero (unit rods: no ``+ 0`` in the expressions)."""
    return x if is_zero(y) else y if is_zero(x) else x + y


def times(x: Any, y: Any) -> Any:
    """``x y``, dropping a Python one."""
    return x if is_one(y) else y if is_one(x) else x * y


def _minimum(x: Any, y: Any, ops: Any) -> Any:
    if isinstance(x, (int, float)) and isinstance(y, (int, float)):
        return min(x, y)
    return ops.minimum(x, y)


class Rods:
    """Link lengths ``l_1 .. l_n`` of a chain in chart order, and the prefix sums and minima the recursion needs.

    Parameters
    ----------
    lengths
        ``n`` lengths: Python ``1`` each for unit rods (:meth:`unit`), numbers,
        numpy arrays, or heyoka expressions (runtime parameters).
    ops
        The backend for ``min`` of non-Python lengths.
    slacks
        ``(hi, lo)`` of the whole chain, ``hi = R_n - L`` and ``lo = L - (R_n - 2 mu_n)``,
        exact to one rounding (:func:`top_slacks`), or ``None`` to form them from
        ``L`` and the lengths (exact for unit rods, and in a working precision
        wider than the lengths' float64).

    Attributes
    ----------
    l, R, mu
        ``l[k-1] = l_k``; ``R[m] = l_1 + ... + l_m`` (``R[0] = 0``); ``mu[m] = min(l_1 .. l_m)``.
    """

    def __init__(self, lengths: Sequence[Any], ops: Any, slacks: tuple[Any, Any] | None = None) -> None:
        self.l = list(lengths)
        self.slacks = slacks
        self.R: list[Any] = [0]
        self.mu: list[Any] = [None]
        for k, lk in enumerate(self.l):
            self.R.append(plus(self.R[-1], lk))
            self.mu.append(lk if k == 0 else _minimum(self.mu[-1], lk, ops))

    @classmethod
    def unit(cls, n: int) -> "Rods":
        """``n`` unit rods (Python integers: every derived length is exact and folds away)."""
        return cls([1] * n, None)

    @property
    def n(self) -> int:
        return len(self.l)

    def fold_gap(self, m: int) -> Any:
        """``R_{m-1} - 2 mu_m = sum_{j<m} (l_j - mu_m) + (m-3) mu_m``: a sum of non-negatives for ``m >= 3``
        (the plain difference cancels where two links are nearly equal and the shortest); ``m - 3`` for unit rods."""
        mu = self.mu[m]
        out = (m - 3) * mu if isinstance(mu, (int, float)) else times(mu, m - 3) if m > 3 else 0
        for lj in self.l[: m - 1]:
            out = plus(out, 0 if isinstance(lj, (int, float)) and lj == mu else lj - mu)
        return out

    def last_excess(self, m: int) -> Any:
        """``2 (l_m - mu_m) >= 0``: a Python 0 for unit rods."""
        d = self.l[m - 1] - self.mu[m]
        return 0 if is_zero(d) else 2 * d

    def min_step(self, m: int) -> Any:
        """``2 (mu_{m-1} - mu_m) >= 0``: a Python 0 for unit rods."""
        d = self.mu[m - 1] - self.mu[m]
        return 0 if is_zero(d) else 2 * d

    def top_base(self, L: Any) -> "Base":
        """The whole chain's base: ``L`` with slacks ``hi = R_n - L`` and ``lo = L - (R_n - 2 mu_n)``."""
        n = self.n
        if self.slacks is not None:
            hi, lo = self.slacks
        else:
            hi, lo = self.R[n] - L, L - (self.R[n] - 2 * self.mu[n])
        return Base(L, lo, hi, n, self)


def top_slacks(lengths: Sequence[float], L: float) -> tuple[float, float]:
    """``(hi, lo) = (R_n - L, L - (R_n - 2 mu_n))`` exactly, rounded once to float64.

    In floating point ``R_n = l_1 + ... + l_n`` is rounded by up to ``n eps R_n``:
    near either end of the sphere range one slack is tiny, and ``alpha`` (about
    its square root) would be that rounding's noise; rationals make them exact.
    """
    ls = [Fraction(float(x)) for x in lengths]
    R, Lf = sum(ls), Fraction(float(L))
    return float(R - Lf), float(Lf - R + 2 * min(ls))


class Base:
    """A sub-chain's base: length ``D`` of links ``l_1 .. l_m`` and its two slacks.

    ``hi = R_m - D`` and ``lo = D - (R_m - 2 mu_m)`` (the distances of ``D`` from
    both ends of its sphere range) are carried down the recursion by
    cancellation-free formulas: near a pole or near the ends of the ``L``
    range one of them is tiny, and recomputing it as a difference of ``O(1)``
    numbers would turn ``alpha`` (a square root of it) into noise.  For unit
    rods ``hi = m - D`` and ``lo = D - (m-2)``.
    """

    def __init__(self, D: Any, lo: Any, hi: Any, m: int, rods: Rods) -> None:
        self.D, self.lo, self.hi, self.m, self.rods = D, lo, hi, m, rods

    @property
    def last(self) -> Any:
        """``l_m``, the link peeled at this level."""
        return self.rods.l[self.m - 1]

    def d_minus_l(self) -> Any:
        """``D - l_m = lo + (R_{m-1} - 2 mu_m)``: both terms ``>= 0`` for ``m >= 3`` (no cancellation)."""
        return plus(self.lo, self.rods.fold_gap(self.m))

    def last_slack(self) -> Any:
        """``D + l_m - R_{m-1} = lo + 2 (l_m - mu_m)``, both terms ``>= 0``: 0 where the last link can fold back."""
        return plus(self.lo, self.rods.last_excess(self.m))

    def alpha(self, ops: Any) -> Any:
        """Half-width of the last link's arc: ``acos((D^2 + l_m^2 - R_{m-1}^2) / (2 D l_m))``.

        Written as ``2 atan2(sqrt(hi (R_{m-1} + D - l_m)), sqrt((D + l_m - R_{m-1}) (R_m + D)))``
        (``tan^2(alpha/2)`` factored into slacks): ``acos`` near ``+-1`` would lose half the digits.
        """
        y2, x2 = self._tan_half_alpha_squares()
        return 2 * ops.atan2(ops.sqrt(y2), ops.sqrt(x2))

    def alpha_rate(self, ops: Any) -> Any:
        """``d alpha / dD``, the base's slacks moving with it (``d hi = -dD``, ``d lo = dD``).

        With ``y^2 = hi A`` and ``x^2 = B C`` of :meth:`alpha` (``A = R_{m-1} + D - l_m``, ``B = D + l_m - R_{m-1}``,
        ``C = R_m + D``, each moving like ``D``) and ``hi - A = -2 (D - l_m)``:

            d alpha / dD = (x^2 (hi - A) - y^2 (B + C)) / (x y (x^2 + y^2))
                         = -(2 x^2 (D - l_m) + y^2 (B + C)) / (x y (x^2 + y^2)),

        a quotient of sums of non-negatives: no cancellation.  It grows like ``1 / sqrt(hi)`` where the base
        nears ``R_m`` (an outer pole) and like ``1 / sqrt(B)`` where the last link can fold back.
        """
        y2, x2 = self._tan_half_alpha_squares()
        r, m = self.rods, self.m
        num = 2 * x2 * self.d_minus_l() + y2 * (self.last_slack() + (r.R[m] + self.D))
        return -num / (ops.sqrt(x2) * ops.sqrt(y2) * (x2 + y2))

    def _tan_half_alpha_squares(self) -> tuple[Any, Any]:
        """``(hi (R_{m-1} + D - l_m), (D + l_m - R_{m-1}) (R_m + D))``, whose quotient is ``tan^2(alpha / 2)``."""
        r, m = self.rods, self.m
        return self.hi * (r.R[m - 1] + self.d_minus_l()), self.last_slack() * (r.R[m] + self.D)

    def inner_lo(self, h: Any, d: Any, ops: Any) -> Any:
        """``lo`` of the inner chain at inner base ``d`` and ``h = sin(theta/2)``:
        ``lo' = lo + (d - (D - l_m)) + 2 (mu_{m-1} - mu_m)``, ``d - (D - l_m) = 4 D l_m h^2 / (d + D - l_m)``."""
        step = times(4 * self.D, self.last) * h * h / (d + self.d_minus_l())
        return plus(self.lo + step, self.rods.min_step(self.m))

    def inner(self, alpha: Any, theta: Any, up: Any, dn: Any, ops: Any) -> "Base":
        """Base of the inner chain (``m-1`` links) after the last link at angle ``theta``.

        ``d^2 = (D - l_m)^2 + 4 D l_m sin^2(theta/2)`` (a sum of positives, accurate also
        for small ``d``), ``lo'`` by :meth:`inner_lo` and
        ``R_{m-1}^2 - d^2 = 4 D l_m sin(alpha up/2) sin(alpha dn/2)``, ``up, dn = 1 +- s``.
        """
        r, m = self.rods, self.m
        h = ops.sin(theta / 2)
        DmL = self.d_minus_l()
        d = ops.sqrt(DmL * DmL + times(4 * self.D, self.last) * h * h)
        X = times(4 * self.D, self.last) * ops.sin(alpha * up / 2) * ops.sin(alpha * dn / 2)
        return Base(d, self.inner_lo(h, d, ops), X / (r.R[m - 1] + d), m - 1, r)

    def peel(self, phi: Any, ops: Any) -> tuple[Any, "Base"]:
        """Peel the last link at latitude ``phi``: its angle ``theta = alpha sin(phi)`` and the inner base."""
        alpha = self.alpha(ops)
        theta = alpha * ops.sin(phi)
        return theta, self.inner(alpha, theta, ops.one_plus_sin(phi), ops.one_minus_sin(phi), ops)


def top_base(n: int, L: Any, rods: Rods | None = None) -> Base:
    """The whole chain's base (unit rods unless ``rods`` is given)."""
    return (Rods.unit(n) if rods is None else rods).top_base(L)


def last_hinge(base: Base, theta: Any, ops: Any) -> Cx:
    """``D - l_m e^{i theta}``: the base minus the last link.

    Its real part is ``(D - l_m) + 2 l_m sin^2(theta/2)``, a sum of non-negatives with the carried
    ``D - l_m``: ``D - l_m cos(theta)`` would carry an error ``eps D`` into a hinge that can pass
    near 0 (a fold), where the elbow ``p_2 / |p_2|`` amplifies it by ``l / |p_2|``.
    """
    l, h = base.last, ops.sin(theta / 2)
    return Cx(plus(base.d_minus_l(), times(2 * l, h * h)), -times(l, ops.sin(theta)))


def _circle_scale(D: Any, l: Any, alpha: Any, up: Any, dn: Any, ops: Any) -> Any:
    """``alpha sqrt(D l sinc(alpha up/2) sinc(alpha dn/2))``, so that ``nu = cos(t) *`` this."""
    return alpha * ops.sqrt(times(D, l) * ops.sinc(alpha * up / 2) * ops.sinc(alpha * dn / 2))


def _elbow(base: Base, theta: Any, P2: Any, ops: Any) -> tuple[Any, Any, Any]:
    """``(c, cbar, r)`` with ``p_1 = p_2 (c + i nu r / 2)`` and ``p_2 - p_1 = p_2 (cbar - i nu r / 2)`` at the
    circle level: ``c = x / d``, ``cbar = 1 - c``, ``r = y / (nu d) * 2``.

    With ``s = |l_1 - l_2|`` and ``lo_2 = d - s`` the two-link chain's slack (carried,
    :meth:`Base.inner_lo`: tiny where the two links fold flat, where a plain difference would cancel):
    ``r = sqrt(lo_2 (lo_2 + 2 s)) / d^2`` and

        2 d^2 c = lo_2 (d + s) + 2 l_1 (l_1 - l_2),    2 d^2 cbar = lo_2 (d + s) - 2 l_2 (l_1 - l_2).

    Numerical trap: ``c`` and ``cbar`` are the link vectors' ``p_1`` and ``p_2 - p_1`` in the elbow's frame,
    so each must be accurate relative to its link.  ``1 - c`` or ``1/2 + (l_1 - l_2)(l_1 + l_2) / (2 d^2)``
    cancel to ``l / d`` for a short ``l_2`` or ``l_1`` (a chart whose pinned base ``L`` is such a link turns
    by it: 254x shorter lost 1.5x the bound); here the cancelling pair is at most ``4 l d``.
    Unit rods: ``c = cbar = 1/2``, ``r = 1/d``.
    """
    l1, l2 = base.rods.l[0], base.rods.l[1]
    diff = l1 - l2
    d = ops.sqrt(P2)
    if is_zero(diff):
        return 0.5, 0.5, 1 / d
    lo2 = base.inner_lo(ops.sin(theta / 2), d, ops)
    s = ops.abs(diff)
    fold = lo2 * (d + s)
    return ((fold + 2 * l1 * diff) / (2 * P2), (fold - 2 * l2 * diff) / (2 * P2),
            ops.sqrt(lo2 * (lo2 + 2 * s)) / P2)


def _rod_slack(w: Cx, ops: Any) -> Any:
    """``|w| - Re(w)``: how much shorter a link's projection on the chord is than the link.

    ``Im(w)^2 / (|w| + Re(w))`` where the link points along the chord (the plain
    difference cancels there, exactly where a sub-chain is nearly stretched).
    """
    r = ops.sqrt(w.abs2())
    return ops.where(ops.gt(w.re, 0), w.im * w.im / (r + ops.abs(w.re)), r - w.re)


def _up_dn(base: Base, alpha: Any, theta: Any, inner_slack: Any, d: Any, ops: Any) -> tuple[Any, Any]:
    """``(1 + s, 1 - s)``, ``s = sin(phi) = theta / alpha``, both to full relative accuracy.

    The larger one is ``1 + |theta| / alpha``.  The smaller one tends to 0 at a
    pole, where ``theta / alpha`` cancels against 1; in the polar half
    (``|s| > 1/2``) it is taken instead from the inner chain's slack
    ``R_{m-1} - d`` (measured link by link) through
    ``R_{m-1}^2 - d^2 = 4 D l_m sin(alpha up/2) sin(alpha dn/2)``.  Numerical
    trap: that ``asin`` is ill-conditioned where its argument nears 1, as it
    does at the equator when ``alpha`` nears ``pi`` (the lower end of the
    range: a chain 2e-7 from it lost 2.4e-12 of ``1 - s`` at ``s = 0``), so
    the equatorial half keeps ``1 - |s|``, which cancels at most 2x there.
    """
    ratio = ops.ratio_or_zero(ops.abs(theta), alpha)
    large = 1 + ratio
    X = inner_slack * (base.rods.R[base.m - 1] + d)
    polar = 2 * ops.ratio_or_zero(
        ops.asin_clipped(X / (times(4 * base.D, base.last) * ops.sin(alpha * large / 2))), alpha)
    small = ops.where(ops.gt(ratio, 0.5), polar, 1 - ratio)
    north = ops.ge(theta, 0)
    return ops.where(north, large, small), ops.where(north, small, large)


def _two_link_elbow(base: Base, sheet: int, ops: Any) -> tuple[Any, Any]:
    """``(x, |y|)`` of ``p_1`` for two links on the base ``D`` (``S^0``):
    ``|y| = sqrt(hi (R_2 + D) lo (lo + 2 |l_1 - l_2|)) / (2D)``; unit rods ``(D/2, sqrt(hi (2 + D))/2)``."""
    D, hi, lo = base.D, base.hi, base.lo
    l1, l2 = base.rods.l[0], base.rods.l[1]
    diff = l1 - l2
    if is_zero(diff):
        return D / 2, ops.sqrt(hi * (2 + D)) / 2
    return (D / 2 + diff * (l1 + l2) / (2 * D),
            ops.sqrt(hi * (base.rods.R[2] + D) * lo * (lo + 2 * ops.abs(diff))) / (2 * D))


def hinges(a: Sequence[Any], L: Any, ops: Any, sheet: int = 1, rods: Rods | None = None) -> list[Cx]:
    """Interior hinges ``p_1 .. p_{n-1}`` of the suspension chart, ``n = len(a) + 2``.

    Parameters
    ----------
    a
        ``(phi_n, ..., phi_4, t)``; empty for ``n = 2``.
    L
        Base length (scalar, array or heyoka expression).
    ops
        Math backend (:data:`manifold.backends.NUMPY` or :class:`manifold.backends.HeyokaOps`).
    sheet
        ``+1`` or ``-1``: the point of ``S^0`` for ``n = 2`` (ignored otherwise).
    rods
        The link lengths in chart order (:class:`Rods`); default unit rods.
    """
    return chain_vectors(a, L, ops, sheet, rods)[0]


def chain_vectors(a: Sequence[Any], L: Any, ops: Any, sheet: int = 1,
                  rods: Rods | None = None) -> tuple[list[Cx], list[Cx]]:
    """The hinges ``p_1 .. p_{n-1}`` of :func:`hinges` and the link vectors ``e_1 .. e_n``.

    Each link vector is formed as such (``l_m e^{i theta}`` in its level's frame, ``p_1`` and
    ``p_2 - p_1 = p_2 (cbar - i k)`` at the circle level, :func:`_elbow`), accurate relative to its own length: a
    difference of hinges would carry their rounding, ``eps`` times the chain's size, into a short link.
    """
    n = len(a) + 2
    base, frame, outer, links = top_base(n, L, rods), None, [], []  # frame: rotation of the current sub-frame

    def place(z: Cx) -> Cx:
        return z if frame is None else frame * z

    for phi in a[:-1]:
        theta, inner = base.peel(phi, ops)
        p = last_hinge(base, theta, ops)
        outer.append(place(p))
        links.append(place(Cx(times(base.last, ops.cos(theta)), times(base.last, ops.sin(theta)))))
        base = inner
        frame = place(p.scale(1 / base.D))
    if n == 2:
        x, y = _two_link_elbow(base, sheet, ops)
        return [Cx(x, sheet * y)], [Cx(x, sheet * y), Cx(base.D - x, -sheet * y)]
    p1, p2, e2, e3 = circle_level(base, a[-1], ops)
    return [place(p1), place(p2)] + outer[::-1], [place(p1), place(e2), place(e3)] + links[::-1]


def circle_level(base: Base, t: Any, ops: Any) -> tuple[Cx, Cx, Cx, Cx]:
    """The circle level's hinges ``p_1``, ``p_2`` and link vectors ``e_2 = p_2 - p_1``, ``e_3``, in its own frame:
    three links on the base ``D`` at the coordinate ``t`` (see the module docstring)."""
    alpha = base.alpha(ops)
    theta = alpha * ops.sin(t)
    p2 = last_hinge(base, theta, ops)
    nu = ops.cos(t) * _circle_scale(base.D, base.last, alpha, ops.one_plus_sin(t), ops.one_minus_sin(t), ops)
    c, cbar, r = _elbow(base, theta, p2.abs2(), ops)
    k = nu * r / 2
    p1 = Cx(c * p2.re - k * p2.im, c * p2.im + k * p2.re)
    e2 = Cx(cbar * p2.re + k * p2.im, cbar * p2.im - k * p2.re)
    e3 = Cx(times(base.last, ops.cos(theta)), times(base.last, ops.sin(theta)))
    return p1, p2, e2, e3


def fold_qualities(a: Sequence[Any], L: Any, ops: Any, rods: Rods | None = None) -> list[Any]:
    """The chart's two quality terms at its circle level (the first three links of its order), in ``[0, 1]``.

    With the circle level's base ``D``, slack ``lo``, ``alpha`` and ``theta = alpha sin t``:

    * ``q_A = P2 / (P2 + (D - l_3) l_3 / 4)``, ``P2 = |p_2|^2 = (D - l_3)^2 + 4 D l_3 sin^2(theta/2)``:
      the fold of the first two links (``p_2 -> 0``, possible only for ``l_1 = l_2``; the
      elbow direction ``p_2 / |p_2|`` turns at the rate ``l_3 (D - l_3) / |p_2|^2`` there);
      unit rods: measured ``sigma_max(J) q_A`` in ``[1.2, 16.9]`` for n = 4..8 and ``L - (n-2)``
      down to 1e-12;
    * ``q_B = sqrt(cos^2 t + sin^2 t cos(alpha/2))``, ``cos^2(alpha/2) = (D + l_3 - R_2)(R_3 + D) / (4 D l_3)``:
      the folded triple (``alpha -> pi``: the third link folds back on the stretched first two,
      at ``t = +-pi/2``); unit rods: ``sigma_min(J) ~ 1.14 (L - (n-2))^(1/4)`` there, measured
      ``sigma_min(J) / q_B`` in ``[0.63, 4.4]``.

    Both are written from the carried slacks: no cancellation near the lower end of
    the ``L`` range (``docs/atlas_quality.md``).
    """
    base = top_base(len(a) + 2, L, rods)
    for phi in a[:-1]:
        _, base = base.peel(phi, ops)
    t, D, l3 = a[-1], base.D, base.last
    h = ops.sin(base.alpha(ops) * ops.sin(t) / 2)
    DmL = base.d_minus_l()
    P2 = DmL * DmL + times(4 * D, l3) * h * h
    cos_half_alpha = ops.sqrt(base.last_slack() * (base.rods.R[3] + D) / times(4 * D, l3))
    s, c = ops.sin(t), ops.cos(t)
    return [P2 / (P2 + times(DmL, l3) / 4), ops.sqrt(c * c + s * s * cos_half_alpha)]


def parameters(z: Sequence[Cx], L: Any, ops: Any, rods: Rods | None = None) -> list[Any]:
    """Inverse of :func:`hinges`: ``(phi_n, ..., phi_4, t)`` from hinges ``z_1 .. z_{n-1}``.

    ``theta = arg(D - p_{m-1})`` and ``phi = asin(theta / alpha)`` level by level, the
    inner chain rotated back by ``conj(phat)``.  At the circle level ``cos t`` is
    taken from the elbow height ``y = Im(z_1 conj(z_2)) / |z_2|`` rather
    than from ``asin``, which loses half the digits near ``t = +-pi/2``.
    ``phi = atan2((up - dn)/2, sqrt(up dn))`` with ``up, dn = 1 +- sin(phi)`` each
    to full relative accuracy (see :func:`_up_dn`), so a configuration a hair
    from a pole keeps the tiny bend of its inner chain.  On a collapsed
    sub-sphere (a stretched sub-chain: the chart's singular set) the inner
    parameters are arbitrary.  Callers may still polish the result by a Newton
    step on the forward map where the chart is ill-conditioned.
    """
    n = len(z) + 1
    base, inner, out = top_base(n, L, rods), list(z), []
    for _ in range(n - 3):
        p = inner[-1]
        alpha = base.alpha(ops)
        theta = ops.atan2(-p.im, base.D - p.re)
        d = ops.sqrt(p.abs2())
        back = p.conj().scale(1 / d)
        ends = [Cx(0.0, 0.0)] + inner
        slack = sum(_rod_slack((q - o) * back, ops) for o, q in zip(ends[:-1], ends[1:]))
        up, dn = _up_dn(base, alpha, theta, slack, d, ops)
        out.append(ops.atan2((up - dn) / 2, ops.sqrt(up * dn)))
        base = base.inner(alpha, theta, up, dn, ops)
        inner = [back * h for h in inner[:-1]]
    if n == 2:
        return out
    p1, p2 = inner
    alpha = base.alpha(ops)
    theta = ops.atan2(-p2.im, base.D - p2.re)
    s = ops.ratio_or_zero(theta, alpha)
    up, dn = 1 + s, 1 - s  # enter only through sinc, whose relative error they barely change
    P2 = p2.abs2()
    _, _, r = _elbow(base, theta, P2, ops)
    nu = 2 * (p1.im * p2.re - p1.re * p2.im) / (r * P2)  # Im(p_1 conj p_2) = nu r P2 / 2
    c = ops.ratio_or_zero(nu, _circle_scale(base.D, base.last, alpha, up, dn, ops))
    out.append(ops.atan2(s, c))
    return out


def rod_angles(a: Sequence[Any], L: Any, ops: Any, sheet: int = 1, rods: Rods | None = None) -> list[Any]:
    """The seed's angle form of the same chart: link angles ``theta_1 .. theta_n``.

    ``Psi^m_D(phi, rest) = (R + Psi^{m-1}_d(rest), theta)`` with
    ``theta = alpha sin(phi)``, ``d = |D - l_m e^{i theta}|``, ``R = arg(D - l_m e^{i theta})``;
    ``Psi^3_D(t) = (R + sigma beta_1(d), R - sigma beta_2(d), theta)`` with
    ``sigma = sign(cos t)`` and ``beta_1``, ``beta_2`` the angles of the triangle
    ``(d, l_1, l_2)`` at its ends (``beta_1 = beta_2 = acos(d / 2)`` for unit rods);
    ``Psi^2_D = (sheet beta_1(D), -sheet beta_2(D))``.
    Only for drawing on the torus and for cross-checks: ``sigma`` jumps, so it
    is not smooth at ``t = +-pi/2``.  Numpy backend only (uses ``sign``).
    """
    import numpy as np

    n = len(a) + 2
    base, R, tail = top_base(n, L, rods), 0.0, []
    for phi in a:
        theta, inner = base.peel(phi, ops)
        p = last_hinge(base, theta, ops)
        tail.append(R + theta)
        R = R + ops.atan2(p.im, p.re)
        base = inner
        if base.m == 2:
            sheet = np.sign(ops.cos(phi))
    x, y = _two_link_elbow(base, 1, ops)  # beta_1 = atan2(y, x), beta_2 = atan2(y, D - x): accurate near D = R_2
    return [R + sheet * ops.atan2(y, x), R - sheet * ops.atan2(y, base.D - x)] + tail[::-1]


def _side_sum(w: Sequence[Any], sides: Sequence[Cx]) -> Cx:
    """``sum_k w_k s_k``: the side that a one-hot ``w`` (runtime parameters) picks."""
    terms = [s.scale(wk) for wk, s in zip(w, sides)]
    out = terms[0]
    for t in terms[1:]:
        out = out + t
    return out


def _sides(hinges: Sequence[Cx], end: Any) -> list[Cx]:
    """Side vectors ``h_k - h_{k-1}`` of a chain from 0 through ``hinges`` to the real ``end``."""
    ends = [Cx(0.0, 0.0)] + list(hinges) + [Cx(end, 0.0)]
    return [q - o for o, q in zip(ends[:-1], ends[1:])]


def pinned_hinges(q: Sequence[Cx], D: Any, L: Any, w: Sequence[Any], links: Sequence[Cx]) -> list[Cx]:
    """Hinges pinned at ``0`` and ``L`` from the chart-frame hinges ``q`` of a chain on a dominant link.

    The chart is the suspension chart of the polygon turned so that the dominant
    link ``l_j = D`` is the base: ``q`` are the hinges of the other ``n`` sides in
    chart order, from 0 to ``D``, and ``links`` their vectors (:func:`chain_vectors`);
    one of them (``w_k = 1``, one-hot) is the pinned base ``L``, whose vector there
    is ``F = sum_k w_k links_k``.  Turning back by ``conj(omega) = -conj(F) / L``
    (``omega = -F / L`` is unimodular because ``|F| = L``) puts that side at ``-L``,
    and putting the link ``l_j`` (the chart's closing side ``-D``) in its place gives
    the chain from 0 to ``L``::

        z_k = -conj(F) / L (q_k - W_k (D + F)),   W_k = w_1 + ... + w_k

    in chart order with the base's slot held by link ``j``.  Smooth: ``|F| = L > 0``.
    ``F`` is taken from the link vectors, not from ``q_{k0} - q_{k0-1}``: the turn's
    direction error is that of ``F`` relative to ``L``, and a difference of hinges
    would make it ``eps R / L`` (``R`` the chain's size).
    """
    F = _side_sum(w, links)
    turn = Cx(-F.re / L, F.im / L)
    out, W = [], 0
    for qk, wk in zip(q, w):
        W = plus(W, wk)
        out.append(turn * (qk - Cx(D + F.re, F.im).scale(W)))
    return out


def chart_frame_hinges(z: Sequence[Cx], D: Any, L: Any, w: Sequence[Any]) -> list[Cx]:
    """Inverse of :func:`pinned_hinges`: with the link's side ``e = sum_k w_k s_k`` of the pinned chain
    (``|e| = D``), ``omega = -conj(e) / D`` and ``q_k = omega (z_k - W_k (e + L))``."""
    e = _side_sum(w, _sides(z, L))
    turn = Cx(-e.re / D, e.im / D)
    out, W = [], 0
    for zk, wk in zip(z, w):
        W = plus(W, wk)
        out.append(turn * (zk - Cx(e.re + L, e.im).scale(W)))
    return out
