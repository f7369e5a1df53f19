"""Riemannian metric induced on an atlas by a constant ambient metric ``K``.

In chart ``i`` at parameters ``a`` the local metric is ``g = J^T K J`` with
``J = d p / d a``; the kinetic energy of coefficients ``c`` is
``E = 1/2 c^T g c = 1/2 v^T K v`` with ``v = J c``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .atlas import Atlas


class InducedMetric:
    """Metric ``g = J^T K J`` on every chart of ``atlas``.

    Parameters
    ----------
    atlas
        The atlas whose charts are pulled back.
    K
        Symmetric positive definite ``(N, N)`` matrix on the embedding space
        ``R^N``, ``N = atlas.ambient_dim``.
    """

    def __init__(self, atlas: Atlas, K: ArrayLike) -> None:
        K = np.asarray(K, dtype=float)
        N = atlas.ambient_dim
        if K.shape != (N, N):
            raise ValueError(f"K must have shape ({N}, {N}), got {K.shape}")
        if not np.all(np.isfinite(K)):
            raise ValueError("K must be finite")
        if not np.allclose(K, K.T, rtol=0, atol=1e-14 * np.abs(K).max()):
            raise ValueError("K must be symmetric")
        if np.linalg.eigvalsh(K).min() <= 0:
            raise ValueError(f"K must be positive definite, smallest eigenvalue {np.linalg.eigvalsh(K).min():g}")
        self.atlas = atlas
        self.K = K

    def local_metric(self, i: int, a: ArrayLike) -> NDArray:
        """``g_i(a) = J^T K J``, shape ``(..., dim, dim)``."""
        J = self.atlas.charts[i].jacobian(a)
        return np.einsum("...ki,kl,...lj->...ij", J, self.K, J)

    def inner(self, i: int, a: ArrayLike, X: ArrayLike, Y: ArrayLike) -> NDArray:
        """``X^T g_i(a) Y`` for coefficient vectors ``X``, ``Y``."""
        return np.einsum("...i,...ij,...j->...", np.asarray(X), self.local_metric(i, a), np.asarray(Y))

    def norm(self, i: int, a: ArrayLike, X: ArrayLike) -> NDArray:
        """``sqrt(X^T g_i(a) X)``."""
        return np.sqrt(self.inner(i, a, X, X))

    def kinetic_energy(self, i: int, a: ArrayLike, c: ArrayLike) -> NDArray:
        """``1/2 c^T g_i(a) c``."""
        return 0.5 * self.inner(i, a, c, c)

    def ambient_kinetic_energy(self, v: ArrayLike) -> NDArray:
        """``1/2 v^T K v`` for an embedded velocity ``v``."""
        v = np.asarray(v)
        return 0.5 * np.einsum("...i,ij,...j->...", v, self.K, v)
