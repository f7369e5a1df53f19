"""Curvature of a submanifold of ``(R^N, K)`` from its second fundamental form (the Gauss equation).

For a chart ``p(a)`` with ``J = dp/da`` and ``H_ab = d^2 p / da_a da_b`` the
second fundamental form is the K-normal part of the second derivative,
``II_ab = H_ab - J Gamma_ab`` (``Gamma_ab = g^{-1} J^T K H_ab``, the
Christoffel symbols), and the Gauss equation gives the Riemann tensor of the
induced metric ``g = J^T K J`` from it alone:

.. math::

    R_{abcd} = \\langle II_{ad}, II_{bc} \\rangle_K - \\langle II_{ac}, II_{bd} \\rangle_K ,

with the sign convention ``R(u, v, v, u) = R_abcd u^a v^b v^c u^d > 0`` on a
round sphere, so that the sectional curvature of the plane of ``u, v`` is
``R(u, v, v, u) / (|u|^2 |v|^2 - <u, v>^2)``.  Only second derivatives of the
chart enter (the intrinsic route through ``d^2 g`` needs third ones).

Everything here works in K-orthonormal ambient coordinates ``y = C p``
(``K = C^T C``, ``C`` the upper Cholesky factor): there ``<x, y>_K`` is the
dot product and the QR factorisation ``C J = Q R`` gives the orthonormal frame
``e_i = J R^{-1} e_i`` of the tangent space.  All functions are batched over
leading axes and work in float64.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def tangent_frame(J: NDArray, C: NDArray) -> tuple[NDArray, NDArray]:
    """``Q, R`` with ``C J = Q R``: ``Q`` ``(..., N, k)`` orthonormal columns spanning ``C T_p``, ``R`` ``(..., k, k)``.

    ``R^T R = g``, and the tangent vectors ``J R^{-1} e_i`` are K-orthonormal.
    """
    return np.linalg.qr(np.einsum("rs,...sk->...rk", C, J))


def second_fundamental_form(Q: NDArray, R: NDArray, H: NDArray, C: NDArray) -> NDArray:
    """``II(e_i, e_j)`` in K-orthonormal ambient coordinates for the frame ``e_i = J R^{-1} e_i``: shape ``(..., N, k, k)``.

    Numerical trap: the normal part ``H - J g^{-1} J^T K H`` through the normal
    equations loses ``cond(J)^2`` digits; the projector ``I - Q Q^T`` of the QR
    factorisation only ``cond(J)``.
    """
    Y = np.einsum("rs,...sab->...rab", C, H)
    normal = Y - np.einsum("...rk,...kab->...rab", Q, np.einsum("...rk,...rab->...kab", Q, Y))
    R_inv = np.linalg.inv(R)  # R is k x k and, in a chart of good quality, well conditioned
    return np.einsum("...rab,...ai,...bj->...rij", normal, R_inv, R_inv)


def frame_riemann(II: NDArray) -> NDArray:
    """``R_ijkl = <II_il, II_jk> - <II_ik, II_jl>`` (the Gauss equation), shape ``(..., k, k, k, k)``."""
    return np.einsum("...ril,...rjk->...ijkl", II, II) - np.einsum("...rik,...rjl->...ijkl", II, II)


def frame_scalar_curvature(II: NDArray) -> NDArray:
    """``S = sum_ij R_ijji = |tr II|^2 - |II|^2`` in an orthonormal frame (``k(k-1)`` on the unit sphere ``S^k``)."""
    mean = np.einsum("...rii->...r", II)
    return np.einsum("...r,...r->...", mean, mean) - np.einsum("...rij,...rij->...", II, II)


def plane_curvature(II: NDArray, x: NDArray, y: NDArray) -> NDArray:
    """Sectional curvature ``R(x, y, y, x) / (|x|^2 |y|^2)`` of the plane of orthogonal frame vectors ``x``, ``y`` (``(..., k)``)."""
    def form(u: NDArray, v: NDArray) -> NDArray:
        return np.einsum("...rij,...i,...j->...r", II, u, v)

    xx, yy, xy = form(x, x), form(y, y), form(x, y)
    num = np.einsum("...r,...r->...", xx, yy) - np.einsum("...r,...r->...", xy, xy)
    return num / (np.einsum("...i,...i->...", x, x) * np.einsum("...i,...i->...", y, y))
