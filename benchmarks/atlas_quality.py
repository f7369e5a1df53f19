"""Worst best-chart quality of the cyclic suspension atlas, and the conditioning it buys.

The quality is ``min(cos(phi_m), q_A, q_B)``: poles and the two fold terms
(:func:`charts.suspension_formula.fold_qualities`).  For unit rods n = 3..8, and
for links of other lengths (``--lengths``), over a grid of ``L`` across the
sphere range ``(R - 2 mu, R)`` including values within 1e-12 .. 1e-3 (times
half its width) of both ends, sample configurations five ways and record
``min over samples of max over charts of quality``:

* random parameters of a chart with a random rod order (generic points);
* the same with one latitude set to exactly +-pi/2 (exact poles: three or
  more rods collinear and pointing the same way);
* with every latitude at +-pi/2 (the most stretched configurations);
* exact folds (latitudes 0, ``t = 0`` or ``pi``: the first two rods folded back) and
  folded triples (latitudes 0, ``t = +-pi/2``);

then polish the worst samples by Nelder-Mead on ``max_i q_i`` (an adversarial
search: sampling alone overestimates the worst case).  With ``--lengths`` it
also reports, over every sampled point, the conditioning the atlas buys
(``docs/atlas_quality.md``): the largest ``cond(J)`` of the best chart, of any
chart of quality ``>= 0.25`` (the active chart until its switch event at the
default ``q_out``), and the largest ``cond(J) q`` over charts of quality
``>= 0.05``; for unit rods n = 4..8 as well (the same measure), and for
chains whose dominant side is a link (their ``L`` range given).

Run: ``python -m benchmarks.atlas_quality [--samples N] [--lengths]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import minimize

from charts import SuspensionAtlas, SuspensionChart
from charts.chain_geometry import sphere_range, validate_sphere_chain

#: Length vectors of the ``--lengths`` study and their ``L`` range (``None``: the base dominates, ``sphere_range``):
#: unit rods for comparison, the tutorial's chain, a very short and a very long link, two nearly equal shortest
#: links (the fold q_A), one long link, a tenfold range, a hundredfold one, two chains whose dominant side is a
#: link (its range of ``L``), and random lengths in [0.2, 3].
LENGTHS: list[tuple[tuple[float, ...], tuple[float, float] | None]] = [
    *[((1.0,) * n, None) for n in range(4, 9)],
    ((1.0, 2.0, 1.5, 2.5, 1.2), None),
    ((0.05, 1.0, 2.0, 3.0, 1.5, 0.7), None),
    ((0.25, 0.2500001, 1.0, 2.0), None),
    ((3.0, 1.0, 1.0, 1.0, 1.0), None),
    ((0.3, 3.0, 1.0, 0.5, 2.0, 1.5, 0.8), None),
    ((1.0, 1.0, 1.0, 0.01), None),
    ((1.0, 1.0, 1.0, 3.5), (0.5, 2.5)),  # l_4 dominates
    ((1.0, 2.0, 6.0, 1.5, 0.5), (1.0, 2.0)),  # l_3 dominates
]


def random_lengths(count: int, seed: int = 1) -> list[tuple[float, ...]]:
    """``count`` length vectors, ``n`` in 4..7, lengths uniform in [0.2, 3], rounded to 3 digits."""
    rng = np.random.default_rng(seed)
    return [tuple(np.round(rng.uniform(0.2, 3.0, int(rng.integers(4, 8))), 3)) for _ in range(count)]


def sample_configurations(lengths: int | tuple, L: float, count: int, rng: np.random.Generator) -> np.ndarray:
    """Interleaved real points: generic, single-pole, all-pole, fold and folded-triple configurations."""
    n = lengths if isinstance(lengths, int) else len(lengths)
    base = validate_sphere_chain(lengths, L)[2]
    sides = np.array([s for s in range(n + 1) if s != base])  # the charts' links: the sides but the base
    points = []
    for kind in ("generic", "pole", "all-poles", "fold", "triple"):
        for _ in range(count // 5 + 1):
            chart = SuspensionChart(lengths, L, order=rng.permutation(sides))
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


def conditioning(atlas: SuspensionAtlas, p: np.ndarray, q_out: float = 0.25) -> tuple[float, float, float]:
    """At ``p``: ``cond(J)`` of the best chart, the largest ``cond(J)`` of a chart of quality ``>= q_out``, and the
    largest ``cond(J) q`` of a chart of quality ``>= 0.05``."""
    best, active, cq = (-np.inf, np.inf), 0.0, 0.0
    for chart in atlas.charts:
        a = chart.get_parameters(p)
        q = float(chart.quality(a))
        if q < 0.05:
            continue
        s = np.linalg.svd(chart.jacobian(a), compute_uv=False)
        cond = s[0] / s[-1]
        cq = max(cq, cond * q)
        if q >= q_out:
            active = max(active, cond)
        if q > best[0]:
            best = (q, cond)
    return best[1], active, cq


def worst_best_quality(lengths: int | tuple, Ls: np.ndarray, count: int, seed: int = 0, polished: int = 3,
                       condition: bool = False) -> dict:
    """Worst best-chart quality and the ``L`` where it occurs over sampled and polished configurations; with
    ``condition``, also the largest ``cond(J)`` of the best chart (``cond_best``), of a chart of quality
    ``>= 0.25`` (``cond_active``) and the largest ``cond(J) q`` (``cond_q``), over the samples."""
    rng = np.random.default_rng(seed)
    found = []  # (best quality, L, point)
    cq, cond_best, cond_active = 0.0, 0.0, 0.0
    for L in Ls:
        atlas = SuspensionAtlas(lengths, L)
        for p in sample_configurations(lengths, L, count, rng):
            found.append((atlas.qualities(p).max(), L, p))
            if condition:
                b, a, w = conditioning(atlas, p)
                cq, cond_best, cond_active = max(cq, w), max(cond_best, b), max(cond_active, a)
    found.sort(key=lambda f: f[0])
    worst = found[0][:2]
    for q, L, p in found[:polished]:
        qp = polish(SuspensionAtlas(lengths, L), p)
        if qp < worst[0]:
            worst = (qp, L)
    return {"q": float(worst[0]), "L": float(worst[1]), "cond_q": cq, "cond_best": cond_best, "cond_active": cond_active}


def L_grid(lengths: int | tuple, inner: int = 7, span: tuple[float, float] | None = None) -> np.ndarray:
    """``L`` across the sphere range (``span``, default the base's: ``sphere_range``): 1e-12, 1e-9, 1e-6, 1e-3 times
    half its width from both ends (the unit-rod range has width 2: absolute gaps) and ``inner`` values between."""
    if span is not None:
        lo, hi = span
    else:
        lo, hi = (lengths - 2.0, float(lengths)) if isinstance(lengths, int) else sphere_range(lengths)
    gaps = 10.0 ** np.array([-12.0, -9.0, -6.0, -3.0]) * (hi - lo) / 2
    return np.concatenate([lo + gaps, np.linspace(lo, hi, inner + 2)[1:-1], hi - gaps[::-1]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=150, help="configurations per (n, L)")
    parser.add_argument("--lengths", action="store_true", help="links of other lengths (LENGTHS and 6 random)")
    args = parser.parse_args()
    if not args.lengths:
        print(f"{'n':>2} {'worst best q':>13} {'at L':>8} {'time s':>7}")
        for n in range(3, 9):
            t0 = time.perf_counter()
            r = worst_best_quality(n, L_grid(n), args.samples)
            print(f"{n:>2} {r['q']:13.4f} {r['L']:8.3f} {time.perf_counter() - t0:7.1f}")
        return
    print(f"{'lengths':<40} {'L range':>13} {'worst best q':>12} {'at (L-lo)/w':>11} {'cond best':>9} "
          f"{'cond q>=.25':>11} {'cond*q':>7} {'time s':>7}")
    for ls, span in LENGTHS + [(r, None) for r in random_lengths(6)]:
        t0 = time.perf_counter()
        lo, hi = sphere_range(ls) if span is None else span
        r = worst_best_quality(tuple(ls), L_grid(tuple(ls), span=span), args.samples, condition=True)
        rel = (r["L"] - lo) / (hi - lo)
        print(f"{str(tuple(float(x) for x in ls)):<40} {f'({lo:.4g}, {hi:.4g})':>13} {r['q']:12.4f} {rel:11.2e} "
              f"{r['cond_best']:9.2f} {r['cond_active']:11.2f} {r['cond_q']:7.2f} {time.perf_counter() - t0:7.1f}",
              flush=True)


if __name__ == "__main__":
    main()
