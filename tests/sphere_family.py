"""The round unit sphere S^2 of ``manifold.stereographic`` (two stereographic charts), and its exact geodesics."""

from __future__ import annotations

import numpy as np

from manifold.stereographic import StereographicChart, StereographicFamily, sphere_metric

__all__ = ["StereographicChart", "StereographicFamily", "great_circle", "sphere_metric", "sphere_start"]


def great_circle(p0: np.ndarray, v0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``cos(s t) p0 + sin(s t) v0 / s`` with ``s = |v0|`` (``v0`` tangent at ``p0``)."""
    s = np.linalg.norm(v0)
    t = np.asarray(t)[..., None]
    return np.cos(s * t) * p0 + np.sin(s * t) * v0 / s


def sphere_start(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A random point of the unit sphere and a tangent velocity of speed 1.3 there (``seed``'s generator)."""
    rng = np.random.default_rng(seed)
    p0 = rng.normal(size=3)
    p0 /= np.linalg.norm(p0)
    v0 = rng.normal(size=3)
    v0 -= (v0 @ p0) * p0
    return p0, v0 / np.linalg.norm(v0) * 1.3
