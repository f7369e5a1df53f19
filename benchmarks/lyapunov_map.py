"""The maximal Lyapunov exponent of the 4-rod chain against L, computed as an ensemble.

Run ``python -m benchmarks.lyapunov_map [--count 12] [--T 800] [--backend threads] [--out docs/figures/lyapunov_n4.png]``.

For each ``L`` it draws ``count`` starts from the Liouville measure of the
unit-speed shell (configurations uniform in the Riemannian volume of the
kinetic metric, velocities uniform on the unit circle of the tangent plane),
runs :func:`linkage.motion.lyapunov_exponents` on them (finite-time exponent
at ``T``, perpendicular deviations, renormalised every 2 time units) and
prints, per ``L``: the median and quartiles of the exponents, the share of
starts above 0.02 (chaotic by time ``T``; a start in a regular island has an
estimate decaying like ``1/T``), and the worst energy error.  The figure
shows every estimate against ``L`` with the medians, and the convergence of
the estimates of one ``L``.

The starts are drawn here by rejection in chart 0 (uniform parameters
``(phi_4, t)``, accepted with probability ``sqrt(det g) / bound``); the
library's sampler of issue 12 (``linkage.sampling``) draws the same measure.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from linkage import Chain
from linkage.motion import lyapunov_exponents

L_VALUES = (2.05, 2.2, 2.4, 2.6, 2.8, 3.0, 3.2, 3.4, 3.6, 3.8, 3.95)
CHAOTIC = 0.02


def liouville_starts(chain: Chain, count: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """``count`` unit-speed starts of a 4-rod chain from the Liouville measure, by rejection in chart 0."""
    atlas, metric = chain.atlas(), chain.metric()
    chart = atlas.charts[0]
    lo, hi = np.array([-np.pi / 2, -np.pi]), np.array([np.pi / 2, np.pi])

    def density(a: np.ndarray) -> float:
        return float(np.sqrt(np.linalg.det(metric.local_metric(0, a))))

    grid = [np.array([p, t]) for p in np.linspace(-1.55, 1.55, 41) for t in np.linspace(-np.pi, np.pi, 81)]
    bound = 1.3 * max(density(a) for a in grid)
    H, V = [], []
    while len(H) < count:
        a = rng.uniform(lo, hi)
        d = density(a)
        if d > bound:
            raise RuntimeError(f"the rejection bound {bound:.3g} is below the density {d:.3g} at {a}: raise it")
        if rng.uniform(0, bound) > d:
            continue
        g = metric.local_metric(0, a)
        u = rng.normal(size=2)
        c = np.linalg.solve(np.linalg.cholesky(g).T, u / np.linalg.norm(u))  # c^T g c = 1, uniform direction
        H.append(chain.from_point(chart.get_point(a)))
        V.append(chain.from_point(chart.tangent_vector(a, c)))
    return np.array(H), np.array(V)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=12)
    ap.add_argument("--T", type=float, default=800.0)
    ap.add_argument("--backend", default="threads")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="docs/figures/lyapunov_n4.png")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows = []
    print(f"n = 4, {args.count} Liouville starts per L, unit speed, T = {args.T:g}, backend {args.backend}")
    print("     L   median   quartiles          chaotic  max energy error   wall")
    for L in L_VALUES:
        chain = Chain(4, L)
        H, V = liouville_starts(chain, args.count, rng)
        t0 = time.perf_counter()
        results = lyapunov_exponents(chain, H, V, args.T, backend=args.backend, interval=2.0)
        wall = time.perf_counter() - t0
        failed = [r.message for r in results if not r.success]
        if failed:
            raise RuntimeError(f"L = {L}: {len(failed)} trajectories failed their checks: {failed[0]}")
        lam = np.array([r.exponent for r in results])
        q1, med, q3 = np.quantile(lam, [0.25, 0.5, 0.75])
        share = float(np.mean(lam > CHAOTIC))
        err = max(r.relative_energy_error for r in results)
        rows.append((L, lam, results))
        print(f"  {L:4.2f}   {med:.4f}   [{q1:.4f}, {q3:.4f}]   {share:5.0%}    {err:.1e}        {wall:6.1f} s")
    _figure(rows, args.out)
    print(f"wrote {args.out}")


def _figure(rows: list, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4), gridspec_kw={"width_ratios": [3, 2]})
    for L, lam, _ in rows:
        ax.scatter(np.full(len(lam), L), lam, s=12, color="tab:blue", alpha=0.5)
    ax.plot([r[0] for r in rows], [np.median(r[1]) for r in rows], "o-", color="tab:red", label="median")
    ax.axhline(CHAOTIC, color="0.6", lw=0.8, ls="--", label=f"{CHAOTIC} (chaotic / regular)")
    ax.set_xlabel("L")
    ax.set_ylabel(r"finite-time $\lambda_1$ (unit speed)")
    ax.set_title("4-rod chain: maximal Lyapunov exponent, Liouville starts")
    ax.legend()
    L, _, results = rows[len(rows) // 2]
    for r in results:
        ax2.plot(r.times, r.history[:, 0], lw=0.8)
    ax2.set_xscale("log")
    ax2.set_xlabel("t")
    ax2.set_ylabel(r"$\lambda_1$ estimate")
    ax2.set_title(f"convergence, L = {L:g}")
    fig.tight_layout()
    fig.savefig(out, dpi=120)


if __name__ == "__main__":
    main()
