"""How short a link the hinge method holds: runs that pass their checks, and the short link's angle error.

Run ``python -m benchmarks.short_links [--starts 8]``.  The chain: links ``(1, 1.3, l, 0.8, 1.1)`` pinned 2.5 apart
(no atlas: only the hinge method runs), ``l`` from 1e-2 down to 1e-8.  From each of ``--starts`` configurations
sampled on its diagonals, with a random unit-energy velocity, the hinge method runs to ``T = 20 l`` (the short link
turns at about ``|v| / l``: a few of its turns) in

* float64 at its default tolerance;
* long double at float64's default tolerance 2.2e-16;
* real128 at 2.2e-16,

and a real128 run at tolerance 1e-25 is the reference.  Printed per ``l`` and precision: how many runs reached ``T``
with every check passed, and the largest angle error of the short link at the end (the distance of its end hinge
from the reference's, over ``l``) over all runs, passed or not.  Hinge coordinates round each hinge to ``u R``
(``R`` the chain's total length): a link of length ``l`` has its direction to about ``u R / l``, and that is what
the checks see.
"""

from __future__ import annotations

import argparse

import mpmath
import numpy as np

from linkage import Chain
from linkage.constraints import HingeConstraints
from linkage.motion import free_motion
from manifold import Precision, SaveAt

LENGTHS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)
PRECISIONS = {"float64": Precision(), "long double": Precision(fp_type="longdouble", tol=2.2e-16),
              "real128": Precision(fp_type="real128", tol=2.2e-16)}
REFERENCE = Precision(fp_type="real128", tol=1e-25)


def start(chain: Chain, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A configuration sampled on the chain's diagonals and a random tangent velocity of unit kinetic energy."""
    rng = np.random.default_rng(seed)
    hinges = chain.diagonal_space().sample(1, rng).hinges[0]
    x = chain.to_point(hinges)
    w = chain.from_point(HingeConstraints(chain).project_velocity(x, rng.standard_normal(x.size)))
    return hinges, w / np.sqrt(2 * chain.kinetic_energy(w))


def angle_errors(l: float, starts: int) -> dict[str, tuple[int, float]]:
    """Per precision: the runs that passed, and the largest angle error of the short link (radians)."""
    chain = Chain(np.array([1.0, 1.3, l, 0.8, 1.1]), 2.5)
    out: dict[str, tuple[int, float]] = {}
    ends: dict[str, list] = {name: [] for name in (*PRECISIONS, "reference")}
    passed = dict.fromkeys(PRECISIONS, 0)
    for seed in range(starts):
        h0, v0 = start(chain, seed)
        for name, precision in (*PRECISIONS.items(), ("reference", REFERENCE)):
            motion = free_motion(chain, h0, v0, 20 * l, method="hinges", throw=False, precision=precision,
                                 save=SaveAt(dense=False))
            if name != "reference":
                passed[name] += bool(motion.success)
            # in 128 bits, from each type's shortest round-trip decimal (within half its unit roundoff): a float64
            # difference of the hinges would round them again, to u R, the very error measured
            ends[name].append([mpmath.mpf(str(u)) for u in motion.solution.end_state()[0]])
    for name in PRECISIONS:
        # the short link is the third: from the second interior hinge (x, y at 2, 3) to the third (4, 5)
        errors = [mpmath.hypot((e[4] - e[2]) - (r[4] - r[2]), (e[5] - e[3]) - (r[5] - r[3])) / l
                  for e, r in zip(ends[name], ends["reference"])]
        out[name] = (passed[name], float(max(errors)))
    return out


def main() -> None:
    mpmath.mp.prec = 128
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=8)
    args = ap.parse_args()
    print("| l | " + " | ".join(f"{name}: passed / angle error" for name in PRECISIONS) + " |")
    print("|---|" + "---|" * len(PRECISIONS))
    for l in LENGTHS:
        row = angle_errors(l, args.starts)
        print(f"| {l:g} | " + " | ".join(f"{k} of {args.starts} / {e:.1g}" for k, e in row.values()) + " |",
              flush=True)


if __name__ == "__main__":
    main()
