"""A test-only chart family: the two stereographic charts of the round unit sphere S^2 in R^3.

Written as its formula alone, to prove that a new family needs no solver code.
Chart ``north`` projects from the north pole: ``a = (u, v)`` maps to
``z = (2u, 2v, |a|^2 - 1) / (|a|^2 + 1)``; chart ``south`` is its mirror image
``p = diag(1, 1, -1) z``.  Quality ``1 / (1 + |a|^2)``: 1 at the antipode of
the projection pole, 1/2 on the equator, 0 at the pole.  Geodesics of the
round metric (``K = I``) are great circles, an exact reference.
"""

from __future__ import annotations

import numpy as np

from manifold import Atlas, ChartDomainError, ChartFamily, InducedMetric, SymbolicChart


class StereographicFamily(ChartFamily):
    dim, point_dim, block, n_params = 2, 3, 1, 0

    def __init__(self, variant: str = "plain") -> None:
        self.variant = variant

    @property
    def key(self):
        return ("stereographic-S2", self.variant)

    def point_expressions(self, a, fp_type):
        u, v = a
        r2 = u * u + v * v
        inv = 1.0 / (r2 + 1.0)
        return [2.0 * u * inv, 2.0 * v * inv, (r2 - 1.0) * inv]

    def quality_expressions(self, a):
        u, v = a
        return [1.0 / (1.0 + u * u + v * v)]


class StereographicChart(SymbolicChart):
    dim, ambient_dim = 2, 3
    family_parameters = np.zeros(0)

    def __init__(self, mirror: bool, family: StereographicFamily | None = None) -> None:
        self.family = family or StereographicFamily()
        self.linear_map = np.diag([1.0, 1.0, -1.0 if mirror else 1.0])

    def offset(self, fp_type=float):
        return np.zeros(3).astype(fp_type)

    def get_parameters(self, p):
        p = np.asarray(p, dtype=float)
        if np.any(np.abs(np.linalg.norm(p, axis=-1) - 1.0) > 1e-9):
            raise ChartDomainError(f"point {p} is not on the unit sphere")
        z = p @ self.linear_map.T  # M is its own inverse
        x, y, h = z[..., 0], z[..., 1], z[..., 2]
        # 1 - h cancels only near the projection pole h = 1, where the quality (1 - h)/2 is near 0 and no solver stays
        return np.stack([x, y], axis=-1) / (1.0 - h)[..., None]


def sphere_metric(family: StereographicFamily | None = None) -> InducedMetric:
    """The round metric on the atlas of both stereographic charts."""
    atlas = Atlas([StereographicChart(False, family), StereographicChart(True, family)], ids=["north", "south"])
    return InducedMetric(atlas, np.eye(3))


def great_circle(p0: np.ndarray, v0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``cos(s t) p0 + sin(s t) v0 / s`` with ``s = |v0|`` (``v0`` tangent at ``p0``)."""
    s = np.linalg.norm(v0)
    t = np.asarray(t)[..., None]
    return np.cos(s * t) * p0 + np.sin(s * t) * v0 / s
