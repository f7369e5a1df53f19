"""The physical chain model: rods, masses, configurations, free motion, pictures and animations.

May import ``charts`` and ``manifold`` (never the other way round).
See ``linkage/README.md``.

The names below are loaded on first use (PEP 562), so that importing the
independent subpackage ``linkage.spatial`` does not pull in ``charts``,
heyoka or matplotlib through this package.
"""

import importlib
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("linkage-manifolds")
except PackageNotFoundError:  # run from a source tree that was not installed
    __version__ = "0+unknown"


_EXPORTS = {
    "Chain": ".chain",
    "ConfigurationError": ".chain",
    "HingeConstraints": ".constraints",
    "animate": ".draw",
    "animation": ".draw",
    "draw_chain_at": ".draw",
    "draw_chart_timeline": ".draw",
    "draw_configuration": ".draw",
    "draw_configurations": ".draw",
    "draw_energy_error": ".draw",
    "draw_sphere_path": ".draw",
}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'linkage' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_EXPORTS))
