"""Throughput of ``free_motions`` against a Python loop of ``free_motion`` calls, and the cost of Dask.

Run ``python -m benchmarks.ensemble_speed [--n 4] [--count 64] [--T 20] [--dask-count 256] [--no-dask]``.
Prints, from one run on this machine (ratios are the numbers to compare;
absolute times are noise on a shared machine):

1. wall time of 64 trajectories of the 4-rod chain over T = 20 (hinge
   method, float64, default tolerance, no dense output), best of 3:

   * a Python loop of ``free_motion(..., method="hinges", save=SaveAt(dense=False))`` calls;
   * ``free_motions`` serial with scalar integrators (``batch_size=1``);
   * ``free_motions`` serial with SIMD batches (``heyoka.recommended_simd_size()`` lanes);
   * ``free_motions`` on threads, scalar and SIMD;

   and the factors: total (loop / threads + SIMD), batch (serial scalar /
   serial SIMD), threads (serial SIMD / threads SIMD);
2. a Dask ``LocalCluster`` (one single-threaded worker process per core)
   against the threads backend for 256 trajectories, once the workers have
   compiled: the overhead ``dask / threads - 1`` at ``T`` and at ``10 T``, as
   quartiles over ``--rounds`` paired runs (single timings on a shared
   machine scatter by 20 %), with one chunk per worker (the default) and with
   four; and Dask's own round trip for as many trivial tasks (its floor).

Every run is checked against the loop: the largest hinge difference is printed.
"""

from __future__ import annotations

import argparse
import os
import time

import heyoka as hy
import numpy as np

from linkage import Chain
from linkage.motion import free_motion, free_motions
from manifold import SaveAt
from manifold.ensemble import chunk_bounds, default_chunk_size

from .starts import chart_start

REPEATS = 3


def starts(chain: Chain, count: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` unit-speed starts at random chart-0 parameters in ``(-1.2, 1.2)``, as arrays ``(count, n - 1)``."""
    rng = np.random.default_rng(seed)
    H, V = zip(*[chart_start(chain, rng, longitude=1.2) for _ in range(count)])
    return np.array(H), np.array(V)


def best_of(fn, repeats: int = REPEATS) -> tuple[float, float, object]:
    """Best wall time of ``repeats`` calls, this process's CPU time / wall time in that call (cores it got), last result."""
    best, out, share = np.inf, None, 0.0
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = time.perf_counter() - t0
        if wall < best:
            best, share = wall, (time.process_time() - c0) / wall
    return best, share, out


def throughput(n: int, count: int, T: float) -> dict:
    """Section 1."""
    chain = Chain(n, n - 1.4)
    H, V = starts(chain, count)
    # compile (or load from heyoka's disk cache) every integrator once, outside the timings
    free_motion(chain, H[0], V[0], 1.0, method="hinges", save=SaveAt(dense=False))
    free_motions(chain, H[:1], V[:1], 1.0)
    loop_s, loop_share, loop = best_of(lambda: [free_motion(chain, h, v, T, method="hinges", save=SaveAt(dense=False))
                                                for h, v in zip(H, V)])
    ends = np.array([chain.from_point(m.solution.end_state()[0]) for m in loop])
    rows = {"loop of free_motion": loop_s}
    lanes = hy.recommended_simd_size()
    for backend in ("serial", "threads"):
        for batch in (1, lanes):
            seconds, share, ens = best_of(lambda: free_motions(chain, H, V, T, backend=backend, batch_size=batch))
            assert ens.success.all(), ens.messages
            gap = float(np.abs(ens.end_hinges - ends).max())
            rows[f"free_motions {backend}, batch {batch}"] = seconds
            print(f"  free_motions {backend:7s} batch {batch}: {seconds:.3f} s  ({loop_s / seconds:5.1f}x the loop)"
                  f"  CPU/wall {share:.2f}  max |hinge - loop| = {gap:.1e}")
    print(f"  loop of free_motion calls:       {loop_s:.3f} s                 CPU/wall {loop_share:.2f}  "
          f"({np.mean([m.n_steps for m in loop]):.0f} steps per trajectory)")
    out = {
        "total": loop_s / rows[f"free_motions threads, batch {lanes}"],
        "batch": rows["free_motions serial, batch 1"] / rows[f"free_motions serial, batch {lanes}"],
        "threads": rows[f"free_motions serial, batch {lanes}"] / rows[f"free_motions threads, batch {lanes}"],
        "threads_scalar": rows["free_motions serial, batch 1"] / rows["free_motions threads, batch 1"],
        "overhead": loop_s / rows["free_motions serial, batch 1"],
    }
    print(f"  factors: total {out['total']:.1f}x (target >= 5x); SIMD batch of {lanes} lanes {out['batch']:.2f}x; "
          f"threads ({len(os.sched_getaffinity(0))} cores) {out['threads']:.2f}x on SIMD batches, "
          f"{out['threads_scalar']:.2f}x on scalar; one call for all instead of a loop {out['overhead']:.2f}x")
    return out


def _identity(x: object) -> object:
    return x


def dask_overhead(n: int, count: int, T: float, rounds: int) -> dict:
    """Section 2: paired runs, Dask then threads, ``rounds`` times at ``T`` and at ``10 T``; the quartiles of
    the per-pair ratio (a pair shares the machine's state, so the ratio is steadier than either time), for
    one chunk per worker (the default) and for four; and Dask's own round trip for as many trivial tasks."""
    from distributed import Client, LocalCluster

    chain = Chain(n, n - 1.4)
    H, V = starts(chain, count, seed=1)
    cores = len(os.sched_getaffinity(0))
    lanes = hy.recommended_simd_size()
    out = {}
    with LocalCluster(n_workers=cores, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        free_motions(chain, H, V, T, backend="dask", client=client)  # every worker compiles (or loads) once
        default = default_chunk_size(count, lanes, "dask", client)
        # four per worker: the threads backend's default, on as many threads as the cluster has workers
        for per_worker, size in ((1, default), (4, default_chunk_size(count, lanes, "threads"))):
            chunks = len(chunk_bounds(count, size))
            floor, _, _ = best_of(lambda: client.gather([client.submit(_identity, k, pure=False)
                                                         for k in range(chunks)]), repeats=10)
            for length in (T, 10 * T):
                ratios, same = [], True
                for _ in range(rounds):
                    dask_s, _, ens = best_of(lambda: free_motions(chain, H, V, length, backend="dask", client=client,
                                                                  chunk_size=size), repeats=1)
                    threads_s, _, ref = best_of(lambda: free_motions(chain, H, V, length, backend="threads"), repeats=1)
                    ratios.append(dask_s / threads_s)
                    same &= bool(np.array_equal(ens.end_hinges, ref.end_hinges))
                q = np.percentile(ratios, [25, 50, 75]) - 1
                out[(per_worker, length)] = float(q[1])
                print(f"  {count} trajectories, T = {length:g}, {chunks} chunks ({per_worker} per worker"
                      f"{', the default' if per_worker == 1 else ''}): Dask / threads - 1 over {rounds} pairs: median "
                      f"{100 * q[1]:+.0f} % (quartiles {100 * q[0]:+.0f} %, {100 * q[2]:+.0f} %; target < 20 %); "
                      f"results identical: {same}; Dask's round trip for {chunks} trivial tasks {floor * 1e3:.0f} ms")
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4)
    ap.add_argument("--count", type=int, default=64)
    ap.add_argument("--T", type=float, default=20.0)
    ap.add_argument("--dask-count", type=int, default=256)
    ap.add_argument("--no-dask", action="store_true")
    ap.add_argument("--rounds", type=int, default=20, help="paired Dask/threads runs per setting")
    args = ap.parse_args(argv)
    print(f"1. throughput: {args.count} trajectories, n = {args.n}, T = {args.T:g} "
          f"(heyoka {hy.__version__}, {hy.recommended_simd_size()} SIMD lanes; load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores: other work takes cores from the thread runs)")
    throughput(args.n, args.count, args.T)
    if not args.no_dask:
        print("2. Dask LocalCluster against threads")
        dask_overhead(args.n, args.dask_count, args.T, args.rounds)


if __name__ == "__main__":
    main()
