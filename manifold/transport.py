"""Parallel transport along a constrained geodesic, as a :class:`~manifold.carried.CarriedTerm`.

A vector field ``W`` along the geodesic ``x(t)`` of ``{c(x) = 0}`` in
``(R^N, K)`` is parallel when its derivative is normal, ``W' = K^{-1} G^T mu``.
Differentiating ``G W = 0`` gives ``G W' = -(dG/dt) W``, so

.. math::

    W' = -K^{-1} G^T M^{-1} \\bigl((dG/dt)\\,W + \\alpha\\, G W\\bigr), \\qquad M = G K^{-1} G^T,

with ``((dG/dt) W)_k = v^T (nabla^2 c_k) W``, the geodesic's own acceleration
with one ``v`` replaced by ``W``.  The term ``alpha G W`` (``alpha`` the
geodesic's Baumgarte rate) is zero on the exact solution and damps rounding's
drift of ``W`` off the tangent space: ``(G W)' = -alpha G W``.

Transport is an isometry: the Gram matrix of the carried vectors and the
velocity in ``K`` is constant, and it is checked at every step.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import TYPE_CHECKING

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .carried import CarriedTerm
from .precision import as_fp
from .validation import real_array

if TYPE_CHECKING:
    from .constrained import ConstrainedGeometry, ConstrainedPieces

__all__ = ["ParallelTransport"]


class ParallelTransport(CarriedTerm):
    """Tangent vectors transported along the geodesic.

    Parameters
    ----------
    vectors
        The vectors at the start, shape ``(N,)`` or ``(k, N)``; their tangential
        parts are transported (a normal part is projected away in the working
        precision: check tangency before, as the callers in ``linkage`` do).
    """

    name = "parallel transport"

    def __init__(self, vectors: ArrayLike) -> None:
        w = real_array("vectors", vectors)
        if w.ndim not in (1, 2) or w.shape[-1] == 0 or w.size == 0:
            raise ValueError(f"vectors must have shape (N,) or (k, N) with k >= 1, got {w.shape}")
        self.vectors = np.atleast_2d(w)

    def __repr__(self) -> str:
        return f"ParallelTransport({len(self.vectors)} vectors)"

    @property
    def key(self) -> Hashable:
        return ("parallel transport", len(self.vectors))

    def size(self, N: int) -> int:
        return len(self.vectors) * N

    def equations(self, pieces: ConstrainedPieces, y: list[hy.expression], stabilised: bool) -> list[hy.expression]:
        N, out = len(pieces.x), []
        for a in range(len(self.vectors)):
            W = y[a * N : (a + 1) * N]
            turn = pieces.bilinear(W)
            if stabilised:
                turn = [h + hy.par[0] * gw for h, gw in zip(turn, pieces.rates(W))]
            out += pieces.correction([-r for r in turn])
        return out

    def start(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray) -> NDArray:
        N = geometry.N
        if self.vectors.shape[1] != N:
            raise ValueError(f"vectors must have {N} entries each, got shape {self.vectors.shape}")
        W = as_fp(self.vectors, geometry.fp)
        return geometry.tangent(np.repeat(x[None, :], len(W), axis=0), W).ravel()

    def _vectors(self, y: NDArray, N: int) -> NDArray:
        return y.reshape(y.shape[0], len(self.vectors), N)

    def invariants(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray,
                   y: NDArray) -> tuple[NDArray, NDArray]:
        # the Gram matrix of (W_1, ..., W_k, v): each entry judged relative to the product of the two norms
        F = np.concatenate([self._vectors(y, geometry.N), v[:, None, :]], axis=1)
        gram = (F @ geometry.K) @ F.transpose(0, 2, 1)
        norms = np.sqrt(np.abs(np.diagonal(gram, axis1=1, axis2=2).astype(float)))
        i, j = np.triu_indices(F.shape[1])
        return gram[:, i, j], (norms[:, :, None] * norms[:, None, :])[:, i, j]

    def read(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray, y: NDArray) -> dict[str, NDArray]:
        return {"vectors": self._vectors(y, geometry.N)}
