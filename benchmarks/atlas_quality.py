"""Worst best-chart quality of the cyclic suspension atlas, for n = 3..8.

The quality is ``min(cos(phi_m), q_A, q_B)``: poles and the two fold terms
(:func:`charts.suspension_formula.fold_qualities`).  For each n and a grid of
L across (n-2, n), including values within 1e-12 .. 1e-3 of both ends, sample
configurations five ways and record
``min over samples of max over charts of quality``:

* random parameters of a chart with a random rod order (generic points);
* the same with one latitude set to exactly +-pi/2 (exact poles: three or
  more rods collinear and pointing the same way);
* with every latitude at +-pi/2 (the most stretched configurations);
* exact folds (latitudes 0, ``t = 0`` or ``pi``: the first two rods folded back) and
  folded triples (latitudes 0, ``t = +-pi/2``);

then polish the worst samples by Nelder-Mead on ``max_i q_i`` (an adversarial
search: sampling alone overestimates the worst case).

Run: ``python -m benchmarks.atlas_quality [--samples N]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import minimize

from charts import SuspensionAtlas, SuspensionChart


def sample_configurations(n: int, L: float, count: int, rng: np.random.Generator) -> np.ndarray:
    """Interleaved real points: generic, single-pole, all-pole, fold and folded-triple configurations."""
    points = []
    for kind in ("generic", "pole", "all-poles", "fold", "triple"):
        for _ in range(count // 5 + 1):
            chart = SuspensionChart(n, L, order=rng.permutation(n))
            a = np.append(rng.uniform(-np.pi / 2, np.pi / 2, n - 3), rng.uniform(-np.pi, np.pi))
            if kind in ("pole", "all-poles") and n == 3:  # the circle level has no latitude
                continue
            if kind == "pole":
                a[rng.integers(n - 3)] = rng.choice([-1, 1]) * np.pi / 2
            elif kind == "all-poles":
                a[:-1] = rng.choice([-1, 1], n - 3) * np.pi / 2
            elif kind in ("fold", "triple"):
                a[:-1] = 0.0
                a[-1] = rng.choice([0.0, np.pi]) if kind == "fold" else rng.choice([-1, 1]) * np.pi / 2
            points.append(chart.get_point(a))
    return np.array(points)


def polish(atlas: SuspensionAtlas, p: np.ndarray) -> float:
    """Locally minimise the best-chart quality starting from point ``p``."""
    chart = atlas.charts[0]
    a0 = chart.get_parameters(p)

    def best_quality(a: np.ndarray) -> float:
        return float(atlas.qualities(chart.get_point(chart.clamp_parameters(a))).max())

    res = minimize(best_quality, a0, method="Nelder-Mead", options={"xatol": 1e-6, "fatol": 1e-8, "maxiter": 400})
    return min(res.fun, best_quality(a0))


def worst_best_quality(n: int, Ls: np.ndarray, count: int, seed: int = 0, polished: int = 3) -> tuple[float, float]:
    """``(worst best-chart quality, L where it occurs)`` over sampled and polished configurations."""
    rng = np.random.default_rng(seed)
    found = []  # (best quality, L, point)
    for L in Ls:
        atlas = SuspensionAtlas(n, L)
        found += [(atlas.qualities(p).max(), L, p) for p in sample_configurations(n, L, count, rng)]
    found.sort(key=lambda f: f[0])
    worst = found[0][:2]
    for q, L, p in found[:polished]:
        qp = polish(SuspensionAtlas(n, L), p)
        if qp < worst[0]:
            worst = (qp, L)
    return float(worst[0]), float(worst[1])


def L_grid(n: int, inner: int = 7) -> np.ndarray:
    """``L`` across ``(n-2, n)``: 1e-12, 1e-9, 1e-6, 1e-3 from both ends and ``inner`` values between."""
    gaps = 10.0 ** np.array([-12.0, -9.0, -6.0, -3.0])
    return np.concatenate([n - 2 + gaps, np.linspace(n - 2, n, inner + 2)[1:-1], n - gaps[::-1]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=150, help="configurations per (n, L)")
    args = parser.parse_args()
    print(f"{'n':>2} {'worst best q':>13} {'at L':>8} {'time s':>7}")
    for n in range(3, 9):
        t0 = time.perf_counter()
        q, L = worst_best_quality(n, L_grid(n), args.samples)
        print(f"{n:>2} {q:13.4f} {L:8.3f} {time.perf_counter() - t0:7.1f}")


if __name__ == "__main__":
    main()
