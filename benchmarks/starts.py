"""Random unit-speed starts in chart 0, shared by the benchmarks that need generic starts."""

from __future__ import annotations

import numpy as np

from linkage import Chain


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
