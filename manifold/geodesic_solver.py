"""Geodesics through an atlas: Taylor integration in the active chart, switching on events.

:func:`solve_chart_exp_ode` integrates the geodesic equations of an
:class:`~manifold.metric.InducedMetric` whose charts are
:class:`~manifold.symbolic.SymbolicChart` s of one family.  In the active chart
``i`` heyoka's Taylor integrator runs until ``t_final`` or until a terminal
event ``quality_i(a) = q_out`` (before the chart's singular set).  At the event
the point ``p`` and embedded velocity ``v = J c`` are computed, the best chart
``j`` and its ``a_j`` come from ``atlas.best_chart`` (closed-form inverse,
then polished by Newton steps in the working precision), and
``c_j = g_j^{-1} J_j^T K v`` (exact for the tangent ``v``, so energy is
unchanged).  The best chart has quality far above ``q_out`` (hysteresis), so
switches cannot chatter.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import geodesic_system as gs
from .metric import InducedMetric
from .precision import as_fp, is_double, unit_roundoff
from .symbolic import SymbolicChart


class GeodesicIntegrationError(RuntimeError):
    """The integration broke down; ``solution`` holds what was computed up to there."""

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


@dataclass
class Segment:
    """A stretch of the solution integrated in one chart."""

    chart: int
    t_start: float
    t_end: float
    n_steps: int
    output: object | None  # heyoka continuous output (None when dense=False)


class _ChartNumerics:
    """Chart ``i`` in the working precision: its affine map and the compiled transfer function."""

    def __init__(self, chart: SymbolicChart, K: NDArray, q_out: float, fp_type: type) -> None:
        self.fp, self.k, self.N = fp_type, chart.dim, chart.ambient_dim
        self.M = as_fp(chart.linear_map, fp_type)
        self.M_inv = as_fp(chart.inverse_linear_map(), fp_type)
        self.m = chart.offset(fp_type)
        self.pars = gs.layout(chart.family).pack(chart.family_parameters, chart.core_metric(K), q_out, fp_type)
        self.cf = gs.transfer_cfunc(chart.family, fp_type)

    def _eval(self, a: NDArray, c: NDArray, u: NDArray) -> NDArray:
        """Batched transfer function: ``a``, ``c`` of shape ``(k, B)``, ``u`` of shape ``(N, B)``."""
        args = as_fp(np.concatenate([a, c, u]), self.fp)
        pars = self.pars[: self.cf.nparams, None]  # the cfunc does not use q_out
        return self.cf(args, pars=np.repeat(pars, args.shape[1], axis=1))

    def point_velocity_energy(self, a: NDArray, c: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """``p = M z(a) + m``, ``v = M J c`` and ``E`` for batches ``(k, B)``."""
        out = self._eval(a, c, np.zeros((self.N, a.shape[1])))
        z, Jc, E = out[: self.N], out[self.N : 2 * self.N], out[-1]
        return (self.M @ z).T + self.m, (self.M @ Jc).T, E

    def coefficients(self, a: NDArray, v: NDArray) -> NDArray:
        """``c = g^{-1} J^T K v``: K-orthogonal tangent coefficients of embedded ``v``."""
        out = self._eval(a[:, None], np.zeros((self.k, 1)), (self.M_inv @ v)[:, None])
        return out[2 * self.N : 2 * self.N + self.k, 0]

    def polish(self, a: NDArray, p: NDArray) -> NDArray:
        """Gauss-Newton steps ``a += g^{-1} J^T W (z* - z(a))`` toward ``p`` in the working precision.

        None in float64, where the closed-form inverse is already backward
        stable.  Beyond, steps run until one is below 4 unit roundoffs: from a
        point on the manifold (a switch) they converge quadratically, from a
        float64 start off it by ~1e-16 per step, so 512 bits need ~10.
        """
        if is_double(self.fp):
            return a
        u = unit_roundoff(self.fp)
        target = self.M_inv @ (p - self.m)
        for _ in range(2 + int(np.ceil(-np.log2(u) / 50))):
            z = self._eval(a[:, None], np.zeros((self.k, 1)), np.zeros((self.N, 1)))[: self.N, 0]
            step = self._eval(a[:, None], np.zeros((self.k, 1)), (target - z)[:, None])[2 * self.N : 2 * self.N + self.k, 0]
            a = a + step
            if float(np.max(np.abs(step))) <= 4 * u * max(1.0, float(np.max(np.abs(a)))):
                break
        return a


@dataclass
class GeodesicSolution:
    """A geodesic stitched from chart segments.

    Attributes
    ----------
    segments
        :class:`Segment` s in integration order.
    switches
        :class:`ChartSwitch` log.
    t_span
        ``(t0, t_final)`` (``t_final < t0`` for backward integration).
    energy_times, energies
        Kinetic energy ``1/2 c^T g c`` at every integrator step (``dense=True``)
        or at every segment end -- switches, angle wraps and ``t_final`` --
        (``dense=False``).
    fp_type
        Floating type of the integration.
    """

    metric: InducedMetric
    fp_type: type
    t_span: tuple[float, float]
    segments: list[Segment] = field(default_factory=list)
    switches: list[ChartSwitch] = field(default_factory=list)
    energy_times: list = field(default_factory=list)
    energies: list = field(default_factory=list)
    _numerics: dict = field(default_factory=dict, repr=False)

    final_state: tuple | None = None  # (chart index, a, c) at t_final

    def end_state(self) -> tuple[NDArray, NDArray]:
        """Point and embedded velocity at ``t_final`` (available also with ``dense=False``)."""
        i, a, c = self.final_state
        p, v, _ = self._numerics[i].point_velocity_energy(a[:, None], c[:, None])
        return p[0], v[0]

    @property
    def n_switches(self) -> int:
        return len(self.switches)

    @property
    def n_steps(self) -> int:
        return sum(s.n_steps for s in self.segments)

    @property
    def relative_energy_error(self) -> float:
        """``max_t |E(t) - E(t0)| / E(t0)`` over the recorded energies."""
        E = np.array(self.energies)
        return float(np.max(np.abs(E - E[0])) / E[0]) if E[0] != 0 else float(np.max(np.abs(E)))

    def _segment_index(self, t: float) -> int:
        t0, t1 = self.t_span
        lo, hi = min(t0, t1), max(t0, t1)
        if not (lo <= t <= hi) or not np.isfinite(t):
            raise ValueError(f"t = {t!r} is outside the solution's time span [{lo}, {hi}]")
        if self.segments[0].output is None:
            raise ValueError("the solution was computed with dense=False: no continuous output")
        ends = [float(s.t_end) if t1 >= t0 else -float(s.t_end) for s in self.segments]
        return min(bisect.bisect_left(ends, t if t1 >= t0 else -t), len(self.segments) - 1)

    def parameters(self, t: float) -> tuple[int, NDArray, NDArray]:
        """``(chart index, a, c)`` at time ``t`` from the continuous output."""
        seg = self.segments[self._segment_index(t)]
        state = np.asarray(seg.output(self.fp_type(t)))
        k = self.metric.atlas.dim
        return seg.chart, state[:k], state[k:]

    def __call__(self, t: ArrayLike) -> tuple[NDArray, NDArray]:
        """Point ``p(t)`` and embedded velocity ``v(t)`` (shape ``(..., N)``) in the working precision."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        ps, vs = [], []
        for tk in ts.ravel():
            i, a, c = self.parameters(tk)
            p, v, _ = self._numerics[i].point_velocity_energy(a[:, None], c[:, None])
            ps.append(p[0])
            vs.append(v[0])
        shape = np.shape(t) + (self.metric.atlas.ambient_dim,)
        return np.array(ps).reshape(shape), np.array(vs).reshape(shape)


def solve_chart_exp_ode(
    metric: InducedMetric,
    p0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    fp_type: type = float,
    tol: float | None = None,
    q_out: float | None = None,
    switching: bool = True,
    form: str = "embedded",
    project_velocity: bool = False,
    tangent_tol: float = 1e-9,
    dense: bool = True,
    max_switches: int = 1_000_000,
    chart: int | None = None,
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
    fp_type
        ``float`` (default), ``numpy.longdouble``, ``heyoka.real128`` or
        :class:`manifold.precision.MultiPrecision` ``(bits)`` (heyoka's ``real``).
        The whole run -- integrator, transition maps, energies, ``sol(t)`` --
        is in this type.
    tol
        Taylor integrator tolerance; default heyoka's, the machine epsilon of ``fp_type``.
    q_out
        Switch threshold on chart quality, in ``(0, 1)``; default ``atlas.switch_threshold``.
    switching
        ``False`` stays in the start chart whatever happens (for studies of
        single-chart failure near a pole).
    form
        ``"embedded"`` (default) or ``"christoffel"`` (cross-check).
    project_velocity
        If true, replace ``v0`` by its K-orthogonal projection on the tangent
        space; otherwise a ``v0`` off the tangent space by more than
        ``tangent_tol * max(1, |v0|)`` raises ``ValueError``.
    dense
        Keep heyoka's continuous output (needed to evaluate the solution at
        any ``t``; about ``(order+1) * 2 dim`` numbers per step).
    max_switches
        Safety limit on the number of chart switches.
    chart
        Start in this chart, with ``(p0, v0)`` given as its parameters ``a``
        and coefficients ``c``.  Default: the best chart at ``p0``.

    Returns
    -------
    GeodesicSolution
        Segments, switch log, energies, and a callable ``t -> (p, v)``.
    """
    sol, i, a, c, q_out = _start(metric, p0, v0, t_final, fp_type, q_out, switching, project_velocity, tangent_tol, chart)
    atlas = metric.atlas
    num = sol._numerics
    family = atlas.charts[0].family
    ta = gs.integrator(family, fp_type, tol, form, backward=float(t_final) < 0)
    n_quality = len(family.quality_expressions(gs.chart_variables(family.dim)))
    two_pi = 8 * np.arctan(as_fp(1.0, fp_type))  # 2 pi exact to fp_type
    t = fp_type(0.0)
    while True:
        ta.state[:] = np.concatenate([a, c])
        ta.time = t
        ta.pars[:] = num[i].pars[: len(ta.pars)]
        if ta.with_events:  # a global chart family has no switch events
            ta.reset_cooldowns()
        res = ta.propagate_until(fp_type(t_final), c_output=dense)
        outcome, n_steps, cout = res[0], res[3], res[4]
        sol.segments.append(Segment(i, t, ta.time, n_steps, cout))
        _record_energy(sol, num[i], cout, ta, atlas.dim, dense)
        state = np.array(ta.state)
        a, c = state[: atlas.dim], state[atlas.dim :]
        if outcome == hy.taylor_outcome.time_limit:
            sol.final_state = (i, a, c)
            return sol
        event = -outcome.value - 1  # heyoka reports terminal event k as outcome -(k + 1)
        if not 0 <= event < len(ta.t_events if ta.with_events else ()):
            sol.t_span = (0.0, float(sol.segments[-1].t_end))
            raise GeodesicIntegrationError(
                f"integration failed at t = {ta.time}: {outcome} (chart {atlas.ids[i]})", sol)
        t = ta.time
        if event >= n_quality:  # a periodic parameter left [-pi, pi]: wrap it, same chart
            k = family.periodic[(event - n_quality) // 2]
            a[k] += -two_pi if (event - n_quality) % 2 == 0 else two_pi
            continue
        if len(sol.switches) >= max_switches:
            raise RuntimeError(f"more than max_switches = {max_switches} chart switches by t = {t}")
        i, a, c = _switch(sol, i, a, c, t, q_out)


def _start(metric, p0, v0, t_final, fp_type, q_out, switching, project_velocity, tangent_tol, chart):
    """Validate the inputs; return the empty solution and the start state ``(i, a, c)``.

    ``q_out`` comes back as the value given to the integrator's events: below
    any cosine (-2) when ``switching`` is off.
    """
    atlas = metric.atlas
    unit_roundoff(fp_type)  # raises on an unknown fp_type
    if atlas.dim == 0:
        raise ValueError("a 0-dimensional manifold has no geodesic motion")
    if not all(isinstance(ch, SymbolicChart) for ch in atlas.charts):
        raise TypeError("geodesic solvers need SymbolicChart charts (heyoka expressions of the chart map)")
    t_final = float(t_final)
    if not np.isfinite(t_final):
        raise ValueError(f"t_final must be finite, got {t_final!r}")
    q_out = atlas.switch_threshold if q_out is None else float(q_out)
    if not 0 < q_out < 1:
        raise ValueError(f"q_out must lie in (0, 1), got {q_out!r}")
    if not switching:
        q_out = -2.0
    if chart is not None:
        a0, c0 = _as_vector(p0, "a", atlas.dim), _as_vector(v0, "c", atlas.dim)
        p0, v0 = atlas.get_point(chart, a0), atlas.charts[chart].tangent_vector(a0, c0)
    p0, v0 = _as_vector(p0, "p0", atlas.ambient_dim), _as_vector(v0, "v0", atlas.ambient_dim)

    sol = GeodesicSolution(metric, fp_type, (0.0, t_final))
    for k, ch in enumerate(atlas.charts):
        sol._numerics[k] = _ChartNumerics(ch, metric.K, q_out, fp_type)
    # validates p0 (closure, shape, finiteness)
    i, a = atlas.best_chart(p0) if chart is None else (chart, atlas.get_parameters(chart, p0))
    num = sol._numerics[i]
    a = num.polish(as_fp(a, fp_type), as_fp(p0, fp_type))
    c = num.coefficients(a, as_fp(v0, fp_type))
    _, v_tan, E0 = num.point_velocity_energy(a[:, None], c[:, None])
    off = float(np.max(np.abs((v_tan[0] - as_fp(v0, fp_type)).astype(float))))
    if off > tangent_tol * max(1.0, float(np.max(np.abs(v0)))) and not project_velocity:
        raise ValueError(
            f"v0 is not tangent at p0: it is {off:.3g} away from the tangent space "
            f"(allowed {tangent_tol:g} * max(1, |v0|)); pass project_velocity=True to project it"
        )
    sol.energy_times.append(fp_type(0.0))
    sol.energies.append(E0[0])
    if switching and float(atlas.charts[i].quality(a.astype(float))) < q_out:
        i, a, c = _switch(sol, i, a, c, fp_type(0.0), q_out)  # its event would never fire: it starts past it
    return sol, i, a, c, q_out


def _switch(sol: GeodesicSolution, i: int, a: NDArray, c: NDArray, t, q_out: float):
    """Move the state ``(a, c)`` of chart ``i`` to the best chart; log the switch."""
    atlas, num = sol.metric.atlas, sol._numerics
    p, v, _ = num[i].point_velocity_energy(a[:, None], c[:, None])
    p, v = p[0], v[0]
    q_from = float(atlas.charts[i].quality(a.astype(float)))
    j, a_j = atlas.best_chart(p.astype(float))
    a_j = num[j].polish(as_fp(a_j, sol.fp_type), p)
    q_to = float(atlas.charts[j].quality(a_j.astype(float)))
    if q_to <= q_out:
        raise RuntimeError(f"no chart of quality above q_out = {q_out} at t = {t} (best {q_to:.3g})")
    p_j = num[j].point_velocity_energy(a_j[:, None], np.zeros((len(a_j), 1)))[0][0]
    gap = float(np.max(np.abs(p_j - p)))
    sol.switches.append(ChartSwitch(float(t), i, j, q_from, q_to, gap))
    return j, a_j, num[j].coefficients(a_j, v)


def _record_energy(sol: GeodesicSolution, num: _ChartNumerics, cout, ta, k: int, dense: bool) -> None:
    if dense and cout is not None:
        times = np.asarray(cout.times)
        states = np.asarray(cout(times)).reshape(len(times), -1).T
    else:
        times = np.array([ta.time])
        states = np.asarray(ta.state)[:, None]
    _, _, E = num.point_velocity_energy(states[:k], states[k:])
    start = 1 if dense else 0  # a dense segment's first time is already recorded
    sol.energy_times.extend(times[start:])
    sol.energies.extend(np.atleast_1d(E)[start:])


def _as_vector(x: ArrayLike, name: str, N: int) -> NDArray:
    x = np.asarray(x, dtype=float)
    if x.shape != (N,):
        raise ValueError(f"{name} must have shape ({N},), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite, got {x}")
    return x
