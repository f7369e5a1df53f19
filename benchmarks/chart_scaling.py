"""How the chart path's cost grows with the chain: the velocity solve, the integrator's size and the step time.

Run ``python -m benchmarks.chart_scaling [--n 4 6 8 10 12] [--rounds 5]`` (unit rods, ``L = n - 1``).  For
each ``n`` it prints:

* the nodes of the velocity solve ``a'(a, V)`` alone (compact ``cfunc``): by the suspension's level recursion
  (:func:`charts.suspension_velocity.chart_velocity`, the default), by the generic forward substitution on the
  jets along the block-triangular Jacobian (:meth:`~manifold.geodesic_system.SymbolicPieces.velocity_coefficients`)
  and by the normal equations ``g^-1 J^T W V`` (:meth:`~...tangent_coefficients`, the fallback of a family without
  a triangular Jacobian);
* the nodes of the default chart integrator (Sundman's time off, the state ``(a, V)``, switch events) in
  heyoka's Taylor decomposition, which a step's cost is proportional to;
* CPU time per Taylor step of ``free_motion`` over T = 20 from one start, charts (the default stepper) and
  hinges, interleaved, the fastest of ``--rounds`` rounds, and their ratio.

Absolute times are machine noise; compare the ratios, measured side by side in one run.
"""

from __future__ import annotations

import argparse
import time

import heyoka as hy
import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from manifold import SaveAt
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.compiled import compiled

from .starts import chart_start


def solve_nodes(chain: Chain) -> tuple[int, int, int]:
    """Nodes of ``a'(a, V)``: the level recursion, the forward substitution on the jets, the normal equations."""
    P = compiled(chain.atlas().charts[0].family).pieces(float)
    V = [hy.expression(f"V{r}") for r in range(P.N)]
    return tuple(len(hy.cfunc(e, P.a + V, compact_mode=True).dc)  # type: ignore[return-value]
                 for e in (P.tangent_velocity(V)[0], P.velocity_coefficients(V), P.tangent_coefficients(V)))


def integrator_nodes(chain: Chain) -> int:
    """Nodes of the default chart integrator's Taylor decomposition (float64, in ``t``; hinge masses: ``(a, V)``)."""
    velocity = ConstrainedVelocity(ChainSystem(chain))
    with compiled(chain.atlas().charts[0].family).integrator(float, terms=(velocity,)) as ta:
        return len(ta.decomposition)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[4, 6, 8, 10, 12])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    chains = {n: Chain(n, n - 1.0) for n in args.n}
    starts = {n: chart_start(chain, np.random.default_rng(1)) for n, chain in chains.items()}
    print("n   a'(a,V) nodes: recursion / forward / normal   integrator nodes")
    for n, chain in chains.items():
        recursion, forward, normal = solve_nodes(chain)
        print(f"{n:<3d} {recursion:>16,d} / {forward:>7,d} / {normal:<8,d} {integrator_nodes(chain):>14,d}")
    best: dict = {}
    for n, chain in chains.items():  # compile outside the timing
        for method in ("charts", "hinges"):
            free_motion(chain, *starts[n], 0.1, method=method)
    for _ in range(args.rounds):
        for n, chain in chains.items():
            for method in ("charts", "hinges"):
                t0 = time.process_time()
                motion = free_motion(chain, *starts[n], 20.0, method=method, save=SaveAt(dense=False))
                per_step = (time.process_time() - t0) / motion.n_steps
                best[n, method] = min(best.get((n, method), np.inf), per_step)
    print("\nn   CPU per step, T = 20 (fastest of", args.rounds, "rounds): charts / hinges   ratio")
    for n in chains:
        c, h = best[n, "charts"], best[n, "hinges"]
        print(f"{n:<3d} {c * 1e6:10.1f} us / {h * 1e6:6.1f} us   {c / h:5.1f}x")


if __name__ == "__main__":
    main()
