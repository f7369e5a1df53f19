"""Which method when: the hinge-coordinate Taylor method against the chart method and DOP853, side by side.

Run ``python -m benchmarks.method_speed [--quick]``.  Prints, from one run on
this machine (ratios are the numbers to compare; absolute times are noise):

1. the hinge method against scipy's DOP853 on the *same compiled* hinge
   right-hand side, wall-time ratio at equal hinge error over T = 20, for
   n = 4, 6, 8, 10 (log-log interpolation of our work-precision curve);
2. the chart method, with the state ``(a, c)`` in ``t`` and in Sundman's time and with ``(a, J c)``
   in Sundman's time (its default, :mod:`manifold.ambient_velocity`), against DOP853 on the chart
   right-hand side (same atlas loop and switch rule), n = 4 and 8;
3. real128 over T = 100 at n = 4: hinge and chart wall times (the chart variants of section 2),
   fastest and median of several runs;
4. the hinge method in float64 at its default tolerance: error against a
   long-double chart reference over T = 20; relative energy error and its
   log-log growth slope over T = 1e4; rod-length error;
5. compact mode on and off, float64 and long double, n = 4..12 (``--compact-n``, ``--compact-fp``): compile
   (CPU and wall) cold and from heyoka's disk cache, CPU time per Taylor step, and in float64 an ensemble
   (``free_motions``, each mode with its default batch: the SIMD width unrolled, twice that compact);
6. constraint stabilisation: Baumgarte (rates 0.1, 1, 10), projection every
   10 time units, none -- wall time, rod-length drift and energy error over
   T = 1e4 at n = 4;
7. the real128 targets: n = 4, T = 100 from a pole (a start whose first latitude is pi/2 in chart 0), both
   methods at their defaults, CPU time, interleaved rounds, fastest of them, against 1.5 s (hinges) and 6 s (charts).

Errors are max |hinge - reference| over 101 samples; the reference is the
chart method in long double (an independent route).
"""

from __future__ import annotations

import argparse
import tempfile
import time

import heyoka as hy
import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem, HingeConstraints
from linkage.motion import free_motion, free_motions
from linkage.time_factor import ChainTimeFactor
from manifold import Precision, SaveAt
from manifold.constrained import compiled_constrained
from manifold.precision import is_double
from manifold.steppers import TaylorStepper
from manifold.sundman import SundmanStepper

from .ensemble_speed import starts
from .study import methods as M
from .study.experiments import errors, generic_start, reference, speed_ratio_at_equal_error

TOLS = [1e-8, 1e-10, 1e-12, 1e-14, None]
RTOLS = [1e-8, 1e-10, 1e-12, 1e-13]


def _rows(fns: dict, chain, p0, v0, T, ts, ref, repeats: int = 2) -> list[dict]:
    rows = []
    for name, (fn, knobs) in fns.items():
        for knob in knobs:
            runs = [fn(chain, p0, v0, T, ts, knob) for _ in range(repeats)]
            rows.append({"method": name, "knob": knob, "wall": min(r.wall for r in runs), "failed": runs[-1].failed,
                         "steps": runs[-1].steps, **errors(runs[-1], ref, chain)})
    return rows


def _geomean(ratios: list[tuple[float, float]]) -> float:
    return float(np.exp(np.mean(np.log([r for _, r in ratios])))) if ratios else float("nan")


def hinge_vs_dop853(ns: list[int], T: float = 20.0, repeats: int = 2) -> dict:
    """Section 1: hinge Taylor vs DOP853 on the same compiled hinge right-hand side."""
    out = {}
    for n in ns:
        chain, p0, v0 = generic_start(n)
        ts = np.linspace(0, T, 101)
        ref = reference(chain, p0, v0, T, ts, fp_type=np.longdouble)
        rows = _rows({"hinge Taylor (ours)": (M.hinge_taylor, TOLS), "scipy DOP853 hinges": (M.scipy_hinges, RTOLS)},
                     chain, p0, v0, T, ts, ref, repeats)
        ratios = speed_ratio_at_equal_error(rows, "hinge Taylor (ours)", "scipy DOP853 hinges")
        out[n] = {"rows": rows, "ratios": ratios, "geomean": _geomean(ratios)}
        print(f"  n = {n:2d}: DOP853 / hinge Taylor at equal error: "
              + ", ".join(f"{r:.1f}x at {e:.0e}" for e, r in ratios) + f"  (geometric mean {out[n]['geomean']:.1f}x)")
        for r in rows:
            print(f"      {r['method']:22s} knob {str(r['knob']):6s} wall {r['wall']:.3f} s  steps {r['steps']:7d}"
                  f"  error {r['hinge']:.1e}  energy {r['energy']:.1e}")
    return out


def chart_vs_dop853(ns: list[int], T: float = 20.0, repeats: int = 5) -> dict:
    """Section 2: chart Taylor (state ``(a, c)`` in ``t`` and in Sundman's time, and ``(a, J c)`` in Sundman's time)
    vs DOP853 on the chart right-hand side."""
    out = {}
    for n in ns:
        chain, p0, v0 = generic_start(n)
        ts = np.linspace(0, T, 101)
        ref = reference(chain, p0, v0, T, ts, fp_type=np.longdouble)
        M.atlas_taylor(chain, p0, v0, 0.5, ts[ts <= 0.5], None)  # compile outside the timings
        M.atlas_sundman(chain, p0, v0, 0.5, ts[ts <= 0.5], None)
        M.atlas_ambient(chain, p0, v0, 0.5, ts[ts <= 0.5], None)
        ours = {"atlas Taylor (ours)": (M.atlas_taylor, [1e-9, 1e-12, None]),
                "atlas Taylor, Sundman time (ours)": (M.atlas_sundman, [1e-9, 1e-12, None]),
                "atlas Taylor, ambient velocity (ours)": (M.atlas_ambient, [1e-9, 1e-12, None])}
        rows = _rows({**ours, "scipy DOP853 atlas": (M.scipy_atlas, RTOLS)}, chain, p0, v0, T, ts, ref, repeats)
        out[n] = {"rows": rows}
        for name, label in zip(ours, ("t", "tau", "tau, (a, J c)")):
            ratios = speed_ratio_at_equal_error(rows, name, "scipy DOP853 atlas")
            out[n][label] = {"ratios": ratios, "geomean": _geomean(ratios)}
            print(f"  n = {n:2d}: DOP853 / chart Taylor in {label:13s} at equal error: "
                  + ", ".join(f"{r:.1f}x at {e:.0e}" for e, r in ratios) + f"  (geometric mean {_geomean(ratios):.1f}x)")
        for r in rows:
            print(f"      {r['method']:34s} knob {str(r['knob']):6s} wall {r['wall']:.3f} s  steps {r['steps']:6d}"
                  f"  error {r['hinge']:.1e}  energy {r['energy']:.1e}")
    return out


def quad_precision(T: float = 100.0, repeats: dict | None = None) -> dict:
    """Section 3: real128 at n = 4 over ``T``, both methods, the charts in Sundman's time and in ``t`` (compiles excluded).

    Single runs on a shared machine scatter by 25 % within minutes, so each method runs ``repeats[method]``
    times (default: hinges 5, charts 2 each) and prints the fastest (the code's cost) and the median (what a user
    meets), the fastest CPU time (less sensitive to other jobs on the machine) and the fastest time per step.
    """
    repeats = {"hinges": 5, "charts": 2, "charts, (a, c)": 2, "charts in t": 2} if repeats is None else repeats
    chain, p0, v0 = generic_start(4)
    h0, w0 = chain.from_point(p0), chain.from_point(v0)
    out: dict = {}
    ends = {}
    # the charts' default: Sundman's time, the state (a, J c) (manifold.ambient_velocity)
    variants = {"hinges": {"method": "hinges"}, "charts": {"method": "charts"},
                "charts, (a, c)": {"method": "charts", "stepper": SundmanStepper(ChainTimeFactor(chain))},
                "charts in t": {"method": "charts", "stepper": TaylorStepper()}}
    for name, kw in variants.items():
        free_motion(chain, h0, w0, 0.01, precision=Precision(fp_type=hy.real128), **kw)
        walls, cpus = [], []
        for _ in range(repeats[name]):
            t0, c0 = time.perf_counter(), time.process_time()
            m = free_motion(chain, h0, w0, T, save=SaveAt(dense=False), precision=Precision(fp_type=hy.real128), **kw)
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        ends[name] = m.solution.end_state()[0]
        out[name] = {"wall": min(walls), "median": float(np.median(walls)), "cpu": min(cpus),
                     "energy": m.relative_energy_error, "steps": m.n_steps}
        print(f"  {name:14s}: fastest {min(walls):.2f} s, median {np.median(walls):.2f} s of {len(walls)} runs, "
              f"CPU {min(cpus):.2f} s ({1e3 * min(walls) / m.n_steps:.2f} ms per step), {m.n_steps} steps, "
              f"energy error {m.relative_energy_error:.1e}")
    out["agreement"] = float(np.max(np.abs((ends["hinges"] - ends["charts"]).astype(float))))
    out["agreement in t"] = float(np.max(np.abs((ends["charts in t"] - ends["charts"]).astype(float))))
    out["agreement (a, c)"] = float(np.max(np.abs((ends["charts, (a, c)"] - ends["charts"]).astype(float))))
    print(f"  hinge and chart end points differ by {out['agreement']:.1e}, the charts in t and in tau by "
          f"{out['agreement in t']:.1e}, in (a, c) and (a, J c) by {out['agreement (a, c)']:.1e}")
    return out


#: The real128 targets at n = 4, T = 100 from a pole: CPU seconds per method.
QUAD_TARGETS = {"hinges": 1.5, "charts": 6.0}


def pole_start(n: int = 4, seed: int = 0) -> tuple:
    """A chain with ``L = n - 1.3``, hinges at a pole of chart 0 (first latitude ``pi/2``) and a unit-energy velocity:
    a random hinge velocity projected K-orthogonally onto the tangent space (chart 0 is singular there)."""
    chain = Chain(n, n - 1.3)
    rng = np.random.default_rng(seed)
    a = np.append(rng.uniform(-1, 1, n - 3), 0.3)
    a[0] = np.pi / 2
    x = chain.atlas().get_point(0, a)
    w = HingeConstraints(chain).project_velocity(x, rng.normal(size=x.size))
    w = w / np.sqrt(w @ chain.ambient_metric @ w)  # kinetic energy 1/2 w^T K w = 1/2
    return chain, chain.from_point(x), chain.from_point(w)


def quad_targets(T: float = 100.0, rounds: int = 3) -> dict:
    """Section 7: real128, n = 4, ``T`` from a pole (:func:`pole_start`), hinges and charts at their defaults:
    CPU time of this process, the methods interleaved round by round, the fastest of ``rounds`` (compiles excluded:
    a short solve of each first), with steps, energy error and the distance of the two end points."""
    chain, h0, w0 = pole_start(4)
    quad = Precision(fp_type=hy.real128)
    for method in QUAD_TARGETS:
        free_motion(chain, h0, w0, 0.01, method=method, precision=quad)
    best = {method: np.inf for method in QUAD_TARGETS}
    ends, runs = {}, {}
    for _ in range(rounds):
        for method in QUAD_TARGETS:
            c0 = time.process_time()
            m = free_motion(chain, h0, w0, T, method=method, save=SaveAt(dense=False), precision=quad)
            best[method] = min(best[method], time.process_time() - c0)
            ends[method], runs[method] = m.solution.end_state()[0], m
    out: dict = {}
    for method, target in QUAD_TARGETS.items():
        m = runs[method]
        out[method] = {"cpu": best[method], "steps": m.n_steps, "energy": m.relative_energy_error, "target": target}
        print(f"  {method:7s}: CPU {best[method]:6.2f} s (fastest of {rounds} interleaved rounds; target {target:g} s), "
              f"{m.n_steps} steps, {1e3 * best[method] / m.n_steps:.2f} ms per step, "
              f"energy error {m.relative_energy_error:.1e}")
    out["agreement"] = float(np.max(np.abs((ends["hinges"] - ends["charts"]).astype(float))))
    print(f"  end points of the two methods differ by {out['agreement']:.1e}")
    return out


def float64_accuracy(T_short: float = 20.0, T_long: float = 1e4) -> dict:
    """Section 4: the hinge method's default-tolerance accuracy, energy growth and closure."""
    chain, p0, v0 = generic_start(4, seed=2)
    ts = np.linspace(0, T_short, 101)
    ref = reference(chain, p0, v0, T_short, ts, fp_type=np.longdouble)
    err = errors(M.hinge_taylor(chain, p0, v0, T_short, ts, None), ref, chain)
    tl = np.concatenate([[0.0], np.geomspace(1.0, T_long, 60)])
    m = free_motion(chain, chain.from_point(p0), chain.from_point(v0), T_long, method="hinges",
                    save=SaveAt(t_eval=tl, dense=False))
    energy = np.maximum.accumulate(np.abs(m.energies / m.energies[0] - 1))
    sel = tl >= T_long / 1000
    slope = float(np.polyfit(np.log(tl[sel]), np.log(np.maximum(energy[sel], 1e-17)), 1)[0])
    out = {"error_T20": err["hinge"], "energy_T_long": float(m.relative_energy_error), "slope": slope,
           "rod_error": float(m.closure_residuals.max()), "steps": m.n_steps, "wall": m.solution.stats.wall_seconds}
    print(f"  error over T = {T_short:g}: {out['error_T20']:.1e}; energy error over T = {T_long:g}: "
          f"{out['energy_T_long']:.1e} (log-log slope {slope:.2f}); rod-length error {out['rod_error']:.1e}; "
          f"{m.n_steps} steps in {out['wall']:.1f} s")
    return out


def compact_modes(ns: list[int], fp_types: tuple = (float, np.longdouble), T: float = 200.0, repeats: int = 3,
                  ensemble: int = 32) -> dict:
    """Section 5: the hinge integrator compact and unrolled, per n and precision.

    Compiles go through a fresh heyoka disk cache (a temporary directory): "cold" is the first build (nothing
    cached, heyoka's memory cache and ours cleared; CPU and wall seconds), "cached" the same build once both
    memory caches are cleared again (what a new process pays once the code is on disk).  Then the CPU time of a
    T = ``T`` run (``SaveAt(dense=False)``, fastest of ``repeats``, the two modes interleaved) per Taylor step.
    In float64 also ``free_motions`` of ``ensemble`` unit-speed starts over T = 20 in each mode (its default batch
    size for that mode, serial backend; batch compiles excluded), the CPU time per trajectory.
    """
    out = {}
    old_path, old_enabled = hy.llvm_state.get_diskcache_path(), hy.llvm_state.get_diskcache_enabled()

    def build(comp, chain, h0, w0, compact, fp) -> tuple[float, float]:
        comp.clear()
        hy.llvm_state.clear_memcache()
        c0, t0 = time.process_time(), time.perf_counter()
        free_motion(chain, h0, w0, 0.01, method="hinges", compact_mode=compact, precision=Precision(fp_type=fp))
        return time.process_time() - c0, time.perf_counter() - t0

    try:
        with tempfile.TemporaryDirectory() as cache:
            hy.llvm_state.set_diskcache_path(cache)
            hy.llvm_state.set_diskcache_enabled(True)
            for fp in fp_types:
                for n in ns:
                    chain, p0, v0 = generic_start(n)
                    h0, w0 = chain.from_point(p0), chain.from_point(v0)
                    comp = compiled_constrained(ChainSystem(chain))
                    for compact in (False, True):
                        cold, cold_wall = build(comp, chain, h0, w0, compact, fp)
                        cached, _ = build(comp, chain, h0, w0, compact, fp)
                        out[(fp, n, compact)] = {"compile_cpu": cold, "compile_wall": cold_wall, "cached_cpu": cached,
                                                 "run": np.inf}
                    for _ in range(repeats):
                        for compact in (False, True):
                            c0 = time.process_time()
                            m = free_motion(chain, h0, w0, T, method="hinges", compact_mode=compact,
                                            save=SaveAt(dense=False), precision=Precision(fp_type=fp))
                            row = out[(fp, n, compact)]
                            row["run"], row["steps"] = min(row["run"], time.process_time() - c0), m.n_steps
                    un, co = out[(fp, n, False)], out[(fp, n, True)]
                    if is_double(fp) and ensemble:
                        H, V = starts(chain, ensemble)
                        for compact in (False, True):  # compile the batches outside the timing
                            free_motions(chain, H[:1], V[:1], 0.01, compact_mode=compact, backend="serial")
                        for row in (un, co):
                            row["ensemble"] = np.inf
                        for _ in range(repeats):
                            for compact, row in ((False, un), (True, co)):
                                c0 = time.process_time()
                                free_motions(chain, H, V, 20.0, compact_mode=compact, backend="serial")
                                row["ensemble"] = min(row["ensemble"], (time.process_time() - c0) / ensemble)
                        print(f"  float64    n = {n:2d}: free_motions of {ensemble}, T = 20, per trajectory: unrolled "
                              f"{1e3 * un['ensemble']:.3f} ms, compact {1e3 * co['ensemble']:.3f} ms, compact / "
                              f"unrolled {co['ensemble'] / un['ensemble']:.2f}", flush=True)
                    print(f"  {np.dtype(fp).name:10s} n = {n:2d}: compile CPU unrolled {un['compile_cpu']:6.2f} s cold "
                          f"(wall {un['compile_wall']:6.2f} s), {un['cached_cpu']:5.2f} s cached; compact "
                          f"{co['compile_cpu']:5.2f} s cold, {co['cached_cpu']:5.2f} s cached; T = {T:g}: unrolled "
                          f"{1e3 * un['run']:7.2f} ms ({1e6 * un['run'] / un['steps']:5.1f} us/step), compact "
                          f"{1e3 * co['run']:7.2f} ms ({1e6 * co['run'] / co['steps']:5.1f} us/step), "
                          f"compact / unrolled {co['run'] / un['run']:.2f}", flush=True)
    finally:
        hy.llvm_state.set_diskcache_path(old_path)
        hy.llvm_state.set_diskcache_enabled(old_enabled)
    return out


def stabilisations(T: float = 1e4) -> dict:
    """Section 6: how each stabilisation holds the rods and the energy over a long run."""
    chain, p0, v0 = generic_start(4, seed=2)
    h0, w0 = chain.from_point(p0), chain.from_point(v0)
    ts = np.linspace(0, T, 201)
    out = {}
    for label, kw in [("baumgarte, rate 0.1", {"rate": 0.1}), ("baumgarte, rate 1", {}),
                      ("baumgarte, rate 10", {"rate": 10.0}), ("projection every 10", {"stabilisation": "projection"}),
                      ("none", {"stabilisation": "none"})]:
        free_motion(chain, h0, w0, 0.01, method="hinges", **kw)  # compile outside the timing
        t0 = time.perf_counter()
        m = free_motion(chain, h0, w0, T, method="hinges", save=SaveAt(t_eval=ts, dense=False), throw=False, **kw)
        wall = time.perf_counter() - t0
        reached = m.times <= float(m.solution.t_reached)
        out[label] = {"wall": wall, "rods": float(m.closure_residuals[reached].max()),
                      "energy": m.relative_energy_error, "status": m.solution.status.value}
        print(f"  {label:20s}: {wall:5.2f} s, rod-length error {out[label]['rods']:.1e}, "
              f"energy error {out[label]['energy']:.1e}, {out[label]['status']}")
    return out


def main(quick: bool = False, sections: str = "1234567", compact_n: list[int] | None = None,
         compact_fp: tuple[str, ...] = ("float64", "longdouble")) -> dict:
    ns = [4, 6] if quick else [4, 6, 8, 10]
    res: dict = {}
    if "1" in sections:
        print("1. hinge Taylor vs DOP853 on the same compiled hinge right-hand side, T = 20")
        res["hinge_vs_dop853"] = hinge_vs_dop853(ns)
    if "2" in sections:
        print("2. chart Taylor vs DOP853 on the chart right-hand side, T = 20")
        res["chart_vs_dop853"] = chart_vs_dop853([4] if quick else [4, 8])
    if "3" in sections:
        print(f"3. real128, n = 4, T = {10 if quick else 100}")
        res["quad"] = quad_precision(10.0 if quick else 100.0)
    if "4" in sections:
        print("4. hinge method, float64, default tolerance")
        res["accuracy"] = float64_accuracy(T_long=1e3 if quick else 1e4)
    if "5" in sections:
        print("5. compact mode")
        fps = {"float64": float, "longdouble": np.longdouble}
        res["compact"] = compact_modes(compact_n or ([4] if quick else [4, 6, 8, 10, 12]),
                                       tuple(fps[name] for name in compact_fp))
    if "6" in sections:
        print(f"6. stabilisation, n = 4, T = {1e3 if quick else 1e4:g}")
        res["stabilisation"] = stabilisations(1e3 if quick else 1e4)
    if "7" in sections:
        print(f"7. real128 targets, n = 4, T = {10 if quick else 100} from a pole")
        res["quad targets"] = quad_targets(10.0 if quick else 100.0)
    return res


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="python -m benchmarks.method_speed", description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="n = 4, 6 and short horizons (minutes)")
    parser.add_argument("--sections", default="1234567", help="which sections to run, e.g. 13 (default all)")
    parser.add_argument("--compact-n", type=int, nargs="+", default=None,
                        help="section 5: chain sizes (default 4 6 8 10 12; quick 4)")
    parser.add_argument("--compact-fp", nargs="+", choices=("float64", "longdouble"), default=("float64", "longdouble"),
                        help="section 5: precisions (default both)")
    args = parser.parse_args()
    main(args.quick, args.sections, args.compact_n, tuple(args.compact_fp))
