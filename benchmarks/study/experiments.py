"""The study's experiments; each returns plain data (lists and dicts) for the report.

* :func:`work_precision`: wall time against error for every method, error
  measured against a quad- (or long-double-) precision heyoka reference;
* :func:`long_run`: energy error against time up to ``T`` for every method;
* :func:`through_pole`: a geodesic aimed through a suspension pole;
* :func:`through_circle_pole`: the circle level's ``t = +-pi/2`` with the
  plain ``sin(x)/x`` against the polynomial ``sinc``;
* :func:`precision_cost`: float64, long double, real128, heyoka's ``real``;
* :func:`size_cost`: compile time and run time against ``n``.
"""

from __future__ import annotations

import time

import heyoka as hy
import numpy as np

from charts import suspension_formula
from manifold import Precision, SaveAt, backends
from linkage import Chain
from manifold import ChartFamily, compiled, solve_chart_exp_ode
from manifold.geodesic_system import SymbolicPieces
from manifold.precision import MultiPrecision

from . import methods as M

HALF_PI = np.pi / 2


def generic_start(n: int, seed: int = 0, L: float | None = None) -> tuple[Chain, np.ndarray, np.ndarray]:
    """A chain with ``L = n - 1.3`` and a unit-energy start at a generic configuration."""
    chain = Chain(n, n - 1.3 if L is None else L)
    atlas = chain.atlas()
    rng = np.random.default_rng(seed)
    a0 = np.append(rng.uniform(-1, 1, n - 3), 0.3)
    p0 = atlas.get_point(0, a0)
    v0 = atlas.charts[0].tangent_vector(a0, rng.normal(size=n - 2))
    return chain, p0, v0 / np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))


def reference(chain: Chain, p0, v0, T: float, ts: np.ndarray, fp_type=hy.real128) -> M.Run:
    """The atlas solution in extended precision, sampled at ``ts``."""
    t0 = time.perf_counter()
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, T, precision=Precision(fp_type=fp_type))
    name = repr(fp_type) if isinstance(fp_type, MultiPrecision) else np.dtype(fp_type).name
    run = M.from_solution(f"reference ({name})", 0.0, chain, sol, time.perf_counter() - t0, ts)
    run.energy_exact = sol.energies[0]
    return run


def errors(run: M.Run, ref: M.Run, chain: Chain) -> dict:
    """Max hinge error against the reference, max relative energy error, max rod-length drift."""
    k = len(run.ts)
    if k == 0:
        return {"hinge": np.inf, "energy": np.inf, "drift": np.inf}
    E0 = float(ref.energy[0])
    return {
        "hinge": float(np.abs(run.hinges - ref.hinges[:k]).max()),
        "energy": float(np.abs(run.energy / E0 - 1).max()),
        "drift": float(chain.closure_residual(run.hinges).max()),
    }


def default_methods(n: int, quick: bool) -> dict:
    """Method name -> (callable(chain, p0, v0, T, ts, knob), knobs)."""
    eps = float(np.finfo(float).eps)  # the tightest tolerance, since the default (None) is 1e-14
    tols = [1e-6, 1e-9, 1e-12, None, eps] if not quick else [1e-8, 1e-10, 1e-12, 1e-13, None, eps]
    rtols = [1e-6, 1e-8, 1e-10, 1e-12, 1e-13] if not quick else [1e-8, 1e-10, 1e-12, 1e-13]
    out = {
        "atlas Taylor (ours)": (M.atlas_taylor, tols),
        "single chart Taylor": (M.single_chart_taylor, tols[-1:]),
        "scipy DOP853 atlas": (lambda *a: M.scipy_atlas(*a, method="DOP853"), rtols),
        "hinge Taylor (ours)": (M.hinge_taylor, tols),
        "scipy DOP853 hinges": (M.scipy_hinges, rtols),
        "scipy RK45 atlas": (lambda *a: M.scipy_atlas(*a, method="RK45"), [1e-6, 1e-8, 1e-10] if not quick else [1e-8]),
        "scipy Radau atlas": (lambda *a: M.scipy_atlas(*a, method="Radau"), [1e-6, 1e-8] if not quick else []),
        "ambient DOP853": (M.ambient, rtols),
        "ambient DOP853 + projection": (lambda *a: M.ambient(*a, project=True), rtols[::2]),
    }
    out.update(M.extra_methods(n, quick))
    return {k: v for k, v in out.items() if v[1]}


def work_precision(n: int, T: float, quick: bool = False, samples: int = 101, repeats: int = 2) -> dict:
    """Every method at every knob: wall time (best of ``repeats``) and errors against the reference."""
    chain, p0, v0 = generic_start(n)
    ts = np.linspace(0, T, samples)
    ref = reference(chain, p0, v0, T, ts, fp_type=np.longdouble if quick else hy.real128)
    M.atlas_taylor(chain, p0, v0, min(T, 0.5), ts[ts <= min(T, 0.5)], None)  # compile outside the timings
    rows = []
    for name, (fn, knobs) in default_methods(n, quick).items():
        for knob in knobs:
            runs = [fn(chain, p0, v0, T, ts, knob) for _ in range(repeats)]  # best of: first calls pay set-up
            run = runs[-1]
            rows.append({"method": name, "knob": knob, "wall": min(r.wall for r in runs), "failed": run.failed,
                         "steps": run.steps, **errors(run, ref, chain)})
    return {"n": n, "L": chain.L, "T": T, "reference": ref.method, "reference_wall": ref.wall, "rows": rows}


def speed_ratio_at_equal_error(rows: list, ours: str, other: str) -> list[tuple[float, float]]:
    """``(error, time_other / time_ours)`` at each of ``other``'s errors inside our error range.

    Our work-precision curve is interpolated log-log at the other method's points.
    """
    def curve(name):
        pts = sorted((r["hinge"], r["wall"]) for r in rows if r["method"] == name and not r["failed"])
        return np.log([e for e, _ in pts]), np.log([w for _, w in pts])

    e_us, w_us = curve(ours)
    out = []
    for r in rows:
        if r["method"] == other and not r["failed"] and e_us.min() <= np.log(r["hinge"]) <= e_us.max():
            out.append((r["hinge"], r["wall"] / float(np.exp(np.interp(np.log(r["hinge"]), e_us, w_us)))))
    return out


def long_run(n: int, T: float, quick: bool = False, samples: int = 60) -> dict:
    """Energy error against time (log-spaced samples) for each method at its production setting."""
    chain, p0, v0 = generic_start(n, seed=2)
    ts = np.concatenate([[0.0], np.geomspace(0.1, T, samples)])
    E0 = chain.kinetic_energy(chain.from_point(v0))
    setups = {
        "atlas Taylor (ours)": lambda: M.atlas_taylor(chain, p0, v0, T, ts, None),
        "single chart Taylor": lambda: M.single_chart_taylor(chain, p0, v0, T, ts, None),
        "scipy DOP853 atlas": lambda: M.scipy_atlas(chain, p0, v0, T, ts, 1e-12),
        "ambient DOP853": lambda: M.ambient(chain, p0, v0, T, ts, 1e-12),
        "ambient DOP853 + projection": lambda: M.ambient(chain, p0, v0, T, ts, 1e-12, project=True),
    }
    setups.update(M.long_run_extras(chain, p0, v0, T, ts, quick))
    curves = {}
    for name, go in setups.items():
        run = go()
        err = np.abs(run.energy / E0 - 1)
        curves[name] = {"t": run.ts.tolist(), "energy_error": err.tolist(), "wall": run.wall, "failed": run.failed,
                        "drift": float(chain.closure_residual(run.hinges).max()) if len(run.ts) else np.nan,
                        "slope": _loglog_slope(run.ts, err, T)}
    return {"n": n, "L": chain.L, "T": T, "curves": curves}


def _loglog_slope(ts: np.ndarray, err: np.ndarray, T: float) -> float:
    """Slope of the running maximum of the energy error against t, log-log, over ``[T/1000, T]``."""
    sel = (ts >= T / 1000) & (err > 0)
    if sel.sum() < 5:
        return float("nan")
    running = np.maximum.accumulate(err)[sel]
    return float(np.polyfit(np.log(ts[sel]), np.log(running), 1)[0])


def pole_crossing_start(chain: Chain, lead: float = 1.0, miss: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A start ``lead`` time units before the geodesic passes through chart 0's pole.

    With ``miss > 0`` it passes instead through the point of latitude
    ``pi/2 - miss`` (a near miss).  Returns ``(p0, v0, pole)``, built by
    integrating backward from the pole.
    """
    atlas = chain.atlas()
    a = np.zeros(chain.dim)
    a[0], a[-1] = HALF_PI - miss, 0.4
    pole = atlas.get_point(0, a)
    j = atlas.get_chart_index(pole)
    v = atlas.charts[j].tangent_vector(atlas.get_parameters(j, pole), np.linspace(1.0, 0.4, chain.dim))
    v /= np.sqrt(2 * chain.metric().ambient_kinetic_energy(v))
    back = solve_chart_exp_ode(chain.metric(), pole, v, -lead, save=SaveAt(dense=False))
    p0, v0 = back.end_state()
    return p0, v0, pole


def through_pole(n: int = 4, T: float = 2.0, samples: int = 401, miss: float = 0.0) -> dict:
    """Each method on a geodesic through chart 0's pole (or ``miss`` from it) at ``t = T/2``."""
    chain = Chain(n, n - 1.4)
    p0, v0, pole = pole_crossing_start(chain, lead=T / 2, miss=miss)
    ts = np.linspace(0, T, samples)
    ref = reference(chain, p0, v0, T, ts, fp_type=np.longdouble)
    runs = {
        "atlas Taylor (ours)": M.atlas_taylor(chain, p0, v0, T, ts, None),
        # at its tightest tolerance, as in the work-precision runs (at the default 1e-14 heyoka steps across the pole
        # and the solver's energy check fails the run instead, after the segment)
        "single chart Taylor (chart 0)": M.single_chart_taylor(chain, p0, v0, T, ts, float(np.finfo(float).eps), chart=0),
        "scipy DOP853 atlas": M.scipy_atlas(chain, p0, v0, T, ts, 1e-12),
        "ambient DOP853": M.ambient(chain, p0, v0, T, ts, 1e-12),
    }
    runs.update(M.pole_extras(chain, p0, v0, T, ts))
    chart0 = chain.atlas().charts[0]
    out = {"n": n, "L": chain.L, "T": T, "miss": miss, "runs": {}}
    for name, run in runs.items():
        e = errors(run, ref, chain)
        sphere = chart0.sphere_point(chart0.get_parameters(chain.to_point(run.hinges))) if len(run.ts) else np.zeros((0, 3))
        E0 = float(ref.energy[0])
        out["runs"][name] = {**e, "failed": run.failed, "t": run.ts.tolist(), "sphere": sphere[:, :3].tolist(),
                             "energy_error": (np.abs(run.energy / E0 - 1)).tolist(),
                             "hinge_error": np.abs(run.hinges - ref.hinges[: len(run.ts)]).max(axis=-1).tolist()}
    out["pole_sphere"] = chart0.sphere_point(chart0.get_parameters(pole))[:3].tolist()
    return out


class _PlainSincOps(backends.HeyokaOps):
    """The trap, on purpose: ``sin(x)/x`` written as the quotient."""

    def sinc(self, x):
        return self.hy.sin(x) / x


class _CircleFamily(ChartFamily):
    """The n = 3 suspension chart with a chosen math backend (no events, no wrap)."""

    dim, point_dim, block, n_params = 1, 4, 2, 1

    def __init__(self, ops) -> None:
        self.ops = ops

    @property
    def key(self):
        return ("circle", type(self.ops).__name__)

    def point_expressions(self, a, fp_type):
        return [c for h in suspension_formula.hinges(list(a), hy.par[0], self.ops) for c in (h.re, h.im)]

    def quality_expressions(self, a):
        return []


def through_circle_pole(L: float = 1.6, T: float = 20.0, max_steps: int = 20000) -> dict:
    """n = 3 from exactly ``t = pi/2`` (the elbow in the base line): the two ``sinc`` forms.

    Records heyoka's step sizes; the plain quotient's Taylor coefficients lose
    all accuracy near ``x = 0`` and the step size collapses.
    """
    chain = Chain(3, L)
    pars = M.chart_pars(chain.atlas().charts[0], chain.ambient_metric)
    out = {"L": L, "T": T}
    cases = [("polynomial sinc (ours)", backends.HeyokaOps(float), HALF_PI),
             ("plain sin(x)/x", _PlainSincOps(float), HALF_PI),
             ("plain sin(x)/x, off the pole", _PlainSincOps(float), 0.3)]
    for label, ops, t_start in cases:
        ta = hy.taylor_adaptive(SymbolicPieces(_CircleFamily(ops), float).equations(), [t_start, 1.0], compact_mode=True)
        ta.pars[:] = pars[: len(ta.pars)]
        times, steps, status = [], [], "reached T"
        t0 = time.perf_counter()
        while ta.time < T:
            oc, h = ta.step(max_delta_t=T - ta.time)
            if not np.all(np.isfinite(ta.state)) or oc not in (hy.taylor_outcome.success, hy.taylor_outcome.time_limit):
                status = f"failed ({oc.name}) at t = {ta.time:.4g}"
                break
            times.append(ta.time)
            steps.append(h)
            if len(steps) >= max_steps:
                status = f"step size collapsed: {len(steps)} steps by t = {ta.time:.4g} (last h = {h:.1e})"
                break
        out[label] = {"t0": t_start, "t": times, "h": steps, "status": status, "steps": len(steps),
                      "wall": time.perf_counter() - t0}
    return out


#: (label, fp_type, fraction of T): multiprecision runs get shorter horizons (their cost grows fast with bits).
PRECISIONS = [("float64", float, 1.0), ("long double", np.longdouble, 1.0), ("real128", hy.real128, 1.0),
              ("real 113 bits", MultiPrecision(113), 1.0), ("real 256 bits", MultiPrecision(256), 0.2),
              ("real 512 bits", MultiPrecision(512), 0.05)]


def precision_cost(n: int = 4, T: float = 10.0, quick: bool = False) -> list[dict]:
    """Wall time and energy error of the atlas solver in float64, long double, real128 and heyoka's ``real``.

    Quick mode halves the extended-precision horizons and stops at 113 bits.
    """
    chain, p0, v0 = generic_start(n, seed=3)
    rows = []
    for label, fp, frac in PRECISIONS[:4] if quick else PRECISIONS:
        T_run = T * frac / (2 if quick and fp not in (float, np.longdouble) else 1)
        solve_chart_exp_ode(chain.metric(), p0, v0, 0.01, precision=Precision(fp_type=fp))  # compile outside the timing
        t0 = time.perf_counter()
        sol = solve_chart_exp_ode(chain.metric(), p0, v0, T_run, save=SaveAt(dense=False),
                                  precision=Precision(fp_type=fp))
        wall = time.perf_counter() - t0
        rows.append({"precision": label, "T": T_run, "wall": wall, "steps": sol.n_steps,
                     "switches": sol.n_switches, "energy_error": sol.relative_energy_error,
                     "wall_per_time": wall / T_run})
    return rows


def size_cost(ns: list[int], T: float = 5.0) -> dict:
    """Cold compile time and wall time per unit time against ``n``, and fitted growth exponents."""
    rows = []
    for n in ns:
        chain, p0, v0 = generic_start(n)
        family = chain.atlas().charts[0].family
        hy.llvm_state.set_diskcache_enabled(False)
        compiled(family).clear()
        hy.llvm_state.clear_memcache()
        t0 = time.perf_counter()
        with compiled(family).integrator() as ta:
            compile_s = time.perf_counter() - t0
            decomposition = len(ta.decomposition)
        solve_chart_exp_ode(chain.metric(), p0, v0, 0.01)
        t0 = time.perf_counter()
        sol = solve_chart_exp_ode(chain.metric(), p0, v0, T, save=SaveAt(dense=False))
        wall = time.perf_counter() - t0
        rows.append({"n": n, "compile": compile_s, "wall_per_time": wall / T, "steps_per_time": sol.n_steps / T,
                     "ms_per_step": 1e3 * wall / max(sol.n_steps, 1), "decomposition": decomposition})
    fit = [r for r in rows if r["n"] >= 4]
    logn = np.log([r["n"] for r in fit])
    expo = {k: float(np.polyfit(logn, np.log([r[k] for r in fit]), 1)[0]) for k in ("compile", "wall_per_time", "ms_per_step")}
    return {"rows": rows, "exponents": expo}
