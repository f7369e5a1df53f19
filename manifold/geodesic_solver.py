"""Geodesics through an atlas: one loop, pluggable steppers, chart switches on events.

:func:`solve_chart_exp_ode` integrates the geodesic equations of an
:class:`~manifold.metric.InducedMetric` whose charts are
:class:`~manifold.symbolic.SymbolicChart` s of one family.  In the active chart
``i`` a :class:`~manifold.steppers.Stepper` (heyoka's Taylor method by
default) runs until ``t_final`` or until a terminal event
``quality_i(a) = q_out`` (before the chart's singular set).  At the event the
point ``p`` and embedded velocity ``v = J c`` are computed, the best chart
``j`` and its ``a_j`` come from ``atlas.best_chart`` (closed-form inverse, then
polished by Newton steps in the working precision), and
``c_j = g_j^{-1} J_j^T K v`` (exact for the tangent ``v``, so energy is
unchanged).  The best chart has quality far above ``q_out`` (hysteresis), so
switches cannot chatter.  The loop is written once; steppers differ only in
how they advance inside a chart.  A quality that the family bounds above
``q_out`` everywhere gets no switch event (:func:`needed_switches`).
"""

from __future__ import annotations

import numbers
import time
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .atlas import Atlas
from .budget import DEFAULT_BUDGET, Budget, spending, spent_message
from .compiled import compiled
from .events import STOP, WRAP
from .interrupt import BUDGET, INTERRUPTED, SolveInterrupted, interruptible, settled
from .metric import InducedMetric
from .options import (DEFAULT_PRECISION, DEFAULT_SAVE, DEFAULT_START, Precision, SaveAt, StartCheck, check_group,
                      takes_option_groups)
from .precision import as_fp, two_pi, unit_roundoff
from .progress import ProgressArgument, as_callback, reporting, solve_progress
from .solution import ChartSwitch, GeodesicIntegrationError, GeodesicSolution, PointDense, Segment, SolverStats, SolveStatus
from .steppers import Stepper, TaylorStepper
from .symbolic import SymbolicChart
from .validation import check_bool, check_index, check_real, check_time_grid, real_array


#: A start point whose chart parameters give back a point farther than this (times ``max(1, |p0|)``) is refused:
#: the start is never silently moved.
START_POINT_TOLERANCE = 1e-9
#: A quality whose floor lies within this of ``q_out`` keeps its switch event (:func:`needed_switches`).
FLOOR_MARGIN = 1e-9


class _NoGoodChart(Exception):
    """No chart has quality above ``q_out`` at a switch."""


class _NumericsOnDemand(dict):
    """Chart index -> :class:`~manifold.compiled.ChartNumerics`, each built when a solve first enters its chart."""

    def __init__(self, charts: list, K: NDArray, q_out: float, fp_type: Any) -> None:
        super().__init__()
        self.charts, self.K, self.q_out, self.fp_type = charts, K, q_out, fp_type

    def __missing__(self, i: int) -> Any:
        self[i] = self.charts[i].numerics(self.K, self.q_out, self.fp_type)
        return self[i]


@takes_option_groups
def solve_chart_exp_ode(
    metric: InducedMetric,
    p0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    stepper: Stepper | None = None,
    precision: Precision = DEFAULT_PRECISION,
    q_out: float | None = None,
    switching: bool = True,
    form: str = "embedded",
    start: StartCheck = DEFAULT_START,
    save: SaveAt = DEFAULT_SAVE,
    max_switches: int = 1_000_000,
    chart: int | None = None,
    throw: bool = True,
    progress: ProgressArgument = None,
    budget: Budget = DEFAULT_BUDGET,
) -> GeodesicSolution:
    """Integrate the geodesic from point ``p0`` with velocity ``v0`` for ``0 <= t <= t_final``.

    Parameters
    ----------
    metric
        Induced metric on an atlas of :class:`~manifold.symbolic.SymbolicChart` s of one family.
    p0, v0
        Start point and embedded velocity (shape ``(N,)``, ``N = atlas.ambient_dim``);
        with ``chart`` given, chart parameters ``a`` and coefficients ``c`` instead.
    t_final
        Final time, finite; negative integrates backward.
    stepper
        How to advance inside a chart: :class:`~manifold.steppers.TaylorStepper`
        (default, heyoka) or :class:`~manifold.steppers.ScipyStepper` (comparisons).
    precision
        :class:`~manifold.options.Precision` ``(fp_type, tol)``: the floating type of the whole run --
        integrator, transition maps, energies, ``sol(t)`` -- (default float64), and the tolerance of the default
        Taylor stepper (``None``: 1e-14 in float64, the machine epsilon of other types;
        :func:`manifold.compiled.default_tolerance`); give ``tol`` to the stepper instead when passing one.
    q_out
        Switch threshold on chart quality, in ``(0, 1)``; default ``atlas.switch_threshold``.
    switching
        ``False`` stays in the start chart whatever happens (for studies of
        single-chart failure near a pole).
    form
        ``"embedded"`` (default) or ``"christoffel"`` (cross-check).
    start
        :class:`~manifold.options.StartCheck` ``(tangent_tol, project_velocity)``: a ``v0`` off the tangent
        space by more than ``tangent_tol * max(1, |v0|)`` (default ``1e-9``) raises ``ValueError``, unless
        ``project_velocity``: then it is replaced by its K-orthogonal projection on the tangent space.
    save
        :class:`~manifold.options.SaveAt` ``(t_eval, dense)``: the times (within ``[0, t_final]``, in
        integration order) at which points and velocities are recorded in ``sol.points``/``sol.velocities``,
        and whether to keep the continuous output (``(order+1) * 2 dim`` numbers per Taylor step, default),
        needed to evaluate the solution at any ``t``; ``SaveAt(t_eval, dense=False)`` keeps memory bounded by
        ``len(t_eval)``.
    max_switches
        Safety limit on the number of chart switches.
    chart
        Start in this chart, with ``(p0, v0)`` given as its parameters ``a``
        and coefficients ``c``.  Default: the best chart at ``p0``.
    throw
        If true (default), a solve that does not reach ``t_final`` raises
        :class:`~manifold.solution.GeodesicIntegrationError` carrying the partial
        solution; if false, it returns it with ``status`` saying why.
    progress
        Report compiles and the time reached (after every segment, and
        between them at most every ``manifold.progress.STEP_INTERVAL`` s):
        ``True`` (a tqdm bar), a callable taking a
        :class:`~manifold.progress.ProgressUpdate`, ``False``, or ``None``
        (report only inside a :func:`manifold.progress.reporting` block).
    budget
        The :class:`~manifold.budget.Budget` of Taylor steps and dense-output bytes (default
        :data:`~manifold.budget.DEFAULT_BUDGET`); spent, the solve stops with status ``BUDGET_EXCEEDED``
        and a message that names the budget and the estimated need.

    Returns
    -------
    GeodesicSolution
    """
    wall0 = time.perf_counter()
    if not isinstance(metric, InducedMetric):
        raise TypeError(f"metric must be a manifold.InducedMetric (an atlas with its metric), got {metric!r}")
    precision, save = check_group("precision", precision, Precision), check_group("save", save, SaveAt)
    fp_type, tol, dense, t_eval = precision.fp_type, precision.tol, save.keeps_dense(True), save.t_eval
    start = check_group("start", start, StartCheck)
    report = as_callback(progress)
    switching = check_bool("switching", switching)
    throw = check_bool("throw", throw)
    if isinstance(max_switches, (bool, np.bool_)) or not isinstance(max_switches, numbers.Integral) or max_switches < 1:
        raise ValueError(f"max_switches must be a positive integer, got {max_switches!r}")
    if stepper is None:
        stepper = TaylorStepper(tol)
    elif not isinstance(stepper, Stepper):
        raise TypeError(f"stepper must be None or a manifold.steppers.Stepper instance (TaylorStepper(), "
                        f"SundmanStepper(...), ScipyStepper(...)), got {stepper!r}")
    elif tol is not None:
        raise ValueError("give tol to the stepper (e.g. TaylorStepper(tol=...)), not beside it in precision=")
    with reporting(report):  # the start compiles the transfer and quality functions
        sol, i, a, c, q_event, t_end, grid, resting = _start(metric, p0, v0, t_final, fp_type, stepper, q_out,
                                                             switching, start, t_eval, chart)
    switch_seconds = time.perf_counter() - wall0
    atlas, num, k = metric.atlas, sol.chart_numerics, metric.atlas.dim
    energy_tol = stepper.relative_tolerance(fp_type)
    family = compiled(atlas.charts[0].family)
    switches = needed_switches(atlas, q_event)
    events = stepper.events(family, fp_type, form, switches)  # what each index means: switch, stop (wrap: dense steppers)
    turn = two_pi(fp_type)
    backward = t_end < 0
    sign = -1.0 if backward else 1.0
    n_wraps, n_grid, status, message = 0, 0, SolveStatus.SUCCESS, ""
    t0 = time.perf_counter()
    with solve_progress(report, sol) as reports, stepper.session(family, fp_type, form=form, backward=backward,
                                                                   switches=switches) as advance, \
            interruptible() as pressed, spending(budget) as account:
        compile_seconds = time.perf_counter() - t0
        t = fp_type(0.0)
        carried = np.zeros(0, dtype=a.dtype)  # what a stepper carries after (a, c): ambient, the same in every chart
        if switching and float(atlas.charts[i].quality(a.astype(float))) < q_event:
            i, a, c = _switch(sol, i, a, c, t, q_event)  # its event would never fire: it starts past it
        rest = resting and not stepper.moves_at_rest(form)  # a Jacobi field carried moves even at rest
        if rest:
            # the geodesic is the start to the working precision; a stepper would see no scale of time at all
            # (Sundman's time ran to |tau| = 1e30 without moving, and raised)
            y = np.concatenate([a, c])
            sol.segments.append(Segment(i, t, fp_type(t_end), 0, PointDense(y) if dense else None))
            if grid is not None:
                sol.points, sol.velocities = num[i].point_velocity_states(np.repeat(y[None, :], len(grid), axis=0))
            t = fp_type(t_end)
        while not rest:
            adv = advance(t, np.concatenate([a, c, carried]), fp_type(t_end), num[i].pars, dense or grid is not None)
            sol.segments.append(Segment(i, t, adv.t, adv.n_steps, adv.dense if dense else None))
            _, _, E = num[i].point_velocity_energy(adv.step_states[:, :k].T, adv.step_states[:, k : 2 * k].T)
            recorded = len(sol.energies)
            sol.energy_times.extend(adv.step_times)
            sol.energies.extend(np.atleast_1d(E))
            violation = sol.energy_violation(recorded, energy_tol, f"chart {atlas.ids[i]}")
            if grid is not None:
                n_grid = sol.record_grid(grid, n_grid, adv, sign, num[i].point_velocity_states)
            a, c, carried, t = adv.y[:k], adv.y[k : 2 * k], adv.y[2 * k :], adv.t
            n_wraps += adv.n_wraps  # a Taylor stepper wraps between its steps; a dense stepper ends at a wrap event
            if reports is not None:
                reports.segment(t, f"chart {atlas.ids[i]}")
            if violation is not None:
                status, message = SolveStatus.ENERGY_CHECK_FAILED, violation
                break
            if pressed() and adv.failure is None:  # Ctrl-C between segments: stop at a whole one
                status, message = SolveStatus.INTERRUPTED, f"{INTERRUPTED} at t = {t} (chart {atlas.ids[i]})"
                break
            if adv.failure is not None or adv.event is None:
                if adv.failure == INTERRUPTED:
                    status, message = SolveStatus.INTERRUPTED, f"{INTERRUPTED} at t = {t} (chart {atlas.ids[i]})"
                elif adv.failure == BUDGET:
                    status, message = SolveStatus.BUDGET_EXCEEDED, spent_message(account, float(t), t_end)
                elif adv.failure is not None:
                    status, message = SolveStatus.STEPPER_FAILED, f"integration failed at t = {t}: {adv.failure} (chart {atlas.ids[i]})"
                break
            event = events[adv.event]
            if event.kind == STOP:  # a term's stop: Sundman's clock reached t_final, or a term's own end of the motion
                if t != t_end:
                    message = f"stopped at t = {t} by a stop event (chart {atlas.ids[i]})"
                break
            if event.kind == WRAP:  # a dense stepper's periodic parameter left [-pi, pi]: wrap it, same chart
                a[event.parameter] += turn if event.shift > 0 else -turn
                n_wraps += 1
                continue
            if len(sol.switches) >= max_switches:
                status, message = SolveStatus.MAX_SWITCHES, f"more than max_switches = {max_switches} chart switches by t = {t}"
                break
            s0 = time.perf_counter()
            try:
                i, a, c = _switch(sol, i, a, c, t, q_event)
            except _NoGoodChart as e:
                status, message = SolveStatus.NO_GOOD_CHART, str(e)
                break
            switch_seconds += time.perf_counter() - s0
        pressed_at_all = pressed()  # also where another failure ended the run: a Ctrl-C is never swallowed
    status, message = settled(pressed_at_all, status, message, t)
    sol.final_state = (i, a, c)
    sol.status, sol.message = status, message or "reached t_final"
    sol.stats = SolverStats(sol.n_steps, sol.n_switches, n_wraps, compile_seconds, switch_seconds,
                            time.perf_counter() - wall0)
    if reports is not None:
        reports.done(t, sol.message)
    if status is SolveStatus.INTERRUPTED:
        raise SolveInterrupted(message, sol)
    if status is not SolveStatus.SUCCESS and throw:
        raise GeodesicIntegrationError(message, sol)
    return sol


def needed_switches(atlas: Atlas, q_out: float) -> tuple[int, ...] | None:
    """The qualities whose switch events can fire at the threshold ``q_out``: those whose floor over every chart of
    ``atlas`` (:attr:`~manifold.atlas.Atlas.chart_quality_floors`) does not lie above it; ``None`` (all) where the
    family knows no floors.  With switching off (``q_out = -2``, below every quality) none.
    """
    floor = atlas.chart_quality_floors
    if floor is None:
        return None
    # an absolute margin: a quality evaluated in floating point may dip below its exact value by rounding
    kept = tuple(int(m) for m in np.flatnonzero(floor <= q_out + FLOOR_MARGIN))
    return None if len(kept) == len(floor) else kept  # all of them: the default integrator, not a copy of it


def _start(metric, p0, v0, t_final, fp_type, stepper, q_out, switching, start, t_eval, chart):
    """Validate the inputs; return the empty solution, the start state ``(i, a, c)``, ``q_out`` for the events,
    ``t_final`` as a float, the sorted output grid (or ``None``) and whether the start is :func:`at_rest`.

    ``q_out`` comes back as the value given to the events: below any quality
    (-2) when ``switching`` is off.
    """
    atlas = metric.atlas
    if atlas.dim == 0:
        raise ValueError("a 0-dimensional manifold has no geodesic motion")
    if not all(isinstance(ch, SymbolicChart) for ch in atlas.charts):
        raise TypeError("geodesic solvers need SymbolicChart charts (heyoka expressions of the chart map)")
    t_final = check_real("t_final", t_final)
    if q_out is None:
        q_out = atlas.switch_threshold
    else:
        q_out = check_real("q_out", q_out, positive=True)
        floor = atlas.quality_floor
        if q_out >= (1.0 if floor is None else floor):
            raise ValueError(f"q_out must lie in (0, {1.0 if floor is None else floor:g}): this atlas guarantees a chart "
                             f"of quality {floor} everywhere, not more; got q_out = {q_out!r}")
    if not switching:
        q_out = -2.0
    grid = None
    if t_eval is not None:
        grid = check_time_grid(t_eval, t_final)
    if chart is not None:
        chart = check_index("chart", chart, len(atlas))
        a0, c0 = _as_vector(p0, "a", atlas.dim), _as_vector(v0, "c", atlas.dim)
        p0, v0 = atlas.get_point(chart, a0), atlas.charts[chart].tangent_vector(a0, c0)
    p0, v0 = _as_vector(p0, "p0", atlas.ambient_dim), _as_vector(v0, "v0", atlas.ambient_dim)

    numerics = _NumericsOnDemand(atlas.charts, metric.K, q_out, fp_type)
    sol = GeodesicSolution(metric, fp_type, stepper.name, (0.0, t_final), numerics)
    if grid is not None:
        sol.t_eval = grid
    # validates p0 (closure, shape, finiteness)
    i, a = atlas.best_chart(p0) if chart is None else (chart, atlas.get_parameters(chart, p0))
    num = numerics[i]
    p0_fp, v0_fp = as_fp(p0, fp_type), as_fp(v0, fp_type)
    a = num.polish(as_fp(a, fp_type), p0_fp)
    c = num.coefficients(a, v0_fp)
    p_start, v_tan, E0 = num.point_velocity_energy(a[:, None], c[:, None])
    scale = max(1.0, float(np.max(np.abs(p0))))
    moved = float(np.max(np.abs((p_start[0] - p0_fp).astype(float))))
    if moved > START_POINT_TOLERANCE * scale:
        raise ValueError(f"p0 cannot be represented in chart {atlas.ids[i]} to {START_POINT_TOLERANCE:g}: its "
                         f"parameters give a point {moved:.3g} away (an ill-conditioned chart); the start is refused "
                         "rather than moved")
    off = float(np.max(np.abs((v_tan[0] - v0_fp).astype(float))))
    if off > start.tangent_tol * max(1.0, float(np.max(np.abs(v0)))) and not start.project_velocity:
        raise ValueError(
            f"v0 is not tangent at p0: it is {off:.3g} away from the tangent space "
            f"(allowed {start.tangent_tol:g} * max(1, |v0|)); pass start=StartCheck(project_velocity=True) to "
            "project it"
        )
    if not np.isfinite(float(E0[0])):
        raise ValueError(f"v0 gives a non-finite kinetic energy {float(E0[0])} (|v0| = {np.max(np.abs(v0)):.3g})")
    sol.energy_times.append(fp_type(0.0))
    sol.energies.append(E0[0])
    return sol, i, a, c, q_out, t_final, grid, at_rest(p_start[0], v_tan[0], t_final, fp_type)


def _switch(sol: GeodesicSolution, i: int, a: NDArray, c: NDArray, t: Any, q_out: float) -> tuple:
    """Move the state ``(a, c)`` of chart ``i`` to the best chart; log the switch."""
    assert sol.metric is not None  # the chart solver always makes its solution with the metric
    atlas, num = sol.metric.atlas, sol.chart_numerics
    p, v, _ = num[i].point_velocity_energy(a[:, None], c[:, None])
    p, v = p[0], v[0]
    q_from = float(atlas.charts[i].quality(a.astype(float)))
    j, a_j, q_to = atlas.chart_choice(p.astype(float))
    j, q_to = int(j), float(q_to)  # one point: one index, one quality
    a_j = num[j].polish(as_fp(a_j, sol.fp_type), p)
    if q_to <= q_out:
        raise _NoGoodChart(f"no chart of quality above q_out = {q_out} at t = {t} (best {q_to:.3g})")
    p_j = num[j].point_velocity_energy(a_j[:, None], np.zeros((len(a_j), 1)))[0][0]
    gap = float(np.max(np.abs((p_j - p).astype(float))))
    sol.switches.append(ChartSwitch(float(t), i, j, q_from, q_to, gap))
    return j, a_j, num[j].coefficients(a_j, v)


def at_rest(p: ArrayLike, v: ArrayLike, t_final: float, fp_type: Any) -> bool:
    """Whether the geodesic from the point ``p`` with embedded velocity ``v`` stays at ``p`` to the precision of
    ``fp_type`` over ``|t_final|``: ``max |v| |t_final|`` at most the unit roundoff times ``max |p|`` (a zero
    velocity, or one of 1e-300; relative to the point's own size, so that a chain of nanometre rods still moves)."""
    travel = float(np.max(np.abs(np.asarray(v).astype(float)))) * abs(float(t_final))
    return travel <= unit_roundoff(fp_type) * max(float(np.max(np.abs(np.asarray(p).astype(float)))),
                                                  np.finfo(float).tiny)


def _as_vector(x: ArrayLike, name: str, N: int) -> NDArray:
    x = real_array(name, x)
    if x.shape != (N,):
        raise ValueError(f"{name} must have shape ({N},), got {x.shape}")
    return x
