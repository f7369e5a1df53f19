"""Many trajectories at once: chunks of work run serially, on every core, or on a Dask cluster.

Nothing here knows what a trajectory is.  An ensemble is cut into chunks;
each chunk is a picklable zero-argument callable that computes its
trajectories, and :func:`map_chunks` runs the chunks on a backend and keeps
their order (:func:`run_chunks` for chunks that return an
:class:`EnsembleSolution`):

* ``"serial"``: one after the other in this thread;
* ``"threads"``: a thread pool with one worker per core.  heyoka's
  integrators release the GIL while they step, so threads scale on the
  integration itself; the Python between steps (starts, checks) is short;
* ``"dask"``: ``client.submit`` on a ``dask.distributed.Client``, from a
  ``LocalCluster`` to a cluster of many machines (``dask-jobqueue``,
  Kubernetes): the chunk callables and their inputs are pickled to the
  workers, which import this package and compile what they need once per
  process (heyoka's disk cache makes that quick after the first time).

Results do not depend on the backend: a chunk computes the same numbers
wherever it runs.  Dask and tqdm are optional extras
(``pip install 'linkage-manifolds[distributed]'``); asking for them without
them installed raises an ``ImportError`` saying so.  Progress follows
:mod:`manifold.progress`: a bar over trajectories, or updates to a callback.

The results of a whole ensemble are one :class:`EnsembleSolution`: end states,
states on a requested time grid, energy errors and a status per trajectory,
so that a failed trajectory is reported next to the others instead of
stopping them.  No dense output is kept: memory is what the grid asks for.
Ctrl-C stops a serial or threaded ensemble within about 0.1 s and raises
:class:`~manifold.interrupt.SolveInterrupted` carrying the partial results
(:func:`map_chunks`).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .interrupt import INTERRUPTED, SolveInterrupted, interruptible
from .progress import ProgressArgument, ProgressUpdate, as_callback
from .solution import GeodesicSolution, SolveStatus

__all__ = ["BACKENDS", "EnsembleSolution", "backend_workers", "check_backend", "chunk_bounds", "default_chunk_size",
           "map_chunks", "progress_bar", "run_chunks"]

#: Where the chunks of an ensemble run (see the module docstring).
BACKENDS = ("serial", "threads", "dask")
#: Chunks per worker thread by default.  Threads start a chunk for nothing, so four balance uneven chunks and
#: advance a progress bar; every Dask task costs a round trip through the scheduler, which on a LocalCluster of
#: two workers (256 trajectories, n = 4, T = 20, 30 paired runs against threads) cost +40 % with four chunks per
#: worker, +23 % with two and +8 % with one.
CHUNKS_PER_WORKER = {"serial": 4, "threads": 4, "dask": 1}


@dataclass
class EnsembleSolution:
    """The results of many trajectories of one system, index ``k`` for trajectory ``k``.

    Attributes
    ----------
    method
        What integrated them (e.g. ``"constrained-taylor batch"``).
    t_final
        The final time asked for (the same for all).
    t_eval
        The output grid, or ``None``.
    end_points, end_velocities
        Where each trajectory stopped, ``(N, dim)`` float64 (NaN if its state
        became non-finite).
    t_reached
        Time reached, ``(N,)`` (``t_final`` on success).
    n_steps
        Steps taken, ``(N,)``.
    relative_energy_errors
        ``max |E - E0| / E0`` over the states checked (every step for
        per-trajectory methods; the grid and the end for batch integration).
    status, messages
        A :class:`~manifold.solution.SolveStatus` and a sentence per trajectory.
    points, velocities
        States on ``t_eval``, ``(N, len(t_eval), dim)``, NaN after a failure;
        ``None`` without ``t_eval``.
    backend, batch_size
        Where the chunks ran, and trajectories per integrator (SIMD lanes; 1 for scalar).
    wall_seconds
        Wall time of the whole ensemble.
    """

    method: str
    t_final: float
    t_eval: NDArray | None
    end_points: NDArray
    end_velocities: NDArray
    t_reached: NDArray
    n_steps: NDArray
    relative_energy_errors: NDArray
    status: list[SolveStatus]
    messages: list[str]
    points: NDArray | None = field(default=None, repr=False)
    velocities: NDArray | None = field(default=None, repr=False)
    backend: str = "serial"
    batch_size: int = 1
    wall_seconds: float = 0.0

    def __len__(self) -> int:
        return len(self.status)

    def __repr__(self) -> str:
        ok = self.success
        err = f"{np.max(self.relative_energy_errors[ok]):.1e}" if np.any(ok) else "n/a"
        return (f"EnsembleSolution({len(self)} trajectories, {self.method}, batch {self.batch_size}, {self.backend}: "
                f"{int(np.sum(ok))} reached t = {self.t_final:g}, {self.n_failed} failed, "
                f"max energy error {err}, {self.wall_seconds:.3g} s)")

    @property
    def success(self) -> NDArray:
        """``(N,)`` booleans: which trajectories reached ``t_final`` and passed every check."""
        return np.array([s is SolveStatus.SUCCESS for s in self.status], dtype=bool)

    @property
    def n_failed(self) -> int:
        return int(np.sum(~self.success))

    @classmethod
    def from_solutions(cls, solutions: Sequence[GeodesicSolution], t_final: float,
                       t_eval: NDArray | None) -> "EnsembleSolution":
        """Summarise single solves (run with ``t_eval`` and ``throw=False``): end states, grid, checks.

        Grid rows past a failed solve's ``t_reached`` are NaN (the solve never got there).
        """
        ends = [s.end_state() for s in solutions]
        points = velocities = None
        if t_eval is not None:
            dim = ends[0][0].shape[0] if ends else 0
            points = np.full((len(solutions), len(t_eval), dim), np.nan)
            velocities = np.full_like(points, np.nan)
            sign = 1.0 if t_final > 0 else -1.0
            for k, s in enumerate(solutions):
                done = int(np.searchsorted(sign * t_eval, sign * float(s.t_reached), side="right"))
                if s.points is not None and s.velocities is not None and done:
                    points[k, :done] = s.points[:done].astype(float)
                    velocities[k, :done] = s.velocities[:done].astype(float)
        return cls(
            method=solutions[0].method if solutions else "", t_final=t_final, t_eval=t_eval,
            end_points=np.array([p.astype(float) for p, _ in ends]).reshape(len(ends), -1),
            end_velocities=np.array([v.astype(float) for _, v in ends]).reshape(len(ends), -1),
            t_reached=np.array([float(s.t_reached) for s in solutions]),
            n_steps=np.array([s.n_steps for s in solutions], dtype=int),
            relative_energy_errors=np.array([s.relative_energy_error for s in solutions]),
            status=[s.status for s in solutions], messages=[s.message for s in solutions],
            points=points, velocities=velocities)

    @classmethod
    def concatenate(cls, parts: Sequence["EnsembleSolution"], **changes: Any) -> "EnsembleSolution":
        """The parts (chunks, in order) as one ensemble; ``changes`` set ``backend``, ``wall_seconds``, ..."""
        first = parts[0]

        def stack(name: str) -> NDArray:
            return np.concatenate([getattr(p, name) for p in parts])

        grids = first.points is not None
        whole = cls(first.method, first.t_final, first.t_eval, stack("end_points"), stack("end_velocities"),
                    stack("t_reached"), stack("n_steps"), stack("relative_energy_errors"),
                    [s for p in parts for s in p.status], [m for p in parts for m in p.messages],
                    stack("points") if grids else None, stack("velocities") if grids else None, first.backend,
                    first.batch_size)
        return replace(whole, **changes)


def chunk_bounds(n: int, chunk_size: int) -> list[tuple[int, int]]:
    """``[(0, c), (c, 2c), ..., (.., n)]``: the index ranges of chunks of at most ``chunk_size``."""
    return [(i, min(i + chunk_size, n)) for i in range(0, n, chunk_size)]


def default_chunk_size(n: int, lanes: int, backend: str = "serial", client: Any = None) -> int:
    """About :data:`CHUNKS_PER_WORKER` chunks per worker thread of ``backend`` (:func:`backend_workers`), each a
    whole number of ``lanes`` (SIMD batches)."""
    workers = backend_workers(backend, client)  # checks the backend first
    per_chunk = math.ceil(n / (CHUNKS_PER_WORKER[backend] * workers))
    return max(lanes, lanes * math.ceil(per_chunk / lanes))


def _dask() -> Any:
    try:
        import distributed  # optional: only backend="dask" needs it
    except ImportError as e:
        raise ImportError("backend='dask' needs dask.distributed, which is not installed: "
                          "pip install 'linkage-manifolds[distributed]'") from e
    return distributed


def check_backend(backend: str, client: Any) -> None:
    """Refuse an unknown ``backend``, a Dask backend without a ``Client``, or a ``client`` for another backend."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
    if backend == "dask":
        distributed = _dask()
        if not isinstance(client, distributed.Client):
            raise TypeError(f"backend='dask' needs client=a dask.distributed.Client, got {client!r}")
    elif client is not None:
        raise ValueError(f"client is only used with backend='dask', got backend={backend!r} and client={client!r}")


def backend_workers(backend: str, client: Any = None) -> int:
    """How many chunks can run at once: 1 (serial), the usable cores (threads), the cluster's threads (dask)."""
    check_backend(backend, client)
    if backend == "serial":
        return 1
    if backend == "threads":
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, sum(client.nthreads().values()))


@contextmanager
def progress_bar(total: int, progress: ProgressArgument, unit: str = "trajectories") -> Iterator[Callable[[int], None]]:
    """Yield ``update(k)``: ``k`` more of ``total`` trajectories are done.

    ``progress`` is a :mod:`manifold.progress` argument: ``True`` or ``"tqdm"``
    draws a tqdm bar over trajectories; a callable (or the callback of an
    enclosing :func:`manifold.progress.reporting` block, for ``None``)
    receives a :class:`~manifold.progress.ProgressUpdate` per finished chunk,
    ``kind="solve"`` with ``t`` the trajectories done of ``t_final = total``
    (so ``fraction`` is the share done), and ``kind="done"`` at the end;
    ``False`` reports nothing.  Raises ``ImportError`` naming the extra if a
    bar is asked for without tqdm.
    """
    if progress is True or (isinstance(progress, str) and progress == "tqdm"):
        try:
            import tqdm  # optional: only a bar needs it
        except ImportError as e:
            raise ImportError("progress=True draws a tqdm bar, but tqdm is not installed: "
                              "pip install 'linkage-manifolds[progress]' (or pass a callable progress=f that takes "
                              "a manifold.progress.ProgressUpdate)") from e
        bar = tqdm.tqdm(total=total, unit=f" {unit}", dynamic_ncols=True)
        try:
            yield bar.update
        finally:
            bar.close()
        return
    callback = as_callback(progress)
    if callback is None:
        yield lambda k: None
        return
    done = [0]

    def update(k: int) -> None:
        done[0] += k
        callback(ProgressUpdate("solve", f"{done[0]} of {total} {unit}", float(done[0]), float(total)))

    yield update
    callback(ProgressUpdate("done", f"{done[0]} of {total} {unit}", float(done[0]), float(total)))


def map_chunks(chunks: Sequence[Callable[[], Any]], sizes: Sequence[int], *, backend: str = "serial",
               client: Any = None, progress: ProgressArgument = False) -> list:
    """Run every chunk on ``backend``; return their results in the order of ``chunks``.

    Parameters
    ----------
    chunks
        Zero-argument callables (picklable for ``"dask"``: a ``functools.partial``
        of a module-level function).
    sizes
        Trajectories per chunk (for the progress bar).
    backend
        ``"serial"``, ``"threads"`` or ``"dask"``.
    client
        The ``dask.distributed.Client`` for ``"dask"`` (else ``None``).
    progress
        ``True``: a tqdm bar over trajectories, advanced as chunks finish; a
        callable: :class:`~manifold.progress.ProgressUpdate` s (:func:`progress_bar`).

    Raises
    ------
    SolveInterrupted
        On Ctrl-C (``"serial"`` and ``"threads"``): every chunk stops within about 0.1 s at a whole step and
        returns what it computed (its unfinished trajectories with status ``INTERRUPTED``); ``result`` is the
        list of the chunks' results.  The chunks read the flag of the :func:`manifold.interrupt.interruptible`
        block held here (worker threads too); a Dask cluster's workers do not (a Ctrl-C stops the wait, as usual).
    Exception
        Whatever a chunk raises (a bad start, a bug); trajectories that fail
        report it in their own results instead.
    """
    check_backend(backend, client)
    if not chunks:
        raise ValueError("an ensemble needs at least one trajectory, got none")
    if backend == "dask":
        with progress_bar(sum(sizes), progress) as update:
            distributed = _dask()
            submitted = [client.submit(chunk, pure=False) for chunk in chunks]
            keys = {future.key: k for k, future in enumerate(submitted)}
            for future in distributed.as_completed(submitted):
                update(sizes[keys[future.key]])
            return client.gather(submitted)
    with progress_bar(sum(sizes), progress) as update, interruptible() as pressed:
        if backend == "serial":
            results = []
            for chunk, size in zip(chunks, sizes):
                results.append(chunk())  # after a Ctrl-C each chunk stops at once, with its unfinished marked
                update(size)
        else:
            with ThreadPoolExecutor(max_workers=backend_workers("threads")) as pool:
                futures = [pool.submit(chunk) for chunk in chunks]
                index = {f: k for k, f in enumerate(futures)}
                for f in as_completed(futures):
                    update(sizes[index[f]])
                results = [f.result() for f in futures]
        interrupted = pressed()
    if interrupted:
        raise SolveInterrupted(f"{INTERRUPTED}: the ensemble stopped with its chunks' partial results", results)
    return results


def run_chunks(chunks: Sequence[Callable[[], EnsembleSolution]], sizes: Sequence[int], *, backend: str = "serial",
               client: Any = None, progress: ProgressArgument = False) -> EnsembleSolution:
    """:func:`map_chunks` for chunks that return :class:`EnsembleSolution` s: one solution, in order,
    with ``backend`` and the ``wall_seconds`` of the whole run; on Ctrl-C, :class:`~manifold.interrupt.SolveInterrupted`
    carrying that solution (unfinished trajectories with status ``INTERRUPTED``)."""
    wall0 = time.perf_counter()
    try:
        results = map_chunks(chunks, sizes, backend=backend, client=client, progress=progress)
    except SolveInterrupted as e:
        raise SolveInterrupted(str(e), EnsembleSolution.concatenate(
            e.result, backend=backend, wall_seconds=time.perf_counter() - wall0)) from None
    return EnsembleSolution.concatenate(results, backend=backend, wall_seconds=time.perf_counter() - wall0)
