"""What a ``free_motion`` call costs around heyoka: ``python -m benchmarks.call_cost [--baseline DIR]``.

For ``method="hinges"`` at n = 4 (and ``--n``), CPU time of this process, the fastest of
``--rounds`` interleaved rounds (each a batch of calls, averaged):

* the fixed cost of a call: ``free_motion`` to T = 1e-3 (one Taylor step), with and without dense output, each
  call from the next of ``STARTS`` different starts of one chain (a user's loop over starts: nothing about a start
  can be remembered from the call before);
* a T = 10 call (as a user calls it, dense output on; and with ``save=SaveAt(dense=False)``) against heyoka's bare
  ``propagate_until`` on the same compiled integrator from the same state with the same parameters:
  the share of the call spent in heyoka;
* the same at T = 200 (``SaveAt(dense=False)``): the call's time over bare heyoka's;
* a T = 20 call sampling 101 times (``SaveAt(t_eval=..., dense=False)``), at the default tolerance and at
  1e-10, against heyoka's bare ``propagate_grid`` on the same integrator and times;
* the bytes of dense output per Taylor step (T = 10);
* with ``--breakdown``: the pieces of a one-step call (the start's arguments, the start's compiled check and
  projection, the geometry call that checks the step, the Ctrl-C block, heyoka's step), each timed alone.

``--baseline DIR`` measures another checkout of the library (``DIR`` on ``PYTHONPATH``) in a
subprocess, alternating with this one round by round, and prints both side by side: before and
after a change, in one run.  The measurement uses only names both checkouts have.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SHORT_T = 1e-3
#: The different starts the fixed-cost calls cycle through.
STARTS = 16


def start(n: int, seed: int = 0, chain=None):
    """A chain with ``L = n - 1.3`` (or ``chain``, of that shape) and a unit-energy generic start (as
    ``benchmarks.study.experiments``)."""
    from linkage import Chain

    chain = Chain(n, n - 1.3) if chain is None else chain
    atlas = chain.atlas()
    rng = np.random.default_rng(seed)
    a0 = np.append(rng.uniform(-1, 1, n - 3), 0.3)
    p0 = atlas.get_point(0, a0)
    v0 = atlas.charts[0].tangent_vector(a0, rng.normal(size=n - 2))
    v0 = v0 / np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))
    return chain, chain.from_point(p0), chain.from_point(v0)


def bare(chain, h0, w0, T: float | np.ndarray, tol: float | None = None):
    """``run()``: heyoka's ``propagate_until(T)`` on the hinge method's own integrator (at ``tol``), state and
    parameters, returning the end state; ``propagate_grid(T)`` if ``T`` is an array of times, returning the states
    at those times."""
    from linkage.constraints import ChainSystem
    from manifold.constrained import compiled_constrained, default_compact_mode

    from .starts import completed_starts

    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    states, parameters = completed_starts(chain, chain.to_point(h0)[None, :], chain.to_point(w0)[None, :], np.max(T))
    y0, pars = states[0], parameters[0]

    def run() -> np.ndarray:
        with comp.integrator(float, tol, True, default_compact_mode(system, float)) as ta:
            ta.state[:] = y0
            ta.time = 0.0
            ta.pars[:] = pars[: len(ta.pars)]
            if isinstance(T, np.ndarray):
                return ta.propagate_grid(T)[-1]
            ta.propagate_until(T)
            return ta.state.copy()

    return run


def measure(n: int, rounds: int) -> dict[str, float]:
    """Seconds per call of each case, the fastest of ``rounds`` batches."""
    from linkage.motion import free_motion

    from manifold import Precision, SaveAt

    no_dense = {"save": SaveAt(dense=False)}
    ts = np.linspace(0.0, 20.0, 101)
    grid = {"save": SaveAt(t_eval=ts, dense=False)}
    chain, h0, w0 = start(n)
    starts = [start(n, seed, chain)[1:] for seed in range(STARTS)]

    def call(T: float, **kw):
        return lambda: free_motion(chain, h0, w0, T, method="hinges", **kw)

    def calls(**kw):
        """One call from each of the ``STARTS`` starts."""
        def run() -> None:
            for h, w in starts:
                free_motion(chain, h, w, SHORT_T, method="hinges", **kw)
        return run

    # (run, runs per batch, calls per run)
    cases = {"fixed, dense": (calls(), 15, STARTS), "fixed, no dense": (calls(**no_dense), 15, STARTS),
             "T = 10, dense": (call(10.0), 20, 1), "T = 10, no dense": (call(10.0, **no_dense), 20, 1),
             "T = 10, bare heyoka": (bare(chain, h0, w0, 10.0), 20, 1),
             "T = 200, no dense": (call(200.0, **no_dense), 2, 1),
             "T = 200, bare heyoka": (bare(chain, h0, w0, 200.0), 2, 1),
             "T = 20, 101 samples": (call(20.0, **grid), 10, 1), "T = 20, bare grid": (bare(chain, h0, w0, ts), 10, 1),
             "... at tol 1e-10": (call(20.0, **grid, precision=Precision(tol=1e-10)), 10, 1),
             "... bare at tol 1e-10": (bare(chain, h0, w0, ts, 1e-10), 10, 1)}
    best = {name: np.inf for name in cases}
    for run, _, _ in cases.values():
        run()  # compiles and caches outside the timing
    sol = free_motion(chain, h0, w0, 10.0, method="hinges").solution
    best["dense bytes per step"] = sol.dense_nbytes / sol.n_steps  # not a time: reported as it is
    for _ in range(rounds):
        for name, (run, batch, per_run) in cases.items():
            c0 = time.process_time()
            for _ in range(batch):
                run()
            best[name] = min(best[name], (time.process_time() - c0) / (batch * per_run))
    return best


def breakdown(n: int, rounds: int) -> dict[str, float]:
    """Seconds per call of the pieces of a one-step ``free_motion`` (no dense output), each timed alone over the
    ``STARTS`` starts (the fastest of ``rounds`` interleaved rounds).  Alone, a piece runs with its code and data
    in the caches: the pieces sum to less than the whole call."""
    from linkage.constraints import chain_system, start_arguments, start_state
    from linkage.motion import chart_metric, free_motion
    from manifold import SaveAt, StartCheck
    from manifold.constrained import ConstrainedGeometry, compiled_constrained, default_compact_mode, solve_constrained
    from manifold.interrupt import interruptible

    chain = start(n)[0]
    starts = [start(n, seed, chain)[1:] for seed in range(STARTS)]
    check, no_dense = StartCheck(), SaveAt(dense=False)
    checked = [start_state(chain, h, w, SHORT_T, check) for h, w in starts]
    system = chain_system(chain)
    geo, metric, comp = ConstrainedGeometry.of(system, float), chart_metric(chain), compiled_constrained(system)
    rows = [(s.x0[None, :], s.v0[None, :]) for s in checked]
    columns = [np.ascontiguousarray(np.concatenate([x.T, v.T, np.zeros((system.n_constraints, 1))])) for x, v in rows]
    one_column = np.ascontiguousarray(geo.pars[: geo.cf.nparams, None])
    states = [np.concatenate([s.x0, s.v0]) for s in checked]
    pars = geo.packed(0.1)

    def block() -> None:
        with interruptible():
            pass

    with comp.integrator(float, None, True, default_compact_mode(system, float)) as ta:
        def step(k: int) -> None:
            ta.state[:], ta.time, ta.pars[:] = states[k], 0.0, pars[: len(ta.pars)]
            ta.propagate_until(SHORT_T)

        pieces = {
            "free_motion": lambda k: free_motion(chain, *starts[k], SHORT_T, method="hinges", save=no_dense),
            "  start_arguments": lambda k: start_arguments(chain, *starts[k], SHORT_T),
            "  solve_constrained": lambda k: solve_constrained(system, checked[k].x0, checked[k].v0, SHORT_T,
                                                               save=no_dense, metric=metric, start=check),
            "    ConstrainedGeometry.start": lambda k: geo.start(*rows[k], SHORT_T, 1.0, check=check),
            "      its projection call": lambda k: geo.projection(*rows[k]),
            "    a geometry call (the step's check)": lambda k: geo(*rows[k]),
            "      its compiled function": lambda k: geo.cf(columns[k], pars=one_column),
            "    interruptible block": lambda k: block(),
            "    heyoka: one step": step,
        }
        best = {name: np.inf for name in pieces}
        for _ in range(rounds):
            for name, piece in pieces.items():
                c0 = time.process_time()
                for _ in range(10):
                    for k in range(STARTS):
                        piece(k)
                best[name] = min(best[name], (time.process_time() - c0) / (10 * STARTS))
    return best


def derived(m: dict[str, float]) -> dict[str, float]:
    return {"share of a T = 10 call in heyoka (dense)": m["T = 10, bare heyoka"] / m["T = 10, dense"],
            "share of a T = 10 call in heyoka (no dense)": m["T = 10, bare heyoka"] / m["T = 10, no dense"],
            "T = 200 call / bare heyoka": m["T = 200, no dense"] / m["T = 200, bare heyoka"],
            "T = 20 grid call / bare propagate_grid": m["T = 20, 101 samples"] / m["T = 20, bare grid"],
            "... at tol 1e-10": m["... at tol 1e-10"] / m["... bare at tol 1e-10"]}


def side_by_side(n: int, rounds: int, baseline: Path) -> None:
    """This checkout and ``baseline``, alternating subprocesses, each the fastest of its rounds."""
    here = Path(__file__).resolve().parent.parent
    best: dict[str, dict[str, float]] = {}
    with tempfile.TemporaryDirectory() as scripts:
        # this checkout's benchmarks package alone, ahead of each tree on the path: the same measuring code (run as a
        # module, for its relative imports) against the library of either tree
        os.symlink(here / "benchmarks", Path(scripts) / "benchmarks")
        for _ in range(rounds):
            for label, tree in (("before", baseline), ("after", here)):
                env = {**os.environ, "PYTHONPATH": os.pathsep.join([scripts, str(tree)])}
                out = subprocess.run([sys.executable, "-m", "benchmarks.call_cost", "--n", str(n), "--rounds", "3",
                                      "--json"], env=env, cwd="/", check=True, capture_output=True, text=True).stdout
                got = json.loads(out.splitlines()[-1])
                best[label] = {k: min(v, best.get(label, {}).get(k, np.inf)) for k, v in got.items()}
    print(f"n = {n}, hinges: before ({baseline}) and after ({here}), CPU time per call, fastest of {rounds} alternating "
          f"runs of 3 rounds")
    for k in best["after"]:
        b, a = best["before"][k], best["after"][k]
        if k == "dense bytes per step":
            print(f"  {k:26s} {b:9.0f} B   {a:9.0f} B   ({a / b:.2f}x)")
        else:
            print(f"  {k:26s} {1e3 * b:9.3f} ms  {1e3 * a:9.3f} ms  ({a / b:.2f}x)")
    for k, a in derived(best["after"]).items():
        print(f"  {k:44s} before {derived(best['before'])[k]:.2f}, after {a:.2f}")


def report(n: int, m: dict[str, float]) -> None:
    print(f"n = {n}, hinges, CPU time per call")
    for k, v in m.items():
        print(f"  {k:26s} {v:9.0f} B" if k == "dense bytes per step" else f"  {k:26s} {1e3 * v:9.3f} ms")
    for k, v in derived(m).items():
        print(f"  {k:44s} {v:.2f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(prog="python -m benchmarks.call_cost", description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, nargs="+", default=[4])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--baseline", type=Path, default=None, help="another checkout, measured alternately")
    parser.add_argument("--breakdown", action="store_true", help="the pieces of a one-step call, each timed alone")
    parser.add_argument("--json", action="store_true", help=argparse.SUPPRESS)  # one n, machine-readable
    args = parser.parse_args()
    for n in args.n:
        if args.breakdown:
            print(f"n = {n}, hinges, one-step call without dense output: CPU time of each piece alone")
            for k, v in breakdown(n, args.rounds).items():
                print(f"  {k:40s} {1e6 * v:7.1f} us")
        elif args.json:
            print(json.dumps(measure(n, args.rounds)))
        elif args.baseline is not None:
            side_by_side(n, args.rounds, args.baseline)
        else:
            report(n, measure(n, args.rounds))
