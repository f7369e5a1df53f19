"""Study baselines: independent methods the library is compared against.

Not part of the installed packages (the wheel ships ``manifold``, ``charts``
and ``linkage`` only); used by ``tests/`` and ``benchmarks/study``.  They may
import the public names of ``charts``, ``linkage`` and ``manifold``.  See
``benchmarks/baselines/README.md``.
"""
