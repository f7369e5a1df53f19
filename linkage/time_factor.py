r"""The chain's factor for Sundman's time: ``det M`` of its rod constraints, as a sum of non-negative terms.

For a planar chain pinned at ``0`` and ``L`` with rods ``e_k = p_k - p_{k-1}``
(``k = 1..n``) and hinge weights ``w_k = 1 / m_k`` (``K^-1 = diag(w) (x) I_2``),
the rows ``e_k`` (on hinge ``k``) and ``-e_k`` (on hinge ``k-1``) of the
constraints' Jacobian give the tridiagonal ``M = G K^-1 G^T``.  Its continuant,
with Lagrange's identity ``|a|^2 |b|^2 - (a . b)^2 = (a x b)^2`` (as in the hinge
method's pivots, :meth:`linkage.constraints.ChainSystem.multiplier_pivots`), is

.. math::

    \theta_k = w_k |e_k|^2 \theta_{k-1} + F_k, \qquad
    F_k = w_{k-1}^2 (e_{k-1} \times e_k)^2 \theta_{k-2} + w_{k-1} |e_k|^2 F_{k-1},

``theta_0 = 1``, ``theta_1 = w_1 |e_1|^2``, ``F_1 = 0``, and ``det M = theta_n = F_n``
(the last rod ends at a pin).  No division, no cancellation: it stays positive
off the singular configurations, and is 0 on them.  On the chart path the state
is on the constraints, so ``|e_k|^2 = l_k^2`` enter as parameters.  With rod
densities ``K^-1`` is dense; the factor then uses the diagonal of ``K`` (any
positive factor gives the same motion; this one was not measured there).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from manifold.sundman import TimeFactor

from .chain import Chain


def multiplier_determinant(rods: Sequence[tuple[Any, Any]], alpha: Sequence[Any], beta: Sequence[Any],
                           gamma: Sequence[Any]) -> Any:
    """``theta_n`` of the module docstring for rods ``(x, y)`` (numbers, arrays or heyoka expressions).

    ``alpha[k] = w_k^2``, ``beta[k] = w_k |e_{k+1}|^2`` (``k = 1..n-1``: the hinge between rods ``k``
    and ``k + 1``) and ``gamma[k] = w_k |e_k|^2`` (``k = 1..n-1``); index 0 of each is unused.
    """
    n = len(rods)
    theta = [1, gamma[1]]
    F: Any = None  # F_1 = 0
    for k in range(2, n + 1):
        (ax, ay), (bx, by) = rods[k - 2], rods[k - 1]
        cross = ax * by - ay * bx
        lagrange = alpha[k - 1] * (cross * cross)  # a square: half the Taylor recursion of a product
        F = lagrange if F is None else lagrange * theta[k - 2] + beta[k - 1] * F
        theta.append(F if k == n else gamma[k] * theta[k - 1] + F)
    return theta[n]


class ChainTimeFactor(TimeFactor):
    """``det(G K^-1 G^T)`` of ``chain`` (module docstring), for :class:`manifold.sundman.SundmanStepper`.

    Parameters ``kappa``: ``L``, then ``alpha``, ``beta``, ``gamma`` (``n - 1`` each) of
    :func:`multiplier_determinant`, from the chain's lengths and the diagonal of its metric.
    """

    def __init__(self, chain: Chain) -> None:
        if not isinstance(chain, Chain):
            raise TypeError(f"chain must be a linkage.Chain, got {type(chain).__name__}")
        self.n = chain.n
        self.n_params = 3 * chain.n - 2
        K = np.asarray(chain.ambient_metric, dtype=float)
        w = 1.0 / np.diag(K)[::2]  # hinge k = 1..n-1
        l2 = np.asarray(chain.lengths, dtype=float) ** 2
        self._values = np.concatenate([[chain.L], w * w, w * l2[1:], w * l2[:-1]])

    @property
    def key(self) -> tuple:
        return ("chain multiplier determinant", self.n)

    def __repr__(self) -> str:
        return f"ChainTimeFactor(n={self.n})"

    def expression(self, p: Sequence[Any], pars: Sequence[Any]) -> Any:
        n = self.n
        ends = [(0.0, 0.0)] + [(p[2 * j], p[2 * j + 1]) for j in range(n - 1)] + [(pars[0], 0.0)]
        rods = [(b[0] - a[0], b[1] - a[1]) for a, b in zip(ends[:-1], ends[1:])]
        rods[0] = (p[0], p[1])  # from the pin at 0: no "- 0" in the expressions
        rods[-1] = (pars[0] - p[2 * n - 4], -p[2 * n - 3])

        def row(start: int) -> list:
            return [None] + [pars[start + j] for j in range(n - 1)]

        return multiplier_determinant(rods, row(1), row(n), row(2 * n - 1))

    def parameters(self) -> NDArray:
        return self._values.copy()
