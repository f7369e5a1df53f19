"""Fuzz the library by families: is a wrong answer ever returned as a success, does anything hang, how much memory?

Run ``python -m benchmarks.reliability_fuzz [--count 20000] [--seed 0] [--hang 660] [--families chart,...]
[--cases START:STOP | --case K [--profile N]]``.  Cases are drawn from
families in fixed shares of ``--count`` (the cheap chart layer most, solves fewer); each is judged by numbers
recomputed here from what the library returned, never by its own verdict:

* ``chart``: a random chain with an atlas (n = 3..8, ``L`` anywhere in ``(n - 2, n)``, or lengths that make
  ``L`` dominant) and random chart parameters: ``get_point`` then ``get_parameters`` of the best chart gives
  the point back (1e-10);
* ``hinges``, ``charts``: ``free_motion`` by each method from a chart start, T in 0.1..3, unit or spread hinge
  masses; a success must conserve the energy recomputed from its end velocity (1e-9) and close (1e-9 per rod,
  or its rounding floor);
* ``long``: the hinge method to T = 20..50 (the same checks);
* ``bad input``: a valid call with one argument spoiled (NaN, inf, negative, zero, wrong shape, a string, a
  bool): it must raise ``ValueError`` or ``TypeError`` (a ``ConfigurationError`` is one), never return;
* ``any lengths``: random lengths (one of them possibly 1e-9..1e-6), configurations from
  ``DiagonalSpace.sample``, the hinge method to T = 0.1..2 (1e-6..1e-4 with a short link, which whips) from a
  velocity projected onto the tangent space:
  the start must be accepted, and a success checked as above;
* ``ensemble``: ``free_motions`` of 3 starts (SIMD batches) against single solves (1e-9);
* ``curvature``: ``sectional_curvature(p, u, v)`` equals ``(p, v, u)`` and is finite;
* ``lyapunov``: ``lyapunov_exponent`` to T = 5 (k = 2): a success has a finite history and energy error 1e-9;
* ``precision``: the hinge method in long double to T = 1, against float64 (1e-9) on success.

A case is stopped (``SLOW``) once it has spent ``--hang`` CPU seconds (a timer sends Ctrl-C, which the solvers
honour; CPU, not wall time, so that other jobs on the machine do not count): by default :data:`HANG`, past what the
default budget (:data:`manifold.budget.DEFAULT_BUDGET`, 300 CPU seconds a solve) allows, so a hang; with a smaller
``--hang``, possibly a run the budget would still allow.  Prints per family: cases, successes, honest failures (a status, or a ``ValueError``/``TypeError``
where the input is bad), refusals of valid input, wrong answers returned as success, other exceptions, slow runs,
the costliest cases (CPU seconds, and each case above a tenth of ``--hang`` as it ends), the numbers of the first ten
honest failures (to replay with ``--case``); and the peak RSS.
``--count`` scales :data:`SHARES`.

Each case draws from its own seed ``(seed, family, k)`` (the chart and curvature families' shared chain from
``(seed, family, k // PER_CHAIN)``), so ``--families charts --case 18`` replays case 18 alone, without a timer,
and prints its CPU time and each solve's steps, chart switches and segments (``--profile 20``: cProfile's 20
costliest functions); ``--cases 0:125`` runs part of each family (to split a run over processes).
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import os
import pstats
import resource
import signal
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from linkage import Chain
from linkage.constraints import HingeConstraints
from linkage.ensemble import free_motions
from linkage.motion import free_motion, lyapunov_exponent
from manifold import Precision, SaveAt
from manifold.budget import DEFAULT_BUDGET
from manifold.progress import ProgressUpdate, reporting

from .starts import chart_start

NO_DENSE = SaveAt(dense=False)  # the fuzz reads end states and energies only

#: Cases per family at ``--count 20000`` (scaled with it), cheapest first: the families' costs differ by 1000x.
SHARES = {"chart": 13290, "bad input": 5000, "ensemble": 80, "hinges": 500, "any lengths": 400, "curvature": 300,
          "charts": 250, "precision": 120, "lyapunov": 40, "long": 20}
assert DEFAULT_BUDGET.seconds is not None
#: Default ``--hang``: more CPU seconds than the default budget allows the two solves of a case (the most any runs),
#: with a margin; a case stopped there escaped its budget.
HANG = 2 * DEFAULT_BUDGET.seconds + 60
#: Cases drawn on one chain (its atlas and compiled functions built once) in the chart and curvature families.
PER_CHAIN = 20


class Wrong(Exception):
    """A success whose recomputed numbers disagree: the thing this fuzz looks for."""


def random_chain(rng: np.random.Generator, atlas: bool = True, spread: bool | None = None) -> Chain:
    n = int(rng.integers(3, 9))
    masses = 10.0 ** rng.uniform(-2, 2, n - 1) if (rng.random() < 0.4 if spread is None else spread) else 1.0
    if rng.random() < 0.7:
        gap = 10.0 ** rng.uniform(-9, np.log10(1.999))  # anywhere, up to 1e-9 of either end
        return Chain(n, n - 2 + gap if rng.random() < 0.5 else n - gap, hinge_masses=masses)
    lengths = rng.uniform(0.3, 2.0, n)
    R, mu = lengths.sum(), lengths.min()
    return Chain(lengths, R - 2 * mu * rng.uniform(0.01, 0.99), hinge_masses=masses)  # L dominant: a sphere


def solved_check(chain: Chain, motion: Any, v0: np.ndarray) -> None:
    """Energy and closure recomputed at the end of a successful motion."""
    p, v = motion.solution.end_state()
    h, w = chain.from_point(np.asarray(p, dtype=float)), chain.from_point(np.asarray(v, dtype=float))
    E0, E = chain.kinetic_energy(v0), chain.kinetic_energy(w)
    if not abs(E - E0) <= 1e-9 * E0:
        raise Wrong(f"energy {E} against {E0}: {abs(E - E0) / E0:.2g}")
    if not chain.closure_excess(h) <= 1:
        raise Wrong(f"closure {chain.closure_residual(h):.2g}")


@dataclass(frozen=True)
class Case:
    """Case ``k`` of a family: its draws come from its own seed, so that any case can be replayed alone."""

    family: str
    seed: int
    k: int

    def rng(self) -> np.random.Generator:
        return np.random.default_rng([self.seed, list(CASES).index(self.family), 0, self.k])

    def chain_rng(self) -> np.random.Generator:
        """The draws of the chain shared by this case's block of :data:`PER_CHAIN` cases."""
        return np.random.default_rng([self.seed, list(CASES).index(self.family), 1, self.k // PER_CHAIN])


_CHAINS: dict[tuple[str, int, int], Chain] = {}


def shared_chain(case: Case) -> Chain:
    """A new chain (with an atlas, ``n >= 4`` for curvature) every :data:`PER_CHAIN` cases of the family."""
    key = (case.family, case.seed, case.k // PER_CHAIN)
    if key not in _CHAINS:
        rng = case.chain_rng()
        chain = random_chain(rng, spread=False)
        while case.family == "curvature" and chain.n < 4:
            chain = random_chain(rng, spread=False)
        _CHAINS.clear()  # one chain at a time: its atlas and compiled functions are what is shared
        _CHAINS[key] = chain
    return _CHAINS[key]


def case_chart(rng: np.random.Generator, case: Case) -> bool:
    chain = shared_chain(case)
    atlas = chain.atlas()
    i = int(rng.integers(len(atlas.charts)))
    a = np.concatenate([rng.uniform(-np.pi / 2, np.pi / 2, chain.dim - 1), rng.uniform(-np.pi, np.pi, 1)])
    p = atlas.get_point(i, a)
    j = atlas.get_chart_index(p)
    q = atlas.get_point(j, atlas.get_parameters(j, p))
    if not np.max(np.abs(q - p)) <= 1e-10:
        raise Wrong(f"round trip off by {np.max(np.abs(q - p)):.2g} ({chain!r}, chart {i} -> {j})")
    return True


def case_motion(rng: np.random.Generator, method: str, T: float, **options: Any) -> bool:
    chain = random_chain(rng)
    h0, v0 = chart_start(chain, rng, latitude=1.4)
    motion = free_motion(chain, h0, v0, T, method=method, throw=False, save=NO_DENSE, **options)
    if motion.success:
        solved_check(chain, motion, v0)
    return motion.success


SPOILED = [np.nan, np.inf, -np.inf, 0.0, "1", True, np.zeros(7), np.array([]), 1j, None, [1.0, 2.0]]


def case_bad_input(rng: np.random.Generator) -> bool:
    """A valid call with one argument spoiled: it must raise ``ValueError`` or ``TypeError``."""
    chain = Chain(4, 2.6)
    h0, v0 = chart_start(chain, rng)
    args: dict[str, Any] = {"hinges0": h0, "velocity0": v0, "t_final": 1.0, "method": "hinges", "tol": 1e-14}
    name = str(rng.choice(list(args)))
    if name in ("hinges0", "velocity0") and rng.random() < 0.3:
        value: Any = args[name] * (1 + 1e-3 * rng.standard_normal(h0.shape))  # off the rods / not tangent
    elif name == "tol" and rng.random() < 0.3:
        value = float(rng.choice([-1e-14, 0.5, 1e3]))
    else:
        value = SPOILED[int(rng.integers(len(SPOILED)))]
        if name == "tol" and value is None:  # None is tol's default: not a spoiled value
            value = np.nan
    args[name] = value
    try:
        tol = args.pop("tol")  # the tolerance is a field of the precision group: spoiled there
        free_motion(chain, **args, precision=Precision(tol=tol), throw=False, save=NO_DENSE)
    except (ValueError, TypeError):
        return False
    raise Wrong(f"accepted {name} = {value!r}")


def case_any_lengths(rng: np.random.Generator) -> bool:
    n = int(rng.integers(4, 9))
    lengths = rng.uniform(0.3, 2.0, n)
    short = rng.random() < 0.5
    if short:
        lengths[rng.integers(n)] = 10.0 ** rng.uniform(-9, -6)
    L = lengths.sum() * rng.uniform(0.1, 0.95)
    try:
        chain = Chain(lengths, L)
        chain.check_generic()
        hinges = chain.diagonal_space().sample(1, rng).hinges
    except ValueError:
        return False  # an empty or singular configuration space, refused by name
    x = chain.to_point(hinges[0])
    w = HingeConstraints(chain).project_velocity(x, rng.standard_normal(x.size))
    v0 = chain.from_point(w / np.sqrt(2 * chain.kinetic_energy(chain.from_point(w))))
    # a short link turns at ~|v| / l_k (1e6..1e9 rad/s from a random velocity): a few of its turns
    T = 10.0 ** rng.uniform(-6, -4) if short else float(rng.uniform(0.1, 2))
    motion = free_motion(chain, hinges[0], v0, T, method="hinges", throw=False,
                         save=NO_DENSE)  # a refused start raises: counted as an exception
    if motion.success:
        solved_check(chain, motion, v0)
    return motion.success


def case_ensemble(rng: np.random.Generator) -> bool:
    chain = random_chain(rng, spread=False)
    starts = [chart_start(chain, rng, latitude=1.4) for _ in range(3)]
    H, V = np.array([h for h, _ in starts]), np.array([v for _, v in starts])
    T = float(rng.uniform(0.5, 3))
    ens = free_motions(chain, H, V, T, method="hinges")
    for k in range(3):
        one = free_motion(chain, H[k], V[k], T, method="hinges", throw=False, save=NO_DENSE)
        if ens.success[k] and one.success:
            d = np.max(np.abs(ens.end_hinges[k] - chain.from_point(one.solution.end_state()[0].astype(float))))
            if not d <= 1e-9:
                raise Wrong(f"ensemble and single solve differ by {d:.2g}")
    return bool(np.all(ens.success))


def case_curvature(rng: np.random.Generator, case: Case) -> bool:
    chain = shared_chain(case)
    h0, _ = chart_start(chain, rng)
    p = chain.to_point(h0)
    project = HingeConstraints(chain).project_velocity
    u, v = (project(p, rng.standard_normal(p.size)) for _ in range(2))
    metric = chain.metric()
    K1, K2 = float(metric.sectional_curvature(p, u, v)), float(metric.sectional_curvature(p, v, u))
    if not (np.isfinite(K1) and abs(K1 - K2) <= 1e-9 * max(1.0, abs(K1))):
        raise Wrong(f"K(u, v) = {K1} but K(v, u) = {K2}")
    return True


def case_lyapunov(rng: np.random.Generator) -> bool:
    chain = random_chain(rng, spread=False)
    while chain.n < 4:
        chain = random_chain(rng, spread=False)
    h0, v0 = chart_start(chain, rng, latitude=1.4)
    # finite-time estimates at T = 5 neither pair as +-lambda nor come out ordered: only what must hold is checked
    r = lyapunov_exponent(chain, h0, v0, 5.0, k=2, throw=False)
    if r.success and not (np.all(np.isfinite(r.history)) and len(r.history) == len(r.times)
                          and r.relative_energy_error <= 1e-9):
        raise Wrong(f"exponents {r.exponents}, energy error {r.relative_energy_error:.2g}")
    return r.success


def case_precision(rng: np.random.Generator) -> bool:
    chain = random_chain(rng, spread=False)
    h0, v0 = chart_start(chain, rng, latitude=1.4)
    long = free_motion(chain, h0, v0, 1.0, method="hinges", precision=Precision(np.longdouble), throw=False,
                       save=NO_DENSE)
    if not long.success:
        return False
    solved_check(chain, long, v0)
    double = free_motion(chain, h0, v0, 1.0, method="hinges", throw=False, save=NO_DENSE)
    if double.success:
        d = np.max(np.abs(long.solution.end_state()[0].astype(float) - double.solution.end_state()[0].astype(float)))
        if not d <= 1e-9 * max(1.0, 1.0 / min(1.0, abs(chain.n - chain.L)) ** 0.5):
            raise Wrong(f"long double and float64 differ by {d:.2g}")
    return True


CASES: dict[str, Callable[[np.random.Generator, Case], bool]] = {
    "chart": case_chart,
    "bad input": lambda rng, case: case_bad_input(rng),
    "hinges": lambda rng, case: case_motion(rng, "hinges", float(rng.uniform(0.1, 3))),
    "charts": lambda rng, case: case_motion(rng, "charts", float(rng.uniform(0.1, 3))),
    "any lengths": lambda rng, case: case_any_lengths(rng),
    "long": lambda rng, case: case_motion(rng, "hinges", float(rng.uniform(20, 50))),
    "ensemble": lambda rng, case: case_ensemble(rng),
    "curvature": case_curvature,
    "lyapunov": lambda rng, case: case_lyapunov(rng),
    "precision": lambda rng, case: case_precision(rng),
}


def run_case(case: Case) -> str:
    """The outcome of one case: ``success``, ``honest failure``, or the name of what went wrong (``Wrong`` and
    ``KeyboardInterrupt`` pass through to the caller)."""
    try:
        return "success" if CASES[case.family](case.rng(), case) else "honest failure"
    except (ValueError, TypeError, ArithmeticError, RuntimeError) as e:
        return f"refused ({type(e).__name__}): {str(e)[:300]}"
    except (Wrong, KeyboardInterrupt):
        raise
    except Exception as e:  # noqa: BLE001 - an unexpected kind of error is itself a finding
        return f"OTHER {type(e).__name__}: {traceback.format_exception_only(e)[-1][:300]}"


def replay(case: Case, profile: int) -> None:
    """Run one case alone, without a timer: its outcome, CPU and wall time, and the solves' steps and segments
    (from their progress reports); with ``profile``, cProfile's ``profile`` costliest functions."""
    solves: list[ProgressUpdate] = []
    segments = collections.Counter[int]()

    def count(update: ProgressUpdate) -> None:
        if update.kind == "solve":
            segments[len(solves)] += 1
        elif update.kind == "done":
            solves.append(update)

    profiler = cProfile.Profile() if profile else None
    cpu, wall = time.process_time(), time.perf_counter()
    with reporting(count):
        if profiler is not None:
            profiler.enable()
        try:
            outcome = run_case(case)
        except Wrong as e:
            outcome = f"WRONG ANSWER AS SUCCESS: {e}"
        finally:
            if profiler is not None:
                profiler.disable()
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    print(f"{case.family} case {case.k} (seed {case.seed}): {outcome}; {cpu:.2f} s CPU, {wall:.2f} s wall")
    for j, u in enumerate(solves):
        rate = u.n_steps / abs(u.t) if u.t else float("nan")
        print(f"    solve {j}: t = {u.t:.6g} of {u.t_final:g}, {u.n_steps} steps ({rate:.3g} per unit time), "
              f"{u.n_switches} switches, {segments[j]} segments: {u.message[:200]}")
    if profiler is not None:
        pstats.Stats(profiler).sort_stats("tottime").print_stats(profile)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=20000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--hang", type=float, default=HANG, help=f"CPU seconds after which a case is stopped ({HANG:g})")
    ap.add_argument("--families", default=",".join(SHARES), help="comma-separated, of: " + ", ".join(SHARES))
    ap.add_argument("--cases", type=lambda text: [int(x) if x else None for x in text.split(":")], default=[None],
                    metavar="START:STOP", help="run only these case indices of each family (to split a run)")
    ap.add_argument("--case", type=int, default=None,
                    help="replay this case of the one family given, alone and without a timer")
    ap.add_argument("--profile", type=int, default=0, metavar="N", help="with --case: cProfile's N costliest functions")
    args = ap.parse_args()
    families = args.families.split(",")
    unknown = set(families) - set(SHARES)
    if unknown:
        ap.error(f"unknown families {sorted(unknown)}: choose from {list(SHARES)}")
    if args.case is not None:
        if len(families) != 1:
            ap.error("--case replays a case of one family: give one in --families")
        replay(Case(families[0], args.seed, args.case), args.profile)
        return
    counts = {name: max(1, round(SHARES[name] * args.count / 20000)) for name in families}
    tally: dict[str, collections.Counter] = {name: collections.Counter() for name in CASES}
    examples: dict[str, list[str]] = collections.defaultdict(list)
    honest: dict[str, list[int]] = collections.defaultdict(list)  # to replay with --case
    t_start = time.perf_counter()
    for name, count in counts.items():
        t0 = time.perf_counter()
        costs: list[tuple[float, int]] = []
        for k in range(*slice(*args.cases).indices(count)):
            done = threading.Event()
            cpu = time.process_time()

            def alarm(cpu0: float = cpu) -> None:  # CPU time, not wall: other jobs on the machine do not count
                while not done.wait(0.5):
                    if time.process_time() - cpu0 > args.hang:
                        os.kill(os.getpid(), signal.SIGINT)
                        return

            threading.Thread(target=alarm, daemon=True).start()
            try:
                outcome = run_case(Case(name, args.seed, k))
            except Wrong as e:
                outcome = f"WRONG ANSWER AS SUCCESS: {e}"
            except KeyboardInterrupt:  # stopped by the timer: longer than --hang (not necessarily past its budget)
                outcome = f"SLOW: ran past {args.hang:g} s of CPU"
            finally:
                done.set()
            kind = outcome.split(":")[0]
            tally[name][kind] += 1
            if kind.startswith(("WRONG", "SLOW", "OTHER")) or (kind.startswith("refused") and name in (
                    "any lengths", "chart", "curvature")):  # these starts are valid: a refusal is news
                examples[name].append(f"case {k}: {outcome}")
            if kind == "honest failure" and name != "bad input":  # there, refusing is the expected outcome
                honest[name].append(k)
            costs.append((time.process_time() - cpu, k))
            if costs[-1][0] > args.hang / 10:  # as it happens: a long family's slow cases before its end
                print(f"    {name} case {k}: {costs[-1][0]:.1f} s CPU, {outcome[:120]}", flush=True)
        print(f"{name}: {len(costs)} cases in {time.perf_counter() - t0:.0f} s: "
              + ", ".join(f"{k} {v}" for k, v in sorted(tally[name].items())), flush=True)
        for line in examples[name][:5]:
            print(f"    {line}", flush=True)
        if honest[name]:
            print(f"    honest failures (--case): {', '.join(map(str, honest[name][:10]))}"
                  + (" ..." if len(honest[name]) > 10 else ""), flush=True)
        print("    costliest (CPU s, case): " + ", ".join(f"{c:.1f} ({k})" for c, k in sorted(costs)[::-1][:5]),
              flush=True)
    total = sum(sum(c.values()) for c in tally.values())
    wrong = sum(c["WRONG ANSWER AS SUCCESS"] for c in tally.values())
    hangs = sum(c["SLOW"] for c in tally.values())
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20  # KiB on Linux
    print(f"total {total} cases in {time.perf_counter() - t_start:.0f} s: wrong answers returned as success {wrong}, "
          f"runs stopped after {args.hang:g} s of CPU {hangs}, peak RSS {rss:.2f} GiB")


if __name__ == "__main__":
    main()
