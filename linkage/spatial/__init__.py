"""Spatial closed revolute linkages: dual quaternions, configuration curves, bonds.

Follows Hegedüs, Schicho, Schröcker, "The Theory of Bonds: A New Method for the
Analysis of Linkages".  Imports neither ``charts`` nor the planar chain model;
matplotlib only inside the drawing functions.  See ``linkage/spatial/README.md``.
"""

from .chain import Bond, RevoluteChain, connection_numbers, motion_factorization
from .curve import ConfigurationCurve, Place
from .dualquat import DualNumber, DualQuaternion

__all__ = [
    "Bond",
    "ConfigurationCurve",
    "DualNumber",
    "DualQuaternion",
    "Place",
    "RevoluteChain",
    "connection_numbers",
    "motion_factorization",
]
