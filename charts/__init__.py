"""Concrete charts: iterated-suspension charts of closed chains of unit rods.

May import ``manifold``, numpy and heyoka; never ``linkage``.  See ``charts/README.md``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("linkage-manifolds")
except PackageNotFoundError:  # run from a source tree that was not installed
    __version__ = "0+unknown"

from .chain_geometry import validate_chain
from .suspension import RoundSphereProposal, SuspensionAtlas, SuspensionChart, cyclic_orders, sphere_parameters

__all__ = [
    "RoundSphereProposal", "SuspensionAtlas", "SuspensionChart", "cyclic_orders", "sphere_parameters", "validate_chain",
]
