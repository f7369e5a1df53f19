"""Speed and accuracy of the atlas geodesic solver, n = 3..8.

For each n (unit hinge masses, L = n - 1.3, unit kinetic speed, a generic start):

* compile time of the geodesic integrator: cold (heyoka's disk cache off and
  its in-memory cache cleared) and from heyoka's disk cache (a fresh cache
  directory, populated once, then rebuilt);
* a long run to T (default 1000) in float64 at the default tolerance:
  wall time per unit simulated time, Taylor steps per second, chart switches,
  relative energy error;
* heyoka against scipy's DOP853 on the same chart ODE and switch rule, over a
  shorter horizon: both at several tolerances, the final hinge error measured
  against a long-double heyoka reference (tol 1e-19), and the DOP853/heyoka
  ratio of CPU times (least of 3) at equal final error (log-log interpolation of
  DOP853's work-precision curve at heyoka's error levels).

Run: ``python -m benchmarks.geodesic_speed [--T 1000] [--T-compare 20] [--n 3 4 5 6 7 8]``.
Timings are wall clock on this machine; ratios are the numbers to compare.
"""

from __future__ import annotations

import argparse
import tempfile
import time

import heyoka as hy
import numpy as np

from linkage import Chain
from manifold import Precision, SaveAt, ScipyStepper, TaylorStepper, compiled, solve_chart_exp_ode

from .study.experiments import generic_start


def _clear_caches(family) -> None:
    compiled(family).clear()
    hy.llvm_state.clear_memcache()


def _build_integrator(family) -> None:
    with compiled(family).integrator():
        pass


def compile_times(n: int) -> tuple[float, float]:
    """(cold, from disk cache) seconds to build the float64 integrator."""
    family = Chain(n, n - 1.3).atlas().charts[0].family
    hy.llvm_state.set_diskcache_enabled(False)
    _clear_caches(family)
    t0 = time.perf_counter()
    _build_integrator(family)
    cold = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as cache:
        hy.llvm_state.set_diskcache_path(cache)
        hy.llvm_state.set_diskcache_enabled(True)
        _clear_caches(family)
        _build_integrator(family)  # populate
        _clear_caches(family)
        t0 = time.perf_counter()
        _build_integrator(family)
        cached = time.perf_counter() - t0
        hy.llvm_state.set_diskcache_enabled(False)
    return cold, cached


def long_run(n: int, T: float) -> dict:
    chain, p0, v0 = generic_start(n)
    solve_chart_exp_ode(chain.metric(), p0, v0, 0.01)  # compile outside the timing
    t0 = time.perf_counter()
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, T, save=SaveAt(dense=False))
    wall = time.perf_counter() - t0
    return {"wall_per_time": wall / T, "steps_per_s": sol.n_steps / wall, "switches": sol.n_switches,
            "energy_error": sol.relative_energy_error, "steps": sol.n_steps}


def _final_hinges(sol) -> np.ndarray:
    return sol.end_state()[0].astype(float)


def work_precision(n: int, T: float) -> dict:
    """Heyoka and DOP853 (time, final error) pairs, and the DOP853/heyoka ratio at equal error."""
    chain, p0, v0 = generic_start(n, seed=1)
    metric = chain.metric()
    ref = _final_hinges(solve_chart_exp_ode(metric, p0, v0, T, save=SaveAt(dense=False),
                                            precision=Precision(fp_type=np.longdouble, tol=1e-19)))

    def measure(stepper, repeat: int = 3):
        """Least CPU time of ``repeat`` solves (a shared machine: wall time would measure the other users)."""
        solve_chart_exp_ode(metric, p0, v0, min(T, 0.5), save=SaveAt(dense=False),
                            stepper=stepper)  # warm-up (compile, caches)
        best = np.inf
        for _ in range(repeat):
            t0 = time.process_time()
            sol = solve_chart_exp_ode(metric, p0, v0, T, save=SaveAt(dense=False), stepper=stepper)
            best = min(best, time.process_time() - t0)
        return best, float(np.abs(_final_hinges(sol) - ref).max())

    hey = [measure(TaylorStepper(tol)) for tol in (1e-6, 1e-9, 1e-12, None, float(np.finfo(float).eps))]
    dop = [measure(ScipyStepper("DOP853", rtol=r, atol=r)) for r in (1e-6, 1e-8, 1e-10, 1e-12, 1e-13)]
    return {"heyoka": hey, "dop853": dop, "ratios": _ratios(hey, dop)}


def _ratios(hey: list, dop: list) -> list:
    """(error, DOP853 time / heyoka time) where heyoka's error lies inside DOP853's range."""
    d_err = np.log([e for _, e in dop])
    d_time = np.log([t for t, _ in dop])
    order = np.argsort(d_err)
    out = []
    for t, e in hey:
        if d_err.min() <= np.log(e) <= d_err.max():
            out.append((e, float(np.exp(np.interp(np.log(e), d_err[order], d_time[order]))) / t))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[3, 4, 5, 6, 7, 8])
    parser.add_argument("--T", type=float, default=1000.0, help="long-run horizon")
    parser.add_argument("--T-compare", type=float, default=20.0, help="horizon of the DOP853 comparison")
    args = parser.parse_args()
    print(f"{'n':>2} {'cold s':>7} {'cached s':>8} {'wall/T':>8} {'steps/s':>8} {'switches':>8} "
          f"{'dE/E at T':>10}   DOP853/heyoka time at equal error")
    for n in args.n:
        cold, cached = compile_times(n)
        hy.llvm_state.set_diskcache_enabled(False)
        lr = long_run(n, args.T)
        wp = work_precision(n, args.T_compare)
        ratios = ", ".join(f"{r:.1f}x @ {e:.0e}" for e, r in wp["ratios"]) or "no overlap"
        print(f"{n:>2} {cold:7.2f} {cached:8.2f} {lr['wall_per_time']:8.4f} {lr['steps_per_s']:8.0f} "
              f"{lr['switches']:>8} {lr['energy_error']:10.1e}   {ratios}", flush=True)
        pts = "; ".join(f"{t:.3f}s/{e:.0e}" for t, e in wp["heyoka"])
        dpts = "; ".join(f"{t:.3f}s/{e:.0e}" for t, e in wp["dop853"])
        print(f"     heyoka (tol 1e-6, 1e-9, 1e-12, default 1e-14, eps): {pts}\n     DOP853 (rtol 1e-6..1e-13): {dpts}", flush=True)


if __name__ == "__main__":
    main()
