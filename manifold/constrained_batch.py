"""Many geodesics of one constrained system at once: heyoka's SIMD batch integrators, on any ensemble backend.

:func:`solve_constrained_ensemble` integrates ``N`` starts of one
:class:`~manifold.constrained.ConstrainedSystem` with the Baumgarte-stabilised
Taylor method of :func:`~manifold.constrained.solve_constrained`, in float64,
``batch_size`` trajectories per integrator step (``heyoka.taylor_adaptive_batch``:
every scalar of the equations becomes a vector of SIMD lanes; each lane keeps
its own step size, so a lane takes exactly the steps of a single solve).  The
per-trajectory Baumgarte rate ``alpha`` (it scales with the speed) is a
per-lane parameter.

Each trajectory starts as a single solve starts
(:meth:`~manifold.constrained.ConstrainedGeometry.start`) and is judged as a
single solve is judged (:func:`~manifold.constrained.verdict`): energy and
``max_k |c_k|`` on the grid and at the end.  A lane whose state turns
non-finite stops heyoka's batch after the step; its batch is then run again
without it, so it does not disturb the others.  The chunks of the ensemble run
on :func:`manifold.ensemble.run_chunks`.  Ctrl-C stops the batch after its
current step (a step callback reads :func:`manifold.interrupt.interruptible`'s
flag); its trajectories, and those of batches not yet run (at their start),
are returned with status ``INTERRUPTED``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .constrained import (ConstrainedGeometry, ConstrainedSystem, compiled_constrained, constraint_bound,
                          default_compact_mode, verdict)
from .ensemble import EnsembleSolution, chunk_bounds, default_chunk_size, run_chunks
from .interrupt import INTERRUPTED, Listener, interruptible
from .options import DEFAULT_PRECISION, DEFAULT_SAVE, Precision, SaveAt, check_group, takes_option_groups
from .precision import is_double
from .progress import ProgressArgument
from .solution import SolveStatus, energy_bound, energy_violation
from .steppers import taylor_relative_tolerance
from .validation import check_bool, check_positive_int, check_real, real_array

__all__ = ["judge_lanes", "solve_constrained_chunk", "solve_constrained_ensemble"]

#: Batch sizes up to this many times heyoka's SIMD width are taken: wider batches only cost compile time and memory.
MAX_BATCH_LANES = 4
#: Default lanes per SIMD width, for unrolled and for compact-mode code.  A compact-mode step calls one compiled
#: function per kind of node, and a wider batch shares those calls: 64 trajectories of T = 20 on AVX2 (4 lanes)
#: took 0.63x (n = 6), 0.68x (n = 8) and 0.60x (n = 10) the CPU time with 8 lanes as with 4 (16 lanes: another
#: 0.86-0.96x), while unrolled code (n = 4) gained 6 % with 8 lanes and lost with 16 (benchmarks.ensemble_simd).
DEFAULT_WIDTHS = {False: 1, True: 2}

METHOD = "constrained-taylor batch (baumgarte)"


@takes_option_groups
def solve_constrained_ensemble(
    system: ConstrainedSystem,
    x0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    save: SaveAt = DEFAULT_SAVE,
    precision: Precision = DEFAULT_PRECISION,
    rate: float = 1.0,
    compact_mode: bool | None = None,
    batch_size: int | None = None,
    chunk_size: int | None = None,
    backend: str = "serial",
    client: Any = None,
    progress: ProgressArgument = False,
) -> EnsembleSolution:
    """Integrate the geodesics of ``system`` from the rows of ``x0``, ``v0`` (float64, SIMD batches).

    Parameters
    ----------
    system
        The :class:`~manifold.constrained.ConstrainedSystem` (picklable for ``backend="dask"``).
    x0, v0
        Starts, shape ``(N, dim)``: each ``x0[k]`` within ``1e-9`` of ``c = 0``
        (else ``ValueError`` naming ``k``), completed to the constraints as in
        :func:`~manifold.constrained.solve_constrained`.
    t_final
        Final time, finite and nonzero; negative integrates backward.
    save
        :class:`~manifold.options.SaveAt` ``(t_eval)``: times (1-d, within ``[0, t_final]``, in integration
        order) at which states are kept, for every trajectory.  No dense output is kept: ``dense=True`` is
        refused.
    precision
        :class:`~manifold.options.Precision` ``(tol=...)``: heyoka's tolerance in ``(0, 1e-2]``; ``None``: the
        float64 machine epsilon.  The batches run in float64 only: another ``fp_type`` is refused.
    rate
        Baumgarte rate in units of each trajectory's speed scale, ``> 0``.
    compact_mode
        heyoka's compact mode (faster compile, slower steps); ``None``: as
        :func:`~manifold.constrained.solve_constrained` chooses
        (:func:`~manifold.constrained.default_compact_mode`).
    batch_size
        SIMD lanes per integrator, ``>= 1`` and at most :data:`MAX_BATCH_LANES` times
        ``heyoka.recommended_simd_size()``; ``None``: ``heyoka.recommended_simd_size()``, twice that in
        compact mode (:data:`DEFAULT_WIDTHS`).
    chunk_size
        Trajectories per chunk of work (rounded up to whole batches);
        ``None``: :func:`manifold.ensemble.default_chunk_size` (four per thread, one per Dask worker thread).
    backend, client, progress
        Where the chunks run and whether a bar shows it (:func:`manifold.ensemble.run_chunks`).

    Returns
    -------
    EnsembleSolution
        Per trajectory: end state, states on ``t_eval``, energy error (over the
        grid and the end), steps, status and message.  The numbers do not
        depend on ``backend``, ``batch_size`` or ``chunk_size``, and agree
        with single :func:`~manifold.constrained.solve_constrained` calls to rounding.
    """
    t_final = check_real("t_final", t_final, nonzero=True)
    save, precision = check_group("save", save, SaveAt), check_group("precision", precision, Precision)
    if save.keeps_dense(False):
        raise TypeError("solve_constrained_ensemble keeps no dense output: ask for states with "
                        "save=SaveAt(t_eval=...)")
    if not is_double(precision.fp_type):
        raise ValueError(f"the SIMD batches integrate in float64, got precision=Precision(fp_type="
                         f"{precision.fp_type!r})")
    tol = precision.tol
    rate = check_real("rate", rate, positive=True)
    compact_mode = check_bool("compact_mode", default_compact_mode(system, float) if compact_mode is None
                              else compact_mode)
    grid = save.grid(t_final)
    dim = system.ambient_dim
    x0, v0 = real_array("x0", x0), real_array("v0", v0)
    for name, arr in (("x0", x0), ("v0", v0)):
        if arr.ndim != 2 or arr.shape[1] != dim or arr.shape[0] == 0:
            raise ValueError(f"{name} must have shape (N, {dim}) with N >= 1 starts, got {arr.shape}")
    if x0.shape != v0.shape:
        raise ValueError(f"x0 and v0 must have the same shape, got {x0.shape} and {v0.shape}")
    lanes = (DEFAULT_WIDTHS[compact_mode] * hy.recommended_simd_size() if batch_size is None
             else check_positive_int("batch_size", batch_size))
    if lanes > MAX_BATCH_LANES * hy.recommended_simd_size():
        raise ValueError(f"batch_size={lanes} is beyond what SIMD makes useful: heyoka's SIMD width here is "
                         f"{hy.recommended_simd_size()}, and batch sizes up to {MAX_BATCH_LANES} times it are taken "
                         "(a 1000-lane integrator took 1.7 GB and minutes to compile); use chunk_size= and "
                         "backend= to run more trajectories at once")
    n = x0.shape[0]
    size = (default_chunk_size(n, lanes, backend, client) if chunk_size is None
            else lanes * -(-check_positive_int("chunk_size", chunk_size) // lanes))
    bounds = chunk_bounds(n, size)
    chunks = [functools.partial(solve_constrained_chunk, system, x0[i:j], v0[i:j], t_final, grid, tol, rate,
                                compact_mode, lanes, i) for i, j in bounds]
    return run_chunks(chunks, [j - i for i, j in bounds], backend=backend, client=client, progress=progress)


def _with_ends(grid: NDArray | None, t_final: float) -> tuple[NDArray, NDArray]:
    """heyoka's grid (strictly monotonic, from 0 to ``t_final``) and where each ``t_eval`` time sits in it.

    Ending the grid at ``t_final`` makes the last step end there, as in a single solve.
    """
    times = np.concatenate([[0.0], [] if grid is None else grid, [t_final]])
    keep = np.concatenate([[True], np.diff(times) != 0])
    position = np.cumsum(keep) - 1
    return times[keep], position[1:-1]


def solve_constrained_chunk(system: ConstrainedSystem, x0: NDArray, v0: NDArray, t_final: float,
                            grid: NDArray | None, tol: float | None, rate: float, compact_mode: bool,
                            batch_size: int, offset: int = 0) -> EnsembleSolution:
    """One chunk of :func:`solve_constrained_ensemble` (arguments checked there): batches of ``batch_size`` lanes.

    ``offset`` is the index of ``x0[0]`` in the whole ensemble, for messages.
    """
    geo = ConstrainedGeometry(system, float)
    comp = compiled_constrained(system)
    n, dim = x0.shape
    X, V, E0, alpha = geo.start(x0, v0, t_final, rate, first_index=offset)
    E0 = E0.astype(float)
    pars = np.repeat(comp.layout.pack(system, 0.0, float)[:, None], n, axis=1)
    pars[0] = alpha  # the Baumgarte rate, per trajectory (layout: par[0])
    times, position = _with_ends(grid, t_final)
    states = np.full((n, len(times), 2 * dim), np.nan)
    ends = np.full((n, 2 * dim), np.nan)
    steps = np.zeros(n, dtype=int)
    t_reached = np.zeros(n)
    failure: list[str | None] = [None] * n
    with comp.batch_integrator(batch_size, tol, compact_mode) as ta, interruptible() as pressed:
        for i in range(0, n, batch_size):
            lanes = list(range(i, min(i + batch_size, n)))
            if pressed():  # not started: held at the start, which passes its checks
                states[lanes, 0] = ends[lanes] = np.concatenate([X[lanes], V[lanes]], axis=1).astype(float)
                for k in lanes:
                    failure[k] = INTERRUPTED
                continue
            _run_batch(ta, lanes, X, V, pars, times, states, ends, steps, t_reached, failure, pressed)
    # checked as a single solve checks: the recorded states after the start (grid times reached, then the end)
    checked = np.concatenate([states[:, 1:], ends[:, None]], axis=1)
    c, _, _, E = geo(checked[..., :dim].reshape(-1, dim), checked[..., dim:].reshape(-1, dim))
    deviations = np.abs(E.reshape(n, -1) - E0[:, None]) / E0[:, None]
    drifts = geo.drift(c).reshape(n, -1)
    errors, status, messages = judge_lanes(deviations, drifts, times, t_reached, steps,
                                           taylor_relative_tolerance(tol, float), failure,
                                           lambda tol: system.rounding_hint(float, tol))
    return EnsembleSolution(
        METHOD, t_final, grid, ends[:, :dim], ends[:, dim:], t_reached, steps, errors, status, messages,
        None if grid is None else states[:, position, :dim],
        None if grid is None else states[:, position, dim:], batch_size=batch_size)


def judge_lanes(deviations: NDArray, drifts: NDArray, times: NDArray, t_reached: NDArray, steps: NDArray,
                eps: float, failure: list[str | None],
                hint: Callable[[float], str | None] | None = None) -> tuple[NDArray, list[SolveStatus], list[str]]:
    """Every lane judged as a single solve is judged (:func:`~manifold.constrained.verdict`), on its checked states.

    Parameters
    ----------
    deviations, drifts
        ``|E - E0| / E0`` and ``max_k |c_k|`` per lane (rows) at ``times[1:]`` and then at the lane's end (columns).
    times
        heyoka's grid, from 0 to ``t_final``.
    t_reached, steps
        Per lane: the time reached (NaN if unknown) and the steps taken.
    eps
        The relative tolerance.
    failure
        Per lane: why the integrator stopped early, ``None`` if it did not.
    hint
        The system's sentence for a failed check, from the tolerance, as :func:`~manifold.constrained.verdict` takes
        it.

    Returns
    -------
    tuple
        ``(errors, status, messages)``: the largest energy deviation over the grid times a lane reached and its
        end (NaN stays NaN), and what :func:`~manifold.constrained.verdict` says of it.  Lanes that pass every
        check are found all at once; only the others go through the checks one by one, for their sentences.
    """
    n = len(t_reached)
    # the grid times each lane reached, and its end (a NaN t_reached compares false: only the end)
    reached = np.concatenate([np.abs(times[1:]) <= np.abs(t_reached)[:, None], np.ones((n, 1), dtype=bool)], axis=1)
    errors = np.max(np.where(reached, deviations, -np.inf), axis=1)
    drift = np.max(np.where(reached, drifts, -np.inf), axis=1)
    passed = (np.array([f is None for f in failure], dtype=bool)
              & np.all(~reached | (deviations <= [[energy_bound(int(s), eps)] for s in steps]), axis=1)
              & (drift <= [constraint_bound(int(s), eps) for s in steps]))
    success = verdict(None, 0.0, 0, eps, float(times[-1]), None)
    status, messages = [], []
    for k in range(n):
        if passed[k]:
            s, m = success
        else:
            checked_times = np.append(times[1:], t_reached[k])[reached[k]]
            s, m = verdict(energy_violation(deviations[k, reached[k]], checked_times, int(steps[k]), eps,
                                            "ambient coordinates"),
                           float(drift[k]), int(steps[k]), eps, float(t_reached[k]), failure[k], hint)
        status.append(s)
        messages.append(m)
    return errors, status, messages


def _run_batch(ta: Any, lanes: list[int], X: NDArray, V: NDArray, pars: NDArray, times: NDArray, states: NDArray,
               ends: NDArray, steps: NDArray, t_reached: NDArray, failure: list[str | None],
               pressed: Listener) -> None:
    """Integrate the trajectories ``lanes`` on the batch integrator ``ta``, filling their rows of the outputs.

    Unused lanes (a short last batch) carry a copy of a live trajectory, whose
    results are discarded.  A lane that reaches ``t_final`` is done; a lane
    that reports an error (a non-finite state) has failed; any other lane was
    stopped by its neighbours and runs again from the start, without the
    failed ones (the steps of a lane do not depend on the others).  A lane
    counts as done only at ``t_final``: heyoka reports ``time_limit`` for
    lanes held at the start by a neighbour that failed in its first step.
    After a Ctrl-C (``pressed``: a step callback stops the batch after its step) every lane not done is
    interrupted where it stopped.
    """
    B = ta.batch_size
    live = list(lanes)
    callback = (lambda ta: not pressed()) if pressed.live else None  # a Python call a step: only if it can matter
    while live:
        fill = live + [live[0]] * (B - len(live))
        ta.set_time(0.0)
        ta.state[:] = np.concatenate([X[fill].T, V[fill].T])
        ta.pars[:] = pars[: len(ta.pars), fill]
        _, out = ta.propagate_grid(np.ascontiguousarray(np.repeat(times[:, None], B, axis=1)), callback=callback)
        interrupted = pressed()
        m, results = len(live), ta.propagate_res[: len(live)]  # a new list at each read: read once
        outcomes = [res[0] for res in results]
        steps[live] = [res[3] for res in results]
        t_reached[live] = ta.time[:m]
        states[live] = np.moveaxis(out[:, :, :m], 2, 0)
        ends[live] = ta.state[:, :m].T
        rerun = []
        for outcome, k in zip(outcomes, live):
            if outcome == hy.taylor_outcome.time_limit and t_reached[k] == times[-1]:
                continue
            if outcome.name.startswith("err") or interrupted:
                failure[k] = str(outcome) if outcome.name.startswith("err") else INTERRUPTED
                states[k, ~(np.abs(times) <= abs(t_reached[k]))] = np.nan  # heyoka never got there
            else:
                rerun.append(k)
        if len(rerun) == len(live):  # nobody failed, nobody finished: nothing would change on a rerun
            for k in rerun:
                failure[k] = f"stopped before t_final ({outcomes[live.index(k)]})"
            return
        live = rerun
