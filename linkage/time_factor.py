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
positive factor gives the same motion; the README's example, rod densities 0.2,
still takes 23 % fewer steps with it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from manifold.sundman import TimeFactor

from .chain import Chain
from .rods import rod_vectors


def multiplier_determinant(rods: Sequence[tuple[Any, Any]], alpha: Sequence[Any], beta: Sequence[Any],
                           gamma: Sequence[Any]) -> Any:
    """``theta_n`` of the module docstring for rods ``(x, y)`` (numbers, arrays or heyoka expressions).

    ``alpha = (w_1^2, ..., w_{n-1}^2)``, ``beta = (w_2 |e_3|^2, ..., w_{n-1} |e_n|^2)`` and
    ``gamma = (w_1 |e_1|^2, ..., w_{n-2} |e_{n-2}|^2)`` (``w_k`` the weight of the hinge between rods
    ``k`` and ``k + 1``); only these enter (``F_1 = 0``, and ``theta_{n-1}`` is not needed).
    """
    n = len(rods)
    theta: list[Any] = [1, gamma[0] if n > 2 else None]
    F: Any = None  # F_1 = 0
    for k in range(2, n + 1):
        (ax, ay), (bx, by) = rods[k - 2], rods[k - 1]
        cross = ax * by - ay * bx
        lagrange = alpha[k - 2] * (cross * cross)  # a square: half the Taylor recursion of a product
        F = lagrange if F is None else lagrange * theta[k - 2] + beta[k - 3] * F
        if k == n:
            return F
        theta.append(gamma[k - 1] * theta[k - 1] + F if k < n - 1 else None)
    raise ValueError(f"rods must hold at least 2 rod vectors, got {n}")


class ChainTimeFactor(TimeFactor):
    """``det(G K^-1 G^T)`` of ``chain`` (module docstring), for :class:`manifold.sundman.SundmanStepper`.

    Parameters ``kappa``: ``L``, then ``alpha`` (``n - 1``), ``beta`` and ``gamma`` (``n - 2`` each) of
    :func:`multiplier_determinant`, from the chain's lengths and the diagonal of its metric, made
    dimensionless by ``c = mean(w) mean(l^2)``: the factor is ``det M / c^n``, of order 1 on ordinary
    configurations whatever the chain's size and masses (its Taylor coefficients in ``tau`` scale like
    its ``k``-th power: with hinge masses 1e-4 or 1e6, or rods of 0.01, the raw ``det M`` overflowed).
    """

    def __init__(self, chain: Chain) -> None:
        if not isinstance(chain, Chain):
            raise TypeError(f"chain must be a linkage.Chain, got {type(chain).__name__}")
        self.n = chain.n
        self.ambient_dim = 2 * (chain.n - 1)
        self.n_params = 3 * chain.n - 4
        K = np.asarray(chain.ambient_metric, dtype=float)
        w = 1.0 / np.diag(K)[::2]  # hinge k = 1..n-1
        l2 = np.asarray(chain.lengths, dtype=float) ** 2
        w, scale = w / np.mean(w), np.mean(l2)  # the crosses in alpha's terms carry l^4: alpha / scale^2
        l2 = l2 / scale
        self._values = np.concatenate([[chain.L], w * w / scale**2, w[1:] * l2[2:], w[:-1] * l2[:-2]])

    @property
    def key(self) -> tuple:
        return ("chain multiplier determinant", self.n)

    def __repr__(self) -> str:
        return f"ChainTimeFactor(n={self.n})"

    def expression(self, p: Sequence[Any], pars: Sequence[Any]) -> Any:
        n = self.n
        rods = [(e.re, e.im) for e in rod_vectors(p, pars[0])]  # pinned at 0 and (L, 0)
        return multiplier_determinant(rods, pars[1:n], pars[n:2 * n - 2], pars[2 * n - 2:3 * n - 4])

    def parameters(self) -> NDArray:
        return self._values.copy()
