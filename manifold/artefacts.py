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


class ArtefactStore:
    """Artefacts built once per key under a lock; integrators lent from per-key pools.

    Attributes
    ----------
    compile_seconds
        Wall time spent building artefacts so far (symbolic work and LLVM).
    """

    def __init__(self) -> None:
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
                self._artefacts[key] = build()
                self.compile_seconds += time.perf_counter() - t0
            return self._artefacts[key]

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
