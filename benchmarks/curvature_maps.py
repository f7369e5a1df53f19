"""Curvature of M^4_L and the time a long free motion spends in each region of it.

Writes ``docs/figures/curvature_m4.png`` (the Gaussian curvature of the 4-rod
configuration space, drawn on the round sphere through chart 0's latitude and
longitude, for several L) and ``docs/figures/ergodicity_m4.png`` (time fractions
of long trajectories in cells of the sphere against the cells' Riemannian
volume fractions), and prints the numbers quoted in ``docs/curvature.md``:
curvature range, Gauss-Bonnet, volume, the distance between time and volume
fractions as T grows, and the acceptance and cost of volume sampling for
n = 3..8 with the box and the round-sphere proposals.

Run: ``python -m benchmarks.curvature_maps [--T 5000] [--runs 4] [--parts curvature,ergodicity,sampling]``
(about a quarter of an hour on two cores).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib import colors  # noqa: E402
from scipy.optimize import brentq, minimize  # noqa: E402

from charts import RoundSphereProposal  # noqa: E402
from linkage import Chain  # noqa: E402
from linkage.motion import free_motion  # noqa: E402
from linkage.sampling import sample_configurations, sample_starts  # noqa: E402
from manifold import SaveAt
from manifold.sampling import BoxProposal, sample_volume  # noqa: E402

FIGURES = Path(__file__).resolve().parent.parent / "docs" / "figures"
LENGTHS = (2.05, 2.3, 2.8, 3.4, 3.9)


def curvature_grid(chain: Chain, n_phi: int = 91, n_t: int = 181) -> tuple[np.ndarray, np.ndarray]:
    """Round-sphere picture (chart 0's ``sphere_point``) and K on a (phi, t) grid of chart 0."""
    metric = chain.metric()
    phi, t = np.meshgrid(np.linspace(-np.pi / 2, np.pi / 2, n_phi), np.linspace(-np.pi, np.pi, n_t), indexing="ij")
    a = np.stack([phi, t], axis=-1)
    chart = metric.atlas.charts[0]
    return chart.sphere_point(a), metric.gaussian_curvature(chart.get_point(a))


def smallest_curvature(L: float) -> tuple[float, np.ndarray]:
    """``min K`` over M^4_L: the smallest value on the 91 x 181 grid, polished by Nelder-Mead in chart 0."""
    chain = Chain(4, L)
    metric, chart = chain.metric(), chain.metric().atlas.charts[0]
    _, K = curvature_grid(chain)
    r, c = np.unravel_index(np.argmin(K), K.shape)
    start = np.array([np.linspace(-np.pi / 2, np.pi / 2, K.shape[0])[r], np.linspace(-np.pi, np.pi, K.shape[1])[c]])
    res = minimize(lambda a: metric.gaussian_curvature(chart.get_point(a)), start, method="Nelder-Mead",
                   options=dict(xatol=1e-11, fatol=1e-15, maxiter=2000))
    return float(res.fun), res.x


def curvature_table() -> list[dict]:
    rows = []
    fig = plt.figure(figsize=(2.9 * len(LENGTHS), 6.4))
    norm = colors.SymLogNorm(linthresh=1.0, vmin=-100.0, vmax=100.0, base=10)  # one scale for every L
    for col, L in enumerate(LENGTHS):
        chain = Chain(4, L)
        metric = chain.metric()
        box = metric.atlas.parameter_box
        t0 = time.perf_counter()
        xyz, K = curvature_grid(chain)
        t_grid = time.perf_counter() - t0
        # chart 0's fold sharpens sqrt(det g) near L = 2: the tensor rule needs more nodes there
        nodes = (128, 192) if L - 2 >= 0.25 else (384, 1152)
        t0 = time.perf_counter()
        total = metric.integrate(metric.gaussian_curvature, 0, box, nodes, periodic=(1,))
        t_gb = time.perf_counter() - t0
        volume = metric.integrate(lambda p: np.ones(p.shape[0]), 0, box, nodes, periodic=(1,))
        # the share of the volume where K < 0, by Monte Carlo over configurations uniform in the volume
        sample = sample_configurations(chain, 4000, np.random.default_rng(11))
        negative = metric.gaussian_curvature(chain.to_point(sample)) < 0
        rows.append(dict(L=L, K_min=float(K.min()), K_max=float(K.max()), gauss_bonnet=total / (4 * np.pi) - 1,
                         volume=volume, negative=float(negative.mean()), seconds=t_grid, nodes=nodes, gb_seconds=t_gb))
        face = plt.cm.RdBu_r(norm(K))
        for row, azim in enumerate((-60, 120)):  # front and back of the sphere
            ax = fig.add_subplot(2, len(LENGTHS), row * len(LENGTHS) + col + 1, projection="3d")
            ax.plot_surface(xyz[..., 1], xyz[..., 2], xyz[..., 0], facecolors=face, rstride=1, cstride=1,
                            linewidth=0, antialiased=False, shade=False)
            ax.set_box_aspect((1, 1, 1))
            ax.set_axis_off()
            ax.view_init(elev=20, azim=azim)
            ax.set_xlim(-0.75, 0.75)
            ax.set_ylim(-0.75, 0.75)
            ax.set_zlim(-0.75, 0.75)
            if row == 0:
                ax.set_title(f"L = {L}\nK in [{K.min():.3g}, {K.max():.3g}]", fontsize=10)
    fig.subplots_adjust(left=0.0, right=0.9, top=0.88, bottom=0.0, wspace=0.0, hspace=0.0)
    cax = fig.add_axes([0.92, 0.15, 0.012, 0.65])
    fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap="RdBu_r"), cax=cax, label="Gaussian curvature K (symlog)")
    fig.suptitle("Gaussian curvature of $M^4_L$ (4 unit rods, unit masses) on the sphere of chart 0's latitude "
                 "$\\phi_4$ (up) and circle angle $t$; front (top) and back (bottom)", fontsize=11)
    fig.savefig(FIGURES / "curvature_m4.png", dpi=100)
    plt.close(fig)
    return rows


def cell_volumes(chain: Chain, edges_phi: np.ndarray, edges_t: np.ndarray) -> np.ndarray:
    """Riemannian volume of each (phi, t) cell of chart 0, by the tensor rule on the cell's box."""
    metric = chain.metric()
    vol = np.empty((len(edges_phi) - 1, len(edges_t) - 1))
    for r in range(vol.shape[0]):
        for c in range(vol.shape[1]):
            box = (np.array([edges_phi[r], edges_t[c]]), np.array([edges_phi[r + 1], edges_t[c + 1]]))
            vol[r, c] = metric.integrate(lambda p: np.ones(p.shape[0]), 0, box, (12, 12))
    return vol


def ergodicity(T: float, runs: int, L: float = 2.6) -> list[dict]:
    """Time fractions of ``runs`` free motions (Liouville starts, E = 1/2) in 6 x 8 cells vs volume fractions."""
    chain = Chain(4, L)
    chart = chain.metric().atlas.charts[0]
    edges_phi = np.arcsin(np.linspace(-1, 1, 7))  # six latitude bands (equal areas on the round picture)
    edges_t = np.linspace(-np.pi, np.pi, 9)
    vol = cell_volumes(chain, edges_phi, edges_t)
    vol /= vol.sum()
    hinges0, velocities0 = sample_starts(chain, runs, 0.5, np.random.default_rng(12))
    checkpoints = list(np.geomspace(T / 100, T, 9))
    rows, finals = [], []
    for r in range(runs):
        t0 = time.perf_counter()
        ts = np.linspace(0, T, int(20 * T) + 1)
        motion = free_motion(chain, hinges0[r], velocities0[r], T, method="charts", save=SaveAt(t_eval=ts))
        seconds = time.perf_counter() - t0
        a = chart.get_parameters(chain.to_point(motion.hinges))
        i = np.clip(np.searchsorted(edges_phi, a[:, 0]) - 1, 0, 5)
        j = np.clip(np.searchsorted(edges_t, a[:, 1]) - 1, 0, 7)
        for Tc in checkpoints:
            keep = ts <= Tc
            frac = np.zeros_like(vol)
            np.add.at(frac, (i[keep], j[keep]), 1.0)
            frac /= frac.sum()
            rows.append(dict(run=r, T=Tc, tv=0.5 * float(np.abs(frac - vol).sum()), seconds=seconds,
                             switches=motion.n_switches, energy_error=motion.relative_energy_error))
        finals.append(frac)
    pooled = np.mean(finals, axis=0)  # all runs together: run-to-run differences would not average out
    rows.append(dict(run=-1, T=runs * T, tv=0.5 * float(np.abs(pooled - vol).sum()), seconds=0.0, switches=0,
                     energy_error=0.0))
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    for r, frac in enumerate(finals):
        left.plot(vol.ravel(), frac.ravel(), "o", ms=3, alpha=0.7, label=f"run {r}")
    top = max(vol.max(), max(f.max() for f in finals)) * 1.05
    left.plot([0, top], [0, top], "k-", lw=0.8)
    left.set_xlabel("Riemannian volume fraction of the cell")
    left.set_ylabel(f"fraction of time in the cell (T = {T:g})")
    left.set_title(f"$M^4_{{{L}}}$: 48 cells of chart 0's (phi, t)")
    left.legend(fontsize=8)
    for r in range(runs):
        pts = [(row["T"], row["tv"]) for row in rows if row["run"] == r]
        right.loglog(*zip(*pts), "o-", label=f"run {r}")
    Ts = np.array(checkpoints)
    right.loglog(Ts, rows[0]["tv"] * np.sqrt(Ts[0] / Ts), "k--", lw=0.8, label="~ T^(-1/2)")
    right.set_xlabel("T")
    right.set_ylabel("total variation distance, time vs volume")
    right.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(FIGURES / "ergodicity_m4.png", dpi=110)
    plt.close(fig)
    return rows


def curvature_part() -> None:
    print("Gaussian curvature of M^4_L (unit masses); grid 91 x 181 of chart 0, K through the best chart")
    print("(K < 0: share of 4000 configurations uniform in the volume, standard error <= 0.008)")
    print(f"{'L':>5} {'K min':>10} {'K max':>10} {'K < 0':>10} {'volume':>9} {'GB/4pi - 1':>11} {'nodes':>11} "
          f"{'GB s':>6} {'grid s':>7}")
    for row in curvature_table():
        print(f"{row['L']:5.2f} {row['K_min']:10.4g} {row['K_max']:10.4g} {row['negative']:10.3f} {row['volume']:9.5f} "
              f"{row['gauss_bonnet']:11.2e} {'x'.join(map(str, row['nodes'])):>11} {row['gb_seconds']:6.1f} {row['seconds']:7.2f}")
    print(f"wrote {FIGURES / 'curvature_m4.png'}")
    L_flat = brentq(lambda L: smallest_curvature(L)[0], 3.0, 3.3, xtol=1e-7)
    print(f"K > 0 everywhere for L > {L_flat:.6f} (min K = 0 there, at chart-0 parameters "
          f"{np.round(smallest_curvature(L_flat)[1], 4)}); min K = {smallest_curvature(3.0)[0]:.4f} at L = 3.0")


def ergodicity_part(T: float, runs: int) -> None:
    print(f"\nTime in 48 cells vs Riemannian volume, M^4_2.6, {runs} Liouville starts (E = 1/2), T = {T:g}")
    print(f"{'run':>3} {'T':>8} {'TV distance':>12} {'switches':>9} {'energy err':>10} {'solve s':>8}")
    for row in ergodicity(T, runs):
        if row["run"] < 0:
            print(f"all runs pooled (total time {row['T']:g}): TV distance {row['tv']:.4f}")
            continue
        print(f"{row['run']:3d} {row['T']:8.1f} {row['tv']:12.4f} {row['switches']:9d} {row['energy_error']:10.2e} "
              f"{row['seconds']:8.2f}")
    print(f"wrote {FIGURES / 'ergodicity_m4.png'}")


def sampling_part(size: int = 1000) -> None:
    """Acceptance and cost of volume sampling, box proposal against the round-sphere proposal, n = 3..8."""
    print(f"\nVolume sampling ({size} configurations, unit masses): acceptance, restarts, seconds")
    print(f"{'n':>2} {'L':>5} {'box acc.':>9} {'restarts':>8} {'box s':>7} {'round acc.':>10} {'restarts':>8} {'round s':>8}")
    for n, L in ((3, 1.7), (4, 2.05), (4, 2.6), (4, 3.9), (5, 3.6), (6, 4.5), (7, 5.5), (8, 6.5)):
        metric = Chain(n, L).metric()
        out = []
        for proposal in (BoxProposal(*metric.atlas.parameter_box), RoundSphereProposal(n - 2)):
            t0 = time.perf_counter()
            sample = sample_volume(metric, size, np.random.default_rng(13), proposal)
            out.append((sample.acceptance, sample.restarts, time.perf_counter() - t0))
        (a0, r0, s0), (a1, r1, s1) = out
        print(f"{n:2d} {L:5.2f} {a0:9.2e} {r0:8d} {s0:7.2f} {a1:10.2e} {r1:8d} {s1:8.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--T", type=float, default=5000.0, help="length of each free motion")
    parser.add_argument("--runs", type=int, default=4, help="number of free motions")
    parser.add_argument("--parts", default="curvature,ergodicity,sampling", help="comma-separated parts to run")
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    FIGURES.mkdir(parents=True, exist_ok=True)
    if "curvature" in parts:
        curvature_part()
    if "ergodicity" in parts:
        ergodicity_part(args.T, args.runs)
    if "sampling" in parts:
        sampling_part()


if __name__ == "__main__":
    main()
