"""The Taylor stepper's defaults, chosen by measurement: compile options, then tolerance.

Run ``python -m benchmarks.taylor_options`` (about 30 minutes on 2 cores; ``--sections`` picks tables).  For each
n (unit masses, ``L = n - 1.3``, the unit-speed generic start of the study):

1. **Compile options** of the float64 integrator: compact mode with LLVM ``opt_level`` 0..3, and
   straight-line code (``compact_mode=False``, against compact mode in a subprocess under ``--timeout``,
   for the n in ``--full-n``).  Columns: cold compile (heyoka's disk cache off), compile again from a
   populated disk cache (what every later process pays), CPU time of a run to ``T`` (the least of 5, the
   options taking turns) and its ratio to compact mode at ``opt_level`` 3.
2. **Tolerance** at the default compile options: CPU time, final hinge error against a long-double
   reference (tol 1e-19) and relative energy error, for tol 1e-12 .. eps.
3. **real128** at n = 4 over ``--real128-T`` with compact mode at each ``opt_level``.
4. **The default chart path** (``free_motion(method="charts")``: the state ``(a, J c)`` in Sundman's time) compact
   and unrolled, for the n in ``--default-n``: the CPU seconds of its first solve with heyoka's disk cache off
   (cold) and again from a populated disk cache, and the CPU time of a T = 20 call at tol 1e-10 with 101 samples
   (as ``benchmarks.peers`` calls it; the least of 5, the two modes interleaved), with their ratio and the
   largest hinge distance between the two runs' samples: what the chart path's compile option is chosen
   from (``TaylorStepper(compact_mode=...)``).  ``--sections 4`` runs it alone (about 5 minutes to n = 8).
5. **heyoka's other code-generation flags** on the hinge method's integrator (float64, its default compile mode,
   the n in ``--flags-n``), which the library leaves at heyoka's defaults: ``fast_math`` and ``slp_vectorize`` on
   the scalar integrator, and ``force_avx512`` on the SIMD batch integrator of ``free_motions`` (heyoka's SIMD
   width and 8 lanes), for ``FLAG_STARTS`` starts to T = ``--T``.  Columns: the cold compile (CPU seconds, disk
   cache off), the CPU time of the whole loop or batch (the least of 7, every variant in turn), its ratio to the
   default scalar loop, and the largest distance of its end states from the default's.  The rows of 8 lanes
   and more move between processes with the stack's alignment (``benchmarks.simd_stack_phase``); within one
   process they run at the same one.  ``--sections 5`` runs it alone (about 2 minutes).

CPU time of this process, not wall time: the machine is shared.  Compare the ratios printed side by side.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from typing import Any

import heyoka as hy
import numpy as np

from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import Precision, SaveAt, TaylorStepper, compiled, solve_chart_exp_ode
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.constrained import compiled_constrained, default_compact_mode
from manifold.sundman import SundmanStepper

from .starts import completed_starts
from .study.experiments import generic_start

COMPACT_OPTIONS = [(True, 3), (True, 2), (True, 1), (True, 0)]
EPS = float(np.finfo(float).eps)
TOLERANCES = [1e-12, 1e-13, 1e-14, 1e-15, EPS]
#: Section 5: the starts each variant integrates, and its rounds.
FLAG_STARTS, FLAG_ROUNDS = 64, 7


def _rebuild(family, fp_type, compact: bool, opt_level: int) -> float:
    """Seconds to build the integrator after forgetting every in-memory copy."""
    compiled(family).clear()
    hy.llvm_state.clear_memcache()
    t0 = time.perf_counter()
    with compiled(family).integrator(fp_type, compact_mode=compact, opt_level=opt_level):
        pass
    return time.perf_counter() - t0


def compile_times(n: int, compact: bool, opt_level: int, fp_type=float) -> tuple[float, float]:
    """(cold, from a populated disk cache) wall seconds to build the integrator.

    Needs heyoka's disk cache pointed at a scratch directory (as :func:`main` does); leaves it enabled,
    so that the runs after fetch their code from it.
    """
    family = generic_start(n)[0].atlas().charts[0].family
    hy.llvm_state.set_diskcache_enabled(False)
    cold = _rebuild(family, fp_type, compact, opt_level)
    hy.llvm_state.set_diskcache_enabled(True)
    _rebuild(family, fp_type, compact, opt_level)  # populate
    return cold, _rebuild(family, fp_type, compact, opt_level)


def run_cpu(n: int, T: float, steppers: list, fp_type=float, repeat: int = 5) -> list[tuple[float, object]]:
    """Per stepper: the least CPU time of ``repeat`` solves to ``T`` (compiled beforehand; the steppers take turns,
    so that the load of a shared machine hits all alike) and the last solution."""
    chain, p0, v0 = generic_start(n, seed=1)
    metric = chain.metric()
    for st in steppers:
        solve_chart_exp_ode(metric, p0, v0, 0.01, stepper=st,
                            precision=Precision(fp_type=fp_type))  # compile, warm the caches
    best, sols = [np.inf] * len(steppers), [None] * len(steppers)
    for _ in range(repeat):
        for k, st in enumerate(steppers):
            t0 = time.process_time()
            sols[k] = solve_chart_exp_ode(metric, p0, v0, T, stepper=st, save=SaveAt(dense=False),
                                          precision=Precision(fp_type=fp_type))
            best[k] = min(best[k], time.process_time() - t0)
    return list(zip(best, sols))


def options_for(n: int, options: list, T: float) -> list[dict]:
    """Compile times and run CPU time of each ``(compact, opt_level)`` option, the runs side by side."""
    compile_s = [compile_times(n, compact, opt) for compact, opt in options]
    runs = run_cpu(n, T, [TaylorStepper(compact_mode=c, opt_level=o) for c, o in options])
    return [{"compact": c, "opt": o, "cold": cold, "cached": cached, "cpu": cpu, "steps": sol.n_steps}
            for (c, o), (cold, cached), (cpu, sol) in zip(options, compile_s, runs)]


def _in_subprocess(n: int, T: float, timeout: float) -> list[dict] | None:
    """Straight-line code against compact mode (opt 3) in a fresh process, under a time limit."""
    cmd = [sys.executable, "-m", "benchmarks.taylor_options", "--one", str(n), "--T", str(T)]
    try:
        out = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=True)
    except subprocess.TimeoutExpired:
        return None
    return json.loads(out.stdout.strip().splitlines()[-1])


def tolerance_sweep(n: int, T: float, compact: bool, opt_level: int) -> list[dict]:
    chain, p0, v0 = generic_start(n, seed=1)
    ref = solve_chart_exp_ode(chain.metric(), p0, v0, T, save=SaveAt(dense=False),
                              precision=Precision(fp_type=np.longdouble, tol=1e-19))
    p_ref = ref.end_state()[0].astype(float)
    runs = run_cpu(n, T, [TaylorStepper(tol, compact_mode=compact, opt_level=opt_level) for tol in TOLERANCES])
    return [{"tol": tol, "cpu": cpu, "steps": sol.n_steps, "switches": sol.n_switches,
             "hinge_error": float(np.abs(sol.end_state()[0] - p_ref).max()), "energy_error": sol.relative_energy_error}
            for tol, (cpu, sol) in zip(TOLERANCES, runs)]


def default_path_modes(n: int, tol: float = 1e-10, T: float = 20.0, repeat: int = 5) -> dict[bool, dict]:
    """Section 4 for one ``n``: per compact mode, the cold and cached compile (CPU seconds of a first short solve)
    and the least CPU time of a T = ``T`` call at ``tol`` with 101 samples; ``"end"`` the samples' hinges."""
    chain, p0, v0 = generic_start(n)
    h0, w0 = chain.from_point(p0), chain.from_point(v0)

    def call(compact: bool, t_final: float, save: SaveAt = SaveAt(dense=False)):
        stepper = SundmanStepper(ChainTimeFactor(chain), tol=tol, compact_mode=compact,
                                 velocity=ConstrainedVelocity(ChainSystem(chain)))
        return free_motion(chain, h0, w0, t_final, method="charts", stepper=stepper, save=save)

    def first_solve(compact: bool) -> float:
        compiled(chain.atlas().charts[0].family).clear()
        hy.llvm_state.clear_memcache()
        c0 = time.process_time()
        call(compact, 0.01)
        return time.process_time() - c0

    out: dict[bool, dict] = {}
    for compact in (False, True):
        hy.llvm_state.set_diskcache_enabled(False)
        cold = first_solve(compact)
        hy.llvm_state.set_diskcache_enabled(True)
        first_solve(compact)  # populate
        out[compact] = {"cold": cold, "cached": first_solve(compact), "cpu": np.inf}
    save = SaveAt(t_eval=np.linspace(0.0, T, 101), dense=False)
    for _ in range(repeat):
        for compact in (False, True):
            c0 = time.process_time()
            motion = call(compact, T, save)
            row = out[compact]
            row["cpu"], row["steps"], row["end"] = min(row["cpu"], time.process_time() - c0), motion.n_steps, motion.hinges
    return out


def hinge_problem(n: int, count: int, T: float) -> tuple[list, np.ndarray, np.ndarray, bool]:
    """The hinge method's equations (Baumgarte-stabilised, as ``free_motion`` and ``free_motions`` integrate
    them), ``count`` start states (rows) and their runtime parameters (rows), from the study's generic starts
    (seeds ``0 .. count - 1`` on the chain of seed 0), and the method's default compact mode."""
    chain = generic_start(n)[0]
    system = ChainSystem(chain)
    starts = [generic_start(n, seed)[1:] for seed in range(count)]
    states, pars = completed_starts(chain, np.array([p for p, _ in starts]), np.array([v for _, v in starts]), T)
    return compiled_constrained(system).pieces(float).equations(True), states, pars, default_compact_mode(system, float)


def flag_variants(n: int, T: float) -> list[dict]:
    """Section 5 for one ``n``: per variant, its cold compile, least CPU time over the starts and end states."""
    equations, Y, P, compact = hinge_problem(n, FLAG_STARTS, T)
    width = hy.recommended_simd_size()
    variants = [("scalar", 1, {}), ("scalar, fast_math", 1, {"fast_math": True}),
                ("scalar, slp_vectorize", 1, {"slp_vectorize": True}),
                (f"batch of {width} (SIMD width)", width, {})]
    variants += [(f"batch of 8{avx}", 8, flags) for avx, flags in (("", {}), (", force_avx512", {"force_avx512": True}))
                 if width != 8 or flags]
    cache_was = hy.llvm_state.get_diskcache_enabled()
    hy.llvm_state.set_diskcache_enabled(False)
    rows = []
    try:
        for name, lanes, flags in variants:
            hy.llvm_state.clear_memcache()
            c0 = time.process_time()
            if lanes == 1:
                ta = hy.taylor_adaptive(equations, Y[0], compact_mode=compact, **flags)
            else:
                ta = hy.taylor_adaptive_batch(equations, np.zeros((Y.shape[1], lanes)), compact_mode=compact, **flags)
            rows.append({"name": name, "lanes": lanes, "ta": ta, "cold": time.process_time() - c0, "cpu": np.inf})
    finally:
        hy.llvm_state.set_diskcache_enabled(cache_was)

    def run(ta: Any, lanes: int) -> np.ndarray:
        npars, ends = len(ta.pars), []
        for i in range(0, len(Y), lanes):
            if lanes == 1:
                ta.state[:], ta.time, ta.pars[:] = Y[i], 0.0, P[i, :npars]
            else:
                ta.set_time(0.0)
                ta.state[:], ta.pars[:] = Y[i : i + lanes].T, P[i : i + lanes, :npars].T
            ta.propagate_until(T)
            ends.append(np.array(ta.state).reshape(Y.shape[1], lanes).T)
        return np.concatenate(ends)

    for _ in range(FLAG_ROUNDS):
        for row in rows:
            c0 = time.process_time()
            row["end"] = run(row["ta"], row["lanes"])
            row["cpu"] = min(row["cpu"], time.process_time() - c0)
    for row in rows:
        row["ratio"] = rows[0]["cpu"] / row["cpu"]
        row["apart"] = float(np.abs(row["end"] - rows[0]["end"]).max())
    return rows


def _show(n: int, rows: list[dict]) -> None:
    base = next(r["cpu"] for r in rows if r["compact"] and r["opt"] == 3)
    for r in rows:
        print(f"{n:>2} {str(r['compact']):>7} {r['opt']:>3} {r['cold']:8.2f} {r['cached']:8.2f} {r['cpu']:8.4f} "
              f"{r['steps']:>6} {r['cpu'] / base:6.2f}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[4, 6, 8])
    parser.add_argument("--T", type=float, default=20.0)
    parser.add_argument("--full-n", type=int, nargs="*", default=[3, 4], help="n at which compact_mode=False is tried")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds allowed to one compact_mode=False trial")
    parser.add_argument("--real128-T", type=float, default=10.0)
    parser.add_argument("--default-n", type=int, nargs="+", default=[3, 4, 5, 6, 8], help="n of section 4")
    parser.add_argument("--flags-n", type=int, nargs="+", default=[4, 8], help="n of section 5")
    parser.add_argument("--sections", default="12345", help="which sections to run, e.g. 4")
    parser.add_argument("--one", type=int, metavar="N", help=argparse.SUPPRESS)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as cache:  # a scratch disk cache: the user's is left alone
        hy.llvm_state.set_diskcache_path(cache)
        if args.one:
            print(json.dumps(options_for(args.one, [(False, 3), (True, 3)], args.T)))
        else:
            report(args)


def report(args: argparse.Namespace) -> None:
    """The tables of the module docstring (those of ``args.sections``)."""
    if "1" in args.sections:
        compile_options(args)
    if "2" in args.sections:
        tolerances(args)
    if "3" in args.sections:
        real128(args)
    if "4" in args.sections:
        default_path(args)
    if "5" in args.sections:
        codegen_flags(args)


def default_path(args: argparse.Namespace) -> None:
    """Section 4."""
    print("\n4. the default chart path ((a, J c) in Sundman's time, float64), unrolled and compact: CPU seconds "
          "of a first solve cold (disk cache off) and cached, CPU time of a T = 20 call at tol 1e-10 with 101 "
          "samples (least of 5, interleaved)")
    print(f"{'n':>2} {'unrolled cold / cached s':>25} {'compact cold / cached s':>24} {'unrolled ms':>12} "
          f"{'compact ms':>11} {'compact / unrolled':>19} {'steps':>6} {'hinge diff':>10}")
    for n in args.default_n:
        un, co = (row := default_path_modes(n))[False], row[True]
        print(f"{n:>2} {un['cold']:12.2f} / {un['cached']:10.2f} {co['cold']:11.2f} / {co['cached']:10.2f} "
              f"{1e3 * un['cpu']:12.2f} {1e3 * co['cpu']:11.2f} {co['cpu'] / un['cpu']:19.2f} {un['steps']:>6} "
              f"{np.abs(un['end'] - co['end']).max():10.1e}", flush=True)


def compile_options(args: argparse.Namespace) -> None:
    """Section 1."""
    print(f"1. compile options (float64, run to T = {args.T:g}; run = least CPU time of 5, options in turn; "
          "ratio = run / run at compact, opt 3)")
    print(f"{'n':>2} {'compact':>7} {'opt':>3} {'cold s':>8} {'cached s':>8} {'run s':>8} {'steps':>6} {'ratio':>6}")
    for n in args.n:
        _show(n, options_for(n, COMPACT_OPTIONS, args.T))
    for n in args.full_n:
        rows = _in_subprocess(n, args.T, args.timeout)
        if rows is None:
            print(f"{n:>2}   False   3   did not compile and run within {args.timeout:g} s", flush=True)
        else:
            _show(n, rows)


def tolerances(args: argparse.Namespace) -> None:
    """Section 2."""
    default = TaylorStepper()
    print(f"\n2. tolerance ({default!r} otherwise; final hinge error against long double at tol 1e-19; CPU time as above)")
    print(f"{'n':>2} {'tol':>7} {'run s':>8} {'steps':>6} {'switches':>8} {'hinge err':>9} {'dE/E':>8}")
    for n in args.n:
        for r in tolerance_sweep(n, args.T, default.compact_mode, default.opt_level):
            tol = "eps" if r["tol"] == EPS else f"{r['tol']:.0e}"
            print(f"{n:>2} {tol:>7} {r['cpu']:8.4f} {r['steps']:>6} {r['switches']:>8} {r['hinge_error']:9.1e} "
                  f"{r['energy_error']:8.1e}", flush=True)


def real128(args: argparse.Namespace) -> None:
    """Section 3."""
    print(f"\n3. real128, n = 4, T = {args.real128_T:g} (compact mode; cold compile, disk cache off; one run each, CPU time)")
    print(f"{'opt':>3} {'compile s':>9} {'run s':>8} {'steps':>6} {'dE/E':>8}")
    builds = [compile_times(4, True, opt, hy.real128)[0] for _, opt in COMPACT_OPTIONS]
    steppers = [TaylorStepper(opt_level=opt) for _, opt in COMPACT_OPTIONS]
    runs = run_cpu(4, args.real128_T, steppers, hy.real128, repeat=1)
    for (_, opt), build, (cpu, sol) in zip(COMPACT_OPTIONS, builds, runs):
        print(f"{opt:>3} {build:9.2f} {cpu:8.2f} {sol.n_steps:>6} {sol.relative_energy_error:8.1e}", flush=True)


def codegen_flags(args: argparse.Namespace) -> None:
    """Section 5."""
    print(f"\n5. heyoka's code-generation flags on the hinge integrator (float64, its default compile mode; "
          f"{FLAG_STARTS} starts to T = {args.T:g}; CPU time, least of {FLAG_ROUNDS}, variants in turn; "
          f"SIMD width here {hy.recommended_simd_size()})")
    print(f"{'n':>2} {'variant':<28} {'cold s':>7} {'ms':>8} {'scalar / it':>11} {'ends apart':>10}")
    for n in args.flags_n:
        for r in flag_variants(n, args.T):
            print(f"{n:>2} {r['name']:<28} {r['cold']:7.2f} {1e3 * r['cpu']:8.2f} {r['ratio']:11.2f} "
                  f"{r['apart']:10.1e}", flush=True)


if __name__ == "__main__":
    main()
