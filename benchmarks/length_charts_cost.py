"""What the lengths cost the chart method: decomposition size and time per Taylor step.

For n = 4..8 it prints, for unit rods (``SuspensionFamily(n)``: lengths are exact
integers in the expressions) and for a chain of unequal links
(``SuspensionFamily(n, lengths=True)``: lengths, slacks and their prefix minima
are runtime parameters), the size of the float64 geodesic integrator's Taylor
decomposition (a step's cost is proportional to it) and the CPU time per Taylor
step of ``free_motion(..., method="charts")`` over ``--T`` (warm caches, fastest
of ``--repeat`` interleaved runs; the chart switches are a small part of it).

The unit-rod half runs unchanged on a checkout from before the lengths
(``PYTHONPATH=<that checkout> python benchmarks/length_charts_cost.py --unit-only``):
compare the two runs' unit-rod lines for what the generalised formula costs unit rods.

Run: ``python -m benchmarks.length_charts_cost [--n 4 8] [--T 50] [--repeat 3] [--unit-only]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from linkage import Chain
from linkage.motion import free_motion
from manifold import SaveAt, compiled


def chains(n: int, unit_only: bool) -> list[tuple[str, Chain]]:
    """Unit rods at ``L = n - 1.4``, and links ``1 + 0.3 sin(k)`` at the same relative place in their range."""
    out = [("unit rods", Chain(n, n - 1.4))]
    if not unit_only:
        ls = 1 + 0.3 * np.sin(np.arange(1, n + 1))
        R, mu = ls.sum(), ls.min()
        out.append(("other lengths", Chain(ls, R - 2 * mu + 0.3 * 2 * mu)))
    return out


def start(chain: Chain, seed: int = 0):
    """A unit-speed start from chart-0 parameters."""
    rng = np.random.default_rng(seed)
    atlas = chain.atlas()
    a = np.append(rng.uniform(-1.0, 1.0, chain.n - 3), 0.4)
    p0 = atlas.get_point(0, a)
    v0 = chain.from_point(atlas.charts[0].tangent_vector(a, rng.normal(size=chain.n - 2)))
    return chain.from_point(p0), v0 / np.sqrt(2 * chain.kinetic_energy(v0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs=2, default=(4, 8), help="range of n (inclusive)")
    parser.add_argument("--T", type=float, default=50.0)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--unit-only", action="store_true", help="only unit rods (runs on older checkouts)")
    args = parser.parse_args()
    print(f"{'n':>2} {'chain':<14} {'decomposition':>13} {'steps':>6} {'switches':>8} {'us/step':>8}")
    for n in range(args.n[0], args.n[1] + 1):
        runs = []
        for label, chain in chains(n, args.unit_only):
            h0, v0 = start(chain)
            family = chain.atlas().charts[0].family
            with compiled(family).integrator(float) as ta:
                size = len(ta.decomposition)
            free_motion(chain, h0, v0, 1.0, method="charts")  # warm: compile and cache
            runs.append((label, chain, h0, v0, size, np.inf, None))
        for _ in range(args.repeat):  # interleaved: load drifts hit every chain alike
            for i, (label, chain, h0, v0, size, best, m) in enumerate(runs):
                t0 = time.process_time()
                m = free_motion(chain, h0, v0, args.T, method="charts", save=SaveAt(dense=False))
                runs[i] = (label, chain, h0, v0, size, min(best, time.process_time() - t0), m)
        for label, chain, h0, v0, size, best, m in runs:
            print(f"{n:>2} {label:<14} {size:>13} {m.n_steps:>6} {m.n_switches:>8} {1e6 * best / m.n_steps:8.1f}")


if __name__ == "__main__":
    main()
