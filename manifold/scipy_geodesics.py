"""The same atlas geodesics with scipy's ``solve_ivp`` instead of heyoka's Taylor method.

The right-hand side is the family's compiled geodesic acceleration (a heyoka
``cfunc``), the chart switches and angle wraps are scipy terminal events, and
the switch itself is the one of :mod:`manifold.geodesic_solver`.  Only the
stepper differs, so comparisons measure the integrator and nothing else.
float64 only.
"""

from __future__ import annotations

from functools import lru_cache

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike
from scipy.integrate import solve_ivp

from . import geodesic_system as gs
from .geodesic_solver import GeodesicSolution, Segment, _start, _switch
from .metric import InducedMetric
from .symbolic import ChartFamily


@lru_cache(maxsize=None)
def _quality_cfunc(family: ChartFamily):
    a = gs.chart_variables(family.dim)
    return hy.cfunc(family.quality_expressions(a), a, compact_mode=True)


def _events(family: ChartFamily, q_out: float) -> tuple[list, int]:
    """Terminal scipy events in heyoka's order: quality crossings, then wraps of periodic angles.

    Returns the events and how many of them are quality crossings (none when
    switching is off, ``q_out <= -1``: a cosine never falls below it).
    """
    k, events = family.dim, []
    qualities = family.quality_expressions(gs.chart_variables(k)) if q_out > -1 else []
    if qualities:
        qcf = _quality_cfunc(family)
        for m in range(len(qualities)):
            events.append(_event(lambda t, y, m=m: qcf(y[:k])[m] - q_out, -1))
    for p in family.periodic:
        events += [_event(lambda t, y, p=p: y[p] - np.pi, 1), _event(lambda t, y, p=p: y[p] + np.pi, -1)]
    return events, len(qualities)


def _event(f, direction: int):
    f.terminal, f.direction = True, direction
    return f


def solve_chart_exp_ode_scipy(
    metric: InducedMetric,
    p0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    method: str = "DOP853",
    rtol: float = 1e-12,
    atol: float = 1e-12,
    q_out: float | None = None,
    switching: bool = True,
    form: str = "embedded",
    dense: bool = True,
    max_switches: int = 1_000_000,
    chart: int | None = None,
    project_velocity: bool = False,
    tangent_tol: float = 1e-9,
) -> GeodesicSolution:
    """Atlas geodesic with ``scipy.integrate.solve_ivp(method=...)``; see :func:`~manifold.geodesic_solver.solve_chart_exp_ode`.

    ``rtol`` and ``atol`` are scipy's tolerances.  The returned solution's
    segments hold scipy's dense output (``dense=True``) and its energies are
    recorded at every accepted step.
    """
    sol, i, a, c, q_event = _start(metric, p0, v0, t_final, float, q_out, switching, project_velocity, tangent_tol, chart)
    atlas = metric.atlas
    family, k = atlas.charts[0].family, atlas.dim
    acc = gs.acceleration_cfunc(family, float, form)
    events, n_quality = _events(family, q_event)
    t, t_final = 0.0, float(t_final)
    while True:
        pars = sol._numerics[i].pars[: acc.nparams]

        def rhs(_t, y, pars=pars):
            return np.concatenate([y[k:], acc(np.ascontiguousarray(y), pars=pars)])  # Radau passes strided views

        res = solve_ivp(rhs, (t, t_final), np.concatenate([a, c]), method=method, rtol=rtol, atol=atol,
                        events=events or None, dense_output=dense)
        if res.status == -1:
            raise RuntimeError(f"{method} failed at t = {res.t[-1]}: {res.message}")
        sol.segments.append(Segment(i, t, res.t[-1], len(res.t) - 1, res.sol))
        _, _, E = sol._numerics[i].point_velocity_energy(res.y[:k], res.y[k:])
        sol.energy_times.extend(res.t[1:])
        sol.energies.extend(E[1:])
        a, c, t = res.y[:k, -1].copy(), res.y[k:, -1].copy(), res.t[-1]
        if res.status == 0:
            sol.final_state = (i, a, c)
            return sol
        event = next(m for m, te in enumerate(res.t_events) if len(te))
        if event >= n_quality:
            p = family.periodic[(event - n_quality) // 2]
            a[p] += -2 * np.pi if (event - n_quality) % 2 == 0 else 2 * np.pi
            continue
        if len(sol.switches) >= max_switches:
            raise RuntimeError(f"more than max_switches = {max_switches} chart switches by t = {t}")
        i, a, c = _switch(sol, i, a, c, t, q_event)
