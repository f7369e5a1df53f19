r"""The suspension chart's velocity by its own recursion: ``a'`` and ``J a'`` from hinge velocities in ``O(n)``.

The chart state ``(a, V)`` (:mod:`manifold.ambient_velocity`) needs, at every Taylor step, the chart
velocity ``a'`` of the hinge velocities ``V`` and the tangent part ``J a'``.  Read level by level
along the block-triangular Jacobian (``docs/math.md`` §7b), the generic solve differentiates the
whole chart formula along ``c`` (first-order jets through every slack, ``atan2`` and square root).
The geometry of a latitude level gives the same numbers from a few products.  Level ``m``
(latitude ``phi``, base ``D``, arc half-width ``alpha(D)``, ``theta = alpha sin(phi)``) places
``w = D - l_m e^{i theta}`` in its frame ``F`` (a rotation, turning at the rate ``Omega``), and the
outer levels have already fixed ``D' `` and ``Omega``:

.. math::

    \dot w &= \bar F V_{m-1} - i \Omega w
        \quad\text{(the hinge's velocity in the level's frame)},\\
    \dot\theta &= \langle -i e^{i\theta}, \dot w - \dot D \rangle / l_m
        \quad\text{(least squares on the hinge's two rows)},\\
    \dot\phi &= \big(\dot\theta - \alpha'(D)\, \dot D \sin\phi\big) / (\alpha \cos\phi),

and then, from the tangent ``\dot w = \dot D - i l_m \dot\theta e^{i\theta}``, the inner base and
frame move with ``\dot d = \langle \hat w, \dot w\rangle`` and
``\Omega \mathrel{+}= (w \times \dot w) / d^2`` (``d = |w|``), and the hinge's tangent velocity is
``F (\dot w + i \Omega w)``.  ``alpha'`` is :meth:`~charts.suspension_formula.Base.alpha_rate`.
The circle level (two hinges, where ``p_2`` alone stands still at ``t = +-pi/2``) is one level of
jets: the formula there (:func:`~charts.suspension_formula.circle_level`) on jets in its own
coordinate ``t`` and along the known motion of its base (``D' ``, with ``lo' = D'`` and
``hi' = -D'``), and ``t'`` by least squares on its four rows.

This is the generic forward substitution's arithmetic, not an approximation of it: the same
least-squares fit per level, the same oblique projection off the tangent space
(``tests/test_chart_velocity_solve.py`` holds the two to rounding on any ``V``).  The values (``w``,
``theta``, the frames) are the formula's own, built as the chart's jets build them, so heyoka
shares them with the point ``z(a)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from manifold.backends import Cx
from manifold.jets import Jet, JetOps

from .suspension_formula import Base, Rods, circle_level, is_one, is_zero, last_hinge, plus, times, top_base


def _value(x: Any) -> Any:
    """The value of a jet; a number or expression as it is."""
    return x.v if isinstance(x, Jet) else x


def _values(z: Cx) -> Cx:
    return Cx(_value(z.re), _value(z.im))


def _minus(x: Any, y: Any) -> Any:
    """``x - y``, dropping a Python zero."""
    return x if is_zero(y) else -y if is_zero(x) else x - y


def _product(x: Any, y: Any) -> Any:
    """``x y``: a Python zero if either is one, the other if either is a Python one."""
    return 0 if is_zero(x) or is_zero(y) else times(x, y)


def _turn(frame: Cx | None, z: Cx, back: bool = False) -> Cx:
    """``F z``, or ``conj(F) z`` with ``back``; ``z`` itself in the top level's frame (``F = 1``)."""
    if frame is None:
        return z
    f = Cx(frame.re, -frame.im) if back else frame
    return Cx(_minus(_product(f.re, z.re), _product(f.im, z.im)), plus(_product(f.re, z.im), _product(f.im, z.re)))


def _moving(frame: Cx | None, spin: Any, w: Cx, w_dot: Cx) -> Cx:
    """``F (w' + i Omega w)``: a point ``w`` of the level's frame moving at ``w'`` there, in the chart's frame."""
    return _turn(frame, Cx(_minus(w_dot.re, _product(spin, w.im)), plus(w_dot.im, _product(spin, w.re))))


def _relative(frame: Cx | None, spin: Any, v: Cx, w: Cx, known: Cx) -> Cx:
    """``conj(F) v - i Omega w - known``: the velocity ``v`` of the point ``w`` seen from the level's frame (which
    turns at ``Omega``), less the part ``known`` already accounted for."""
    seen = _turn(frame, v, back=True)
    return Cx(plus(_minus(seen.re, known.re), _product(spin, w.im)),
              _minus(_minus(seen.im, known.im), _product(spin, w.re)))


def _seeded(x: Any, rate: Any) -> Any:
    """A base quantity of the circle level as a jet in ``t`` (no dependence) moving at ``rate``."""
    return Jet(x.v, [0], rate, 0) if isinstance(x, Jet) else x


def chart_velocity(a: Sequence[Any], V: Sequence[Cx], L: Any, ops: Any,
                   rods: Rods | None = None) -> tuple[list[Any], list[Cx]]:
    """``(a', W)``: the chart velocity of hinge velocities ``V`` and the hinges' tangent velocities ``W = J a'``.

    Parameters
    ----------
    a
        Chart parameters ``(phi_n, ..., phi_4, t)`` (heyoka variables), ``n >= 3``.
    V
        Velocities of the hinges ``p_1 .. p_{n-1}`` in the chart's frame (:class:`~manifold.backends.Cx`).
    L, rods
        The base and the links, as for :func:`charts.suspension_formula.chain_vectors`.
    ops
        The heyoka backend (:class:`manifold.backends.HeyokaOps`); the formula's values are built on jets over it,
        as the chart's own jets build them.

    Returns
    -------
    a_dot
        ``a'`` in the order of ``a``.
    W
        ``J a'`` as the velocities of ``p_1 .. p_{n-1}``: ``V``'s part along the chart.
    """
    jets = JetOps(ops)
    base: Base = top_base(len(a) + 2, L, rods)
    frame: Cx | None = None  # the level's frame F, value parts
    frame_jets: Cx | None = None  # the same as the chart's jets build it
    rate: Any = 0  # D' of the level's base
    spin: Any = 0  # Omega, the turning rate of F
    a_dot: list[Any] = []
    outer: list[Cx] = []
    for phi in a[:-1]:
        phi_jet = Jet(phi, [], 0, 0)
        theta_jet, inner = base.peel(phi_jet, jets)
        w_jet = last_hinge(base, theta_jet, jets)
        w, theta, l = _values(w_jet), _value(theta_jet), base.last
        sin_theta, cos_theta = ops.sin(theta), ops.cos(theta)
        seen = _relative(frame, spin, V[base.m - 2], w, Cx(rate, 0))  # w' - D'
        theta_dot = _minus(_product(sin_theta, seen.re), _product(cos_theta, seen.im))
        theta_dot = theta_dot if is_one(l) else theta_dot / l
        sin_phi, cos_phi = ops.sin(phi), ops.cos(phi)
        alpha = _value(base.alpha(jets))
        # numerical trap: alpha cos(phi) vanishes at a pole of this level, the chart's singular set (its quality
        # event switches before it); alpha' grows like 1 / sqrt(hi) near an outer pole, where D' vanishes with it
        shift = 0 if is_zero(rate) else _value(base.alpha_rate(jets)) * rate * sin_phi
        a_dot.append(_minus(theta_dot, shift) / (alpha * cos_phi))
        swing = _product(l, theta_dot)
        w_dot = Cx(plus(rate, swing * sin_theta), -(swing * cos_theta))
        outer.append(_moving(frame, spin, w, w_dot))
        d = _value(inner.D)
        rate, spin = w.dot(w_dot) / d, plus(spin, w.cross(w_dot) / (d * d))
        base = inner
        turn = w_jet.scale(1 / base.D)
        frame_jets = turn if frame_jets is None else frame_jets * turn
        frame = _values(frame_jets)
    if isinstance(base.D, Jet):
        base = Base(_seeded(base.D, rate), _seeded(base.lo, rate), _seeded(base.hi, _minus(0, rate)), base.m,
                    base.rods)
    hinges = circle_level(base, Jet(a[-1], [1], 0, 0), jets)[:2]
    along = [Cx(_in_t(h.re), _in_t(h.im)) for h in hinges]  # d p / dt in the level's frame
    moved = [Cx(_along_base(h.re), _along_base(h.im)) for h in hinges]  # with t' = 0
    w_s = [_values(h) for h in hinges]
    num, den = 0, 0
    for g, m, w, v in zip(along, moved, w_s, V):  # p_1 and p_2
        num, den = plus(num, g.dot(_relative(frame, spin, v, w, m))), plus(den, g.abs2())
    t_dot = num / den  # numerical trap: den vanishes only where the circle level's own derivative does (a fold)
    a_dot.append(t_dot)
    circle = [_moving(frame, spin, w, Cx(plus(m.re, t_dot * g.re), plus(m.im, t_dot * g.im)))
              for g, m, w in zip(along, moved, w_s)]
    return a_dot, circle + outer[::-1]


def _in_t(x: Any) -> Any:
    """The ``t`` derivative of a circle-level jet (0 for a constant)."""
    return x.g[0] if isinstance(x, Jet) else 0


def _along_base(x: Any) -> Any:
    """The rate of a circle-level jet along its base's motion, ``t`` held (0 for a constant)."""
    return x.d1 if isinstance(x, Jet) else 0
