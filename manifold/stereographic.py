"""Your own manifold, worked: the round unit sphere ``S^2`` in ``R^3``, by charts and by a constraint.

Written as its formulas alone, to show that a new manifold needs no solver
code, and run through the conformance suite (:mod:`manifold.testing`) like
every family of the library.

* :class:`StereographicFamily` and :class:`StereographicChart`: chart ``north``
  projects from the north pole, ``a = (u, v)`` maps to
  ``z = (2u, 2v, |a|^2 - 1) / (|a|^2 + 1)``; chart ``south`` is its mirror
  image ``p = diag(1, 1, -1) z``.  Quality ``1 / (1 + |a|^2)``: 1 at the
  antipode of the projection pole, 1/2 on the equator, 0 at the pole.
  :func:`sphere_metric` is the atlas of both with the round metric ``K = I``.
* :class:`UnitSphere`: the same sphere as the constraint ``|x|^2 - 1 = 0``
  (:class:`~manifold.constrained.ConstrainedSystem`), so geodesics, transport
  and Jacobi fields run on it without charts.

Geodesics are great circles, an exact reference.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .atlas import Atlas
from .chart import ChartDomainError
from .constrained import ConstrainedSystem
from .family import ChartFamily
from .metric import InducedMetric
from .symbolic import SymbolicChart

__all__ = ["StereographicChart", "StereographicFamily", "UnitSphere", "sphere_metric"]


class StereographicFamily(ChartFamily):
    """The stereographic chart of ``S^2`` from the north pole, as heyoka expressions (``variant`` only renames the key,
    for tests that need a second compiled copy)."""

    dim, point_dim, block, n_params = 2, 3, 1, 0

    def __init__(self, variant: str = "plain") -> None:
        self.variant = variant

    @property
    def key(self) -> Hashable:
        return ("stereographic-S2", self.variant)

    def point_expressions(self, a: Sequence[hy.expression], fp_type: Any) -> list[hy.expression]:
        u, v = a
        r2 = u * u + v * v
        inv = 1.0 / (r2 + 1.0)
        return [2.0 * u * inv, 2.0 * v * inv, (r2 - 1.0) * inv]

    def quality_expressions(self, a: Sequence[hy.expression]) -> list[hy.expression]:
        u, v = a
        return [1.0 / (1.0 + u * u + v * v)]


class StereographicChart(SymbolicChart):
    """Chart ``north`` (``mirror=False``) or ``south`` (``mirror=True``) of :class:`StereographicFamily`."""

    dim, ambient_dim = 2, 3
    family_parameters = np.zeros(0)

    def __init__(self, mirror: bool, family: StereographicFamily | None = None) -> None:
        self.family = family or StereographicFamily()
        self.linear_map = np.diag([1.0, 1.0, -1.0 if mirror else 1.0])

    def offset(self, fp_type: Any = float) -> NDArray:
        return np.zeros(3).astype(fp_type)

    def get_parameters(self, p: ArrayLike) -> NDArray:
        p = np.asarray(p, dtype=float)
        if np.any(np.abs(np.linalg.norm(p, axis=-1) - 1.0) > 1e-9):
            raise ChartDomainError(f"point {p} is not on the unit sphere")
        z = p @ self.linear_map.T  # M is its own inverse
        x, y, h = z[..., 0], z[..., 1], z[..., 2]
        # 1 - h cancels only near the projection pole h = 1, where the quality (1 - h)/2 is near 0 and no solver stays
        return np.stack([x, y], axis=-1) / (1.0 - h)[..., None]


def sphere_metric(family: StereographicFamily | None = None) -> InducedMetric:
    """The round metric on the atlas of both stereographic charts (ids ``north``, ``south``)."""
    atlas = Atlas([StereographicChart(False, family), StereographicChart(True, family)], ids=["north", "south"])
    return InducedMetric(atlas, np.eye(3))


class UnitSphere(ConstrainedSystem):
    """``S^2 = {x in R^3 : |x|^2 - 1 = 0}`` with ``K = I``: the constraint side of the same manifold."""

    ambient_dim, n_constraints = 3, 1

    def __repr__(self) -> str:
        return "UnitSphere()"

    @property
    def key(self) -> Hashable:
        return ("unit sphere S^2",)

    @property
    def metric_matrix(self) -> NDArray:
        return np.eye(3)

    def constraint_expressions(self, x: list[hy.expression], p: list[hy.expression],
                               fp_type: Any) -> list[hy.expression]:
        return [hy.sum([xi * xi for xi in x]) - hy.expression(fp_type(1.0))]
