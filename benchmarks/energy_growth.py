"""Where energy errors come from: unequal masses, and long runs.

Run ``python -m benchmarks.energy_growth [--quick] [--long]``.  Prints:

1. **Unequal masses.**  Relative energy error over T = 20 of both methods for
   hinge masses equal, spread over 1e-3..1e2 and spread the other way (n = 4
   and 6, four generic unit-speed starts each), with the wall time of the
   four runs; the charts also with the conserving equations (``charts:conserving`` below).  The hinge method is also run in long double; the chart method
   at the float64 machine epsilon as tolerance, in float64 and in long double:
   if long double at the *same* tolerance errs as much, the error is the
   integrator's truncation (its error control), not rounding.
2. **Long runs** (n = 4, L = 2.5, several starts): the energy error of the
   solver's own record and of the hinge velocities (chart-free: ``1/2 v^T K v``
   in float64) at 1 %, 10 % and 100 % of T, the median over starts, and the
   log-log slope per decade (Brouwer's law, rounding as a random walk: 0.5;
   a systematic error: 1).  ``--long`` runs T = 1.2e5 (about ten minutes per
   chart-method start), otherwise T = 1.2e4 (``--T`` sets it).  Each method
   also prints the signed energy errors of the hinge velocities at T, their
   mean and its standard error over the starts: a drift of one sign in every
   start (a systematic error, growing like t) shows as a mean many standard
   errors from 0, a random walk as a mean within a few.  ``--tols`` runs the
   methods at each of these tolerances (``none``: each method's default);
   ``--methods`` takes ``hinges``, ``charts`` (the default chart path: Sundman's
   time, the state ``(a, V)``, its drift damped) and the chart path with one
   part switched off: ``charts:t`` (in ``t``), ``charts:ac`` (the state
   ``(a, c)``), ``charts:undamped`` (damping rate 0), ``charts:jets`` (``a'`` read from ``V`` on the jets, not
   by the charts' level recursion), the chart path with the mass-weighted state ``(a, R J c)``,
   ``charts:weighted`` (:mod:`manifold.weighted_velocity`), the conserving equations ``charts:conserving``
   (``ConstrainedVelocity(..., conserving=True)``); and ``charts:longdouble``
   (the default chart path in long double: at the same tolerance the same
   truncation, 2^-11 of the rounding).
3. **Where the chart path's energy changes** (n = 4, L = 2.5, ``--T3``, default
   3000, ``--starts3`` starts, default 3, dense output): the chart energy at the start and the end
   of every segment, split into the changes inside segments (integration, with
   the wraps of the periodic parameter between steps, ``t -> t -+ 2 pi`` in
   float64) and the jumps across chart switches (the transfer to the new chart); and, logged around
   each wrap's projection of ``V`` onto the tangent space (``StateTerm.rewrapped``), the change of
   ``|V|^2`` it makes.  Per start, the sum of each kind against the square root of the count times the spread
   of one change (the size a sum of independent changes would have); over all starts, the mean change per
   event in eps and its standard error.  A mean many standard errors from 0 is a bias of one sign.
4. **Rounding of heyoka's float64 functions**: ``sin``, ``cos`` (the chart
   maps use them; the hinge equations use only ``+ - * /``, which IEEE
   rounds correctly) and ``sqrt`` compiled by heyoka at 2e6 uniform points
   of ``[-pi, pi]``, against long double, in scalar code (``batch_size=1``: what the Taylor integrators run) and
   in heyoka's default SIMD batch: the mean signed error in units in
   the last place (positive: away from 0), its standard error and the
   largest error; numpy's float64 functions beside them.
5. **A planted bias of ``sin`` and ``cos``** (``--factors``, ``--T5``, ``--starts5``): the default chart path with
   every ``sin`` and ``cos`` of the chart formulas multiplied by a factor ``1 + b`` (``b`` a few eps; each factor
   in a fresh process, so that nothing compiled is shared), n = 4, L = 2.5: the signed energy errors of the
   hinge velocities at T, and their mean per Taylor step in eps.  How strongly the drift answers a bias of the
   functions bounds what their own rounding can make of it.
6. **One step's energy change, float64 against long double** (``--T6``, ``--starts6``): from the states of the
   default chart path's float64 run (the first ``--steps6`` steps of every segment, n = 4, L = 2.5), one
   float64 Taylor step, and a long double integration of the same equations (the same parameter values) over
   the same interval.  Their energy changes ``|M V|_K^2 / 2`` per step: the long double one is what the exact
   flow does from the float64 state, the difference is the float64 step's rounding; and the rounding of the
   right-hand side alone (the order-1 Taylor coefficients in the two precisions, along ``V``, times the step).
   Means over all steps in eps, with their standard errors.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Iterator
from contextlib import contextmanager

import heyoka as hy
import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import Precision, SaveAt
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.steppers import TaylorStepper
from manifold.sundman import SundmanStepper
from manifold.weighted_velocity import WeightedVelocity

from .starts import chart_start

EPS = float(np.finfo(float).eps)


def _starts(chain: Chain, count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """``count`` unit-energy starts (complex hinges and hinge velocities) at random chart-0 parameters."""
    rng = np.random.default_rng(0)
    return [chart_start(chain, rng) for _ in range(count)]


def unequal_masses(ns: list[int], count: int, T: float = 20.0) -> None:
    """Section 1."""
    print(f"1. relative energy error over T = {T:g}, {count} generic unit-speed starts (max over the run, per start)")
    for n in ns:
        for label, masses in (("equal", np.ones(n - 1)), ("1e-3..1e2", np.geomspace(1e-3, 1e2, n - 1)),
                              ("1e2..1e-3", np.geomspace(1e2, 1e-3, n - 1))):
            chain = Chain(n, n - 1.5, hinge_masses=masses)
            rows = {"hinges": {"method": "hinges"},
                    "hinges, long double": {"method": "hinges", "precision": Precision(np.longdouble)},
                    "charts": {"method": "charts"},
                    "charts, conserving": _options(chain, "charts:conserving", None),
                    "charts, tol eps": {"method": "charts", "precision": Precision(tol=EPS)},
                    "charts, tol eps, long double": {"method": "charts", "precision": Precision(np.longdouble, EPS)}}
            for name, kw in rows.items():
                errs, wall = [], 0.0
                for h0, v0 in _starts(chain, count):
                    free_motion(chain, h0, v0, 0.01, **kw)  # compile outside the timing
                    t0 = time.perf_counter()
                    errs.append(free_motion(chain, h0, v0, T, save=SaveAt(dense=False), throw=False,
                                            **kw).relative_energy_error)
                    wall += time.perf_counter() - t0
                print(f"  n = {n}, masses {label:9s}  {name:28s} " + "  ".join(f"{e:.1e}" for e in errs)
                      + f"   ({wall:.2f} s)")


def _options(chain: Chain, method: str, tol: float | None) -> dict:
    """``free_motion`` options of a ``--methods`` entry."""
    if method in ("hinges", "charts"):
        return {"method": method, "precision": Precision(tol=tol)}
    if method == "charts:longdouble":
        return {"method": "charts", "precision": Precision(np.longdouble, tol)}
    if method == "charts:weighted":
        velocity: ConstrainedVelocity | WeightedVelocity | None = WeightedVelocity(ChainSystem(chain), block=2)
    else:
        velocity = None if method == "charts:ac" else ConstrainedVelocity(
            ChainSystem(chain), **({"rate": 0.0} if method == "charts:undamped" else
                                   {"solve": "jets"} if method == "charts:jets" else
                                   {"conserving": True} if method == "charts:conserving" else {}))
    stepper = (TaylorStepper(tol=tol, velocity=velocity) if method == "charts:t"
               else SundmanStepper(ChainTimeFactor(chain), tol=tol, velocity=velocity))
    return {"method": "charts", "stepper": stepper}


def long_runs(T: float, count: int, methods: tuple[str, ...] = ("charts", "hinges"),
              tols: tuple[float | None, ...] = (None,)) -> None:
    """Section 2."""
    for tol in tols:
        for method in methods:
            _long_run(T, count, method, tol)


def _long_run(T: float, count: int, method: str, tol: float | None) -> None:
    chain = Chain(4, 2.5)
    fractions = np.array([0.01, 0.1, 1.0])
    print(f"2. long runs, n = 4, L = 2.5, T = {T:g}, {count} starts, {method}, tol {tol or 'default'}: energy error "
          "at 1 %, 10 % and 100 % of T")
    record, ambient, signed = [], [], []
    for k, (h0, v0) in enumerate(_starts(chain, count)):
        t0 = time.perf_counter()
        m = free_motion(chain, h0, v0, T, save=SaveAt(dense=False, t_eval=T * fractions), **_options(chain, method, tol))
        E0 = float(chain.kinetic_energy(v0))
        times = np.array([float(t) for t in m.solution.energy_times])
        E = np.array([float(e) for e in m.solution.energies])
        dev = np.maximum.accumulate(np.abs(E - E[0]) / E[0])  # running maximum of the solver's own record
        record.append([dev[np.searchsorted(times, f * T, side="right") - 1] for f in fractions])
        ambient.append(np.abs(m.energies - E0) / E0)
        signed.append(float((m.energies[-1] - E0) / E0))
        print(f"  {method}, start {k}: record {'  '.join(f'{x:.1e}' for x in record[-1])};  hinge velocities "
              f"{'  '.join(f'{x:.1e}' for x in ambient[-1])}  ({m.n_steps} steps, {m.n_switches} switches, "
              f"{time.perf_counter() - t0:.0f} s)")
    for name, data in (("record", record), ("hinge velocities", ambient)):
        med = np.median(np.array(data), axis=0)
        slope = np.polyfit(np.log10(fractions), np.log10(np.maximum(med, EPS / 4)), 1)[0]
        print(f"  {method}: median of the {name}: {'  '.join(f'{x:.1e}' for x in med)};  slope {slope:.2f} per decade")
    mean, se = np.mean(signed), np.std(signed, ddof=1) / np.sqrt(len(signed)) if len(signed) > 1 else np.nan
    print(f"  {method}: signed (E - E0) / E0 of the hinge velocities at T: {'  '.join(f'{x:+.1e}' for x in signed)};"
          f"  mean {mean:+.1e}, standard error {se:.1e} ({abs(mean) / se:.1f} of them)")


class _ProbedVelocity(ConstrainedVelocity):
    """The default ``(a, V)`` state, logging the relative change of ``|V|_W^2`` (long double) at each wrap's
    projection into ``log`` (the same compiled code: the key is the parent's)."""

    def __init__(self, system: ChainSystem, log: list) -> None:
        super().__init__(system)
        self.log = log

    def rewrapped(self, segment):
        project = super().rewrapped(segment)
        k, N = segment.family.family.dim, segment.family.family.point_dim
        at = segment.family.layout.map_index  # the chart's M in its parameters (ChartNumerics.pars)
        M = np.asarray(segment.pars[at : at + N * N], dtype=np.longdouble).reshape(N, N)
        W = M.T @ np.asarray(self.system.metric_matrix, dtype=np.longdouble) @ M

        def logged(state):
            before = np.array(state[k : k + N], dtype=np.longdouble)
            project(state)
            after = np.array(state[k : k + N], dtype=np.longdouble)
            self.log.append(float((after @ W @ after) / (before @ W @ before) - 1))

        return logged


def energy_budget(T: float, count: int) -> None:
    """Section 3."""
    chain = Chain(4, 2.5)
    print(f"3. where the chart path's energy changes, n = 4, L = 2.5, T = {T:g}, {count} starts: sum of the changes "
          "(relative to E0) and sqrt(count) * spread, for each kind")
    kinds: dict[str, list] = {"inside segments": [], "at switches": [], "wrap projections (|V|^2)": []}
    for k, (h0, v0) in enumerate(_starts(chain, count)):
        log: list = []
        stepper = SundmanStepper(ChainTimeFactor(chain), velocity=_ProbedVelocity(ChainSystem(chain), log))
        sol = free_motion(chain, h0, v0, T, method="charts", stepper=stepper, save=SaveAt(dense=True)).solution
        num, dim = sol.chart_numerics, chain.atlas().dim
        ends = []
        for seg in sol.segments:
            y = seg.dense(np.array([seg.t_start, seg.t_end]))
            ends.append([float(e) for e in num[seg.chart].point_velocity_energy(y[:, :dim].T, y[:, dim:2 * dim].T)[2]])
        E = np.array(ends) / float(sol.energies[0])
        changes = (E[:, 1] - E[:, 0], E[1:, 0] - E[:-1, 1], np.array(log))  # a segment ends only at a switch
        for name, x in zip(kinds, changes):
            kinds[name].append(x)
        print(f"  start {k} ({sol.n_steps} steps, {sol.stats.n_wraps} wraps, E(T)/E0 - 1 = {E[-1, 1] - 1:+.1e}): " + ";  ".join(
            f"{name} ({len(x)}): {x.sum():+.1e} against {np.sqrt(len(x)) * x.std():.1e}" for name, x in zip(kinds, changes)))
    for name, parts in kinds.items():
        x = np.concatenate(parts) / EPS
        print(f"  {name}: {len(x)} changes, mean {x.mean():+.4f} eps (standard error {x.std(ddof=1) / np.sqrt(len(x)):.4f}, "
              f"spread {x.std():.2f})")


def function_rounding(count: int = 2_000_000) -> None:
    """Section 4."""
    x = hy.make_vars("x")
    X = np.random.default_rng(0).uniform(-np.pi, np.pi, count)
    XL = X.astype(np.longdouble)
    print(f"4. rounding of float64 functions at {count} points of [-pi, pi] against long double "
          "(mean signed error in ulp, positive away from 0; its standard error; the largest)")
    references = (("sin", np.sin(XL), np.sin(X)), ("cos", np.cos(XL), np.cos(X)),
                  ("sqrt(x^2 + 1)", np.sqrt(XL * XL + 1), np.sqrt(X * X + 1)))
    codes = {"heyoka scalar": hy.cfunc([hy.sin(x), hy.cos(x), hy.sqrt(x * x + 1.0)], [x], batch_size=1)}
    simd = hy.cfunc([hy.sin(x), hy.cos(x), hy.sqrt(x * x + 1.0)], [x])
    codes[f"heyoka SIMD batch of {simd.batch_size}"] = simd
    values = {name: cf(X[None, :]) for name, cf in codes.items()}
    for k, (name, ref, theirs) in enumerate(references):
        cells = []
        for who, ours in [*((who, v[k]) for who, v in values.items()), ("numpy", theirs)]:
            ulp = np.spacing(np.abs(ours)).astype(np.longdouble)
            err = np.asarray((ours.astype(np.longdouble) - ref) / ulp * np.sign(ref), dtype=float)
            cells.append(f"{who} {err.mean():+.4f} ({err.std() / np.sqrt(count):.4f}), max {np.abs(err).max():.2f}")
        print(f"  {name:14s} " + ";  ".join(cells))


def planted_bias(factors: list[float], T: float, count: int) -> None:
    """Section 5: each factor in its own process (:func:`_planted_run`)."""
    import subprocess
    import sys

    print(f"5. sin and cos of the chart formulas times 1 + b, n = 4, L = 2.5, T = {T:g}, {count} starts: signed "
          "(E - E0) / E0 of the hinge velocities at T, and their mean per Taylor step")
    for factor in factors:
        out = subprocess.run([sys.executable, "-m", "benchmarks.energy_growth", "--plant", repr(factor), "--T5", repr(T),
                              "--starts5", str(count)], check=True, capture_output=True, text=True).stdout
        print(out, end="")


def _planted_run(factor: float, T: float, count: int) -> None:
    """One factor of section 5, in this (fresh) process: ``HeyokaOps.sin`` and ``cos`` replaced before anything is
    compiled."""
    from manifold.backends import HeyokaOps

    sin, cos = HeyokaOps.sin, HeyokaOps.cos
    HeyokaOps.sin = lambda self, x: sin(self, x) * factor  # type: ignore[method-assign]
    HeyokaOps.cos = lambda self, x: cos(self, x) * factor  # type: ignore[method-assign]
    chain = Chain(4, 2.5)
    K = np.asarray(chain.ambient_metric, dtype=np.longdouble)
    errors, steps = [], []
    for h0, v0 in _starts(chain, count):
        m = free_motion(chain, h0, v0, T, method="charts", save=SaveAt(dense=False, t_eval=[0.0, T]))
        w0, w = (np.asarray(u, dtype=np.longdouble) for u in (chain.to_point(v0), m.solution.velocities[-1]))
        errors.append(float((w @ K @ w) / (w0 @ K @ w0) - 1))  # the start's energy in long double too
        steps.append(m.n_steps)
    per_step = np.mean(errors) / np.mean(steps) / EPS
    print(f"  b = {(factor - 1) / EPS:+.2f} eps: {'  '.join(f'{e:+.2e}' for e in errors)};  mean per step "
          f"{per_step:+.4f} eps ({np.mean(steps):.0f} steps a start)")


@contextmanager
def _segments_kept() -> Iterator[list]:
    """In the block, every segment of Sundman's time as the chart path starts it: its integrator, start state
    ``(a, V)`` and parameters (:func:`manifold.sundman.sundman_advance` wrapped)."""
    import manifold.sundman as sundman

    original, kept = sundman.sundman_advance, []

    def keep(ta, t, y, t_final, pars, *args, **kwargs):
        kept.append((ta, np.array(y), np.array(pars)))
        return original(ta, t, y, t_final, pars, *args, **kwargs)

    sundman.sundman_advance = keep  # type: ignore[assignment]
    try:
        yield kept
    finally:
        sundman.sundman_advance = original  # type: ignore[assignment]


def step_rounding(T: float, count: int, steps: int) -> None:
    """Section 6."""
    chain = Chain(4, 2.5)
    k, N = chain.atlas().dim, 2 * (chain.n - 1)
    K = np.asarray(chain.ambient_metric, dtype=np.longdouble)
    starts = _starts(chain, count)
    with _segments_kept() as kept:  # the long double integrator of the same equations
        free_motion(chain, *starts[0], 0.5, method="charts", precision=Precision(np.longdouble),
                    save=SaveAt(dense=False, t_eval=[0.0, 0.5]))
    quad = kept[-1][0]
    rows: list = []  # per step: float64 change, long double change, right-hand side's rounding along V
    for h0, v0 in starts:
        with _segments_kept() as kept:
            sol = free_motion(chain, h0, v0, T, method="charts", save=SaveAt(dense=False, t_eval=[0.0, T])).solution
        for (ta, y, pars), seg in zip(kept, sol.segments):
            M = np.asarray(sol.chart_numerics[seg.chart].M, dtype=np.longdouble)
            ta.state[:], ta.time, ta.pars[:] = np.append(y, 0.0), 0.0, pars[: len(ta.pars)]
            quad.pars[:] = np.asarray(pars[: len(quad.pars)], dtype=np.longdouble)
            for _ in range(steps):
                before = np.array(ta.state)
                w = M @ before[k : k + N].astype(np.longdouble)
                E = w @ K @ w / 2
                outcome, h = ta.step(write_tc=True)
                if outcome != hy.taylor_outcome.success:
                    break
                rate = np.array(ta.tc[k : k + N, 1], dtype=np.longdouble)
                quad.state[:], quad.time = before.astype(np.longdouble), np.longdouble(0.0)
                quad.step(max_delta_t=np.longdouble(1e-30), write_tc=True)  # only its order-1 coefficients
                rate = rate - np.array(quad.tc[k : k + N, 1])
                quad.state[:], quad.time = before.astype(np.longdouble), np.longdouble(0.0)
                quad.propagate_until(np.longdouble(h))
                ends = [M @ np.array(u[k : k + N], dtype=np.longdouble) for u in (ta.state, quad.state)]
                rows.append([float((u @ K @ u / 2 - E) / E) for u in ends] + [float(h * (w @ K @ (M @ rate)) / E)])
    x = np.array(rows) / EPS
    print(f"6. one step's energy change from the float64 run's states, n = 4, L = 2.5, T = {T:g}, {count} starts, "
          f"the first {steps} steps of each segment ({len(x)} steps): mean per step in eps (standard error)")
    for name, col in (("float64 step", x[:, 0]), ("long double over the same interval (the exact flow)", x[:, 1]),
                      ("their difference (the float64 step's rounding)", x[:, 0] - x[:, 1]),
                      ("the right-hand side's rounding along V, times the step", x[:, 2])):
        print(f"  {name}: {col.mean():+.4f} ({col.std(ddof=1) / np.sqrt(len(col)):.4f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 4 only, two starts, T = 1.2e3")
    ap.add_argument("--long", action="store_true", help="T = 1.2e5 for the long runs (the issue's run)")
    ap.add_argument("--starts", type=int, default=None, help="starts of the long runs (default 6, with --long 3)")
    ap.add_argument("--sections", default="123456", help="which sections to run, e.g. 2")
    ap.add_argument("--T", type=float, default=None, help="T of the long runs (default 1.2e4, with --long 1.2e5)")
    ap.add_argument("--tols", default="none", help="tolerances of the long runs, comma-separated (none: the default)")
    ap.add_argument("--methods", default="charts,hinges", help="methods of the long runs, comma-separated")
    ap.add_argument("--T3", type=float, default=3000.0, help="T of section 3")
    ap.add_argument("--starts3", type=int, default=3, help="starts of section 3")
    ap.add_argument("--factors", default="1.0000000000000002,1.0,0.9999999999999999,0.9999999999999998",
                    help="the factors 1 + b of section 5, comma-separated")
    ap.add_argument("--T5", type=float, default=3000.0, help="T of section 5")
    ap.add_argument("--starts5", type=int, default=4, help="starts of section 5")
    ap.add_argument("--T6", type=float, default=300.0, help="T of section 6")
    ap.add_argument("--starts6", type=int, default=100, help="starts of section 6")
    ap.add_argument("--steps6", type=int, default=150, help="steps of each segment in section 6")
    ap.add_argument("--plant", type=float, default=None, help=argparse.SUPPRESS)  # one factor of section 5
    args = ap.parse_args()
    if args.plant is not None:
        _planted_run(args.plant, args.T5, args.starts5)
        return
    if args.quick:
        unequal_masses([4], 2)
        long_runs(1.2e3, 2)
        return
    if "1" in args.sections:
        unequal_masses([4, 6], 4)
    if "2" in args.sections:
        tols = tuple(None if t == "none" else float(t) for t in args.tols.split(","))
        long_runs(args.T or (1.2e5 if args.long else 1.2e4), args.starts or (3 if args.long else 6),
                  tuple(args.methods.split(",")), tols)
    if "3" in args.sections:
        energy_budget(args.T3, args.starts3)
    if "4" in args.sections:
        function_rounding()
    if "5" in args.sections:
        planted_bias([float(f) for f in args.factors.split(",")], args.T5, args.starts5)
    if "6" in args.sections:
        step_rounding(args.T6, args.starts6, args.steps6)


if __name__ == "__main__":
    main()
