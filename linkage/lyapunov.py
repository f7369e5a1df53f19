"""Lyapunov exponents of a chain's free motion, one start or many: :func:`lyapunov_exponent`, :func:`lyapunov_exponents`.

Thin layers over :func:`manifold.lyapunov.lyapunov_spectrum` on the chain's
rod constraints (:class:`~linkage.constraints.ChainSystem`, hinge
coordinates: no chart, nothing singular).  Re-exported by :mod:`linkage.motion`.
"""

from __future__ import annotations

import functools
from typing import Any

from numpy.typing import ArrayLike, NDArray

from manifold.ensemble import chunk_bounds, default_chunk_size, map_chunks
from manifold.interrupt import SolveInterrupted
from manifold.lyapunov import LyapunovResult, float64_precision, lyapunov_spectrum
from manifold.options import DEFAULT_PRECISION, DEFAULT_START, Precision, StartCheck, takes_option_groups
from manifold.progress import ProgressArgument
from manifold.validation import check_positive_int

from .chain import Chain
from .constraints import ChainSystem, start_state, start_states

__all__ = ["lyapunov_exponent", "lyapunov_exponents"]


@takes_option_groups
def lyapunov_exponent(
    chain: Chain,
    hinges0: ArrayLike,
    velocity0: ArrayLike,
    t_final: float,
    *,
    k: int = 1,
    interval: float = 1.0,
    deviations: str = "perpendicular",
    precision: Precision = DEFAULT_PRECISION,
    start: StartCheck = DEFAULT_START,
    **kwargs: Any,
) -> LyapunovResult:
    """The maximal finite-time Lyapunov exponent of the chain's free motion from ``hinges0`` (and, with ``k > 1``,
    the next ones).

    The deviations follow the variational equations of the hinge-coordinate
    equations of motion, tangent to the phase space of the rod constraints
    and, by default, perpendicular to the flow and to the energy (where the
    exponent is 0 and deviations only grow linearly); Benettin's
    renormalisation every ``interval`` (:mod:`manifold.lyapunov`).  The
    exponent is in 1/time for the speed of ``velocity0`` (it scales with the
    speed: use unit kinetic speed, ``v^T K v = 1``, to compare motions).

    Parameters
    ----------
    chain
        The chain.
    hinges0, velocity0
        Complex start (closing to ``1e-9``) and tangent hinge velocity (nonzero),
        checked as in :func:`~linkage.motion.free_motion`.
    t_final
        Length of the estimate, ``> 0``.
    k
        How many exponents (in Gram-Schmidt order, largest first only as ``t_final`` grows:
        :mod:`manifold.lyapunov`): up to ``2 (n - 2) - 2`` perpendicular, ``2 (n - 2)`` tangent.
    interval
        Time between renormalisations.
    deviations
        ``"perpendicular"`` (default) or ``"tangent"`` (the whole tangent space of the phase space).
    precision
        :class:`manifold.Precision` ``(tol=...)``: heyoka's tolerance; float64 only (another ``fp_type`` raises
        ``ValueError``).
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the start check of
        :func:`~linkage.motion.free_motion`.
    **kwargs
        ``rate``, ``compact_mode``, ``seed``, ``throw``, ``budget`` of :func:`manifold.lyapunov.lyapunov_spectrum`.

    Returns
    -------
    manifold.lyapunov.LyapunovResult
        ``exponent`` (the maximal one), ``exponents``, the convergence
        ``history`` against ``times`` (``plot()`` draws it) and the trajectory's checks.
    """
    _, x0, v0, t_final = start_state(chain, hinges0, velocity0, t_final, start)
    return lyapunov_spectrum(ChainSystem(chain), x0, v0, t_final, k=k, interval=interval, deviations=deviations,
                             precision=precision, **kwargs)


@takes_option_groups
def lyapunov_exponents(
    chain: Chain,
    hinges0: ArrayLike,
    velocities0: ArrayLike,
    t_final: float,
    *,
    backend: str = "serial",
    client: Any = None,
    progress: ProgressArgument = False,
    chunk_size: int | None = None,
    precision: Precision = DEFAULT_PRECISION,
    start: StartCheck = DEFAULT_START,
    **kwargs: Any,
) -> list[LyapunovResult]:
    """:func:`lyapunov_exponent` for many starts (rows of ``hinges0``, ``velocities0``, shape ``(N, n-1)``),
    on ``backend`` (``"serial"``, ``"threads"``, ``"dask"`` with ``client``; :mod:`manifold.ensemble`).

    Each start is its own estimate; a trajectory that fails its checks is
    returned with its ``status`` (``throw=False``) instead of stopping the
    others.  ``precision``, ``start`` and ``kwargs`` are those of :func:`lyapunov_exponent`.  Ctrl-C (serial and
    threads backends) stops every estimate within about 0.1 s and raises :class:`~manifold.interrupt.SolveInterrupted`
    carrying the list of them as far as they got (status ``INTERRUPTED``).
    """
    options = {"precision": float64_precision(precision), "throw": False, **kwargs}  # refused here, not per chunk
    _, X0, V0, t_final = start_states(chain, hinges0, velocities0, t_final, start)
    size = (default_chunk_size(len(X0), 1, backend, client) if chunk_size is None
            else check_positive_int("chunk_size", chunk_size))
    bounds = chunk_bounds(len(X0), size)
    chunks = [functools.partial(lyapunov_chunk, chain, X0[i:j], V0[i:j], t_final, options)
              for i, j in bounds]
    try:
        parts = map_chunks(chunks, [j - i for i, j in bounds], backend=backend, client=client, progress=progress)
    except SolveInterrupted as e:  # Ctrl-C: every estimate as far as it got
        raise SolveInterrupted(str(e), [r for part in e.result for r in part]) from None
    return [r for part in parts for r in part]


def lyapunov_chunk(chain: Chain, X0: NDArray, V0: NDArray, t_final: float, options: dict) -> list[LyapunovResult]:
    """One chunk of :func:`lyapunov_exponents`: real interleaved starts (checked there), one estimate each."""
    system = ChainSystem(chain)

    def estimate(x: NDArray, v: NDArray) -> LyapunovResult:
        try:
            return lyapunov_spectrum(system, x, v, t_final, **options)
        except SolveInterrupted as e:  # Ctrl-C: the estimate so far, and the ensemble raises it (map_chunks)
            return e.result

    return [estimate(x, v) for x, v in zip(X0, V0)]
