"""How the chart path's cost grows with the chain: the velocity solve, the integrator's size and the step time.

Run ``python -m benchmarks.chart_scaling [--n 4 6 8 10 12] [--rounds 5]`` (unit rods, ``L = n - 1``).  For
each ``n`` it prints:

* the nodes of the velocity solve ``a'(a, V)`` alone (compact ``cfunc``): by the suspension's level recursion
  (:func:`charts.suspension_velocity.chart_velocity`, the default), by the generic forward substitution on the
  jets along the block-triangular Jacobian (:meth:`~manifold.geodesic_system.SymbolicPieces.velocity_coefficients`)
  and by the normal equations ``g^-1 J^T W V`` (:meth:`~...tangent_coefficients`, the fallback of a family without
  a triangular Jacobian);
* the nodes of the default chart integrator (Sundman's time off, the state ``(a, V)``, switch events) in
  heyoka's Taylor decomposition, and those of the hinge method's integrator, by kind (:func:`node_kinds`): a
  product, quotient or elementary function of series costs ``O(p^2)`` at Taylor order ``p``, a product with a
  parameter or a number and a sum ``O(p)``, so the first kind sets a step's cost;
* CPU time per Taylor step of ``free_motion`` over T = 20 from one start, charts (the default stepper) and
  hinges, interleaved, the fastest of ``--rounds`` rounds, and their ratio.

Absolute times are machine noise; compare the ratios, measured side by side in one run.
"""

from __future__ import annotations

import argparse
import re
import time
from collections import Counter

import heyoka as hy
import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from manifold import SaveAt
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.compiled import compiled
from manifold.constrained import compiled_constrained

from .starts import chart_start


def solve_nodes(chain: Chain) -> tuple[int, int, int]:
    """Nodes of ``a'(a, V)``: the level recursion, the forward substitution on the jets, the normal equations."""
    P = compiled(chain.atlas().charts[0].family).pieces(float)
    V = [hy.expression(f"V{r}") for r in range(P.N)]
    return tuple(len(hy.cfunc(e, P.a + V, compact_mode=True).dc)  # type: ignore[return-value]
                 for e in (P.tangent_velocity(V)[0], P.velocity_coefficients(V), P.tangent_coefficients(V)))


#: The kinds of :func:`node_kinds`, in the order they are printed.
KINDS = ("series", "scaled", "sums")
_SERIES = re.compile(r"^(\(u_\d+ \* u_\d+\)|div\(.*, u_\d+\)|u_\d+\*\*.*|combined_(sin|cos)\(.*\)|atan2\(.*\))$")
_SCALED = re.compile(r"^(\(u_\d+ \* [^u(]\S*\)|\([^u(]\S* \* u_\d+\)|div\(u_\d+, [^u]\S*\)|(?!.*u_\d).*)$")
_SUM = re.compile(r"^(\(.* [-+] .*\)|sub\(.*\)|-u_\d+)$")


def node_kinds(decomposition: list, n_vars: int) -> Counter:
    """The nodes of a heyoka Taylor decomposition by the cost of their Taylor recursion at order ``p``.

    ``series``: products and quotients of two series, powers (square roots), sine-cosine pairs and ``atan2``, each
    ``O(p^2)``; a square inside a sum (``atan2``'s ``u^2 + v^2``) adds one per square.  ``scaled``: products with a
    runtime parameter or a number, ``O(p)``, and constants.  ``sums``: sums, differences and negations, ``O(p)``
    for each of their terms (counted here as one node each).  ``other``: anything else (none in the chart or hinge
    integrators).  ``n_vars`` is the state's size: the decomposition's first and last ``n_vars`` entries are the
    variables and the right-hand sides.
    """
    kinds: Counter = Counter()
    for expression, _ in decomposition[n_vars : len(decomposition) - n_vars]:
        text = str(expression)
        if _SERIES.match(text):
            kinds["series"] += 1
        elif _SCALED.match(text):
            kinds["scaled"] += 1
        elif _SUM.match(text):
            kinds["sums"] += 1
            kinds["series"] += len(re.findall(r"u_\d+\*\*2", text))
        else:
            kinds["other"] += 1
    return kinds


def integrator_nodes(chain: Chain) -> tuple[int, Counter]:
    """Nodes of the default chart integrator's Taylor decomposition (float64, in ``t``; hinge masses: ``(a, V)``), and
    by kind (:func:`node_kinds`)."""
    velocity = ConstrainedVelocity(ChainSystem(chain))
    with compiled(chain.atlas().charts[0].family).integrator(float, terms=(velocity,)) as ta:
        return len(ta.decomposition), node_kinds(ta.decomposition, len(ta.state))


def hinge_nodes(chain: Chain) -> tuple[int, Counter]:
    """Nodes of the hinge method's integrator (float64, Baumgarte's terms), and by kind (:func:`node_kinds`)."""
    with compiled_constrained(ChainSystem(chain)).integrator(float, compact_mode=True) as ta:  # the same nodes
        return len(ta.decomposition), node_kinds(ta.decomposition, len(ta.state))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[4, 6, 8, 10, 12])
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    chains = {n: Chain(n, n - 1.0) for n in args.n}
    starts = {n: chart_start(chain, np.random.default_rng(1)) for n, chain in chains.items()}
    print("n   a'(a,V) nodes: recursion / forward / normal   integrator nodes: charts (series / scaled / sums)   "
          "hinges (series / scaled / sums)")
    for n, chain in chains.items():
        recursion, forward, normal = solve_nodes(chain)
        (charts, c), (hinges, h) = integrator_nodes(chain), hinge_nodes(chain)
        print(f"{n:<3d} {recursion:>16,d} / {forward:>7,d} / {normal:<8,d} {charts:>22,d} "
              f"({' / '.join(f'{c[k]:,d}' for k in KINDS)})   {hinges:>6,d} ({' / '.join(f'{h[k]:,d}' for k in KINDS)})"
              + ("" if c["other"] + h["other"] == 0 else f"   other: {c['other']} / {h['other']}"))
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
