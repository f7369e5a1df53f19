"""Fuzz the public free motion where it is hardest: is any energy error above 1e-10 returned as a success?

Run ``python -m benchmarks.honesty_fuzz [--count 400] [--seed 0]``.  Draws, as
``tests/test_honest_results.py`` does (there 20 draws per CI run): ``n`` in
3..8; ``L`` within 10^U(-12, -3) of either end of ``(n - 2, n)``; unit hinge
masses or masses 10^U(-2, 2); a unit-speed start at random chart-0
parameters; both methods.  Prints, per method, how the runs ended (success,
refused start, failed own check) and the worst energy error among successes.
"""

from __future__ import annotations

import argparse
import collections
import time

import numpy as np

from linkage import Chain
from linkage.motion import free_motion
from manifold import SaveAt

from .starts import chart_start


def draw(rng: np.random.Generator) -> tuple[Chain, np.ndarray, np.ndarray, float, str, str]:
    """One case: the chain, a unit-speed start (complex hinges and velocities), ``T``, a label and its kind."""
    n = int(rng.integers(3, 9))
    end = rng.choice(["low", "high"])
    gap = 10.0 ** rng.uniform(-12, -3)
    L = n - 2 + gap if end == "low" else n - gap
    masses = np.ones(n - 1) if rng.random() < 0.5 else 10.0 ** rng.uniform(-2, 2, n - 1)
    chain = Chain(n, L, hinge_masses=masses)
    h0, v0 = chart_start(chain, rng, latitude=1.4)
    # near L = n the sphere has diameter ~ sqrt(gap): a unit-speed run of T = 2 would circle it 1e6 times
    T = 2.0 if end == "low" else 2.0 * min(1.0, 10 * np.sqrt(gap))
    kind = f"L near {'n - 2' if end == 'low' else 'n'}, {'unit' if np.all(masses == 1) else 'spread'} masses"
    return chain, h0, v0, T, f"n = {n}, L = {L!r}", kind


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=400)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    cases = [draw(rng) for _ in range(args.count)]
    for method in ("charts", "hinges"):
        t0 = time.perf_counter()
        ends: collections.Counter = collections.Counter()
        kinds: collections.Counter = collections.Counter()
        worst, where = 0.0, ""
        for chain, h0, v0, T, label, kind in cases:
            try:
                motion = free_motion(chain, h0, v0, T, method=method, throw=False, save=SaveAt(dense=False),
                                     **({"compact_mode": True} if method == "hinges" else {}))
            except ValueError as e:
                ends[f"start refused ({str(e).split(':')[0][:60]})"] += 1
                continue
            ends[motion.solution.status.name] += 1
            kinds[(kind, motion.solution.status.name)] += 1
            if motion.success and motion.relative_energy_error > worst:
                worst, where = motion.relative_energy_error, label
        print(f"{method}: {args.count} draws in {time.perf_counter() - t0:.0f} s: "
              + ", ".join(f"{k} {v}" for k, v in sorted(ends.items())))
        for kind in sorted({k for k, _ in kinds}):
            print(f"  {kind}: " + ", ".join(f"{status} {c}" for (k, status), c in sorted(kinds.items()) if k == kind))
        print(f"  worst energy error returned as success: {worst:.2e} ({where}); above 1e-10: {worst > 1e-10}")


if __name__ == "__main__":
    main()
