"""Generic multi-chart manifolds: charts, atlases, induced metrics, geodesics.

Knows nothing of linkages: it may import numpy, scipy and heyoka, never
``charts`` or ``linkage``.  See ``manifold/README.md``.
"""

from .atlas import Atlas
from .chart import Chart, ChartDomainError
from .metric import InducedMetric

__all__ = ["Atlas", "Chart", "ChartDomainError", "InducedMetric"]
