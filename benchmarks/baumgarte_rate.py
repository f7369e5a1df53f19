"""Which Baumgarte rate: the hinge method's energy error and step count per rate, over the regions that differ.

``python -m benchmarks.baumgarte_rate [--seeds 6]`` prints, for each rate and
each family of starts, the median and largest relative energy error (a run
that did not succeed counts as ``inf``) and the mean step count:

* generic bases ``L = n - 0.5`` (n = 3, 4, 6), T = 3;
* the top of the range, ``L = n - 1e-3 .. n - 1e-6`` (n = 3, 4, 6), T = 3:
  the sphere shrinks to radius ``~sqrt(n - L)``, the motion turns at
  ``~1 / sqrt(n - L)``, the rods carry large tensions;
* the bottom of the range, ``L = n - 2 + 1e-4``;
* hinge masses spread over 1e-3 .. 1e2, ``L = n - 1.5``, T = 20 (light hinges whip);
* rod densities 1e-2 beside those masses.

All rates run on the same starts (:func:`benchmarks.starts.chart_start`) in one
process, so the columns compare.
"""

from __future__ import annotations

import argparse

import numpy as np

from linkage import Chain
from linkage.motion import free_motion
from manifold import SaveAt

from .starts import chart_start

RATES = (1.0, 3.0, 10.0, 30.0)


def families() -> list[tuple[str, list[Chain], float]]:
    """``(label, chains, T)`` of each family of starts."""
    masses = {n: np.geomspace(1e-3, 1e2, n - 1) for n in (3, 4, 6)}
    return [
        ("generic, L = n - 0.5", [Chain(n, n - 0.5) for n in (3, 4, 6)], 3.0),
        ("top, L = n - 1e-3", [Chain(n, n - 1e-3) for n in (3, 4, 6)], 3.0),
        ("top, L = n - 1e-4", [Chain(n, n - 1e-4) for n in (3, 4, 6)], 3.0),
        ("top, L = n - 1e-5", [Chain(n, n - 1e-5) for n in (3, 4, 6)], 3.0),
        ("top, L = n - 1e-6", [Chain(n, n - 1e-6) for n in (3, 4, 6)], 3.0),
        ("bottom, L = n - 2 + 1e-4", [Chain(n, n - 2 + 1e-4) for n in (3, 4, 6)], 3.0),
        ("hinge masses 1e-3..1e2", [Chain(n, n - 1.5, hinge_masses=m) for n, m in masses.items()], 20.0),
        ("  and rod densities 1e-2", [Chain(n, n - 1.5, hinge_masses=m, rod_densities=1e-2)
                                      for n, m in masses.items()], 20.0),
    ]


def energy_errors(chains: list[Chain], T: float, rate: float, seeds: int) -> tuple[np.ndarray, float]:
    """Relative energy errors (``inf`` where the run refused itself) and the mean step count."""
    errors, steps = [], []
    for chain in chains:
        rng = np.random.default_rng(0)
        for _ in range(seeds):
            h0, v0 = chart_start(chain, rng)
            m = free_motion(chain, h0, v0, T, method="hinges", rate=rate, save=SaveAt(dense=False), throw=False)
            errors.append(m.relative_energy_error if m.success else np.inf)
            steps.append(m.n_steps)
    return np.array(errors), float(np.mean(steps))


def main(seeds: int = 6) -> dict:
    out: dict = {}
    print(f"relative energy error, median / largest over {seeds} starts per n, and mean steps; rates {RATES}")
    for label, chains, T in families():
        cells = []
        for rate in RATES:
            errors, steps = energy_errors(chains, T, rate, seeds)
            out[(label, rate)] = {"median": float(np.median(errors)), "max": float(np.max(errors)), "steps": steps}
            cells.append(f"{np.median(errors):.1e} / {np.max(errors):.1e} ({steps:.0f})")
        print(f"  {label:26s} " + "  ".join(cells), flush=True)
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=6)
    main(parser.parse_args().seeds)
