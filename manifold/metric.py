"""Riemannian metric induced on an atlas by a constant ambient metric ``K``.

In chart ``i`` at parameters ``a`` the local metric is ``g = J^T K J`` with
``J = d p / d a``; the kinetic energy of coefficients ``c`` is
``E = 1/2 c^T g c = 1/2 v^T K v`` with ``v = J c``.  Its curvature comes from
the second fundamental form of the embedding (:mod:`manifold.curvature`),
evaluated at a point through the atlas's best chart.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .atlas import Atlas
from .curvature import frame_riemann, frame_scalar_curvature, plane_curvature, second_fundamental_form, tangent_frame
from .validation import real_array

#: Largest K-normal part of ``u`` (relative to ``|u|_K``) that :meth:`InducedMetric.sectional_curvature`
#: accepts as rounding of a tangent vector.
TANGENT_RTOL = 1e-8
#: Smallest ``sin`` of the angle between ``u`` and ``v`` for which a sectional curvature is computed:
#: closer to parallel, the plane itself is known to fewer than 8 digits.
PLANE_SIN_MIN = 1e-8


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
        #: Upper Cholesky factor ``C`` of ``K = C^T C``: ``y = C p`` are K-orthonormal ambient coordinates.
        self.K_root = np.linalg.cholesky(K).T

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

    def volume_density(self, i: int, a: ArrayLike) -> NDArray:
        """``sqrt(det g_i(a))``, the Riemannian volume per ``da`` in chart ``i``; 0 where the chart is singular.

        Computed as ``|det R|`` of ``C J = Q R`` (:func:`manifold.curvature.tangent_frame`)
        rather than from ``det(J^T K J)``, which squares the condition number.
        """
        J = self.atlas.charts[i].raw_jacobian(a)
        regular = np.all(np.isfinite(J), axis=(-2, -1))
        _, R = tangent_frame(np.where(regular[..., None, None], J, 0.0), self.K_root)
        return np.where(regular, np.abs(np.prod(np.diagonal(R, axis1=-2, axis2=-1), axis=-1)), 0.0)

    def integrate(self, f: Callable[[NDArray], NDArray], i: int, box: tuple[ArrayLike, ArrayLike],
                  nodes: Sequence[int], periodic: Sequence[int] = ()) -> float | NDArray:
        """``int f(p) dvol`` over the image of the box ``lower <= a <= upper`` of chart ``i``: a tensor quadrature rule.

        ``f`` maps points ``(B, N)`` to values ``(B,)`` (a float is returned) or
        ``(B, ...)`` (an array of the trailing shape); it is called once on all
        nodes.  Parameter ``j`` gets ``nodes[j]`` Gauss-Legendre nodes, or, if
        ``j`` is in ``periodic`` (its box spanning one period), the trapezoidal
        rule, spectrally accurate for a smooth periodic integrand.  The result
        is the integral over the manifold when chart ``i`` maps the box onto it
        one-to-one up to a null set; the integrand ``f sqrt(det g_i)`` has to be
        smooth in the parameters for fast convergence, which a chart's singular
        set can spoil (compare two node counts).
        """
        lower, upper = (real_array(name, x).reshape(-1) for name, x in zip(("box lower", "box upper"), box))
        k = self.atlas.dim
        if lower.shape != (k,) or upper.shape != (k,) or len(nodes) != k:
            raise ValueError(f"box and nodes need dim = {k} entries, got {lower.size}, {upper.size} and {len(nodes)}")
        axes, weights = [], []
        for j, (lo, hi, m) in enumerate(zip(lower, upper, nodes)):
            if int(m) != m or m < 1:
                raise ValueError(f"nodes[{j}] must be a positive integer, got {m!r}")
            if j in periodic:
                x, w = lo + (hi - lo) * np.arange(m) / m, np.full(int(m), (hi - lo) / m)
            else:
                x, w = np.polynomial.legendre.leggauss(int(m))
                x, w = lo + (hi - lo) * (x + 1) / 2, w * (hi - lo) / 2
            axes.append(x)
            weights.append(w)
        a = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, k)
        w = np.prod(np.stack(np.meshgrid(*weights, indexing="ij"), axis=-1).reshape(-1, k), axis=-1)
        values = np.asarray(f(self.atlas.get_point(i, a)), dtype=float)
        out = np.tensordot(w * self.volume_density(i, a), values, axes=(0, 0))
        return float(out) if out.ndim == 0 else out

    # -- curvature --------------------------------------------------------------------
    def _frame_form(self, i: int, a: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """``II`` in the orthonormal frame, ``Q`` and ``R`` of ``C J = Q R``, in chart ``i`` at ``a``."""
        chart = self.atlas.charts[i]
        Q, R = tangent_frame(chart.jacobian(a), self.K_root)
        return second_fundamental_form(Q, R, chart.hessian(a), self.K_root), Q, R

    def riemann_tensor(self, i: int, a: ArrayLike) -> NDArray:
        """Riemann tensor ``R_abcd`` in the coordinates of chart ``i`` at ``a``, shape ``(..., k, k, k, k)``.

        Convention: ``R(u, v, v, u) = R_abcd u^a v^b v^c u^d`` is the sectional
        curvature of the plane of ``u, v`` times ``|u|^2 |v|^2 - <u, v>^2``
        (positive on a round sphere).  From the Gauss equation in the chart's
        orthonormal frame (:func:`manifold.curvature.frame_riemann`), carried to
        coordinates by ``d/da_a = sum_i R_ia e_i``.
        """
        II, _, R = self._frame_form(i, real_array("a", a))
        return np.einsum("...ia,...jb,...kc,...ld,...ijkl->...abcd", R, R, R, R, frame_riemann(II))

    def _best_frames(self, p: ArrayLike) -> tuple[tuple[int, ...], NDArray, NDArray]:
        """Leading shape of ``p`` and, per point flattened, ``II`` and ``Q`` in its best chart."""
        idx, a = self.atlas.best_chart(p)
        lead = np.shape(idx)
        idx, a = np.ravel(idx), a.reshape(-1, self.atlas.dim)
        N, k = self.atlas.ambient_dim, self.atlas.dim
        II, Q = np.empty((idx.size, N, k, k)), np.empty((idx.size, N, k))
        for i in np.unique(idx):
            rows = idx == i
            II[rows], Q[rows], _ = self._frame_form(int(i), a[rows])
        return lead, II, Q

    def _frame_coordinates(self, lead: tuple[int, ...], Q: NDArray, *vectors: tuple[str, ArrayLike]) -> list[NDArray]:
        """Coordinates in the orthonormal frame (columns of ``Q``, flattened points) of each named embedded tangent
        vector, broadcast to the points' leading shape ``lead``; ``ValueError`` naming a vector that is zero, of
        the wrong shape, or has a K-normal part above ``TANGENT_RTOL`` of its length."""
        N, out = self.atlas.ambient_dim, []
        for name, w in vectors:
            w = real_array(name, w)
            if w.shape[-1:] != (N,):
                raise ValueError(f"{name} must have shape (..., {N}) like p, got {w.shape}")
            w = np.broadcast_to(w, (*lead, N)).reshape(-1, N)
            y = w @ self.K_root.T
            x = np.einsum("...rk,...r->...k", Q, y)
            size = np.linalg.norm(y, axis=-1)
            if np.any(size == 0):
                raise ValueError(f"{name} must be a nonzero tangent vector, got {name} = 0")
            normal = np.linalg.norm(y - np.einsum("...rk,...k->...r", Q, x), axis=-1) / size
            if np.any(normal > TANGENT_RTOL):
                raise ValueError(f"{name} is not tangent at p: its K-normal part is {normal.max():.3g} of its length "
                                 f"(at most {TANGENT_RTOL:g})")
            out.append(x)
        return out

    def second_fundamental_form(self, p: ArrayLike, u: ArrayLike, v: ArrayLike) -> NDArray:
        """``II(u, v)``, the K-normal part of the second derivative of the embedding along ``u`` and ``v``.

        For a curve of the manifold through ``p`` with velocity ``v``, ``II(v, v)``
        is its acceleration normal to the manifold: for a geodesic, all of it (the
        constraint force per unit mass matrix, ``K x'' = K II(v, v)``).  Evaluated
        in the best chart at each point (:func:`manifold.curvature.second_fundamental_form`).

        Parameters
        ----------
        p
            Point(s), shape ``(..., N)``.
        u, v
            Embedded tangent vectors at ``p``, shape ``(..., N)`` (checked as in
            :meth:`sectional_curvature`).

        Returns
        -------
        numpy.ndarray
            Embedded normal vectors, shape ``(..., N)``; symmetric in ``u, v``.
        """
        lead, II, Q = self._best_frames(p)
        x, y = self._frame_coordinates(lead, Q, ("u", u), ("v", v))
        normal = np.einsum("nrij,ni,nj->nr", II, x, y)  # in the K-orthonormal coordinates C p
        return np.linalg.solve(self.K_root, normal.T).T.reshape(*lead, self.atlas.ambient_dim)

    def bending(self, p: ArrayLike) -> float | NDArray:
        """``|II|^2 = sum_ij |II(e_i, e_j)|_K^2`` over a K-orthonormal frame ``e_i`` at point(s) ``p``: how much the
        manifold bends in its ambient space (0 where it is flat in it); ``|II|^2 = |tr II|^2 - S``."""
        lead, II, _ = self._best_frames(p)
        B = np.sum(II**2, axis=(-3, -2, -1)).reshape(lead)
        return float(B) if B.ndim == 0 else B

    def stiffness(self, p: ArrayLike, v: ArrayLike) -> float | NDArray:
        """``|II(v, v)|_K``: the normal acceleration of the geodesic through ``p`` with velocity ``v`` (``(..., N)``),
        which the constraints must supply; for the chain, how hard its rods pull when it moves that way."""
        lead, II, Q = self._best_frames(p)
        (x,) = self._frame_coordinates(lead, Q, ("v", v))
        S = np.linalg.norm(np.einsum("nrij,ni,nj->nr", II, x, x), axis=-1).reshape(lead)
        return float(S) if S.ndim == 0 else S

    def scalar_curvature(self, p: ArrayLike) -> float | NDArray:
        """Scalar curvature ``S = g^{ad} g^{bc} R_abcd`` at point(s) ``p`` (``k(k-1)`` on the unit sphere ``S^k``).

        Evaluated in the best chart at each point (:meth:`Atlas.best_chart`);
        in an orthonormal frame ``S = |tr II|^2 - |II|^2``.
        """
        lead, II, _ = self._best_frames(p)
        S = frame_scalar_curvature(II).reshape(lead)
        return float(S) if S.ndim == 0 else S

    def gaussian_curvature(self, p: ArrayLike) -> float | NDArray:
        """Gaussian curvature ``K = R_1221 / det g = <II_11, II_22> - |II_12|^2`` (orthonormal frame) of a surface.

        Raises ``ValueError`` unless the manifold has dimension 2.
        """
        if self.atlas.dim != 2:
            raise ValueError(f"gaussian_curvature needs a manifold of dimension 2, got dimension {self.atlas.dim} "
                             "(use sectional_curvature or scalar_curvature)")
        return self.scalar_curvature(p) / 2  # S = 2 K on a surface

    def sectional_curvature(self, p: ArrayLike, u: ArrayLike, v: ArrayLike) -> float | NDArray:
        """Sectional curvature ``R(u, v, v, u) / (|u|^2 |v|^2 - <u, v>^2)`` of the plane of ``u, v`` at ``p``.

        Parameters
        ----------
        p
            Point(s) of the manifold, shape ``(..., N)``.
        u, v
            Embedded tangent vectors at ``p`` (shape ``(..., N)``), nonzero and
            not parallel (``sin`` of their angle at least ``PLANE_SIN_MIN``).

        Raises
        ------
        ValueError
            If the dimension is below 2, if ``u`` or ``v`` is zero, has a
            K-normal part above ``TANGENT_RTOL`` of its length, or if they are
            (nearly) parallel.
        """
        if self.atlas.dim < 2:
            raise ValueError(f"a sectional curvature needs dimension >= 2, got dimension {self.atlas.dim}")
        lead, II, Q = self._best_frames(p)
        frame = self._frame_coordinates(lead, Q, ("u", u), ("v", v))
        x, y = frame
        # Numerical trap: |u|^2 |v|^2 - <u, v>^2 cancels for nearly parallel vectors.  Gram-Schmidt
        # (y_perp = y - (x.y / x.x) x) leaves R(x, y, y, x) unchanged and gives the denominator
        # |x|^2 |y_perp|^2 and the angle's sine |y_perp| / |y| to rounding.
        y = y - (np.einsum("...i,...i->...", x, y) / np.einsum("...i,...i->...", x, x))[..., None] * x
        sine = np.linalg.norm(y, axis=-1) / np.linalg.norm(frame[1], axis=-1)
        if np.any(sine < PLANE_SIN_MIN):
            raise ValueError(f"u and v must span a plane: sin of their angle is {sine.min():.3g} "
                             f"(at least {PLANE_SIN_MIN:g})")
        K = plane_curvature(II, x, y).reshape(lead)
        return float(K) if K.ndim == 0 else K
