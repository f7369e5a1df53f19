"""The physical chain model: rods, masses, configurations, drawing.

May import ``charts`` and ``manifold`` (never the other way round).
See ``linkage/README.md``.
"""

from .chain import Chain, ConfigurationError
from .constraints import HingeConstraints
from .draw import draw_configuration, draw_configurations

__all__ = ["Chain", "ConfigurationError", "HingeConstraints", "draw_configuration", "draw_configurations"]
