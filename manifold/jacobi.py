"""Jacobi fields along a constrained geodesic, as a :class:`~manifold.carried.CarriedTerm`.

A Jacobi field is the linearised geodesic flow: for a family of geodesics
``x(t, s)``, ``J = dx/ds`` and ``U = dv/ds`` solve the variational equations
of the geodesic equations ``x' = v``, ``v' = f(x, v)``:

.. math::

    J' = U, \\qquad U' = \\frac{d}{de} f(x + e J, v + e U) \\Big|_{e = 0},

written in forward mode (a few times the cost of ``f``).  The covariant
derivative is the tangential part of ``U``, ``D_t J = P U`` with
``P = I - K^{-1} G^T M^{-1} G``.  A start ``(J(0), D_t J(0))`` tangent at
``x(0)`` needs the normal part that keeps the linearised tangency
``G U + (dG[J]) v = 0``:

.. math::

    U(0) = D_t J(0) - K^{-1} G^T M^{-1} \\bigl(v^T \\nabla^2 c\\, J(0)\\bigr).

The Baumgarte terms of ``f`` vanish to first order along such variations, so
the fields are those of the unstabilised flow; off it they damp the
linearised drift as they damp the geodesic's.

Checked at every step: ``<D_t J, v>_K`` is constant (the tangential part of a
Jacobi field is ``(a t + b) v``), and for two fields the symplectic form
``<D_t J_1, J_2>_K - <J_1, D_t J_2>_K``.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import TYPE_CHECKING

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .carried import CarriedTerm
from .precision import as_fp
from .validation import check_bool, real_array

if TYPE_CHECKING:
    from .constrained import ConstrainedGeometry, ConstrainedPieces

__all__ = ["JacobiField"]


class JacobiField(CarriedTerm):
    """Jacobi fields along the geodesic, from their values and covariant derivatives at the start.

    Parameters
    ----------
    fields, derivatives
        ``J(0)`` and ``D_t J(0)``, shape ``(N,)`` or ``(k, N)`` each (the same);
        tangent at the start (their normal parts are projected away in the
        working precision).
    checked
        Whether the solve checks the invariants ``<D_t J, v>`` and ``<D_t J_a, J_b> - <J_a, D_t J_b>`` (default).
        Off for fields that measure a strong growth (:func:`linkage.sensitivity.sensitivity`): the invariants
        cancel products of fields grown ``A``-fold, and lose digits with ``A`` where the fields themselves keep
        their relative accuracy.
    """

    name = "Jacobi field"

    def __init__(self, fields: ArrayLike, derivatives: ArrayLike, checked: bool = True) -> None:
        self.checked = check_bool("checked", checked)
        j, w = real_array("fields", fields), real_array("derivatives", derivatives)
        if j.ndim not in (1, 2) or j.size == 0 or j.shape != w.shape:
            raise ValueError(f"fields and derivatives must have one shape, (N,) or (k, N) with k >= 1, got {j.shape} "
                             f"and {w.shape}")
        self.fields, self.derivatives = np.atleast_2d(j), np.atleast_2d(w)

    def __repr__(self) -> str:
        return f"JacobiField({len(self.fields)} fields)"

    @property
    def key(self) -> Hashable:
        return ("Jacobi field", len(self.fields))

    def size(self, N: int) -> int:
        return 2 * len(self.fields) * N

    def equations(self, pieces: ConstrainedPieces, y: list[hy.expression], stabilised: bool) -> list[hy.expression]:
        N = len(pieces.x)
        acceleration = [rhs for _, rhs in pieces.equations(stabilised)[N:]]
        e = hy.expression("jacobi_e")
        out = []
        for a in range(len(self.fields)):
            J, U = y[2 * a * N : (2 * a + 1) * N], y[(2 * a + 1) * N : (2 * a + 2) * N]
            shift = {str(xi): xi + e * ji for xi, ji in zip(pieces.x, J)}
            shift.update({str(vi): vi + e * ui for vi, ui in zip(pieces.v, U)})
            shifted = hy.subs(acceleration, shift)
            out += list(U) + hy.subs([hy.diff(g, e) for g in shifted], {"jacobi_e": hy.expression(pieces.fp(0))})
        return out

    def start(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray) -> NDArray:
        N, k = geometry.N, len(self.fields)
        if self.fields.shape[1] != N:
            raise ValueError(f"fields and derivatives must have {N} entries each, got shape {self.fields.shape}")
        X, V = np.repeat(x[None, :], k, axis=0), np.repeat(v[None, :], k, axis=0)
        J = geometry.tangent(X, as_fp(self.fields, geometry.fp))
        U = geometry.tangent(X, as_fp(self.derivatives, geometry.fp))
        U = U + geometry(X, V, -geometry.bilinear(X, V, J))[2]  # the normal part: G U = -(dG[J]) v
        return np.concatenate([J, U], axis=1).ravel()

    def _pairs(self, y: NDArray, N: int) -> tuple[NDArray, NDArray]:
        JU = y.reshape(y.shape[0], len(self.fields), 2, N)
        return JU[:, :, 0], JU[:, :, 1]

    def invariants(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray,
                   y: NDArray) -> tuple[NDArray, NDArray]:
        if not self.checked:
            return np.zeros((len(y), 0)), np.zeros((len(y), 0))
        J, U = self._pairs(y, geometry.N)
        KU, KJ = U @ geometry.K, J @ geometry.K
        along = np.sum(KU * v[:, None, :], axis=-1)  # <U, v> = <D_t J, v> for a tangent v
        speed = np.sqrt(np.abs(geometry.inner(v, v).astype(float)))
        size_U = np.sqrt(np.abs(np.sum(KU * U, axis=-1).astype(float)))
        size_J = np.sqrt(np.abs(np.sum(KJ * J, axis=-1).astype(float)))
        a, b = np.triu_indices(len(self.fields), 1)
        omega = (KU[:, a] * J[:, b] - KJ[:, a] * U[:, b]).sum(axis=-1)
        values = np.concatenate([along, omega], axis=1)
        scales = np.concatenate([size_U * speed[:, None], size_U[:, a] * size_J[:, b] + size_J[:, a] * size_U[:, b]],
                                axis=1)
        return values, scales

    def read(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray, y: NDArray) -> dict[str, NDArray]:
        J, U = self._pairs(y, geometry.N)
        B, k, N = U.shape
        DJ = geometry.tangent(np.repeat(x, k, axis=0), U.reshape(B * k, N)).reshape(B, k, N)
        return {"field": J, "field_derivative": DJ}
