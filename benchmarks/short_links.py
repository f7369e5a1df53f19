"""How short a link the hinge method holds: runs that pass their checks, and the short link's angle error.

Run ``python -m benchmarks.short_links [--starts 8]``.  The chain: links ``(1, 1.3, l, 0.8, 1.1)`` pinned 2.5 apart
(no atlas: only the hinge method runs), ``l`` from 1e-2 down to 1e-8.  From each of ``--starts`` configurations
sampled on its diagonals, with a random velocity of unit speed (kinetic energy 1/2), the hinge method runs to
``T = 20 l`` (the short link turns at about ``|v| / l``: a few of its turns) in

* float64 at its default tolerance;
* long double at float64's default tolerance 2.2e-16;
* real128 at 2.2e-16,

and a real128 run at tolerance 1e-25 is the reference.  Printed per ``l`` and precision: how many runs reached ``T``
with every check passed; the largest angle error of the short link at the end (the distance of its end hinge from
its start hinge, against the reference's, over ``l``) over the runs that passed and over all runs; and the largest
distance of any hinge from the reference's over all runs.  Hinge coordinates round each hinge to ``u R`` (``R`` the
chain's total length): a link of length ``l`` has its direction to about ``u R / l``, and that is what the checks see.
"""

from __future__ import annotations

import argparse
from typing import NamedTuple

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
    """A configuration sampled on the chain's diagonals and a random tangent velocity of unit speed (kinetic energy
    1/2)."""
    rng = np.random.default_rng(seed)
    hinges = chain.diagonal_space().sample(1, rng).hinges[0]
    x = chain.to_point(hinges)
    w = chain.from_point(HingeConstraints(chain).project_velocity(x, rng.standard_normal(x.size)))
    return hinges, w / np.sqrt(2 * chain.kinetic_energy(w))


class Row(NamedTuple):
    """One precision at one ``l``: runs that passed; the short link's largest angle error (radians) over the runs that
    passed (NaN if none) and over all; the largest hinge distance from the reference over all."""

    passed: int
    angle_passed: float
    angle_all: float
    position_all: float


def errors(l: float, starts: int) -> dict[str, Row]:
    """Per precision, the :class:`Row` of the chain with the short link ``l``."""
    chain = Chain(np.array([1.0, 1.3, l, 0.8, 1.1]), 2.5)
    ends: dict[str, list] = {name: [] for name in (*PRECISIONS, "reference")}
    passed: dict[str, list[bool]] = {name: [] for name in PRECISIONS}
    for seed in range(starts):
        h0, v0 = start(chain, seed)
        for name, precision in (*PRECISIONS.items(), ("reference", REFERENCE)):
            motion = free_motion(chain, h0, v0, 20 * l, method="hinges", throw=False, precision=precision,
                                 save=SaveAt(dense=False))
            if name != "reference":
                passed[name].append(bool(motion.success))
            # in 128 bits, from each type's shortest round-trip decimal (within half its unit roundoff): a float64
            # difference of the hinges would round them again, to u R, the very error measured
            ends[name].append([mpmath.mpf(str(u)) for u in motion.solution.end_state()[0]])
    out = {}
    for name in PRECISIONS:
        # the short link is the third: from the second interior hinge (x, y at 2, 3) to the third (4, 5)
        angle = [float(mpmath.hypot((e[4] - e[2]) - (r[4] - r[2]), (e[5] - e[3]) - (r[5] - r[3])) / l)
                 for e, r in zip(ends[name], ends["reference"])]
        position = [float(max(abs(a - b) for a, b in zip(e, r))) for e, r in zip(ends[name], ends["reference"])]
        kept = [a for a, ok in zip(angle, passed[name]) if ok]
        out[name] = Row(sum(passed[name]), max(kept, default=float("nan")), max(angle), max(position))
    return out


def main() -> None:
    mpmath.mp.prec = 128
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=8)
    args = ap.parse_args()
    print("| l | precision (tolerance) | passed | angle error: passed runs / all | hinge error: all |")
    print("|---|---|---|---|---|")
    for l in LENGTHS:
        for name, row in errors(l, args.starts).items():
            label = f"{name} ({PRECISIONS[name].tol:.2g})" if PRECISIONS[name].tol is not None else f"{name} (default)"
            print(f"| {l:g} | {label} | {row.passed} of {args.starts} | {row.angle_passed:.1g} / {row.angle_all:.1g} "
                  f"| {row.position_all:.1g} |", flush=True)


if __name__ == "__main__":
    main()
