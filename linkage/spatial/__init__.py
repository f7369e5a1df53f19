"""Spatial closed revolute linkages: dual quaternions, configuration curves, bonds.

Follows Hegedüs, Schicho, Schröcker, "The Theory of Bonds: A New Method for the
Analysis of Linkages".  Imports neither ``charts`` nor the planar chain model;
matplotlib only inside the drawing functions.  See ``linkage/spatial/README.md``.
"""

from .chain import Bond, RevoluteChain, connection_numbers, distances_from_connections, motion_factorization
from .curve import ConfigurationCurve, Place
from .dualquat import DualNumber, DualQuaternion
from .elimination import ReducibleCurveError, RigidLinkageError
from .factorization import MotionFactorizationError
from .synthesis import bennett_linkage, double_bennett, goldberg, goldberg_decomposition, linkage_from_factorizations

__all__ = [
    "Bond",
    "MotionFactorizationError",
    "ConfigurationCurve",
    "DualNumber",
    "DualQuaternion",
    "Place",
    "ReducibleCurveError",
    "RevoluteChain",
    "RigidLinkageError",
    "bennett_linkage",
    "connection_numbers",
    "distances_from_connections",
    "double_bennett",
    "goldberg",
    "goldberg_decomposition",
    "linkage_from_factorizations",
    "motion_factorization",
]
