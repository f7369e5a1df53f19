"""The one result type of every geodesic method: :class:`GeodesicSolution`.

Whatever the stepper (heyoka's Taylor method, scipy's ``solve_ivp``), a solve
returns a :class:`GeodesicSolution`: status and :class:`SolverStats`, the
chart :class:`Segment` s and the :class:`ChartSwitch` log, the energy record,
vectorised evaluation ``sol(ts)`` and ``sol.parameters(ts)`` from a compact
dense output, the states on a requested time grid (``t_eval``), and the end
state.  A failure raises :class:`GeodesicIntegrationError` carrying the
partial solution, or, with ``throw=False``, is reported in ``status``.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from functools import cached_property
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .compiled import ChartNumerics
from .metric import InducedMetric
from .precision import as_fp
from .validation import real_array


#: The energy check: a solve fails where ``|E - E0| > (ENERGY_SAFETY sqrt(steps + 1) + ENERGY_FLOOR) tol E0``, ``tol`` the
#: stepper's relative tolerance.  Well-conditioned runs stay below ``10 tol sqrt(steps)``; near a fold (L close to n-2) the
#: chart conditioning costs up to two more digits.
ENERGY_SAFETY = 1000.0
#: Evaluating ``E`` itself loses ``tol`` times the chart's conditioning (up to ``1/sqrt(L - (n-2))`` near a fold).
ENERGY_FLOOR = 1e5


def energy_bound(n_steps: int, tol: float) -> float:
    """The solvers' bound on ``|E - E0| / E0`` after ``n_steps`` steps: ``(ENERGY_SAFETY sqrt(n_steps + 1) + ENERGY_FLOOR) tol``."""
    return float((ENERGY_SAFETY * math.sqrt(n_steps + 1) + ENERGY_FLOOR) * tol)  # math: no numpy scalar round trip


def energy_violation(deviations: NDArray, times: Any, n_steps: int, tol: float, where: str) -> str | None:
    """A sentence naming the first energy that breaks :func:`energy_bound`, else ``None``.

    Parameters
    ----------
    deviations
        ``|E_k - E_0| / E_0`` as floats (NaN breaks the bound).
    times
        The times of those energies.
    n_steps
        Steps taken so far (the bound grows like their square root).
    tol
        The stepper's relative tolerance.
    where
        The place (a chart, ambient coordinates), for the sentence.
    """
    err = np.asarray(deviations, dtype=float)
    bound = energy_bound(n_steps, tol)
    within = err <= bound  # NaN counts as a violation
    if within.all():
        return None
    k = int(np.argmax(~within))
    return (f"energy check failed at t = {float(times[k]):.6g} in {where}: "
            f"|E - E0| / E0 = {err[k]:.3g} exceeds the bound {bound:.3g} = ({ENERGY_SAFETY:g} sqrt(steps + 1) + "
            f"{ENERGY_FLOOR:g}) tol (tol = {tol:.3g})")


class SolveStatus(enum.Enum):
    """How a solve ended."""

    SUCCESS = "success"
    STEPPER_FAILED = "the stepper failed"
    MAX_SWITCHES = "max_switches chart switches reached"
    NO_GOOD_CHART = "no chart of quality above q_out"
    ENERGY_CHECK_FAILED = "the energy left its bound"
    CONSTRAINT_CHECK_FAILED = "the state left the constraints"
    CARRIED_CHECK_FAILED = "a quantity carried along the geodesic left its bound"
    INTERRUPTED = "interrupted by Ctrl-C (KeyboardInterrupt)"
    BUDGET_EXCEEDED = "the budget of steps, of dense output or of CPU time is spent"


class GeodesicIntegrationError(RuntimeError):
    """A solve did not reach ``t_final``; ``solution`` holds what was computed up to there."""

    def __init__(self, message: str, solution: "GeodesicSolution") -> None:
        super().__init__(message)
        self.solution = solution


@dataclass(frozen=True)
class ChartSwitch:
    """One chart switch: when, from which chart to which, and the qualities there."""

    time: float
    from_chart: int
    to_chart: int
    quality_from: float
    quality_to: float
    point_gap: float  # max |p_after - p_before| in the working precision: the transfer's own error


@dataclass(frozen=True)
class SolverStats:
    """Counts and timings of one solve (wall-clock seconds)."""

    n_steps: int
    n_switches: int
    n_wraps: int
    compile_seconds: float  # building or fetching compiled code (about 0 once cached)
    switch_seconds: float  # starting and switching charts (inverse maps, transfers)
    wall_seconds: float  # the whole solve


class DenseOutput(Protocol):
    """Continuous output of one segment: states ``(len(ts), 2k)`` at times ``ts`` inside it."""

    def __call__(self, ts: NDArray) -> NDArray: ...

    @property
    def nbytes(self) -> int:
        """Bytes held by the continuous output."""
        ...


class TaylorDense:
    """Taylor polynomials of every step: ``y(t) = sum_j tcs[s, :, j] (t - times[s])^j`` on step ``s``.

    ``(order + 1) * 2k`` numbers per step, evaluated by a vectorised Horner
    scheme in the working precision.
    """

    def __init__(self, times: NDArray, tcs: NDArray, fp_type: Any) -> None:
        self.times, self.tcs, self.fp_type = times, tcs, fp_type
        self._sign = 1.0 if times[-1] >= times[0] else -1.0
        self._starts = np.asarray(times[:-1], dtype=float) * self._sign

    @property
    def nbytes(self) -> int:
        """Bytes held: the step times and the Taylor coefficients."""
        return int(self.times.nbytes + self.tcs.nbytes)

    def __call__(self, ts: NDArray) -> NDArray:
        s = np.searchsorted(self._starts, np.asarray(ts, dtype=float) * self._sign, side="right") - 1
        s = np.clip(s, 0, len(self._starts) - 1)
        return self.at(s, as_fp(ts, self.fp_type) - self.times[s])

    def at(self, steps: NDArray, h: NDArray) -> NDArray:
        """States ``(m, 2k)`` at offsets ``h`` from the starts of the steps ``steps`` (both ``(m,)``)."""
        return polynomial_values(self.tcs[steps], h[:, None])


class SecondOrderDense(TaylorDense):
    """Taylor polynomials of every step of a system whose first ``N`` equations are ``x' = v`` (positions
    ``x``, velocities ``v`` the next ``N`` state components): only the positions' polynomials are kept.

    On such a system the velocity's Taylor coefficients are the derivative's, ``v_j = (j + 1) x_{j+1}``
    for ``j < order``, so ``x_0 .. x_order`` and the velocity's last coefficient ``v_order`` hold both
    polynomials: ``(order + 2) N`` numbers per step instead of :class:`TaylorDense`'s ``(order + 1) 2N``.
    Positions come from the same coefficients as there (the same numbers); velocities from
    ``sum_{j < order} (j + 1) x_{j+1} h^j + v_order h^order``, whose coefficients differ from the velocity's
    own by the rounding of ``x_{j+1} = v_j / (j + 1)`` in the Taylor recursion (``v_0 = x_1`` exactly).
    """

    def __init__(self, times: NDArray, tcs: NDArray, top: NDArray, fp_type: Any) -> None:
        super().__init__(times, tcs, fp_type)  # tcs: the positions' coefficients, (steps, N, order + 1)
        self.top = top  # the velocities' last coefficients, (steps, N)

    @cached_property
    def _factors(self) -> NDArray:
        """``(j + 1)`` for ``x_{j+1}``, ``j = 0 .. order - 1`` (built when first evaluated: most short solves never are)."""
        return as_fp(np.arange(1, self.tcs.shape[-1]), self.fp_type)

    @property
    def nbytes(self) -> int:
        """Bytes held: the step times, the positions' coefficients and the velocities' last ones."""
        return super().nbytes + int(self.top.nbytes)

    @property
    def step_velocities(self) -> NDArray:
        """The velocity at the start of every step, ``v_0 = x_1`` (exact)."""
        return self.tcs[:, :, 1]

    def at(self, steps: NDArray, h: NDArray) -> NDArray:
        """States ``(m, 2N)``, positions then velocities, at offsets ``h`` from the starts of the steps ``steps``."""
        x = self.tcs[steps]
        v = np.concatenate([x[..., 1:] * self._factors, self.top[steps][..., None]], axis=-1)
        return np.concatenate([polynomial_values(x, h[:, None]), polynomial_values(v, h[:, None])], axis=-1)


class PointDense:
    """The continuous output of a segment without steps (one that starts where it ends: a switch that lands
    on ``t_final``): its one state, at its one time."""

    def __init__(self, y: NDArray) -> None:
        self.y = y

    @property
    def nbytes(self) -> int:
        """Bytes held: the one state."""
        return int(self.y.nbytes)

    def __call__(self, ts: NDArray) -> NDArray:
        return np.repeat(self.y[None, :], np.size(ts), axis=0)


def polynomial_values(coeffs: NDArray, h: NDArray) -> NDArray:
    """``sum_j coeffs[..., j] h^j`` by Horner's scheme, ``h`` broadcast against ``coeffs[..., 0]``."""
    out = coeffs[..., -1]
    for j in range(coeffs.shape[-1] - 2, -1, -1):
        out = out * h + coeffs[..., j]
    return out


class CallableDense:
    """Dense output from a callable ``f(ts) -> (2k, len(ts))`` (scipy's ``OdeSolution``)."""

    def __init__(self, f: Any, n_steps: int, dim: int) -> None:
        self.f, self._nbytes = f, 8 * n_steps * dim * 8  # DOP853's interpolant: ~7 coefficients per component

    @property
    def nbytes(self) -> int:
        """Bytes held, estimated as 8 doubles per step and component (DOP853's interpolant)."""
        return self._nbytes

    def __call__(self, ts: NDArray) -> NDArray:
        return np.asarray(self.f(np.asarray(ts, dtype=float))).T


@dataclass
class Segment:
    """A stretch of the solution integrated in one chart, or in ambient coordinates.

    ``chart`` is the chart index, whose state is ``(a, c)``; ``None`` for a
    method that integrates the embedded point and velocity ``(p, v)`` directly
    (hinge coordinates).  ``dense`` is ``None`` when not kept.
    """

    chart: int | None
    t_start: Any
    t_end: Any
    n_steps: int
    dense: DenseOutput | None = field(default=None, repr=False)


@dataclass
class GeodesicSolution:
    """A geodesic stitched from chart segments.

    Attributes
    ----------
    metric
        The :class:`~manifold.metric.InducedMetric` (its atlas names the charts);
        ``None`` for a method without an atlas (then there are no chart parameters).
    fp_type
        Floating type of the integration.
    method
        Name of the stepper.
    t_span
        ``(0, t_final)`` requested (``t_final < 0`` for backward integration).
    status, message
        :class:`SolveStatus` and a sentence saying what happened.
    segments, switches
        :class:`Segment` s in integration order and the :class:`ChartSwitch` log.
    energy_times, energies
        Kinetic energy ``1/2 c^T g c`` at every step (``dense=True``) or at
        every segment end (switches, ``t_final``; angle wraps too with a stepper that locates them as events).
    t_eval, points, velocities
        The requested output grid and the points and embedded velocities on it
        (``None`` without ``t_eval``), in ``fp_type``.
    final_state
        ``(chart, a, c)`` where the solve stopped.
    chart_numerics
        Chart index -> :class:`~manifold.compiled.ChartNumerics` in ``fp_type``.
    stats
        :class:`SolverStats`.
    ambient_dim
        ``N``, set by the solvers in ambient coordinates (whose state may carry more than ``(p, v)``).
    """

    metric: InducedMetric | None
    fp_type: Any
    method: str
    t_span: tuple[float, float]
    chart_numerics: dict[int, ChartNumerics] = field(repr=False)
    status: SolveStatus = SolveStatus.SUCCESS
    message: str = ""
    segments: list[Segment] = field(default_factory=list, repr=False)
    _segments_counted: int = field(default=0, init=False, repr=False, compare=False)  # by n_steps, so far
    _steps_counted: int = field(default=0, init=False, repr=False, compare=False)
    switches: list[ChartSwitch] = field(default_factory=list, repr=False)
    energy_times: list = field(default_factory=list, repr=False)
    energies: list = field(default_factory=list, repr=False)
    t_eval: NDArray | None = field(default=None, repr=False)
    points: NDArray | None = field(default=None, repr=False)
    velocities: NDArray | None = field(default=None, repr=False)
    final_state: tuple | None = field(default=None, repr=False)
    stats: SolverStats | None = field(default=None, repr=False)
    ambient_dim: int | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        err = f"{self.relative_energy_error:.1e}" if self.energies else "n/a"
        wall = f", {self.stats.wall_seconds:.3g} s" if self.stats else ""
        return (f"GeodesicSolution({self.method}, {self.status.value}, t = 0 -> {float(self.t_reached):g}, "
                f"{self.n_steps} steps, {self.n_switches} switches, energy error {err}{wall})")

    @property
    def success(self) -> bool:
        """True if the solve reached ``t_final`` (``status`` is :attr:`SolveStatus.SUCCESS`)."""
        return self.status is SolveStatus.SUCCESS

    @property
    def t_reached(self) -> Any:
        """Where the solve stopped (``t_final`` on success)."""
        return self.segments[-1].t_end if self.segments else 0.0

    @property
    def n_switches(self) -> int:
        """Number of chart switches (angle wraps are not switches)."""
        return len(self.switches)

    @property
    def n_steps(self) -> int:
        """Accepted steps of the stepper, over all segments."""
        # counted on from the segments added since the last call: the solvers ask after each segment, and a long
        # chart solve has 1e5 segments (a sum over all of them each time made the loop quadratic)
        for segment in self.segments[self._segments_counted:]:
            self._segments_counted += 1
            self._steps_counted += segment.n_steps
        return self._steps_counted

    @property
    def dense_nbytes(self) -> int:
        """Bytes held by the dense output."""
        return sum(s.dense.nbytes for s in self.segments if s.dense is not None)

    @property
    def relative_energy_error(self) -> float:
        """``max_t |E(t) - E(0)| / E(0)`` over the recorded energies (a float for every method)."""
        return float(np.max(self.energy_deviations()))

    def energy_deviations(self, start: int = 0) -> NDArray:
        """``|E_k - E_0| / E_0`` (``|E_k|`` if ``E_0 = 0``) for the energies recorded from index ``start``, as floats.

        The differences are taken in the working precision: rounding each energy
        to float64 first would hide every deviation below 1e-16.
        """
        E0 = self.energies[0]
        dev = [abs(e - E0) / E0 if E0 != 0 else abs(e) for e in self.energies[start:]]
        return np.array([float(d) for d in dev])

    def energy_violation(self, start: int, tol: float, where: str) -> str | None:
        """A sentence if an energy recorded since index ``start`` breaks the solvers' bound, else ``None``
        (:func:`energy_violation` on :meth:`energy_deviations` ``(start)``)."""
        return energy_violation(self.energy_deviations(start), self.energy_times[start:], self.n_steps, tol, where)

    def record_grid(self, grid: NDArray, done: int, adv: Any, sign: float,
                    point_velocity: Callable[[NDArray], tuple[NDArray, NDArray]]) -> int:
        """Record the ``t_eval`` times inside the segment just integrated; return how many are done.

        ``adv`` is the stepper's :class:`~manifold.steppers.Advance`: its samples, if it was given the grid's
        times from ``done`` on (as many as it reached), else its dense output evaluated at the times up to where it
        stopped; ``point_velocity`` maps states ``(m, 2k)`` to points and embedded velocities ``(m, N)`` each;
        ``sign`` is the direction of integration.
        """
        if adv.samples is not None:  # counted, not compared with adv.t: the times were reached in the working precision
            upto, states = done + len(adv.samples), adv.samples
        else:
            upto = int(np.searchsorted(sign * grid, sign * float(adv.t), side="right"))
            states = adv.dense(grid[done:upto]) if upto > done and adv.dense is not None else None
        if upto <= done or states is None:
            return done
        p, v = point_velocity(states)
        if self.points is None or self.velocities is None:  # the first grid times: allocate both
            self.points = np.empty((len(grid), p.shape[1]), dtype=p.dtype)
            self.velocities = np.empty_like(self.points)
        self.points[done:upto], self.velocities[done:upto] = p, v
        return upto

    def end_state(self) -> tuple[NDArray, NDArray]:
        """Point and embedded velocity where the solve stopped (available also with ``dense=False``)."""
        if self.final_state is None:
            raise ValueError("the solve has not finished: no end state yet")
        i, a, c = self.final_state
        if i is None:
            return a, c
        p, v, _ = self.chart_numerics[i].point_velocity_energy(a[:, None], c[:, None])
        return p[0], v[0]

    def _locate(self, ts: NDArray) -> NDArray:
        """Segment index of each time in ``ts`` (1-d float); raises outside the span or without dense output."""
        t0, t1 = 0.0, float(self.t_reached)
        lo, hi = min(t0, t1), max(t0, t1)
        bad = ~((ts >= lo) & (ts <= hi))  # also catches NaN
        if np.any(bad):
            raise ValueError(f"t = {ts[bad][:5]} lies outside the solution's time span [{lo}, {hi}]")
        if any(s.dense is None for s in self.segments):
            raise ValueError("the solution was computed with SaveAt(dense=False): no continuous output "
                             "(use save=SaveAt(t_eval=...) to record a grid, or SaveAt(dense=True); the state where "
                             "the solve stopped needs neither: end_state())")
        sign = 1.0 if t1 >= t0 else -1.0
        ends = sign * np.array([float(s.t_end) for s in self.segments])
        # a time on a boundary belongs to the later segment: its start is the state after a switch or projection
        return np.minimum(np.searchsorted(ends, sign * ts, side="right"), len(self.segments) - 1)

    def _states(self, flat: NDArray) -> tuple[NDArray, NDArray]:
        """Segment index and dense state of each time in the 1-d ``flat`` (none for no times)."""
        seg = self._locate(flat)
        if not flat.size:  # the state's width, from one evaluation at the start
            first = self.segments[0]
            assert first.dense is not None  # _locate refuses a solution without dense output
            return seg, first.dense(np.array([float(first.t_start)]))[:0]
        rows = [(np.nonzero(seg == s)[0], self.segments[s].dense(flat[seg == s])) for s in np.unique(seg)]
        width = max(vals.shape[1] for _, vals in rows)
        states = np.empty((flat.size, width), dtype=rows[0][1].dtype)
        for sel, vals in rows:
            states[sel, : vals.shape[1]] = vals
        return seg, states

    def states(self, t: ArrayLike) -> NDArray:
        """The integrator's state at time(s) ``t``, shape ``t.shape + (width,)``, in ``fp_type``, as integrated
        (chart segments: ``(a, c)`` padded to the widest segment; ambient ones: ``(x, v)`` and any quantities
        carried along, :mod:`manifold.carried`)."""
        ts = real_array("t", t, finite=False, expected="a real time or an array of times")  # a NaN is refused by _locate, naming the span
        _, states = self._states(ts.ravel())
        return states.reshape(*ts.shape, states.shape[1])

    def parameters(self, t: ArrayLike) -> tuple:
        """Chart index, parameters ``a`` and coefficients ``c`` at time(s) ``t``.

        Scalar ``t``: ``(i, a, c)`` with ``a, c`` of shape ``(k,)``.  Array
        ``t`` (any shape): arrays of shapes ``t.shape``, ``t.shape + (k,)`` twice.
        A segment integrated in ambient coordinates is read in the best chart
        of the atlas at each time (float64 inverse).
        """
        if self.metric is None:
            raise ValueError("this solution has no atlas (solved without metric=...): no chart parameters")
        ts = real_array("t", t, finite=False, expected="a real time or an array of times")
        flat = ts.ravel()
        seg, states = self._states(flat)
        k, N = self.metric.atlas.dim, self.metric.atlas.ambient_dim
        charts = np.empty(flat.size, dtype=int)
        a = np.empty((flat.size, k), dtype=states.dtype)
        c = np.empty((flat.size, k), dtype=states.dtype)
        for m, s in enumerate(seg):
            chart = self.segments[s].chart
            if chart is None:
                p, v = states[m, :N].astype(float), states[m, N : 2 * N].astype(float)
                charts[m], a_m = self.metric.atlas.best_chart(p)
                a[m], c[m] = a_m, self.metric.atlas.charts[charts[m]].coefficients(a_m, v)
            else:
                charts[m], a[m], c[m] = chart, states[m, :k], states[m, k : 2 * k]
        if ts.ndim == 0:
            return int(charts[0]), a[0], c[0]
        return charts.reshape(ts.shape), a.reshape(*ts.shape, k), c.reshape(*ts.shape, k)

    def __call__(self, t: ArrayLike) -> tuple[NDArray, NDArray]:
        """Point ``p(t)`` and embedded velocity ``v(t)`` (shape ``t.shape + (N,)``) in the working precision."""
        ts = real_array("t", t, finite=False, expected="a real time or an array of times")
        flat = ts.ravel()
        seg, states = self._states(flat)
        # without an atlas every segment is in ambient coordinates, the state (p, v, anything carried along)
        N = self.ambient_dim or (states.shape[1] // 2 if self.metric is None else self.metric.atlas.ambient_dim)
        ps = np.empty((flat.size, N), dtype=states.dtype)
        vs = np.empty((flat.size, N), dtype=states.dtype)
        charts = np.array([-1 if self.segments[s].chart is None else self.segments[s].chart for s in seg])
        for i in np.unique(charts):
            sel = np.nonzero(charts == i)[0]
            if i < 0:  # ambient coordinates
                ps[sel], vs[sel] = states[sel, :N], states[sel, N : 2 * N]
            else:
                ps[sel], vs[sel] = self.chart_numerics[int(i)].point_velocity_states(states[sel])
        return ps.reshape(*ts.shape, N), vs.reshape(*ts.shape, N)
