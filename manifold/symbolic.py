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
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chart import Chart
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

    def check_parameters(self, a: ArrayLike) -> NDArray:
        """``a`` as a float array of shape ``(..., dim)``; subclasses add their domain checks."""
        a = real_array("chart parameters", a, finite=False)
        if a.ndim == 0 or a.shape[-1] != self.dim:
            raise ValueError(f"chart parameters must have shape (..., {self.dim}), got shape {a.shape}")
        return a

    def get_point(self, a: ArrayLike) -> NDArray:
        """``p = M z(a) + m``, shape ``(..., ambient_dim)``."""
        a = self.check_parameters(a)
        z, _ = compiled(self.family).evaluate_jacobian(self.family_parameters, a)
        return z @ self.linear_map.T + self.offset()

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
        """``M^{-1}``, rounded to integers when it is an integer matrix (as for rod relabelings)."""
        inv = np.linalg.inv(self.linear_map)
        return np.rint(inv) if np.allclose(inv, np.rint(inv), rtol=0, atol=1e-12) else inv

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
        """This chart in the working precision ``fp_type`` for the ambient metric ``K`` (see :class:`ChartNumerics`)."""
        return ChartNumerics(self, K, q_out, fp_type)
