r"""The rods of a chain and their constraints, written once for numpy numbers and heyoka expressions.

A chain pinned at ``p_0 = 0`` and ``p_n = (L, 0)`` with interior hinges
``p_1 .. p_{n-1}``, given as interleaved real coordinates
``x = (x_1, y_1, ..., x_{n-1}, y_{n-1})``, has the rods

.. math::

    e_1 = p_1, \qquad e_k = p_k - p_{k-1}, \qquad e_n = (L, 0) - p_{n-1},

and, with ``q_k = 1 / l_k^2`` (the rod lengths ``l_k``), the relative constraints and what the
hinge methods need of them:

.. math::

    c_k = q_k |e_k|^2 - 1, \qquad g_k = 2 q_k e_k, \qquad
    (G v)_k = 2 q_k\, e_k \cdot e_k', \qquad (\dot G v)_k = 2 q_k |e_k'|^2 ,

where row ``k`` of ``G = dc/dx`` is ``g_k`` on hinge ``k`` and ``-g_k`` on hinge ``k - 1`` (the pins do
not move, so ``e_k'`` are the rods of the hinge velocities with both pins at ``0``).

The functions take sequences of numbers (numpy scalars or arrays of one batch shape: float64 for
:class:`linkage.constraints.HingeConstraints`) or of heyoka expressions (the integrators of
:class:`linkage.constraints.ChainSystem`), and a rod is a :class:`manifold.backends.Cx` pair.  Only
``+``, ``-`` and ``*`` occur, so both evaluate the same formula in the same order: the numpy and the
compiled code of the rods agree to rounding, and a change to one is a change to both.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from manifold.backends import Cx

__all__ = ["constraint_rates", "gradients", "relative_residuals", "rod_vectors", "velocity_terms"]


def rod_vectors(x: Sequence[Any], L: Any) -> list[Cx]:
    """The rods ``e_1 .. e_n`` of the interleaved hinge coordinates ``x`` (``2(n-1)`` entries), pins ``0`` and ``L``.

    The rods' rates ``e_k'`` are the rods of the hinge velocities with ``L = 0`` (pins at rest).
    """
    hinges = [Cx(x[2 * j], x[2 * j + 1]) for j in range(len(x) // 2)]
    last = hinges[-1]
    return [hinges[0], *(b - a for a, b in zip(hinges, hinges[1:])), Cx(L - last.re, -last.im)]


def relative_residuals(rods: Sequence[Cx], q: Sequence[Any], one: Any) -> list[Any]:
    """``c_k = q_k |e_k|^2 - 1`` with ``q_k = 1 / l_k^2``; ``one`` the constant ``1`` of the working precision."""
    return [e.abs2() * qk - one for e, qk in zip(rods, q)]


def gradients(rods: Sequence[Cx], q: Sequence[Any]) -> list[Cx]:
    """``g_k = 2 q_k e_k = dc_k / dp_k`` (and ``-g_k = dc_k / dp_{k-1}``)."""
    return [Cx(qk * (2.0 * e.re), qk * (2.0 * e.im)) for e, qk in zip(rods, q)]


def constraint_rates(rods: Sequence[Cx], rates: Sequence[Cx], q: Sequence[Any]) -> list[Any]:
    """``(G v)_k = 2 q_k e_k . e_k'``: the rate of change of ``c_k`` (two products per rod; the rows of ``G`` take
    four)."""
    return [qk * (2.0 * e.dot(d)) for e, d, qk in zip(rods, rates, q)]


def velocity_terms(rates: Sequence[Cx], q: Sequence[Any]) -> list[Any]:
    """``(dG/dt) v = 2 q_k |e_k'|^2``: what the constraints' second derivative adds to ``G x''``."""
    return [qk * (2.0 * d.abs2()) for d, qk in zip(rates, q)]
