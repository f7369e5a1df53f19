"""Free motions of many starts of one chain: :func:`free_motions` and its result :class:`EnsembleMotion`.

The hinge method in float64 (the default) runs on heyoka's SIMD batch
integrators (:func:`manifold.constrained_batch.solve_constrained_ensemble`);
any other method or precision runs single :func:`~linkage.motion.free_motion`
solves, chunk by chunk.  Either way the chunks run serially, on every core
(threads) or on a Dask cluster (:mod:`manifold.ensemble`), and every
trajectory is checked and reported on its own.  Re-exported by
:mod:`linkage.motion`.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.constrained_batch import solve_constrained_ensemble
from manifold.ensemble import EnsembleSolution, chunk_bounds, default_chunk_size, run_chunks
from manifold.interrupt import SolveInterrupted
from manifold.options import (DEFAULT_PRECISION, DEFAULT_SAVE, DEFAULT_START, PROJECTED_START, Precision, SaveAt,
                              StartCheck, check_group, refuse_moved_options)
from manifold.precision import fp_name
from manifold.progress import ProgressArgument
from manifold.solution import GeodesicSolution, SolveStatus
from manifold.validation import check_positive_int

from .chain import Chain
from .constraints import ChainSystem, start_states

__all__ = ["EnsembleMotion", "free_motions"]

#: Options of the hinge method that the SIMD batch integrators support (with ``precision`` in float64, Baumgarte).
BATCH_OPTIONS = {"rate", "compact_mode", "stabilisation"}


class EnsembleMotion:
    """Free motions of many starts of one chain: a :class:`manifold.ensemble.EnsembleSolution` in complex hinges.

    Index ``k`` is the trajectory from ``hinges0[k]``.

    Attributes
    ----------
    chain
        The chain.
    solution
        The underlying :class:`~manifold.ensemble.EnsembleSolution` (interleaved real points).
    """

    def __init__(self, chain: Chain, solution: EnsembleSolution) -> None:
        self.chain, self.solution = chain, solution

    def __len__(self) -> int:
        return len(self.solution)

    def __repr__(self) -> str:
        return f"EnsembleMotion({self.chain!r}, {self.solution!r})"

    @property
    def end_hinges(self) -> NDArray:
        """Complex hinges where each trajectory stopped, ``(N, n-1)`` (NaN if its state became non-finite)."""
        return self.chain.from_point(self.solution.end_points)

    @property
    def end_velocities(self) -> NDArray:
        """Complex hinge velocities where each trajectory stopped, ``(N, n-1)``."""
        return self.chain.from_point(self.solution.end_velocities)

    @property
    def times(self) -> NDArray:
        """The ``t_eval`` grid."""
        return self._grid(self.solution.t_eval)

    @property
    def hinges(self) -> NDArray:
        """Complex hinges on ``t_eval``, ``(N, len(t_eval), n-1)``; NaN after a trajectory failed."""
        return self.chain.from_point(self._grid(self.solution.points))

    @property
    def velocities(self) -> NDArray:
        """Complex hinge velocities on ``t_eval``, ``(N, len(t_eval), n-1)``; NaN after a trajectory failed."""
        return self.chain.from_point(self._grid(self.solution.velocities))

    def _grid(self, values: NDArray | None) -> NDArray:
        if values is None:
            raise ValueError("no states were kept on a time grid: pass save=SaveAt(t_eval=...) to free_motions")
        return values

    @property
    def relative_energy_errors(self) -> NDArray:
        """``max |E - E0| / E0`` per trajectory (NaN for one whose state became non-finite)."""
        return self.solution.relative_energy_errors

    @property
    def closure_residuals(self) -> NDArray:
        """``max_k | |e_k| - l_k | / l_k`` at each end state (NaN for a non-finite end)."""
        ends = self.solution.end_points
        out = np.full(len(self), np.nan)
        finite = np.all(np.isfinite(ends), axis=1)
        out[finite] = self.chain.closure_residual(self.chain.from_point(ends[finite]))
        return out

    @property
    def status(self) -> list[SolveStatus]:
        return self.solution.status

    @property
    def messages(self) -> list[str]:
        return self.solution.messages

    @property
    def success(self) -> NDArray:
        """``(N,)`` booleans: reached ``t_final`` and passed the energy and constraint checks."""
        return self.solution.success

    @property
    def n_failed(self) -> int:
        return self.solution.n_failed

    @property
    def n_steps(self) -> NDArray:
        return self.solution.n_steps


def free_motions(
    chain: Chain,
    hinges0: ArrayLike,
    velocities0: ArrayLike,
    t_final: float,
    *,
    method: str = "auto",
    save: SaveAt = DEFAULT_SAVE,
    precision: Precision = DEFAULT_PRECISION,
    backend: str = "serial",
    client: Any = None,
    progress: ProgressArgument = False,
    batch_size: int | None = None,
    chunk_size: int | None = None,
    start: StartCheck = DEFAULT_START,
    **kwargs: Any,
) -> EnsembleMotion:
    """Integrate the chain's free motion from many starts: ``hinges0[k]`` with velocity ``velocities0[k]``.

    Every trajectory is the one :func:`~linkage.motion.free_motion` computes
    from the same start (to rounding: the batch integrator takes the same
    steps); only where the work runs changes:

    * ``method="hinges"`` in float64 with Baumgarte stabilisation (what
      ``"auto"``, the default, stands for but on a nearly stretched chain):
      heyoka's SIMD batch integrators, ``batch_size`` trajectories per step
      (:func:`manifold.constrained_batch.solve_constrained_ensemble`);
    * any other method or option: single solves, one after the other in each chunk.

    Parameters
    ----------
    chain
        The chain.
    hinges0, velocities0
        Complex starts, shape ``(N, n-1)``: each configuration must close to
        ``1e-9`` and each velocity be tangent (as for
        :func:`~linkage.motion.free_motion`; errors name the index ``k``).
    t_final
        Final time (finite, nonzero; negative integrates backward), the same for all.
    method
        ``"auto"`` (default), ``"hinges"`` or ``"charts"``.  ``"auto"`` is the method
        :func:`~linkage.motion.free_motion` takes by default (:func:`~linkage.motion.choose_method`): the hinges,
        except on a nearly stretched chain with an atlas, where they lose digits, and where an option only the
        charts take is given; a ``batch_size`` above 1 asks for the hinges' SIMD batches.
    save
        :class:`manifold.SaveAt` ``(t_eval)``: times (within ``[0, t_final]``, in integration order) at which
        to keep every trajectory's state; nothing else is kept (no dense output: ``SaveAt(dense=True)`` is refused).
    precision
        :class:`manifold.Precision` ``(fp_type, tol)``, as for :func:`~linkage.motion.free_motion`; the SIMD
        batches run in float64 only.
    backend
        ``"serial"`` (default), ``"threads"`` (every core) or ``"dask"``.
    client
        A ``dask.distributed.Client`` for ``backend="dask"``.
    progress
        ``True``: a tqdm bar over trajectories (needs the ``progress`` extra);
        a callable: :class:`manifold.progress.ProgressUpdate` s counting
        trajectories (``manifold.ensemble.progress_bar``); ``None``: the
        callback of an enclosing ``manifold.progress.reporting`` block.
    batch_size
        SIMD lanes per batch integrator (hinge method in float64 only);
        ``None``: ``heyoka.recommended_simd_size()``, twice that in compact mode
        (:data:`manifold.constrained_batch.DEFAULT_WIDTHS`); 1: scalar steps.
    chunk_size
        Trajectories per chunk of work; ``None``: four chunks per thread, one per Dask worker thread.
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the start check of
        :func:`~linkage.motion.free_motion`, applied to every row.
    **kwargs
        Options of the method (``rate``, ``compact_mode``, ``stabilisation``, ``q_out``, ...), as for
        :func:`~linkage.motion.free_motion`; ``throw`` is not accepted (an ensemble reports failures per
        trajectory).

    Returns
    -------
    EnsembleMotion
        End states, states on ``t_eval``, energy errors, steps and a status per trajectory.
    """
    from .motion import AUTO, METHODS, choose_method  # free_motion's methods; motion re-exports this module

    if method not in (*METHODS, AUTO):
        raise ValueError(f"method must be one of {(*METHODS, AUTO)}, got {method!r}")
    refuse_moved_options("free_motions", kwargs)
    if "throw" in kwargs:
        raise TypeError("free_motions does not take throw=: an ensemble reports a failed trajectory in its status")
    save, precision = check_group("save", save, SaveAt), check_group("precision", precision, Precision)
    if save.keeps_dense(False):
        raise TypeError("free_motions keeps no dense output: ask for states with save=SaveAt(t_eval=...)")
    _, X0, V0, t_final = start_states(chain, hinges0, velocities0, t_final, start)
    grid = save.grid(t_final)
    if method == AUTO:  # a batch size is an option of the hinge method's SIMD batches alone
        method = choose_method(chain, kwargs) if batch_size in (None, 1) else "hinges"
    # what keeps this call off the SIMD batches, which run the hinge method in float64 with Baumgarte stabilisation
    unbatched = [f"method={method!r}"] if method != "hinges" else []
    if precision.fp_type is not float:
        unbatched.append(f"precision {fp_name(precision.fp_type)}")
    unbatched += [f"{k}={v!r}" for k, v in kwargs.items()
                  if k not in BATCH_OPTIONS or (k == "stabilisation" and v != "baumgarte")]
    if not unbatched:
        options = {k: v for k, v in kwargs.items() if k in ("rate", "compact_mode")}
        solution = solve_constrained_ensemble(
            ChainSystem(chain), X0, V0, t_final, save=save, precision=precision, batch_size=batch_size,
            chunk_size=chunk_size, backend=backend, client=client, progress=progress, **options)
        return EnsembleMotion(chain, solution)
    if batch_size not in (None, 1):
        raise ValueError(f"batch_size={batch_size!r}: SIMD batches run the hinge method in float64 with Baumgarte "
                         f"stabilisation only, not with {', '.join(unbatched)}; without batch_size it runs single "
                         f"solves")
    size = (default_chunk_size(len(X0), 1, backend, client) if chunk_size is None
            else check_positive_int("chunk_size", chunk_size))
    bounds = chunk_bounds(len(X0), size)
    options = {"precision": precision, **kwargs}
    chunks = [functools.partial(solve_motion_chunk, chain, X0[i:j], V0[i:j], t_final, grid, method, options)
              for i, j in bounds]
    return EnsembleMotion(chain, run_chunks(chunks, [j - i for i, j in bounds], backend=backend, client=client,
                                            progress=progress))


def solve_motion_chunk(chain: Chain, X0: NDArray, V0: NDArray, t_final: float, grid: NDArray | None, method: str,
                       options: dict) -> EnsembleSolution:
    """One chunk of single :func:`~linkage.motion.free_motion` solves (starts checked by :func:`free_motions`)."""
    from .motion import free_motion

    save = SaveAt(t_eval=grid, dense=False)

    def solve(x: NDArray, v: NDArray) -> GeodesicSolution:
        # progress=False: the ensemble reports per chunk; single solves inside it stay silent
        try:
            # start=PROJECTED_START: free_motions checked the starts with the user's StartCheck (a default one here
            # refused a velocity that tangent_tol=1e-6 had taken); the projection only removes rounding
            return free_motion(chain, chain.from_point(x), chain.from_point(v), t_final, method=method, save=save,
                               start=PROJECTED_START, throw=False, progress=False, **options).solution
        except SolveInterrupted as e:  # Ctrl-C: the partial result, and the ensemble raises it (map_chunks)
            return e.result

    return EnsembleSolution.from_solutions([solve(x, v) for x, v in zip(X0, V0)], t_final, grid)
