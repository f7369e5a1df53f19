"""The iterated-suspension chart of a closed chain, written once for any backend.

A chain of ``m`` unit rods from ``0`` to a real base ``D`` (``m-2 < D < m``) has
parameters ``a = (phi_m, ..., phi_4, t)`` (latitudes first, the circle angle
last; ``m - 2`` of them).  Level ``m >= 4`` ("peel the last rod")::

    alpha_m = acos((D^2 - (m-1)^2 + 1) / (2 D)),   theta = alpha_m sin(phi_m)
    p_{m-1} = D - e^{i theta},   d = |p_{m-1}|,    phat = p_{m-1} / d

and the inner chain of ``m-1`` rods from 0 to ``d`` gives the remaining hinges,
rotated by ``phat``.  Circle level ``m = 3`` with ``s = sin t``::

    alpha = acos((D^2 - 3) / (2D)),  theta = alpha s,  p_2 = D - e^{i theta}
    nu    = alpha cos(t) sqrt(D sinc(alpha (1+s)/2) sinc(alpha (1-s)/2))
    p_1   = p_2 / 2 + i nu p_2 / (2 |p_2|)

``nu`` is the signed elbow height (``nu^2 = 4 - |p_2|^2``, sign of ``cos t``),
smooth across ``t = +-pi/2``.  Level ``m = 2`` is ``S^0``:
``p_1 = (D + i sheet sqrt(4 - D^2)) / 2``.

Functions here take and return lists of scalars (numpy arrays or heyoka
expressions) and :class:`~manifold.backends.Cx` pairs; they know nothing of
rod relabelings, batching or validation (see :mod:`charts.suspension`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from manifold.backends import Cx


class Base:
    """A sub-chain's base: length ``D`` of ``m`` rods and its two slacks.

    ``hi = m - D`` and ``lo = D - (m - 2)`` are carried down the recursion by
    cancellation-free formulas: near a pole or near the ends of the ``L`` range
    one of them is tiny, and recomputing it as a difference of ``O(1)`` numbers
    would turn ``alpha`` (a square root of it) into noise.
    """

    def __init__(self, D: Any, lo: Any, hi: Any, m: int) -> None:
        self.D, self.lo, self.hi, self.m = D, lo, hi, m

    def alpha(self, ops: Any) -> Any:
        """Half-width of the last rod's arc: ``acos((D^2 - (m-1)^2 + 1) / (2D))``.

        Written as ``2 atan2(sqrt(hi (m + D - 2)), sqrt(lo (m + D)))``: ``acos``
        near ``+-1`` would lose half the digits.
        """
        D, m = self.D, self.m
        return 2 * ops.atan2(ops.sqrt(self.hi * (m - 2 + D)), ops.sqrt(self.lo * (m + D)))

    def inner(self, alpha: Any, theta: Any, up: Any, dn: Any, ops: Any) -> "Base":
        """Base of the inner chain (``m-1`` rods) after the last rod at angle ``theta``.

        ``d^2 = (D-1)^2 + 4 D sin^2(theta/2)`` (a sum of positives, accurate also
        for small ``d``), ``d - (D-1) = 4 D sin^2(theta/2) / (d + D - 1)`` and
        ``(m-1)^2 - d^2 = 4 D sin(alpha up/2) sin(alpha dn/2)``, ``up, dn = 1 +- s``.
        """
        D, m = self.D, self.m
        h = ops.sin(theta / 2)
        D_minus_1 = (m - 3) + self.lo
        d = ops.sqrt(D_minus_1 * D_minus_1 + 4 * D * h * h)
        X = 4 * D * ops.sin(alpha * up / 2) * ops.sin(alpha * dn / 2)
        return Base(d, self.lo + 4 * D * h * h / (d + D_minus_1), X / (m - 1 + d), m - 1)

    def peel(self, phi: Any, ops: Any) -> tuple[Any, "Base"]:
        """Peel the last rod at latitude ``phi``: its angle ``theta = alpha sin(phi)`` and the inner base."""
        alpha = self.alpha(ops)
        theta = alpha * ops.sin(phi)
        return theta, self.inner(alpha, theta, ops.one_plus_sin(phi), ops.one_minus_sin(phi), ops)


def top_base(n: int, L: Any) -> Base:
    """The whole chain's base: ``L`` with slacks ``L - (n-2)`` and ``n - L``."""
    return Base(L, L - (n - 2), n - L, n)


def _last_hinge(D: Any, theta: Any, ops: Any) -> Cx:
    """``D - e^{i theta}``: the base minus the last rod."""
    return Cx(D - ops.cos(theta), -ops.sin(theta))


def _circle_scale(D: Any, alpha: Any, up: Any, dn: Any, ops: Any) -> Any:
    """``alpha sqrt(D sinc(alpha up/2) sinc(alpha dn/2))``, so that ``nu = cos(t) *`` this."""
    return alpha * ops.sqrt(D * ops.sinc(alpha * up / 2) * ops.sinc(alpha * dn / 2))


def _rod_slack(w: Cx, ops: Any) -> Any:
    """``|w| - Re(w)``: how much shorter a rod's projection on the chord is than the rod.

    ``Im(w)^2 / (|w| + Re(w))`` where the rod points along the chord (the plain
    difference cancels there, exactly where a sub-chain is nearly stretched).
    """
    r = ops.sqrt(w.abs2())
    return ops.where(ops.gt(w.re, 0), w.im * w.im / (r + ops.abs(w.re)), r - w.re)


def _up_dn(base: Base, alpha: Any, theta: Any, inner_slack: Any, d: Any, ops: Any) -> tuple[Any, Any]:
    """``(1 + s, 1 - s)``, ``s = sin(phi) = theta / alpha``, both to full relative accuracy.

    The larger one is ``1 + |theta| / alpha``.  The smaller one tends to 0 at a
    pole, where ``theta / alpha`` cancels against 1; it is taken instead from
    the inner chain's slack ``(m-1) - d`` (measured rod by rod) through
    ``(m-1)^2 - d^2 = 4 D sin(alpha up/2) sin(alpha dn/2)``.
    """
    large = 1 + ops.ratio_or_zero(ops.abs(theta), alpha)
    X = inner_slack * (base.m - 1 + d)
    small = 2 * ops.ratio_or_zero(ops.asin_clipped(X / (4 * base.D * ops.sin(alpha * large / 2))), alpha)
    north = ops.ge(theta, 0)
    return ops.where(north, large, small), ops.where(north, small, large)


def hinges(a: Sequence[Any], L: Any, ops: Any, sheet: int = 1) -> list[Cx]:
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
    """
    n = len(a) + 2
    base, frame, outer = top_base(n, L), None, []  # frame: rotation of the current sub-frame (None = identity)

    def place(z: Cx) -> Cx:
        return z if frame is None else frame * z

    for phi in a[:-1]:
        theta, inner = base.peel(phi, ops)
        p = _last_hinge(base.D, theta, ops)
        base = inner
        outer.append(place(p))
        frame = place(p.scale(1 / base.D))
    D = base.D
    if n == 2:  # 4 - D^2 = hi (2 + D)
        return [Cx(D / 2, sheet * ops.sqrt(base.hi * (2 + D)) / 2)]
    t = a[-1]
    alpha = base.alpha(ops)
    p2 = _last_hinge(D, alpha * ops.sin(t), ops)
    scale = _circle_scale(D, alpha, ops.one_plus_sin(t), ops.one_minus_sin(t), ops)
    k = ops.cos(t) * scale / (2 * ops.sqrt(p2.abs2()))
    p1 = Cx(p2.re / 2 - k * p2.im, p2.im / 2 + k * p2.re)
    return [place(p1), place(p2)] + outer[::-1]


def fold_qualities(a: Sequence[Any], L: Any, ops: Any) -> list[Any]:
    """The chart's two quality terms at its circle level (the first three rods of its order), in ``[0, 1]``.

    With the circle level's base ``D``, ``lo = D - 1``, ``alpha`` and ``theta = alpha sin t``:

    * ``q_A = P2 / (P2 + lo/4)``, ``P2 = |p_2|^2 = lo^2 + 4 D sin^2(theta/2)``: the fold of the
      first two rods (``p_2 -> 0``), where ``sigma_max(J) ~ pi / |p_2|``; measured
      ``sigma_max(J) q_A`` in ``[1.2, 16.9]`` for n = 4..8 and ``L - (n-2)`` down to 1e-12;
    * ``q_B = sqrt(cos^2 t + sin^2 t cos(alpha/2))``, ``cos^2(alpha/2) = lo (3 + D) / (4 D)``: the
      folded triple (``D -> 1`` at ``t = +-pi/2``), where ``sigma_min(J) ~ 1.14 (L - (n-2))^(1/4)``;
      measured ``sigma_min(J) / q_B`` in ``[0.63, 4.4]``.

    Both are written from the carried slack ``lo``: no cancellation near ``L = n - 2``
    (``docs/atlas_quality.md``).
    """
    base = top_base(len(a) + 2, L)
    for phi in a[:-1]:
        _, base = base.peel(phi, ops)
    t, D, lo = a[-1], base.D, base.lo
    h = ops.sin(base.alpha(ops) * ops.sin(t) / 2)
    P2 = lo * lo + 4 * D * h * h
    cos_half_alpha = ops.sqrt(lo * (3 + D) / (4 * D))
    s, c = ops.sin(t), ops.cos(t)
    return [P2 / (P2 + lo / 4), ops.sqrt(c * c + s * s * cos_half_alpha)]


def parameters(z: Sequence[Cx], L: Any, ops: Any) -> list[Any]:
    """Inverse of :func:`hinges`: ``(phi_n, ..., phi_4, t)`` from hinges ``z_1 .. z_{n-1}``.

    ``theta = arg(e_last)`` and ``phi = asin(theta / alpha)`` level by level, the
    inner chain rotated back by ``conj(phat)``.  At the circle level ``cos t`` is
    taken from the elbow height ``nu = 2 Im(z_1 conj(z_2)) / |z_2|`` rather
    than from ``asin``, which loses half the digits near ``t = +-pi/2``.
    ``phi = atan2((up - dn)/2, sqrt(up dn))`` with ``up, dn = 1 +- sin(phi)`` each
    to full relative accuracy (see :func:`_up_dn`), so a configuration a hair
    from a pole keeps the tiny bend of its inner chain.  On a collapsed
    sub-sphere (a stretched sub-chain: the chart's singular set) the inner
    parameters are arbitrary.  Callers may still polish the result by a Newton
    step on the forward map where the chart is ill-conditioned.
    """
    n = len(z) + 1
    base, inner, out = top_base(n, L), list(z), []
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
    nu = 2 * (p1.im * p2.re - p1.re * p2.im) / ops.sqrt(p2.abs2())
    c = ops.ratio_or_zero(nu, _circle_scale(base.D, alpha, up, dn, ops))
    out.append(ops.atan2(s, c))
    return out


def rod_angles(a: Sequence[Any], L: Any, ops: Any, sheet: int = 1) -> list[Any]:
    """The seed's angle form of the same chart: rod angles ``theta_1 .. theta_n``.

    ``Psi^m_D(phi, rest) = (R + Psi^{m-1}_d(rest), theta)`` with
    ``theta = alpha sin(phi)``, ``d = |D - e^{i theta}|``, ``R = arg(D - e^{i theta})``;
    ``Psi^3_D(t) = (R + sigma beta(d), R - sigma beta(d), theta)`` with
    ``sigma = sign(cos t)``, ``beta(d) = acos(d / 2)``; ``Psi^2_D = (sheet beta(D), -sheet beta(D))``.
    Only for drawing on the torus and for cross-checks: ``sigma`` jumps, so it
    is not smooth at ``t = +-pi/2``.  Numpy backend only (uses ``sign``).
    """
    import numpy as np

    n = len(a) + 2
    base, R, tail = top_base(n, L), 0.0, []
    for phi in a:
        theta, inner = base.peel(phi, ops)
        p = _last_hinge(base.D, theta, ops)
        tail.append(R + theta)
        R = R + ops.atan2(p.im, p.re)
        base = inner
        if base.m == 2:
            sheet = np.sign(ops.cos(phi))
    beta = ops.atan2(ops.sqrt(base.hi * (2 + base.D)), base.D)  # acos(D/2), accurate near D = 2
    return [R + sheet * beta, R - sheet * beta] + tail[::-1]
