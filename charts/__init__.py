"""Concrete charts: iterated-suspension charts of closed chains of unit rods.

May import ``manifold``, numpy and heyoka; never ``linkage``.  See ``charts/README.md``.
"""

from .chain_geometry import validate_chain
from .suspension import SuspensionAtlas, SuspensionChart, cyclic_orders

__all__ = ["SuspensionAtlas", "SuspensionChart", "cyclic_orders", "validate_chain"]
