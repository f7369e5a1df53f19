"""Speed against the strongest peers, on the same equations: ``python -m benchmarks.peers [--quick]``.

Every peer integrates the hinge method's own equations (the Baumgarte-stabilised multiplier
equations of :class:`linkage.constraints.ChainSystem`, transcribed from heyoka's decomposition of
the compiled right-hand side by :mod:`benchmarks.transcribed_rhs`), from the hinge method's own
start and with its damping rate:

* scipy's DOP853 on a numba-compiled right-hand side (``numba.njit``);
* diffrax's Dopri8 on JAX for CPU, the whole solve ``jax.jit``-compiled (compile excluded),
  with a PID step-size controller at ``rtol = atol``.

Ours: ``free_motion(method="hinges")`` and ``free_motion(method="charts")`` (its default stepper),
each as a user calls it (start check, compile fetched from the cache, ``t_eval``, no dense output).
``--compile-modes`` adds the hinges with heyoka's compact mode forced on and off (``compact_mode=True`` /
``False``), each against DOP853: what the default compile option (``default_compact_mode``) gains or loses; and
the charts' default stepper compiled unrolled (``free_motion(method="charts", compact_mode=False)``: the charts are
compact by default, for the compile's sake), against DOP853.

Conditions (the same for every row): a generic unit-energy start (``generic_start``:
``L = n - 1.3``, unit hinge masses), T = 20, the state at 101 equally spaced times; the error of a
run is the largest hinge distance ``max_t,k |h_k - h_k^ref|`` to the hinge method's solution in
real128 (``--quick``: long double) at those times; time is this process's CPU time
(``time.process_time``: the peers' threads count too, other jobs on the machine do not) with the process pinned to
one core (:func:`pin_to_one_core`; ``--all-cores`` leaves it free), every run
warmed up first (compiles excluded), all methods interleaved round by round, the fastest of
``--rounds`` rounds kept.  Pinned, a run beside other jobs gives the same ratios: alone and beside three busy
processes on the two cores, every ratio at n = 8 agreed within 9 % (at 1e-10: DOP853 15.3x / 15.5x, diffrax
7.5x / 7.4x, charts against DOP853 1.0x / 1.0x), and at n = 4, where a run takes a millisecond, within 20 %
where both runs gave a value rather than a bound.  On all cores it did not: JAX keeps a second thread busy while diffrax solves, which doubled diffrax's
CPU time when a core was free and not when other jobs took it (hinges vs diffrax at 1e-10: 18.7x alone, 8.1x
beside two busy processes).  A method's time at an error ``e`` is read log-log along its fastest
runs (the Pareto front of its tolerance sweep); a ratio is the peer's time over ours, at errors
1e-8, 1e-10 and the peer's best error.  ``>=`` marks a ratio where our loosest run was already
more accurate than ``e`` (our time at ``e`` is then at most that run's), ``<=`` one where the peer's was.

``--markdown`` writes the table into ``docs/benchmarks.md`` (its section "Against the strongest
peers", which ``python -m benchmarks.study`` keeps when it rewrites the page).

numba, jax and diffrax are benchmark-only (``pip install -e '.[bench]'``); a peer that is not
installed is reported as such and its column left empty.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import heyoka as hy
import numpy as np
import scipy
from scipy.integrate import solve_ivp

from linkage import Chain
from linkage.motion import free_motion
from manifold import Precision, SaveAt

from .study.experiments import generic_start
from .study.report import PEERS_SECTION, replace_section
from .transcribed_rhs import hinge_rhs, hinge_start

#: Tolerances swept: ours (``None``: the machine epsilon) and the peers' ``rtol = atol``.
OUR_TOLS: tuple[float | None, ...] = (1e-6, 1e-8, 1e-10, 1e-12, None)
CHART_TOLS: tuple[float | None, ...] = (1e-6, 1e-8, 1e-10, 1e-12, None)
PEER_RTOLS = (1e-6, 1e-8, 1e-10, 1e-12, 1e-13)
#: Errors at which ratios are read; ``None`` is the peer's best error.
TARGETS: tuple[float | None, ...] = (1e-8, 1e-10, None)
#: The columns of the table: (ours, peer); the last compares our two methods (which method when).
PAIRS = (("hinges", "DOP853"), ("hinges", "diffrax"), ("charts", "DOP853"), ("hinges", "charts"))
#: The hinges with the compile option forced (``--compile-modes``): row name -> ``compact_mode``.
COMPILE_MODES = {"compact": True, "unrolled": False}
#: The charts' default stepper compiled unrolled (``--compile-modes``), at the tolerances around the error 1e-10 only:
#: each tolerance is a compile of its own, 75-82 s of CPU at n = 8.
CHARTS_UNROLLED = "charts unrolled"
UNROLLED_CHART_TOLS = (1e-8, 1e-10, 1e-12)
MODE_PAIRS = tuple((mode, "DOP853") for mode in (*COMPILE_MODES, CHARTS_UNROLLED))
SECTION = PEERS_SECTION


@dataclass
class Problem:
    """One chain and start, sampled at ``ts``, with its reference."""

    n: int
    T: float
    chain: Chain
    h0: np.ndarray
    w0: np.ndarray
    ts: np.ndarray
    y0: np.ndarray = field(init=False)
    pars: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.y0, self.pars = hinge_start(self.chain, self.h0, self.w0, self.T)

    def hinges(self, points: np.ndarray) -> np.ndarray:
        """Complex hinges from interleaved real points (rows)."""
        return self.chain.from_point(np.asarray(points, dtype=float)[:, : 2 * (self.chain.n - 1)])


@dataclass
class Row:
    """One method at one tolerance: fastest CPU time, steps and error."""

    method: str
    knob: float | None
    cpu: float = np.inf
    steps: int = 0
    error: float = np.nan


def problem(n: int, T: float, samples: int = 101) -> Problem:
    chain, p0, v0 = generic_start(n)
    return Problem(n, T, chain, chain.from_point(p0), chain.from_point(v0), np.linspace(0.0, T, samples))


def reference(pb: Problem, fp_type: Any) -> np.ndarray:
    """The hinge method in ``fp_type`` (compact code: a short compile), hinges at ``pb.ts``."""
    m = free_motion(pb.chain, pb.h0, pb.w0, pb.T, method="hinges", save=SaveAt(t_eval=pb.ts, dense=False),
                    precision=Precision(fp_type=fp_type), compact_mode=True)
    return pb.hinges(m.solution.points.astype(float))


# --- the runners: each returns a callable() -> (hinges at ts, steps), warmed up --------------------------------


def ours(pb: Problem, method: str, tol: float | None,
         compact_mode: bool | None = None) -> Callable[[], tuple[np.ndarray, int]]:
    """``free_motion(method=...)``; ``compact_mode`` forced if not ``None`` (the charts: their default stepper,
    Sundman's time with the state ``(a, J c)``, compiled so)."""
    options = {} if compact_mode is None else {"compact_mode": compact_mode}

    def run() -> tuple[np.ndarray, int]:
        m = free_motion(pb.chain, pb.h0, pb.w0, pb.T, method=method, save=SaveAt(t_eval=pb.ts, dense=False),
                        precision=Precision(tol=tol), **options)
        return m.hinges, m.n_steps

    free_motion(pb.chain, pb.h0, pb.w0, min(pb.T, 0.1), method=method,
                precision=Precision(tol=tol), **options)  # compile outside the timing
    return run


def dop853(pb: Problem, numba: Any) -> Callable[[float], Callable[[], tuple[np.ndarray, int]]]:
    """scipy's DOP853 on the numba-compiled equations; returns ``rtol -> runner`` (one compile for all)."""
    f = numba.njit(hinge_rhs(pb.chain))
    pars = pb.pars

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        return f(y, pars)

    rhs(0.0, pb.y0)  # numba compiles at the first call

    def at(rtol: float) -> Callable[[], tuple[np.ndarray, int]]:
        def run() -> tuple[np.ndarray, int]:
            sol = solve_ivp(rhs, (0.0, pb.T), pb.y0, method="DOP853", rtol=rtol, atol=rtol, t_eval=pb.ts)
            if not sol.success:
                raise RuntimeError(f"DOP853 failed at rtol {rtol:g}: {sol.message}")
            return pb.hinges(sol.y.T), int(sol.nfev)  # DOP853: right-hand-side evaluations, 12 per step
        return run
    return at


def diffrax_dopri8(pb: Problem, modules: tuple[Any, Any]) -> Callable[[float], Callable[[], tuple[np.ndarray, int]]]:
    """diffrax's Dopri8 with a PID controller at ``rtol = atol``; returns ``rtol -> runner``.  The solve is one
    ``jax.jit`` function with the tolerance a traced argument (one compile for all), run once before timing."""
    jax, diffrax = modules
    f = hinge_rhs(pb.chain, stack=jax.numpy.stack)
    term, solver = diffrax.ODETerm(lambda t, y, args: f(y, args)), diffrax.Dopri8()
    saveat = diffrax.SaveAt(ts=jax.numpy.asarray(pb.ts))

    @jax.jit
    def solve(y0: Any, pars: Any, rtol: Any) -> Any:
        sol = diffrax.diffeqsolve(term, solver, 0.0, pb.T, None, y0, args=pars, saveat=saveat,
                                  stepsize_controller=diffrax.PIDController(rtol=rtol, atol=rtol),
                                  max_steps=1_000_000)
        return sol.ys, sol.stats["num_accepted_steps"]

    y0, pars = jax.numpy.asarray(pb.y0), jax.numpy.asarray(pb.pars)

    def at(rtol: float) -> Callable[[], tuple[np.ndarray, int]]:
        def run() -> tuple[np.ndarray, int]:
            ys, steps = jax.block_until_ready(solve(y0, pars, jax.numpy.asarray(rtol)))
            return pb.hinges(np.asarray(ys)), int(steps)
        run()  # the first call compiles
        return run
    return at


def peer_modules() -> dict[str, Any]:
    """The installed peers' modules; a missing one maps to the reason (a string)."""
    out: dict[str, Any] = {}
    try:
        import numba
        out["DOP853"] = numba
    except ImportError as err:
        out["DOP853"] = f"numba is not installed ({err}; pip install -e '.[bench]')"
    try:
        import jax
        jax.config.update("jax_enable_x64", True)
        jax.config.update("jax_platforms", "cpu")
        import diffrax
        out["diffrax"] = (jax, diffrax)
    except ImportError as err:
        out["diffrax"] = f"jax/diffrax are not installed ({err}; pip install -e '.[bench]')"
    return out


# --- measurement --------------------------------------------------------------------------------------------


def measure(pb: Problem, ref: np.ndarray, peers: dict[str, Any], rounds: int, charts: bool,
            modes: bool = False) -> list[Row]:
    """Every method at every tolerance, interleaved round by round; the fastest CPU time of ``rounds``.  ``modes``:
    also the hinges with each of :data:`COMPILE_MODES` forced."""
    jobs: list[tuple[Row, Callable[[], tuple[np.ndarray, int]]]] = []
    jobs += [(Row("hinges", tol), ours(pb, "hinges", tol)) for tol in OUR_TOLS]
    if modes:
        jobs += [(Row(mode, tol), ours(pb, "hinges", tol, compact)) for mode, compact in COMPILE_MODES.items()
                 for tol in OUR_TOLS]
    if charts:
        jobs += [(Row("charts", tol), ours(pb, "charts", tol)) for tol in CHART_TOLS]
    if charts and modes:
        jobs += [(Row(CHARTS_UNROLLED, tol), ours(pb, "charts", tol, False)) for tol in UNROLLED_CHART_TOLS]
    for name, build in (("DOP853", dop853), ("diffrax", diffrax_dopri8)):
        if not isinstance(peers[name], str):
            at = build(pb, peers[name])
            jobs += [(Row(name, r), at(r)) for r in PEER_RTOLS]
    for _ in range(rounds):
        for row, run in jobs:
            c0 = time.process_time()
            hinges, steps = run()
            row.cpu = min(row.cpu, time.process_time() - c0)
            row.steps, row.error = steps, float(np.abs(hinges - ref).max())
    return [row for row, _ in jobs]


def front(rows: list[Row], method: str) -> list[tuple[float, float]]:
    """``(error, cpu)`` of the method's runs that no other of its runs beats in both, by increasing error."""
    pts = sorted((r.error, r.cpu) for r in rows if r.method == method and np.isfinite(r.error))
    out: list[tuple[float, float]] = []
    for e, c in pts:  # increasing error: keep a run only if it is faster than every more accurate one
        if not out or c < out[-1][1]:
            out.append((e, c))
    return out


def cpu_at(pts: list[tuple[float, float]], e: float) -> tuple[float, str]:
    """CPU time at error ``e`` along a front, log-log; ``(time, "<=")`` if even the loosest run beats ``e``,
    ``(nan, "")`` if no run reaches it."""
    if not pts or e < pts[0][0] * (1 - 1e-12):
        return np.nan, ""
    if e >= pts[-1][0]:
        return pts[-1][1], "<=" if e > pts[-1][0] else ""
    errs, cpus = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.exp(np.interp(np.log(e), errs, cpus))), ""


def ratios(rows: list[Row], us: str, peer: str) -> list[tuple[float, float, str]]:
    """``(error, peer time / our time, mark)`` at :data:`TARGETS` (``None``: the peer's best error)."""
    ours_front, peer_front = front(rows, us), front(rows, peer)
    if not ours_front or not peer_front:
        return []
    out = []
    for target in TARGETS:
        e = peer_front[0][0] if target is None else target
        t_us, bound = cpu_at(ours_front, e)
        t_peer, peer_bound = cpu_at(peer_front, e)
        # a time read as a bound (the loosest run already beat e) bounds the ratio: ours from below, the peer's
        # from above; both at once say nothing
        mark = {(True, False): ">=", (False, True): "<=", (False, False): ""}.get((bool(bound), bool(peer_bound)))
        out.append((e, t_peer / t_us if mark is not None else np.nan, mark or ""))
    return out


def ratio_cell(rs: list[tuple[float, float, str]], missing: str = "") -> str:
    if not rs:
        return missing or "not measured"
    return " / ".join("-" if not np.isfinite(r) else f"{mark}{r:.1f}x" for _, r, mark in rs)


# --- the run ------------------------------------------------------------------------------------------------


def pin_to_one_core() -> int | None:
    """Pin every thread of this process to one CPU (threads started later inherit it).

    JAX's CPU runtime keeps a second thread busy while a solve runs: on 2 cores diffrax's CPU time at n = 8 was
    1.7-2x its wall time, and fell by half when other jobs took the spare core.  On one core every method's CPU
    time is its own work, whatever else the machine runs.  Call it before the peers are imported (:func:`main`
    does), so that their threads start pinned.

    Returns
    -------
    int or None
        The CPU, or ``None`` where the system cannot pin threads (no ``os.sched_setaffinity`` or no
        ``/proc/self/task``): then the process runs on all cores.
    """
    if not hasattr(os, "sched_setaffinity") or not os.path.isdir("/proc/self/task"):
        return None
    cpu = min(os.sched_getaffinity(0))
    done: set[int] = set()
    while True:  # until no thread is left unpinned: one may have started while the others were pinned
        tids = {int(tid) for tid in os.listdir("/proc/self/task")} - done
        if not tids:
            return cpu
        for tid in tids:
            try:  # sched_setaffinity(0, ...) would pin the calling thread alone
                os.sched_setaffinity(tid, {cpu})
            except ProcessLookupError:  # the thread ended in between
                pass
        done |= tids


def main(ns: list[int], T: float, rounds: int, quick: bool, markdown: Path | None, chart_max_n: int,
         modes: bool = False, all_cores: bool = False) -> dict:
    cpu = None if all_cores else pin_to_one_core()
    where = "all cores" if cpu is None else f"pinned to CPU {cpu}"
    peers = peer_modules()
    for name, mod in peers.items():
        if isinstance(mod, str):
            print(f"peer {name}: {mod}")
    fp_ref = np.longdouble if quick else hy.real128
    print(f"T = {T:g}, CPU time of this process ({where}), fastest of {rounds} interleaved rounds; errors against the hinge "
          f"method in {'long double' if quick else 'real128'}")
    results: dict[int, dict] = {}
    for n in ns:
        pb = problem(n, T)
        c0 = time.process_time()
        ref = reference(pb, fp_ref)
        ref_cpu = time.process_time() - c0
        rows = measure(pb, ref, peers, rounds, charts=n <= chart_max_n, modes=modes)
        pairs = PAIRS + (MODE_PAIRS if modes else ())
        results[n] = {"rows": rows, "ratios": {f"{a} vs {b}": ratios(rows, a, b) for a, b in pairs},
                      "reference_cpu": ref_cpu}
        print(f"n = {n} (L = {pb.chain.L:g}; reference {ref_cpu:.1f} s CPU)")
        for r in rows:
            knob = "eps" if r.knob is None else f"{r.knob:g}"
            unit = "evaluations" if r.method == "DOP853" else "steps"
            print(f"    {r.method:8s} tol {knob:6s} {1e3 * r.cpu:9.2f} ms  {r.steps:7d} {unit:11s} error {r.error:.1e}")
        print("    " + ";  ".join(f"{k}: {ratio_cell(v)}" for k, v in results[n]["ratios"].items()), flush=True)
    table = render(results, peers, T, rounds, quick, modes, pinned=cpu is not None)
    print("\n" + table)
    if markdown is not None:
        markdown.write_text(replace_section(markdown.read_text(), SECTION, table))
        print(f"wrote the section {SECTION[3:]!r} of {markdown}")
    return results


def render(results: dict[int, dict], peers: dict[str, Any], T: float, rounds: int, quick: bool,
           modes: bool = False, pinned: bool = True) -> str:
    """The section: conditions in one paragraph (``pinned``: whether the process ran on one core,
    :func:`pin_to_one_core`), then the ratio table."""
    versions = [f"Python {platform.python_version()}", f"numpy {np.__version__}", f"scipy {scipy.__version__}",
                f"heyoka {hy.__version__}"]
    for name, mod in peers.items():
        if not isinstance(mod, str):
            versions += [f"{m.__name__} {m.__version__}" for m in (mod if isinstance(mod, tuple) else (mod,))]
    missing = {name: "peer not installed" for name, mod in peers.items() if isinstance(mod, str)}
    lines = [SECTION, "",
             f"`python -m benchmarks.peers{' --quick' if quick else ''}{' --compile-modes' if modes else ''}`: every peer integrates the hinge method's own "
             "equations (transcribed from heyoka's decomposition of its compiled right-hand side), from its start and "
             "with its Baumgarte rate: scipy's DOP853 on a numba right-hand side, diffrax's Dopri8 on JAX for CPU "
             "(jit-compiled, compile excluded). Generic unit-energy start, L = n - 1.3, unit hinge masses, "
             f"T = {T:g}, 101 samples; error: largest hinge distance to the hinge method in "
             f"{'long double' if quick else 'real128'}; time: CPU time of the process, "
             + ("pinned to one core (JAX keeps a second thread busy while it solves: on two cores diffrax's CPU time "
                "was up to twice its work, and halved when other jobs took the spare core)" if pinned else
                "on all cores (`--all-cores`: a peer's waiting threads count too)")
             + ", every method warmed up, "
             f"all interleaved, fastest of {rounds} rounds. Ratio: the peer's time over ours at equal error "
             "1e-8 / 1e-10 / the peer's best error (log-log along each method's fastest runs; `>=` and `<=`: our "
             "or the peer's loosest tolerance was already more accurate, a bound; `-`: an error not reached). "
             "Hinges and charts are `free_motion(method=...)` with their default steppers; the column \"hinges vs "
             "charts\" is the charts' time over the hinges' (at 1e-8 / 1e-10 / the charts' best error). "
             + ("The columns \"compact\" and \"unrolled\" are the hinges with heyoka's compact mode forced on and "
                "off (`compact_mode=True` / `False`) against DOP853; \"charts unrolled\" is the charts' default stepper "
                "compiled unrolled (`free_motion(method=\"charts\", compact_mode=False)`, tolerances 1e-8, 1e-10, 1e-12) against "
                "DOP853. " if modes else "")
             + ", ".join(versions) + ".", "",
             "| n | hinges vs DOP853 | hinges vs diffrax | charts vs DOP853 | hinges vs charts | "
             + "".join(f"{mode} vs DOP853 | " for mode, _ in (MODE_PAIRS if modes else ()))
             + "best error: hinges / charts / DOP853 / diffrax |",
             "|---|---|---|---|---|---|" + "---|" * (len(MODE_PAIRS) if modes else 0)]
    for n, res in results.items():
        best = []
        for method in ("hinges", "charts", "DOP853", "diffrax"):
            errs = [r.error for r in res["rows"] if r.method == method]
            best.append(f"{min(errs):.0e}" if errs else "-")
        cells = [ratio_cell(res["ratios"][f"{a} vs {b}"], missing.get(b, ""))
                 for a, b in PAIRS + (MODE_PAIRS if modes else ())]
        lines.append(f"| {n} | " + " | ".join(cells) + " | " + " / ".join(best) + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="python -m benchmarks.peers", description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="n = 4, 6, 3 rounds, long-double reference (minutes)")
    parser.add_argument("--n", type=int, nargs="+", default=None, help="chain sizes (default 4 6 8 10 12)")
    parser.add_argument("--T", type=float, default=20.0, help="horizon (default 20)")
    parser.add_argument("--rounds", type=int, default=None, help="interleaved rounds (default 5; quick 3)")
    parser.add_argument("--chart-max-n", type=int, default=10, help="largest n run with method='charts' (default 10)")
    parser.add_argument("--compile-modes", action="store_true",
                        help="also the hinges with compact_mode forced True and False, each against DOP853")
    parser.add_argument("--markdown", type=Path, default=None, help="write the table into this page (docs/benchmarks.md)")
    parser.add_argument("--all-cores", action="store_true",
                        help="do not pin the process to one core (then a peer's waiting threads add CPU time)")
    args = parser.parse_args()
    main(args.n or ([4, 6] if args.quick else [4, 6, 8, 10, 12]), args.T, args.rounds or (3 if args.quick else 5),
         args.quick, args.markdown, args.chart_max_n, args.compile_modes, args.all_cores)
