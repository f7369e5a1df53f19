"""The round unit sphere S^2 of ``manifold.stereographic`` (two stereographic charts), and its exact geodesics."""

from __future__ import annotations

import numpy as np

from manifold.stereographic import StereographicChart, StereographicFamily, sphere_metric

__all__ = ["StereographicChart", "StereographicFamily", "great_circle", "sphere_metric"]


def great_circle(p0: np.ndarray, v0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``cos(s t) p0 + sin(s t) v0 / s`` with ``s = |v0|`` (``v0`` tangent at ``p0``)."""
    s = np.linalg.norm(v0)
    t = np.asarray(t)[..., None]
    return np.cos(s * t) * p0 + np.sin(s * t) * v0 / s
