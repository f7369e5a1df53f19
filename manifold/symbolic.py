"""Charts known as heyoka expressions, so that geodesic systems can be compiled.

A :class:`ChartFamily` is a parametrised map ``a -> z(a; theta)`` written as heyoka
expressions, with the family parameters ``theta`` as runtime parameters
``par[0 .. n_params-1]``.  A :class:`SymbolicChart` is one member: fixed
``theta`` and a constant affine map ``p = M z + m`` into the embedding space.
All charts of one family share one compiled integrator; ``theta`` and the
pulled-back ambient metric ``M^T K M`` are runtime parameters.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Hashable, Sequence

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from .chart import Chart


class ChartFamily(ABC):
    """A family of chart maps ``z(a; theta)`` as heyoka expressions.

    Attributes
    ----------
    dim
        Number of chart parameters ``a``.
    point_dim
        Number of coordinates of ``z``.
    block
        ``z`` is made of ``point_dim / block`` points of ``R^block`` (2 for planar
        hinges); the ambient metric must be ``B (x) I_block``.
    n_params
        Number of family parameters ``theta``.
    periodic
        Indices of ``2 pi``-periodic parameters.  The integrator wraps them into
        ``[-pi, pi]``: heyoka's error control is relative to the state's size,
        so an angle left to grow to ``O(1000)`` would cost three digits.
    key
        Hashable identity used to cache compiled systems.
    """

    dim: int
    point_dim: int
    block: int
    n_params: int
    periodic: tuple[int, ...] = ()

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """Cache key: two families with equal keys compile to the same code."""

    @abstractmethod
    def point_expressions(self, a: Sequence[hy.expression], fp_type: type) -> list[hy.expression]:
        """``z(a; theta)`` with ``theta = par[0 .. n_params-1]``, constants exact in ``fp_type``."""

    def point_jets(self, a: Sequence[hy.expression], c: Sequence[hy.expression], fp_type: type) -> list | None:
        """``z`` as :class:`~manifold.jets.Jet` s along velocity ``c``, or ``None`` (the default).

        A family that can run its formula on jets gets the geodesic equations
        from one forward sweep instead of symbolic differentiation of the
        expanded ``z``: much smaller for deep formulas.
        """
        return None

    @abstractmethod
    def quality_expressions(self, a: Sequence[hy.expression]) -> list[hy.expression]:
        """Expressions whose minimum is the chart quality (empty: the chart is global)."""


class SymbolicChart(Chart):
    """A chart ``p = M z(a; theta) + m`` of a :class:`ChartFamily`.

    Subclasses set ``family``, ``family_parameters`` (``theta``), ``linear_map``
    (``M``, square and invertible) and implement :meth:`offset`.
    """

    family: ChartFamily
    family_parameters: NDArray
    linear_map: NDArray

    @abstractmethod
    def offset(self, fp_type: type = float) -> NDArray:
        """The constant ``m`` of ``p = M z + m``, in ``fp_type``."""

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
