"""Where energy errors come from: unequal masses, and long runs.

Run ``python -m benchmarks.energy_growth [--quick] [--long]``.  Prints:

1. **Unequal masses.**  Relative energy error over T = 20 of both methods for
   hinge masses equal, spread over 1e-3..1e2 and spread the other way (n = 4
   and 6, four generic unit-speed starts each), with the wall time of the
   four runs.  The hinge method is also run in long double; the chart method
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
   ``charts:weighted`` (:mod:`manifold.weighted_velocity`); and ``charts:longdouble``
   (the default chart path in long double: at the same tolerance the same
   truncation, 2^-11 of the rounding).
3. **Where the chart path's energy changes** (n = 4, L = 2.5, ``--T3``, default
   3000, three starts, dense output): the chart energy at the start and the end
   of every segment, split into the changes inside segments (integration, with
   the wraps of the periodic parameter between steps, ``t -> t -+ 2 pi`` in
   float64) and the jumps across chart switches (the transfer to the new chart).  For each kind:
   the sum over the run, and the square root of the count times the spread of
   one change, the size a sum of independent changes would have.  A sum many
   times that size is a systematic error.
4. **Rounding of heyoka's float64 functions**: ``sin``, ``cos`` (the chart
   maps use them; the hinge equations use only ``+ - * /``, which IEEE
   rounds correctly) and ``sqrt`` compiled by heyoka at 2e6 uniform points
   of ``[-pi, pi]``, against long double: the mean signed error in units in
   the last place (positive: away from 0), its standard error and the
   largest error; numpy's float64 functions beside them.
"""

from __future__ import annotations
from manifold import Precision, SaveAt

import argparse
import time

import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
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
                                   {"solve": "jets"} if method == "charts:jets" else {}))
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


def energy_budget(T: float, count: int) -> None:
    """Section 3."""
    chain = Chain(4, 2.5)
    print(f"3. where the chart path's energy changes, n = 4, L = 2.5, T = {T:g}, {count} starts: sum of the changes "
          "(relative to E0) and sqrt(count) * spread, for each kind")
    for k, (h0, v0) in enumerate(_starts(chain, count)):
        sol = free_motion(chain, h0, v0, T, method="charts", save=SaveAt(dense=True)).solution
        num, dim = sol.chart_numerics, chain.atlas().dim
        ends = []
        for seg in sol.segments:
            y = seg.dense(np.array([seg.t_start, seg.t_end]))
            ends.append([float(e) for e in num[seg.chart].point_velocity_energy(y[:, :dim].T, y[:, dim:2 * dim].T)[2]])
        E = np.array(ends) / float(sol.energies[0])
        inside, jumps = E[:, 1] - E[:, 0], E[1:, 0] - E[:-1, 1]
        kinds = (("inside segments", inside), ("at switches", jumps))  # a segment ends only at a switch
        print(f"  start {k} ({sol.n_steps} steps, {sol.stats.n_wraps} wraps, E(T)/E0 - 1 = {E[-1, 1] - 1:+.1e}): " + ";  ".join(
            f"{name} ({len(x)}): {x.sum():+.1e} against {np.sqrt(len(x)) * x.std():.1e}" for name, x in kinds))


def function_rounding(count: int = 2_000_000) -> None:
    """Section 4."""
    import heyoka as hy

    x = hy.make_vars("x")
    cf = hy.cfunc([hy.sin(x), hy.cos(x), hy.sqrt(x * x + 1.0)], [x])
    X = np.random.default_rng(0).uniform(-np.pi, np.pi, count)
    XL = X.astype(np.longdouble)
    print(f"4. rounding of float64 functions at {count} points of [-pi, pi] against long double "
          "(mean signed error in ulp, positive away from 0; its standard error; the largest)")
    ours = cf(X[None, :])
    for k, (name, ref, theirs) in enumerate((("sin", np.sin(XL), np.sin(X)), ("cos", np.cos(XL), np.cos(X)),
                                             ("sqrt(x^2 + 1)", np.sqrt(XL * XL + 1), np.sqrt(X * X + 1)))):
        ulp = np.spacing(np.abs(ours[k])).astype(np.longdouble)
        cells = []
        for who, values in (("heyoka", ours[k]), ("numpy", theirs)):
            err = np.asarray((values.astype(np.longdouble) - ref) / ulp * np.sign(ref), dtype=float)
            cells.append(f"{who} {err.mean():+.4f} ({err.std() / np.sqrt(count):.4f}), max {np.abs(err).max():.2f}")
        print(f"  {name:14s} " + ";  ".join(cells))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="n = 4 only, two starts, T = 1.2e3")
    ap.add_argument("--long", action="store_true", help="T = 1.2e5 for the long runs (the issue's run)")
    ap.add_argument("--starts", type=int, default=None, help="starts of the long runs (default 6, with --long 3)")
    ap.add_argument("--sections", default="1234", help="which sections to run, e.g. 2")
    ap.add_argument("--T", type=float, default=None, help="T of the long runs (default 1.2e4, with --long 1.2e5)")
    ap.add_argument("--tols", default="none", help="tolerances of the long runs, comma-separated (none: the default)")
    ap.add_argument("--methods", default="charts,hinges", help="methods of the long runs, comma-separated")
    ap.add_argument("--T3", type=float, default=3000.0, help="T of section 3")
    args = ap.parse_args()
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
        energy_budget(args.T3, 3)
    if "4" in args.sections:
        function_rounding()


if __name__ == "__main__":
    main()
