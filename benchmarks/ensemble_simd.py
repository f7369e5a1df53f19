"""``free_motions`` against heyoka's bare batch mode on the same compiled equations, and against a serial loop.

Run ``python -m benchmarks.ensemble_simd [--n 4 8] [--count 64] [--T 20] [--rounds 5]``, or
``--widths 4 6 8 10`` for ``free_motions``' CPU time against the batch size (1 lane, and 1, 2 and 4 times
the SIMD width; compact mode, and unrolled code where that is the default, n <= 8 in float64).

For each ``n``: ``--count`` unit-speed starts of the chain ``L = n - 1.4`` over ``T``, hinge
method, float64, default tolerance and compile options, no dense output.  Rows:

* ``bare batch``: heyoka's ``taylor_adaptive_batch`` of the very equations ``free_motions``
  integrates (borrowed from the same compiled store), with as many lanes as ``free_motions``
  takes by default (``heyoka.recommended_simd_size()``, twice that in compact mode), states set
  from the already completed starts and ``propagate_until(T)``, batch after batch: no start
  checks, no energy or constraint checks, no per-lane status.  The floor.  In compact mode also
  at ``heyoka.recommended_simd_size()`` lanes (``bare batch, width``).
* ``free_motions serial``: the whole call (start checks, completion to the constraints, batches,
  energy and constraint checks, per-lane status), one thread.
* ``bare scalar loop``: heyoka's scalar integrator of the same equations, one start after the other
  (``propagate_until``), the serial loop a user of heyoka would write.
* ``free_motion loop``: a Python loop of ``free_motion(..., save=SaveAt(dense=False))`` calls.
* ``free_motions threads``: as ``serial`` on the threads backend (wall time: the CPU time of
  threads adds up over cores).

Before the table's rows run, the pair the 0.8x target compares (``bare batch`` and ``free_motions serial``) is
timed alone, interleaved over a few seconds (printed after the table).  On 8 AVX-512 lanes and more the SIMD
code's speed depends on the alignment of the calling thread's stack (``benchmarks.simd_stack_phase``), which the
kernel sets at random for the main thread of each process: the same rows moved by up to 1.9x from one process to
the next, and earlier runs of the table spread over 0.65-1.14.

On a machine shared with other jobs the threads row says little (Linux gives the process its
share of the cores however many threads it runs), so the run also checks the premise of the
threads backend directly: a pure-Python counter thread counts while ``free_motions`` runs serially
in the main thread, and again while the main thread sleeps as long.  The first count over the
second is the share of the run during which the GIL was free for other threads (0 if heyoka held
it; up to 1, less where both threads share one core).

Times are this process's CPU time (``time.process_time``; wall time for the threads row), every
method warmed up first (compiles excluded), the methods interleaved round by round, the minimum
of ``--rounds`` rounds kept.  Printed side by side: each row's time, bare batch / row (the
target for ``free_motions serial`` is at least 0.8), row / bare batch, and free_motions serial's
speed-up over the loops (the target on 8 lanes is 6x, about 3x on 4).  Each row's end states are
checked against the ``free_motion`` loop.
"""

from __future__ import annotations

import argparse
import functools
import os
import threading
import time
from collections.abc import Callable

import heyoka as hy
import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem, start_states
from linkage.motion import free_motion, free_motions
from manifold import SaveAt, StartCheck
from manifold.constrained import compiled_constrained, default_compact_mode
from manifold.constrained_batch import DEFAULT_WIDTHS

from .ensemble_speed import starts
from .starts import completed_starts


def bare(chain: Chain, H: np.ndarray, V: np.ndarray, T: float, lanes: int) -> Callable[[], np.ndarray]:
    """heyoka alone on the compiled equations of ``free_motions``: ``lanes`` per integrator (1: scalar)."""
    system = ChainSystem(chain)
    _, X0, V0, _ = start_states(chain, H, V, T, StartCheck())
    start, rows = completed_starts(chain, X0, V0, T)
    pars = rows.T  # a column per start, as heyoka's batch takes them
    comp = compiled_constrained(system)
    compact = default_compact_mode(system, float)
    N = start.shape[1] // 2

    def run() -> np.ndarray:
        ends = np.empty_like(start)
        if lanes == 1:
            with comp.integrator(float, None, True, compact) as ta:
                for k in range(len(start)):
                    ta.time = 0.0
                    ta.state[:] = start[k]
                    ta.pars[:] = pars[: len(ta.pars), k]
                    ta.propagate_until(T)
                    ends[k] = ta.state
            return ends[:, :N]
        with comp.batch_integrator(lanes, None, compact) as ta:
            for i in range(0, len(start), lanes):
                fill = [min(k, len(start) - 1) for k in range(i, i + lanes)]
                ta.set_time(0.0)
                ta.state[:] = start[fill].T
                ta.pars[:] = pars[: len(ta.pars), fill]
                ta.propagate_until(T)
                ends[i: i + lanes] = ta.state.T[: len(start) - i]
        return ends[:, :N]
    return run


def fastest(runs: dict, rounds: int) -> dict:
    """Each callable's least CPU time (seconds) over ``rounds`` rounds that call them all in turn, after one
    warm-up call of each (compiles, caches)."""
    for run in runs.values():
        run()
    best = dict.fromkeys(runs, np.inf)
    for _ in range(rounds):
        for key, run in runs.items():
            t0 = time.process_time()
            run()
            best[key] = min(best[key], time.process_time() - t0)
    return best


def gil_free_share(run: Callable[[], object]) -> float:
    """A counter thread's progress while ``run()`` works in this thread, over its progress while this thread sleeps
    as long."""
    stop, count = threading.Event(), [0]

    def counter() -> None:
        while not stop.is_set():
            count[0] += 1

    thread = threading.Thread(target=counter)
    thread.start()
    try:
        time.sleep(0.05)
        c0, t0 = count[0], time.perf_counter()
        run()
        busy, seconds = count[0] - c0, time.perf_counter() - t0
        c1 = count[0]
        time.sleep(seconds)
        idle = count[0] - c1
    finally:
        stop.set()
        thread.join()
    return busy / idle


def measure(n: int, count: int, T: float, rounds: int) -> tuple[dict[str, float], dict[str, float]]:
    """Prints and returns ``(best, gaps)``: each row's least time (seconds; also ``"bare batch, pair alone"`` and
    ``"free_motions serial, pair alone"``, the pair timed before the other rows) and the largest distance of its end
    points from the loop of single solves'."""
    chain = Chain(n, n - 1.4)
    H, V = starts(chain, count)
    width = hy.recommended_simd_size()
    compact = default_compact_mode(ChainSystem(chain), float)
    lanes = DEFAULT_WIDTHS[compact] * width
    rows: dict[str, tuple[Callable[[], np.ndarray], bool]] = {
        "bare batch": (bare(chain, H, V, T, lanes), False),
        **({"bare batch, width": (bare(chain, H, V, T, width), False)} if lanes != width else {}),
        "free_motions serial": (lambda: free_motions(chain, H, V, T).solution.end_points, False),
        "bare scalar loop": (bare(chain, H, V, T, 1), False),
        "free_motion loop": (lambda: np.array([free_motion(chain, h, v, T, method="hinges", save=SaveAt(dense=False))
                                               .solution.end_state()[0].astype(float) for h, v in zip(H, V)]), False),
        "free_motions threads": (lambda: free_motions(chain, H, V, T, backend="threads").solution.end_points, True),
    }
    # the pair the 0.8x target compares, alone first, timed together: the SIMD code's speed moves with the machine
    paired = fastest({name: rows[name][0] for name in ("bare batch", "free_motions serial")}, rounds)
    ends = {name: fn() for name, (fn, _) in rows.items()}  # warm-up of the rest
    best = dict.fromkeys(rows, np.inf)
    for _ in range(rounds):
        for name, (fn, wall) in rows.items():
            clock = time.perf_counter if wall else time.process_time
            t0 = clock()
            fn()
            best[name] = min(best[name], clock() - t0)
    reference = ends["free_motion loop"]
    floor = best["bare batch"]
    print(f"n = {n}: {count} starts, T = {T:g}, {lanes} lanes (SIMD width {width}), compact mode {compact}")
    gaps = {name: float(np.max(np.abs(ends[name] - reference))) for name in rows}
    print(f"  {'':22s} {'time ms':>9s} {'bare batch / it':>16s} {'it / bare batch':>16s}  max |x - loop|")
    for name in rows:
        print(f"  {name:22s} {1e3 * best[name]:9.2f} {floor / best[name]:16.2f} {best[name] / floor:16.2f}  {gaps[name]:.1e}")
    serial = best["free_motions serial"]
    at_width = f" ({best['bare batch, width'] / serial:.2f}x at the SIMD width)" if "bare batch, width" in best else ""
    print(f"  the pair alone, before the other rows: bare batch {1e3 * paired['bare batch']:.2f} ms, free_motions serial "
          f"{1e3 * paired['free_motions serial']:.2f} ms: {paired['bare batch'] / paired['free_motions serial']:.2f}x "
          "bare batch (target >= 0.8)")
    print(f"  free_motions serial: {floor / serial:.2f}x bare batch{at_width} (target >= 0.8); "
          f"{best['bare scalar loop'] / serial:.2f}x the bare scalar loop, "
          f"{best['free_motion loop'] / serial:.2f}x the free_motion loop (target 6x on 8 lanes); "
          f"threads on {len(os.sched_getaffinity(0))} cores: {serial / best['free_motions threads']:.2f}x serial (wall)")
    share = gil_free_share(lambda: free_motions(chain, H, V, 10 * T))
    print(f"  GIL free for another thread during free_motions serial at T = {10 * T:g}: {share:.2f} of the idle rate")
    best.update({f"{name}, pair alone": seconds for name, seconds in paired.items()})
    return best, gaps


def widths(n: int, count: int, T: float, rounds: int, compact: bool) -> dict[int, float]:
    """CPU time of ``free_motions`` (one chunk) with 1 lane and 1, 2 and 4 times the SIMD width, compact or unrolled."""
    chain = Chain(n, n - 1.4)
    H, V = starts(chain, count)
    width = hy.recommended_simd_size()
    runs = {b: functools.partial(free_motions, chain, H, V, T, compact_mode=compact, batch_size=b, chunk_size=count)
            for b in (1, width, 2 * width, 4 * width)}
    best = fastest(runs, rounds)
    print(f"n = {n}, compact mode {compact}: " + ", ".join(
        f"{b} lanes {1e3 * t:.1f} ms ({t / best[width]:.2f}x the width's)" for b, t in best.items()))
    return best


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--count", type=int, default=64)
    ap.add_argument("--T", type=float, default=20.0)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--widths", type=int, nargs="*", default=None, metavar="N",
                    help="instead: free_motions' CPU time against the batch size, for these n (compact mode; "
                         "unrolled too where that is the default, n <= 8)")
    args = ap.parse_args(argv)
    if args.widths is not None:
        for n in args.widths:
            unrolled_default = not default_compact_mode(ChainSystem(Chain(n, n - 1.4)), float)
            for compact in ((True, False) if unrolled_default else (True,)):
                widths(n, args.count, args.T, args.rounds, compact)
        return
    print(f"heyoka {hy.__version__}, {hy.recommended_simd_size()} SIMD lanes; CPU time per process, interleaved, "
          f"min of {args.rounds} rounds")
    for n in args.n:
        measure(n, args.count, args.T, args.rounds)


if __name__ == "__main__":
    main()
