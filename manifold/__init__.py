"""Generic multi-chart manifolds: charts, atlases, induced metrics, geodesics.

Knows nothing of linkages: it may import numpy, scipy and heyoka, never
``charts`` or ``linkage``.  See ``manifold/README.md``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("linkage-manifolds")
except PackageNotFoundError:  # run from a source tree that was not installed
    __version__ = "0+unknown"

from .atlas import Atlas
from .chart import Chart, ChartDomainError
from .compiled import ChartNumerics, CompiledFamily, compiled
from .family import ChartFamily
from .geodesic_solver import solve_chart_exp_ode
from .metric import InducedMetric
from .options import Precision, SaveAt, StartCheck
from .sampling import BoxProposal, Proposal, VolumeSample, sample_velocities, sample_volume
from .solution import CallableDense, ChartSwitch, GeodesicIntegrationError, GeodesicSolution, Segment, SolverStats, SolveStatus
from .steppers import ScipyStepper, Stepper, TaylorStepper
from .symbolic import SymbolicChart

__all__ = [
    "Atlas", "BoxProposal", "CallableDense", "Chart", "ChartDomainError", "ChartFamily", "ChartNumerics", "ChartSwitch",
    "CompiledFamily", "GeodesicIntegrationError", "GeodesicSolution", "InducedMetric", "Precision", "Proposal",
    "SaveAt", "ScipyStepper", "Segment", "SolveStatus", "SolverStats", "StartCheck", "Stepper", "SymbolicChart", "TaylorStepper",
    "VolumeSample", "compiled", "sample_velocities", "sample_volume", "solve_chart_exp_ode",
]
