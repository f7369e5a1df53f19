"""Charts that are members of a compiled :class:`~manifold.family.ChartFamily`.

A :class:`SymbolicChart` is one member of a family: fixed family parameters
``theta`` and a constant invertible affine map ``p = M z(a; theta) + m`` into
the embedding space.  Its Jacobian and quality come from the family's
compiled functions (:mod:`manifold.compiled`), so the formula that the
integrator compiles is the one the chart evaluates.  All charts of one family
share one compiled integrator; ``theta`` and the pulled-back ambient metric
``M^T K M`` are runtime parameters.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chart import Chart, ChartDomainError
from .compiled import ChartNumerics, compiled
from .family import ChartFamily
from .validation import real_array


class SymbolicChart(Chart):
    """A chart ``p = M z(a; theta) + m`` of a :class:`~manifold.family.ChartFamily`.

    Subclasses set ``family``, ``family_parameters`` (``theta``), ``linear_map``
    (``M``, square and invertible), implement :meth:`offset`,
    :meth:`get_parameters` (the inverse) and may override
    :meth:`check_parameters` (domain validation).  :meth:`get_point`,
    :meth:`raw_jacobian` and :meth:`quality` are derived from the family.
    """

    family: ChartFamily
    family_parameters: NDArray
    linear_map: NDArray

    @abstractmethod
    def offset(self, fp_type: Any = float) -> NDArray:
        """The constant ``m`` of ``p = M z + m``, in ``fp_type``."""

    def check_point(self, p: ArrayLike) -> NDArray:
        """``p`` as a float array of shape ``(..., ambient_dim)``; subclasses add their checks that ``p`` lies on
        the manifold (:class:`~manifold.chart.ChartDomainError`).  Charts of one family share the manifold, so
        one chart's check serves them all (:class:`ChartRanking`)."""
        p = real_array("p", p, finite=False)
        if p.ndim == 0 or p.shape[-1] != self.ambient_dim:
            raise ChartDomainError(f"a point has shape (..., {self.ambient_dim}), got {p.shape}")
        return p

    def approximate_parameters(self, p: ArrayLike) -> NDArray:
        """The family's compiled closed-form inverse at ``z = M^{-1} (p - m)`` (:meth:`get_parameters` without one)."""
        if "_ranking" not in self.__dict__:
            self._ranking = chart_ranking([self])
        if self._ranking is None:
            return self.get_parameters(p)
        p = self.check_point(p)
        A, _ = self._ranking(p.reshape(-1, self.ambient_dim))
        return A[:, 0].reshape(*p.shape[:-1], self.dim)

    def check_parameters(self, a: ArrayLike) -> NDArray:
        """``a`` as a float array of shape ``(..., dim)``; subclasses add their domain checks."""
        a = real_array("chart parameters", a, finite=False)
        if a.ndim == 0 or a.shape[-1] != self.dim:
            raise ValueError(f"chart parameters must have shape (..., {self.dim}), got shape {a.shape}")
        return a

    def get_point(self, a: ArrayLike) -> NDArray:
        """``p = M z(a) + m``, shape ``(..., ambient_dim)``."""
        a = self.check_parameters(a)
        z = compiled(self.family).evaluate_point(self.family_parameters, a)
        return z @ self.linear_map.T + self.float_offset()

    def float_offset(self) -> NDArray:
        """``offset(float)``, computed once (read-only)."""
        if "_float_offset" not in self.__dict__:
            self._float_offset = self.offset(float)
            self._float_offset.flags.writeable = False
        return self._float_offset

    def point_and_jacobian(self, a: ArrayLike) -> tuple[NDArray, NDArray]:
        """``get_point(a)`` and ``raw_jacobian(a)`` from one evaluation of the compiled Jacobian."""
        a = self.check_parameters(a)
        z, Jz = compiled(self.family).evaluate_jacobian(self.family_parameters, a)
        return z @ self.linear_map.T + self.float_offset(), self.linear_map @ Jz

    def raw_jacobian(self, a: ArrayLike) -> NDArray:
        """``M dz/da``, shape ``(..., ambient_dim, dim)``; non-finite on the singular set."""
        a = self.check_parameters(a)
        _, Jz = compiled(self.family).evaluate_jacobian(self.family_parameters, a)
        return self.linear_map @ Jz

    def raw_hessian(self, a: ArrayLike) -> NDArray:
        """``M d^2 z / da_i da_j``, shape ``(..., ambient_dim, dim, dim)``; non-finite on the singular set."""
        a = self.check_parameters(a)
        H = compiled(self.family).evaluate_hessian(self.family_parameters, a)
        return np.einsum("rs,...sij->...rij", self.linear_map, H)

    def quality(self, a: ArrayLike) -> NDArray:
        """``min_m quality_m(a)`` from the family's quality expressions (1 for a global chart)."""
        a = self.check_parameters(a)
        return compiled(self.family).evaluate_quality(self.family_parameters, a)

    def inverse_linear_map(self) -> NDArray:
        """``M^{-1}``, rounded to integers when it is an integer matrix (as for rod relabelings); computed once (read-only)."""
        if "_inverse_linear_map" not in self.__dict__:
            inv = np.linalg.inv(self.linear_map)
            self._inverse_linear_map = np.rint(inv) if np.allclose(inv, np.rint(inv), rtol=0, atol=1e-12) else inv
            self._inverse_linear_map.flags.writeable = False
        return self._inverse_linear_map

    def core_metric(self, K: NDArray) -> NDArray:
        """``B`` with ``M^T K M = B (x) I_block``: the metric seen by the family's ``z``.

        Raises ``ValueError`` if ``M^T K M`` lacks that block structure.
        """
        W = self.linear_map.T @ K @ self.linear_map
        b = self.family.block
        B = W[::b, ::b]
        if not np.allclose(np.kron(B, np.eye(b)), W, rtol=0, atol=1e-13 * np.abs(W).max()):
            raise ValueError(f"ambient metric is not of the form B (x) I_{b} in this chart")
        return B

    def numerics(self, K: NDArray, q_out: float, fp_type: Any = float) -> ChartNumerics:
        """This chart in the working precision ``fp_type`` for the ambient metric ``K`` (see :class:`ChartNumerics`).

        Built once per ``(K, q_out, fp_type)`` and kept: every solve on the same atlas reuses it.
        """
        K = np.asarray(K, dtype=float)
        key = (K.shape, K.tobytes(), float(q_out), fp_type)
        cache = self.__dict__.setdefault("_numerics", {})
        if key not in cache:
            cache[key] = ChartNumerics(self, K, q_out, fp_type)
        return cache[key]

    def __getstate__(self) -> dict:
        """The chart without its cache of :meth:`numerics` (compiled, rebuilt on demand): a chart that has been
        solved on pickles like a new one (ensembles ship charts to workers)."""
        state = self.__dict__.copy()
        state.pop("_numerics", None)
        return state


class ChartRanking:
    """Approximate parameters and quality of points in every chart of a list, in one compiled call.

    For charts of one family with a closed-form inverse
    (:meth:`~manifold.family.ChartFamily.inverse_expressions`): chart ``c``
    sees ``z_c = M_c^{-1} (p - m_c)``, and the family's compiled inverse gives
    its parameters ``a_c(z_c)`` and its quality at them, all ``B x C`` pairs of
    points and charts in one batched evaluation.  Build it with
    :func:`chart_ranking`; the stacked maps are computed once.
    """

    def __init__(self, charts: Sequence[SymbolicChart]) -> None:
        self.family = charts[0].family  # compiled on use, not held: a ranking (and its atlas) stays picklable
        self.check_point = charts[0].check_point  # charts of one family share the manifold: one check serves all
        self.inverse_maps = np.stack([c.inverse_linear_map() for c in charts])  # (C, N, N)
        self.offsets = np.stack([c.float_offset() for c in charts])  # (C, N)
        self.theta = np.stack([np.asarray(c.family_parameters, dtype=float) for c in charts])  # (C, n_params)

    def __call__(self, p: NDArray) -> tuple[NDArray, NDArray]:
        """``A`` (``(B, C, dim)``) and ``Q`` (``(B, C)``) at the checked points ``p`` (``(B, N)``); ``Q = -inf``
        where a chart's inverse is not finite (the point lies outside its image)."""
        z = np.einsum("cij,bcj->bci", self.inverse_maps, p[:, None, :] - self.offsets)
        A, Q = compiled(self.family).evaluate_inverse(self.theta, z)
        inside = np.all(np.isfinite(A), axis=-1) & np.isfinite(Q)
        return A, np.where(inside, Q, -np.inf)


def chart_ranking(charts: Sequence[SymbolicChart]) -> ChartRanking | None:
    """The :class:`ChartRanking` of ``charts`` (one family), or ``None`` if the family has no closed-form inverse."""
    if compiled(charts[0].family).inverse(float) is None:
        return None
    return ChartRanking(charts)
