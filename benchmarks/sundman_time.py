"""Sundman's time against the step limit: how many Taylor steps the motion needs with ``d tau = dt / det M``.

``python -m benchmarks.sundman_time`` prints, side by side in one run:

1. the hinge equations (:class:`manifold.constrained.ConstrainedPieces`, Baumgarte-stabilised) over
   T = 100 in float64 at n = 4 and 8: steps in ``t``, and in ``tau`` with the right-hand side multiplied
   by ``det M`` (the product of the multiplier pivots) and the time as one more variable, stopped by an
   event at ``t = T``;
2. the same in real128 at n = 4 over T = 20: steps and CPU time of each, three rounds (plain first in each);
3. the chart equations (:class:`manifold.geodesic_system.SymbolicPieces`) of the best chart of each of
   three starts, up to its first switch event (threshold ``q_out = 0.05``, so that a chart is kept long) or
   t = 100: steps in ``t`` and in ``tau`` with ``det M`` of the chart's hinges.  No wrap events: heyoka's
   integrators in the library wrap the circle angle between steps, and the equations are periodic in it.

Each line also prints how far apart the two end states are (both runs at heyoka's default tolerance).
The step of a Taylor method is limited by the nearest singularity of the solution in complex time;
multiplying by ``det M`` removes those where ``M = G K^-1 G^T`` is singular, so falling step counts
suggest that these are the limiting ones.  A study for ``docs/methods.md``, on bare equations (the
chart equations with ``B = I`` in the best chart's own frame, and ``det M`` of that frame's hinges); the
chart path's own Sundman stepper, with each chart's map and the chain's masses, is :mod:`manifold.sundman`, measured by
``python -m benchmarks.method_speed --sections 23``.
"""

from __future__ import annotations

import time

import heyoka as hy
import numpy as np

from charts.suspension_symbolic import SuspensionFamily
from linkage.constraints import ChainSystem, start_state
from manifold.constrained import ConstrainedLayout, ConstrainedPieces
from manifold.events import heyoka_events
from manifold.geodesic_system import Layout, SymbolicPieces
from manifold.options import DEFAULT_START
from manifold.precision import as_fp

from .study.experiments import generic_start


def _in_tau(equations: list, factor: hy.expression) -> tuple[list, hy.expression]:
    """``dy/dtau = factor * dy/dt`` and ``dt/dtau = factor``: the system in Sundman's time, and the time variable."""
    t = hy.expression("sundman_t")
    return [(lhs, factor * rhs) for lhs, rhs in equations] + [(t, factor)], t


def _hinge_integrators(n: int, T: float, fp_type) -> tuple:
    """Plain and Sundman integrators of the hinge equations from the study's generic start, pars set."""
    chain, p0, v0 = generic_start(n)
    _, x0, w0, _ = start_state(chain, chain.from_point(p0), chain.from_point(v0), T, DEFAULT_START)
    system = ChainSystem(chain)
    layout = ConstrainedLayout.of(system)
    pieces = ConstrainedPieces(system, layout, fp_type)
    equations = pieces.equations(True)
    K = chain.ambient_metric
    alpha = np.sqrt(w0 @ K @ w0 * np.trace(np.linalg.inv(K))) / len(x0) / system.length_scale
    pars = layout.pack(system, alpha, fp_type)
    y0 = np.concatenate([x0, w0])
    plain = hy.taylor_adaptive(equations, as_fp(y0, fp_type), compact_mode=True, fp_type=fp_type)
    tau_equations, t = _in_tau(equations, hy.prod(pieces.pivots))
    sundman = hy.taylor_adaptive(tau_equations, as_fp(np.append(y0, 0.0), fp_type), compact_mode=True,
                                 fp_type=fp_type, t_events=[hy.t_event(t - fp_type(T), fp_type=fp_type)])
    for ta in (plain, sundman):
        ta.pars[:] = pars[: len(ta.pars)]
    return plain, sundman, y0


def _run(plain, sundman, y0, T: float, fp_type) -> tuple[int, float, int, float, float]:
    """Steps and CPU seconds of each from ``y0`` to ``t = T``, and the largest state difference at the end."""
    plain.time, plain.state[:] = fp_type(0), as_fp(y0, fp_type)
    c0 = time.process_time()
    steps_t = plain.propagate_until(fp_type(T))[3]
    cpu_t = time.process_time() - c0
    sundman.time, sundman.state[:] = fp_type(0), as_fp(np.append(y0, 0.0), fp_type)
    c0 = time.process_time()
    steps_tau = sundman.propagate_until(fp_type(1e12))[3]  # stops at the event t = T
    cpu_tau = time.process_time() - c0
    gap = max(abs(float(a - b)) for a, b in zip(plain.state, sundman.state[:-1]))
    return steps_t, cpu_t, steps_tau, cpu_tau, gap


def hinge_steps(ns: tuple[int, ...] = (4, 8), T: float = 100.0) -> dict:
    """Section 1: float64 step counts of the hinge equations in ``t`` and ``tau``."""
    out = {}
    for n in ns:
        plain, sundman, y0 = _hinge_integrators(n, T, float)
        steps_t, _, steps_tau, _, gap = _run(plain, sundman, y0, T, float)
        out[n] = (steps_t, steps_tau)
        print(f"  n = {n}: {steps_t} steps in t, {steps_tau} in tau ({steps_tau / steps_t:.2f}x); end states "
              f"{gap:.1e} apart")
    return out


def hinge_real128(T: float = 20.0, rounds: int = 3) -> list:
    """Section 2: real128 steps and CPU time, ``rounds`` rounds of a plain and a Sundman run; the CPU ratios."""
    plain, sundman, y0 = _hinge_integrators(4, T, hy.real128)
    rows = []
    for _ in range(rounds):
        steps_t, cpu_t, steps_tau, cpu_tau, gap = _run(plain, sundman, y0, T, hy.real128)
        rows.append(cpu_tau / cpu_t)
        print(f"  t: {steps_t} steps, {cpu_t:.2f} s CPU; tau: {steps_tau} steps, {cpu_tau:.2f} s "
              f"({cpu_tau / cpu_t:.2f}x); end states {gap:.1e} apart")
    return rows


def chart_steps(seeds: tuple[int, ...] = (0, 1, 2), q_out: float = 0.05) -> list:
    """Section 3: chart equations from the study's starts to the first switch event or t = 100, in ``t`` and
    ``tau``."""
    n = 4
    family = SuspensionFamily(n)
    pieces = SymbolicPieces(family, float)
    equations = pieces.equations("embedded")
    # det M of the chart's hinges (unit rods and masses): the continuant of the tridiagonal M
    pins = [(hy.expression(0.0), hy.expression(0.0))]
    points = pins + [(pieces.z[2 * j], pieces.z[2 * j + 1]) for j in range(n - 1)] + [(hy.par[0], hy.expression(0.0))]
    rods = [(b[0] - a[0], b[1] - a[1]) for a, b in zip(points[:-1], points[1:])]
    diagonal = [(4.0 if k in (0, n - 1) else 8.0) * (ex * ex + ey * ey) for k, (ex, ey) in enumerate(rods)]
    below = [-4.0 * (rods[k - 1][0] * rods[k][0] + rods[k - 1][1] * rods[k][1]) for k in range(1, n)]
    minors = [hy.expression(1.0), diagonal[0]]
    for k in range(1, n):
        minors.append(diagonal[k] * minors[-1] - below[k - 1] * below[k - 1] * minors[-2])
    tau_equations, t = _in_tau(equations, minors[-1])
    rows = []
    for seed in seeds:
        chain, p0, v0 = generic_start(n, seed=seed)
        atlas = chain.atlas()
        i, a0 = atlas.best_chart(p0)
        c0 = atlas.charts[i].coefficients(a0, v0)
        pars = Layout.of(family).pack([chain.L], np.eye(n - 1), q_out, float)
        # switch events only: the library's heyoka integrators wrap angles between steps, and a wrap event here
        # would end the run at a wrap and call it the first switch
        events = heyoka_events(pieces.events(wraps=False), False, float)
        plain = hy.taylor_adaptive(equations, np.concatenate([a0, c0]), compact_mode=True, t_events=events)
        plain.pars[:] = pars[: len(plain.pars)]
        outcome, _, _, steps_t, *_ = plain.propagate_until(100.0)
        if outcome == hy.taylor_outcome.time_limit:
            ended = "no switch before"
        elif int(outcome) < 0 and -int(outcome) - 1 < len(events):  # heyoka: terminal event i ends as -i - 1
            ended = "first switch at"
        else:
            raise RuntimeError(f"the run in t stopped with {outcome} at t = {plain.time}")
        sundman = hy.taylor_adaptive(tau_equations, np.concatenate([a0, c0, [0.0]]), compact_mode=True,
                                     t_events=events + [hy.t_event(t - plain.time)])
        sundman.pars[:] = pars[: len(sundman.pars)]
        steps_tau = sundman.propagate_until(1e12)[3]
        gap = float(np.max(np.abs(sundman.state[:-1] - plain.state)))
        rows.append((steps_t, steps_tau))
        print(f"  start {seed}, chart {i}: {ended} t = {plain.time:.3f}: {steps_t} steps in t, {steps_tau} "
              f"in tau; end states {gap:.1e} apart")
    return rows


def main() -> dict:
    print("1. hinge equations, float64, T = 100")
    out = {"hinge_steps": hinge_steps()}
    print("2. hinge equations, real128, n = 4, T = 20")
    out["hinge_real128"] = hinge_real128()
    print("3. chart equations, float64, n = 4, to the first switch")
    out["chart_steps"] = chart_steps()
    return out


if __name__ == "__main__":
    main()
