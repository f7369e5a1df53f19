"""Abstract chart of an embedded manifold.

A chart maps parameters ``a`` (shape ``(..., dim)``) to points ``p`` of the
embedding space ``R^N`` (shape ``(..., N)``).  Vocabulary follows Manifolds.jl:
``get_point`` is the chart map, ``get_parameters`` its inverse.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
from numpy.typing import ArrayLike, NDArray


class ChartDomainError(ValueError):
    """Raised when parameters lie outside a chart or a point is not in its image."""


class Chart(ABC):
    """A local parametrisation ``a -> p`` of a ``dim``-manifold in ``R^ambient_dim``.

    Subclasses implement the map, its inverse, its Jacobian and a quality
    function.  All methods accept a single point or a batch (leading axes).
    """

    #: manifold dimension (number of parameters)
    dim: int
    #: dimension of the embedding space
    ambient_dim: int

    @abstractmethod
    def get_point(self, a: ArrayLike) -> NDArray:
        """Point ``p(a)`` in the embedding space, shape ``(..., ambient_dim)``."""

    @abstractmethod
    def get_parameters(self, p: ArrayLike) -> NDArray:
        """Inverse of :meth:`get_point`, shape ``(..., dim)``."""

    @abstractmethod
    def raw_jacobian(self, a: ArrayLike) -> NDArray:
        """``J = dp/da``, shape ``(..., ambient_dim, dim)``; non-finite on the singular set."""

    def jacobian(self, a: ArrayLike) -> NDArray:
        """``J = dp/da``, shape ``(..., ambient_dim, dim)``.

        Raises :class:`ChartDomainError` where the chart is singular (the
        derivative does not exist there).
        """
        J = self.raw_jacobian(a)
        bad = ~np.all(np.isfinite(J), axis=(-2, -1))
        if np.any(bad):
            where = np.asarray(a)[bad] if np.ndim(bad) else np.asarray(a)
            raise ChartDomainError(f"{self!r} is singular at parameters {where}: no Jacobian there")
        return J

    @abstractmethod
    def quality(self, a: ArrayLike) -> NDArray:
        """Chart quality in ``[0, 1]``: 0 on the singular set, 1 far from it."""

    def tangent_vector(self, a: ArrayLike, c: ArrayLike) -> NDArray:
        """Embedded tangent vector ``v = J(a) c`` of coefficients ``c``."""
        return _apply(self.jacobian(a), c)

    def coefficients(self, a: ArrayLike, v: ArrayLike) -> NDArray:
        """Coefficients ``c`` with ``J(a) c = v`` for a tangent vector ``v``.

        Least squares through the pseudo-inverse (exact for tangent ``v``; no
        normal equations, which would square the condition number of ``J``).
        Use :meth:`tangent_residual` to check tangency.
        """
        return _apply(np.linalg.pinv(self.jacobian(a)), v)

    def tangent_residual(self, a: ArrayLike, v: ArrayLike) -> NDArray:
        """``|v - J c| / |v|`` with ``c`` the least-squares coefficients: 0 iff tangent."""
        v = np.asarray(v, dtype=float)
        r = v - self.tangent_vector(a, self.coefficients(a, v))
        scale = np.maximum(np.linalg.norm(v, axis=-1), np.finfo(float).tiny)
        return np.linalg.norm(r, axis=-1) / scale

    def refine_parameters(self, a: ArrayLike, p: ArrayLike, steps: int = 2) -> NDArray:
        """Polish approximate parameters ``a`` of point ``p`` by Gauss-Newton steps.

        ``a <- a + J^+ (p - get_point(a))``, a step being kept only where it does
        not increase the residual.  A closed-form inverse that goes through
        ill-conditioned intermediates (as near a chart's singular set) is so
        brought to the accuracy the forward map allows.
        """
        a = np.array(a, dtype=float)
        p = np.asarray(p, dtype=float)
        res = np.linalg.norm(p - self.get_point(a), axis=-1)
        for _ in range(steps):
            J = self.raw_jacobian(a)
            regular = np.all(np.isfinite(J), axis=(-2, -1))
            J = np.where(regular[..., None, None], J, 0.0)  # singular points: zero step
            step = _apply(np.linalg.pinv(J), p - self.get_point(a))
            trial = self.clamp_parameters(a + step)
            res_trial = np.linalg.norm(p - self.get_point(trial), axis=-1)
            better = res_trial <= res
            a = np.where(better[..., None], trial, a)
            res = np.where(better, res_trial, res)
        return a

    def clamp_parameters(self, a: NDArray) -> NDArray:
        """Bring parameters just outside the domain (by rounding) back into it; identity by default."""
        return a


def _apply(M: NDArray, v: ArrayLike) -> NDArray:
    """Batched matrix-vector product ``M v``."""
    return np.einsum("...ij,...j->...i", M, np.asarray(v, dtype=M.dtype))
