"""Lazily built, thread-safe compiled artefacts, and a pool of stateful integrators to lend.

Both the chart families (:mod:`manifold.compiled`) and the constrained systems
(:mod:`manifold.constrained`) compile heyoka code once per identity and share
it between solves: compiled functions are stateless and shared as they are;
integrators carry state, so each caller borrows a private copy from a pool.
"""

from __future__ import annotations

import copy
import threading
import time
from collections.abc import Callable, Hashable, Iterator
from contextlib import contextmanager
from typing import Any

from .precision import fp_name
from .progress import compiling

#: What each kind of artefact (the first item of its key) is, for progress reports; ``pieces`` is symbolic work
#: in Python, the rest LLVM machine code (which heyoka caches on disk).
ARTEFACTS = {"pieces": "the symbolic equations", "transfer": "the chart-transfer function",
             "acceleration": "the acceleration function", "quality": "the chart-quality function",
             "jacobian": "the chart Jacobian", "geometry": "the constraint-geometry function",
             "integrator": "the Taylor integrator", "batch integrator": "the SIMD batch Taylor integrator",
             "tangent integrator": "the Taylor integrator with variational equations",
             "phase jacobian": "the phase-space constraint Jacobian"}


class ArtefactStore:
    """Artefacts built once per key under a lock; integrators lent from per-key pools.

    Parameters
    ----------
    subject
        What the artefacts are compiled from, for progress reports (``repr`` of the family or system).

    Attributes
    ----------
    compile_seconds
        Wall time spent building artefacts so far (symbolic work and LLVM).
    """

    def __init__(self, subject: str = "a compiled system") -> None:
        self.subject = subject
        self.compile_seconds = 0.0
        self._artefacts: dict[Hashable, Any] = {}
        self._pools: dict[Hashable, list] = {}
        self._lock = threading.RLock()

    def _get(self, key: Hashable, build: Callable[[], Any]) -> Any:
        """The artefact ``key``, built once (under the lock) on first use."""
        try:
            return self._artefacts[key]
        except KeyError:
            pass
        with self._lock:
            if key not in self._artefacts:
                t0 = time.perf_counter()
                kind = key[0] if isinstance(key, tuple) else key
                with compiling(self.describe(key), machine_code=kind != "pieces"):
                    self._artefacts[key] = build()
                self.compile_seconds += time.perf_counter() - t0
            return self._artefacts[key]

    def describe(self, key: Hashable) -> str:
        """What the artefact ``key`` is, for progress reports: its kind, :attr:`subject` and precision.

        Keys are tuples ``(kind, fp_type, ...)``; the kind names an entry of :data:`ARTEFACTS`.
        """
        parts = key if isinstance(key, tuple) else (key,)
        what = f"{ARTEFACTS.get(parts[0], parts[0])} of {self.subject}"
        return what if len(parts) < 2 else f"{what} in {fp_name(parts[1])}"

    @contextmanager
    def _lend(self, key: Hashable, build: Callable[[], Any]) -> Iterator[Any]:
        """Lend a private copy of the integrator ``key`` (copying the template only when the pool is empty)."""
        template = self._get(key, build)
        with self._lock:
            pool = self._pools.setdefault(key, [])
            ta = pool.pop() if pool else None
        if ta is None:
            ta = copy.copy(template)
        try:
            yield ta
        finally:
            with self._lock:
                self._pools.setdefault(key, []).append(ta)

    def clear(self) -> None:
        """Forget every artefact (for measuring cold compiles; heyoka's disk cache is separate)."""
        with self._lock:
            self._artefacts.clear()
            self._pools.clear()
