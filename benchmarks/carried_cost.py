"""What carrying a quantity along a geodesic costs: parallel transport and Jacobi fields against the geodesic alone.

Run ``python -m benchmarks.carried_cost [--n 4 6 8] [--T 50] [--repeats 5]`` (L = n - 0.6, unit masses, a
Liouville start of speed ~1).  For each n, in hinge coordinates, it times (CPU time of this process,
interleaved, the fastest of ``--repeats`` rounds, compiles excluded):

* the geodesic alone (``solve_constrained``, compact mode: as the carried solves, and in its default mode);
* the geodesic with one and with ``n - 2`` transported vectors (``ParallelTransport``);
* the geodesic with one Jacobi field and with ``n - 2`` (a full basis: what each Newton step of ``log`` solves);
* in the atlas: the geodesic alone (``free_motion``'s default) and with one transported vector beside it;

and prints each one's time and steps as ratios to the geodesic alone in compact mode, then the time of one
``log`` at distance 1 (Newton steps and solves) against one ``exp``.  Absolute times are machine noise:
compare the ratios, measured side by side in one run.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from linkage import Chain, geometry
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from manifold.carried import solve_carried
from manifold.constrained import solve_constrained
from manifold.jacobi import JacobiField
from manifold.transport import ParallelTransport


def _cpu(run: Callable[[], object]) -> tuple[float, object]:
    t0 = time.process_time()
    out = run()
    return time.process_time() - t0, out


def _steps(result: object) -> int:
    """Steps of a GeodesicSolution, a ChainMotion, a CarriedSolution or a linkage.geometry result."""
    for name in ("carried", "solution"):
        result = getattr(result, name, result)
    return int(getattr(result, "n_steps"))


def measure(n: int, T: float, repeats: int) -> None:
    chain = Chain(n, n - 0.6)
    H, V = sample_starts(chain, 1, 0.5, np.random.default_rng(n))
    system = ChainSystem(chain)
    x0, v0 = chain.to_point(H[0]), chain.to_point(V[0])
    basis = chain.to_point(geometry.tangent_basis(chain, H[0]))
    zeros = np.zeros_like(basis)
    runs: dict[str, Callable[[], object]] = {
        "geodesic (compact)": lambda: solve_constrained(system, x0, v0, T, compact_mode=True),
        "geodesic (default mode)": lambda: solve_constrained(system, x0, v0, T),
        "+ 1 transported vector": lambda: solve_carried(system, x0, v0, T, [ParallelTransport(basis[:1])]),
        f"+ {n - 2} transported vectors": lambda: solve_carried(system, x0, v0, T, [ParallelTransport(basis)]),
        "+ 1 Jacobi field": lambda: solve_carried(system, x0, v0, T, [JacobiField(zeros[:1], basis[:1])]),
        f"+ {n - 2} Jacobi fields": lambda: solve_carried(system, x0, v0, T, [JacobiField(zeros, basis)]),
        "atlas: geodesic": lambda: free_motion(chain, H[0], V[0], T),
        "atlas: + 1 transported vector": lambda: geometry.parallel_transport(chain, H[0], V[0], V[0], T,
                                                                             method="charts"),
    }
    for run in runs.values():  # compile everything first
        run()
    best = {name: np.inf for name in runs}
    steps = {}
    for _ in range(repeats):  # interleaved rounds
        for name, run in runs.items():
            seconds, out = _cpu(run)
            best[name] = min(best[name], seconds)
            steps[name] = _steps(out)
    base, base_steps = best["geodesic (compact)"], steps["geodesic (compact)"]
    print(f"\nn = {n}, L = {n - 0.6}, T = {T}: CPU time (fastest of {repeats}) and steps, as ratios to the geodesic "
          "alone in compact mode")
    for name in runs:
        print(f"  {name:32s} {best[name] * 1e3:9.2f} ms  x{best[name] / base:6.2f}   steps {steps[name]:6d}  "
              f"x{steps[name] / base_steps:5.2f}")
    h1 = geometry.exp(chain, H[0], V[0] / np.sqrt(2 * float(chain.kinetic_energy(V[0]))))
    exp_best = log_best = np.inf
    for _ in range(repeats):
        exp_best = min(exp_best, _cpu(lambda: geometry.exp(chain, H[0], V[0]))[0])
        seconds, result = _cpu(lambda: geometry.log(chain, H[0], h1))
        log_best = min(log_best, seconds)
    print(f"  log at distance 1: {log_best * 1e3:.1f} ms ({result.iterations} Newton steps), "
          f"x{log_best / exp_best:.1f} one exp")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[4, 6, 8])
    parser.add_argument("--T", type=float, default=50.0)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    for n in args.n:
        measure(n, args.T, args.repeats)


if __name__ == "__main__":
    main()
