"""Abstract chart of an embedded manifold.

A chart maps parameters ``a`` (shape ``(..., dim)``) to points ``p`` of the
embedding space ``R^N`` (shape ``(..., N)``).  Vocabulary follows Manifolds.jl:
``get_point`` is the chart map, ``get_parameters`` its inverse.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .validation import real_array


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

    def raw_hessian(self, a: ArrayLike) -> NDArray:
        """``H = d^2 p / da_i da_j``, shape ``(..., ambient_dim, dim, dim)``; non-finite on the singular set.

        Needed for curvature only; the base class has no second derivatives
        (:class:`~manifold.symbolic.SymbolicChart` derives them from its family).
        """
        raise NotImplementedError(f"{type(self).__name__} provides no second derivatives (raw_hessian); curvature needs them")

    def hessian(self, a: ArrayLike) -> NDArray:
        """``H = d^2 p / da_i da_j``, shape ``(..., ambient_dim, dim, dim)``; :class:`ChartDomainError` where singular."""
        H = self.raw_hessian(a)
        bad = ~np.all(np.isfinite(H), axis=(-3, -2, -1))
        if np.any(bad):
            where = np.asarray(a)[bad] if np.ndim(bad) else np.asarray(a)
            raise ChartDomainError(f"{self!r} is singular at parameters {where}: no second derivatives there")
        return H

    @abstractmethod
    def quality(self, a: ArrayLike) -> NDArray:
        """Chart quality in ``[0, 1]``: 0 on the singular set, 1 far from it."""

    def tangent_vector(self, a: ArrayLike, c: ArrayLike) -> NDArray:
        """Embedded tangent vector ``v = J(a) c`` of coefficients ``c`` (shape ``(..., dim)``)."""
        c = real_array("c", c)
        if c.ndim == 0 or c.shape[-1] != self.dim:
            raise ValueError(f"c must hold the {self.dim} coefficients of a tangent vector on its last axis, "
                             f"got shape {c.shape}")
        return _apply(self.jacobian(a), c)

    def coefficients(self, a: ArrayLike, v: ArrayLike) -> NDArray:
        """Coefficients ``c`` with ``J(a) c = v`` for a tangent vector ``v``.

        Least squares through the pseudo-inverse (exact for tangent ``v``; no
        normal equations, which would square the condition number of ``J``).
        Use :meth:`tangent_residual` to check tangency.
        """
        v = real_array("v", v)
        if v.ndim == 0 or v.shape[-1] != self.ambient_dim:
            raise ValueError(f"v must be an embedded vector of R^{self.ambient_dim} on its last axis, got shape {v.shape}")
        return _apply(np.linalg.pinv(self.jacobian(a)), v)

    def tangent_residual(self, a: ArrayLike, v: ArrayLike) -> NDArray:
        """``|v - J c| / |v|`` with ``c`` the least-squares coefficients: 0 iff tangent."""
        v = np.asarray(v, dtype=float)
        r = v - self.tangent_vector(a, self.coefficients(a, v))
        scale = np.maximum(np.linalg.norm(v, axis=-1), np.finfo(float).tiny)
        return np.linalg.norm(r, axis=-1) / scale

    def point_and_jacobian(self, a: ArrayLike) -> tuple[NDArray, NDArray]:
        """``get_point(a)`` and ``raw_jacobian(a)`` (charts that compute both in one evaluation override this)."""
        return self.get_point(a), self.raw_jacobian(a)

    def refine_parameters(self, a: ArrayLike, p: ArrayLike, steps: int = 2) -> NDArray:
        """Polish approximate parameters ``a`` of point ``p`` by Gauss-Newton steps ``a <- a + J^+ (p - get_point(a))``.

        A closed-form inverse that goes through ill-conditioned intermediates
        (as near a chart's singular set) is so brought to the accuracy the
        forward map allows (see :func:`gauss_newton`).  Each trial's point and
        Jacobian come from one :meth:`point_and_jacobian`; the Jacobian serves
        the next step when the trial is kept.
        """
        last: dict = {}

        def point(x: NDArray) -> NDArray:
            z, last["J"] = self.point_and_jacobian(x)
            last["x"] = x
            return z

        def solve(x: NDArray, r: NDArray) -> NDArray:
            J = last["J"] if np.array_equal(x, last["x"]) else self.raw_jacobian(x)
            regular = np.all(np.isfinite(J), axis=(-2, -1))
            J = np.where(regular[..., None, None], J, 0.0)  # singular points: zero step
            return _apply(np.linalg.pinv(J), r)

        return gauss_newton(np.array(a, dtype=float), np.asarray(p, dtype=float), point, solve,
                            max_steps=steps, clamp=self.clamp_parameters)

    def approximate_parameters(self, p: ArrayLike) -> NDArray:
        """The inverse before its polish: ``get_parameters(p) = polish_parameters(approximate_parameters(p), p)``.

        A chart whose inverse is a cheap closed form followed by a costlier
        polish (Gauss-Newton steps) overrides both, so that an atlas can rank
        its charts by their quality at these parameters and polish only those
        that can win (:meth:`manifold.atlas.Atlas.best_chart`).  Default:
        :meth:`get_parameters` itself, with nothing left to polish.
        """
        return self.get_parameters(p)

    def polish_parameters(self, a: ArrayLike, p: ArrayLike) -> NDArray:
        """The polish that :meth:`get_parameters` applies to :meth:`approximate_parameters`; the identity by default."""
        return np.asarray(a, dtype=float)

    def clamp_parameters(self, a: NDArray) -> NDArray:
        """Bring parameters just outside the domain (by rounding) back into it; identity by default."""
        return a


def _apply(M: NDArray, v: ArrayLike) -> NDArray:
    """Batched matrix-vector product ``M v``."""
    return np.einsum("...ij,...j->...i", M, np.asarray(v, dtype=M.dtype))


def gauss_newton(a: NDArray, target: NDArray, point: Callable, solve: Callable, *, max_steps: int,
                 step_tol: float = 0.0, clamp: Callable[[NDArray], NDArray] | None = None) -> NDArray:
    """Polish ``a`` so that ``point(a) = target``: steps ``a <- a + solve(a, target - point(a))``.

    Batched over leading axes.  A step is kept only where it does not increase
    the residual ``max |target - point(a)|``; the loop stops after
    ``max_steps`` or once every step is at most ``step_tol * max(1, |a|)``.
    Works in any floating type that ``point`` and ``solve`` return.

    Parameters
    ----------
    a, target
        Start parameters ``(..., k)`` and the point sought ``(..., N)``.
    point, solve
        ``a -> point(a)`` and ``(a, r) -> da`` (e.g. ``J^+ r``).
    clamp
        Maps a trial back into the parameter domain (default: identity).
    """
    z = point(a)
    res = np.max(np.abs(target - z), axis=-1)
    for _ in range(max_steps):
        step = solve(a, target - z)
        trial = a + step if clamp is None else clamp(a + step)
        z_trial = point(trial)
        res_trial = np.max(np.abs(target - z_trial), axis=-1)
        better = np.asarray(res_trial <= res)  # a 0-d comparison of real128 scalars is a Python bool
        a = np.where(better[..., None], trial, a)
        z = np.where(better[..., None], z_trial, z)
        res = np.where(better, res_trial, res)
        size = np.asarray(np.max(np.abs(a), axis=-1)).astype(float)  # convergence judged in float64
        if np.all(np.asarray(np.max(np.abs(step), axis=-1)).astype(float) <= step_tol * np.maximum(1.0, size)):
            break
    return a
