"""The methods under study, behind one interface.

Each method takes a chain, a start ``(p0, v0)`` (interleaved real point and
tangent velocity), a horizon ``T``, sample times ``ts`` and one accuracy knob
(a tolerance or a step size), and returns a :class:`Run`: hinges and energy at
``ts``, wall time, and the failure it met, if any.  A failure is data here:
the study shows where methods break.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from linkage import Chain
from linkage.ambient import integrate_ambient
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import GeodesicIntegrationError, Precision, SaveAt, ScipyStepper, compiled, solve_chart_exp_ode
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.constrained import compiled_constrained
from manifold.sundman import SundmanStepper, SundmanTime
from manifold.terms import ChartGeodesic

from ..baselines.rattle import integrate_rattle
from ..baselines.seed_geodesics import integrate_seed_rk4


@dataclass
class Run:
    """One integration: what came out and what it cost."""

    method: str
    knob: float
    wall: float
    ts: np.ndarray  # times actually reached (prefix of the requested ones on failure)
    hinges: np.ndarray  # complex, (len(ts), n-1)
    energy: np.ndarray  # kinetic energy at ts
    failed: str | None = None  # what went wrong, if it did
    steps: int = 0  # accepted steps; right-hand-side evaluations for the ambient methods


def _timed(fn: Callable):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def from_solution(
    name: str, knob: float, chain: Chain, sol, wall: float, ts: np.ndarray, failed: str | None = None
) -> Run:
    """A :class:`Run` from an atlas solution ``sol`` (real points), read at ``ts`` and converted to complex hinges."""
    ps, vs = sol(ts)
    h = chain.from_point(np.asarray(ps, dtype=float))
    v = chain.from_point(np.asarray(vs, dtype=float))
    return Run(name, knob, wall, ts, h, chain.kinetic_energy(v), failed, sol.n_steps)


def _warm_up(chain: Chain, tol=None, scipy: bool = False, factor=None, velocity=None) -> None:
    """Compile (or fetch from the caches) what a method needs, outside its timing."""
    family = compiled(chain.atlas().charts[0].family)
    family.transfer(float)
    if scipy:
        family.acceleration(float)
        family.event_values(float)
    else:
        state = ChartGeodesic() if velocity is None else velocity
        with family.integrator(float, tol, (state,) if factor is None else (state, SundmanTime(factor))):
            pass


def atlas_taylor(chain: Chain, p0, v0, T, ts, tol) -> Run:
    """Method 1 (ours): heyoka Taylor in the atlas, event-located switches."""
    _warm_up(chain, tol)
    sol, wall = _timed(lambda: solve_chart_exp_ode(chain.metric(), p0, v0, T, precision=Precision(tol=tol)))
    return from_solution("atlas Taylor (ours)", tol, chain, sol, wall, ts)


def atlas_sundman(chain: Chain, p0, v0, T, ts, tol) -> Run:
    """Method 1 in Sundman's time ``dt = det M dtau`` (:class:`manifold.sundman.SundmanStepper`), the state ``(a, c)``."""
    factor = ChainTimeFactor(chain)
    _warm_up(chain, tol, factor=factor)
    stepper = SundmanStepper(factor, tol=tol)
    sol, wall = _timed(lambda: solve_chart_exp_ode(chain.metric(), p0, v0, T, stepper=stepper))
    return from_solution("atlas Taylor, Sundman time (ours)", tol, chain, sol, wall, ts)


def atlas_ambient(chain: Chain, p0, v0, T, ts, tol) -> Run:
    """Method 1 in Sundman's time with the ambient velocity as state (:mod:`manifold.ambient_velocity`):
    the chart gives the point, the rod constraints the acceleration; the chart path's default without rod densities."""
    factor, velocity = ChainTimeFactor(chain), ConstrainedVelocity(ChainSystem(chain))
    _warm_up(chain, tol, factor=factor, velocity=velocity)
    stepper = SundmanStepper(factor, tol=tol, velocity=velocity)
    sol, wall = _timed(lambda: solve_chart_exp_ode(chain.metric(), p0, v0, T, stepper=stepper))
    return from_solution("atlas Taylor, ambient velocity (ours)", tol, chain, sol, wall, ts)


def single_chart_taylor(chain: Chain, p0, v0, T, ts, tol, chart: int = 0) -> Run:
    """Method 2: heyoka Taylor in one suspension chart, no switching."""
    atlas = chain.atlas()
    a0 = atlas.get_parameters(chart, p0)
    c0 = atlas.charts[chart].coefficients(a0, v0)
    name = "single chart Taylor"
    _warm_up(chain, tol)
    t0 = time.perf_counter()
    failed = None
    try:
        sol = solve_chart_exp_ode(chain.metric(), a0, c0, T, precision=Precision(tol=tol), chart=chart, switching=False)
    except GeodesicIntegrationError as err:  # keep what was computed before the breakdown
        sol, failed = err.solution, str(err)
    wall = time.perf_counter() - t0
    reached = ts[ts <= float(sol.t_reached)]
    return _finite_prefix(from_solution(name, tol, chain, sol, wall, reached, failed))


def scipy_atlas(chain: Chain, p0, v0, T, ts, rtol, method: str = "DOP853") -> Run:
    """Method 3: scipy ``solve_ivp`` on the same chart ODE, switches through scipy events."""
    name = f"scipy {method} atlas"
    _warm_up(chain, scipy=True)
    t0 = time.perf_counter()
    try:
        sol = solve_chart_exp_ode(chain.metric(), p0, v0, T, stepper=ScipyStepper(method, rtol=rtol, atol=rtol))
    except RuntimeError as err:
        return Run(name, rtol, time.perf_counter() - t0, ts[:0], np.zeros((0, chain.n - 1)), np.zeros(0), str(err))
    return from_solution(name, rtol, chain, sol, time.perf_counter() - t0, ts)


def hinge_taylor(chain: Chain, p0, v0, T, ts, tol) -> Run:
    """Method 5 (ours): heyoka Taylor in hinge coordinates, Baumgarte-stabilised rod constraints."""
    h0, w0 = chain.from_point(p0), chain.from_point(v0)
    free_motion(chain, h0, w0, min(T, 0.1), method="hinges", precision=Precision(tol=tol))  # compile outside the timing
    m, wall = _timed(lambda: free_motion(chain, h0, w0, T, method="hinges", save=SaveAt(t_eval=ts, dense=False),
                                         precision=Precision(tol=tol)))
    return Run("hinge Taylor (ours)", tol, wall, m.times, m.hinges, m.energies, None, m.n_steps)


def scipy_hinges(chain: Chain, p0, v0, T, ts, rtol, method: str = "DOP853") -> Run:
    """Method 6: scipy ``solve_ivp`` on the hinge method's compiled right-hand side (same equations, same Baumgarte term)."""
    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    acc = comp.acceleration(float)
    alpha = np.sqrt(2 * chain.kinetic_energy(chain.from_point(v0)) / np.trace(chain.ambient_metric))
    pars = comp.layout.pack(system, alpha, float)[: acc.nparams]
    N = system.ambient_dim

    def rhs(_t, y):
        return np.concatenate([y[N:], acc(y, pars=pars)])

    sol, wall = _timed(lambda: solve_ivp(rhs, (0.0, T), np.concatenate([p0, v0]), method=method, rtol=rtol,
                                         atol=rtol, t_eval=ts))
    hinges = chain.from_point(sol.y[:N].T)
    energy = chain.kinetic_energy(chain.from_point(sol.y[N:].T))
    return Run(f"scipy {method} hinges", rtol, wall, sol.t, hinges, energy,
               None if sol.success else sol.message, sol.nfev)


def ambient(chain: Chain, p0, v0, T, ts, rtol, project: bool = False) -> Run:
    """Method 4: hinge space with Lagrange multipliers (DOP853), optionally projected."""
    name = "ambient DOP853" + (" + projection" if project else "")
    sol, wall = _timed(lambda: integrate_ambient(chain, chain.from_point(p0), chain.from_point(v0), T,
                                                  save=SaveAt(t_eval=ts), rtol=rtol, atol=rtol, project=project,
                                                  throw=False))
    return Run(name, rtol, wall, sol.times, sol.hinges, sol.energies, None if sol.success else sol.solution.message,
               sol.n_steps)


def _finite_prefix(run: Run) -> Run:
    """Cut a run at its first non-finite sample and say so."""
    ok = np.all(np.isfinite(run.hinges), axis=-1) & np.isfinite(run.energy)
    if ok.all():
        return run
    k = int(np.argmin(ok))
    run.failed = run.failed or f"non-finite state at t = {run.ts[k]:.4g}"
    run.ts, run.hinges, run.energy = run.ts[:k], run.hinges[:k], run.energy[:k]
    return run


def chart_pars(chart, K: np.ndarray, q_out: float = -2.0) -> np.ndarray:
    """Runtime parameters of a chart's compiled geodesic system (float64)."""
    return chart.numerics(K, q_out).pars


def _sampled(name, knob, t, hinges, energy, ts, wall, failed, steps) -> Run:
    """A fixed-step run read at the requested times (nearest recorded step, which the step sizes align)."""
    reached = ts[ts <= t[-1] + 1e-9]
    idx = np.clip(np.searchsorted(t, reached - 1e-9), 0, len(t) - 1)
    return Run(name, knob, wall, reached, hinges[idx], energy[idx], failed, steps)


def rattle(chain: Chain, p0, v0, T, ts, h) -> Run:
    """Method 5: RATTLE (symplectic, constrained, fixed step ``h``) in hinge space."""
    try:
        sol, wall = _timed(lambda: integrate_rattle(chain, chain.from_point(p0), chain.from_point(v0), T, h))
    except RuntimeError as err:
        return Run("RATTLE", h, 0.0, ts[:0], np.zeros((0, chain.n - 1)), np.zeros(0), str(err))
    return _sampled("RATTLE", h, sol.t, sol.hinges, sol.energy, ts, wall, None, sol.n_steps)


def seed_rk4(chain: Chain, p0, v0, T, ts, h) -> Run:
    """Method 6 (n = 4): the seed's closed-form metric, finite-difference Christoffels, fixed-step RK4, one chart."""
    chart = chain.atlas().charts[0]  # the seed's chart: identity rod order
    a0 = chart.get_parameters(p0)
    c0 = chart.coefficients(a0, v0)
    sol, wall = _timed(lambda: integrate_seed_rk4(chain.L, a0, c0, T, h))
    failed = None if sol.failed_at is None else f"left the chart (non-finite or |phi| > pi/2) at t = {sol.failed_at:.4g}"
    return _sampled("seed RK4 (metric4 + FD Christoffel)", h, sol.t, sol.hinges, sol.energy, ts, wall, failed,
                    sol.n_steps)


def extra_methods(n: int, quick: bool) -> dict:
    """Methods 5 and 6 for the work-precision sweep (method 6 exists for n = 4 only)."""
    hs = [0.02, 0.01, 0.005] if quick else [0.05, 0.02, 0.01, 0.005, 0.002]
    out = {"RATTLE": (rattle, hs)}
    if n == 4:  # metric4 is for 4 rods, unit hinge masses, massless rods: the study's chains
        out["seed RK4 (metric4 + FD Christoffel)"] = (seed_rk4, hs)
    return out


def long_run_extras(chain, p0, v0, T, ts, quick) -> dict:
    out = {"RATTLE (h = 0.01)": lambda: rattle(chain, p0, v0, T, ts, 0.01)}
    if chain.n == 4:
        out["seed RK4 (h = 0.01)"] = lambda: seed_rk4(chain, p0, v0, T, ts, 0.01)
    return out


def pole_extras(chain, p0, v0, T, ts) -> dict:
    out = {"RATTLE (h = 0.005)": rattle(chain, p0, v0, T, ts, 0.005)}
    if chain.n == 4:
        out["seed RK4 (h = 0.005)"] = seed_rk4(chain, p0, v0, T, ts, 0.005)
    return out
