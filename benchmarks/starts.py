"""Starts shared by the benchmarks: random unit-speed starts in chart 0, and starts completed as the hinge method
completes them, for heyoka run bare on the method's own equations."""

from __future__ import annotations

import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from manifold.constrained import ConstrainedGeometry, compiled_constrained


def chart_start(chain: Chain, rng: np.random.Generator, latitude: float = 1.2,
                longitude: float = np.pi) -> tuple[np.ndarray, np.ndarray]:
    """A start at chart-0 parameters: latitudes ``U(-latitude, latitude)``, the longitude
    ``U(-longitude, longitude)``, a velocity ``J(a) c`` with ``c ~ N(0, I)`` scaled to unit kinetic speed.

    Returns
    -------
    tuple
        Complex hinges and hinge velocities, shape ``(n - 1,)`` each; ``1/2 v^T K v = 1/2``.
    """
    a = np.append(rng.uniform(-latitude, latitude, chain.n - 3), rng.uniform(-longitude, longitude))
    chart = chain.atlas().charts[0]
    v = chain.from_point(chart.tangent_vector(a, rng.normal(size=chain.n - 2)))
    return chain.from_point(chart.get_point(a)), v / np.sqrt(2 * chain.kinetic_energy(v))


def completed_starts(chain: Chain, points: np.ndarray, velocities: np.ndarray,
                     T: float) -> tuple[np.ndarray, np.ndarray]:
    """Ambient starts (rows ``(B, N)``) completed as ``free_motion(method="hinges")`` completes them for a run to
    ``T``: projected onto the constraints (:meth:`ConstrainedGeometry.start
    <manifold.constrained.ConstrainedGeometry.start>`, Baumgarte rate 1), with each start's runtime parameters.
    heyoka's integrator of the method (``compiled_constrained(ChainSystem(chain))``) set to a row of each then steps
    exactly what the method steps.

    Returns
    -------
    tuple
        ``(states, parameters)``: rows ``[x, v]`` of shape ``(B, 2 N)``, and rows of the packed parameters with
        each start's Baumgarte rate (:meth:`ConstrainedLayout.pack <manifold.constrained.ConstrainedLayout.pack>`).
    """
    system = ChainSystem(chain)
    layout = compiled_constrained(system).layout
    x, v, _, alphas = ConstrainedGeometry(system, float).start(points, velocities, T, 1.0)
    return np.concatenate([x, v], axis=1), np.array([layout.pack(system, float(a), float) for a in alphas])
