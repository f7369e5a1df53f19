"""Main job: a chain moving freely through suspension poles, checked against a chart-free reference.

Run ``python -m linkage.demo`` (defaults: 4 rods, L = 2.6, T = 200, float64).
It starts the chain exactly at a pole of chart 0 (its first three rods in one
line), integrates the free motion with heyoka in the atlas, prints the chart
switches, the energy error and the distance from the chart-free hinge-coordinate
reference, and writes a PNG with the public pictures of :mod:`linkage.draw`:
the path on the configuration sphere coloured by the active chart, snapshots
of the chain, the energy error, the chart timeline, and the agreement with the
reference.  ``--animation motion.gif`` also writes the moving chain
(:func:`linkage.draw.animate`); ``--progress`` reports compiles and shows a
progress bar.
"""

from __future__ import annotations

import argparse
import time

import heyoka as hy
import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

from manifold.options import Precision, SaveAt
from manifold.progress import ProgressArgument, TqdmProgress

from .chain import Chain
from .draw import (animate, animation_writer, draw_chain_at, draw_chart_timeline, draw_configurations,
                   draw_energy_error, draw_sphere_path)
from .motion import ChainMotion, free_motion

PRECISIONS = {"float64": float, "longdouble": np.longdouble, "real128": hy.real128}


def pole_start(chain: Chain) -> tuple[np.ndarray, np.ndarray]:
    """Chart 0's pole (first rods stretched) with a unit-energy tangent velocity.

    Chart 0's parameters ``a = (pi/2, 0, ..., 0, 0.4)`` put its first three
    rods in one line (``phi_n = pi/2``); the velocity is ``v = J_j(a_j) c``
    in the best chart ``j`` there, ``c`` a fixed random vector, scaled to
    kinetic energy ``1/2 v^T K v = 1/2``.

    Returns
    -------
    tuple
        Complex hinges and hinge velocity.
    """
    atlas = chain.atlas()
    a = np.zeros(chain.dim)
    if chain.dim > 1:
        a[0] = np.pi / 2
    a[-1] = 0.4
    p0 = atlas.get_point(0, a)
    j = int(atlas.get_chart_index(p0))  # one point: one index
    rng = np.random.default_rng(1)
    v0 = atlas.charts[j].tangent_vector(atlas.get_parameters(j, p0), rng.normal(size=chain.dim))
    v0 /= np.sqrt(2 * chain.metric(atlas).ambient_kinetic_energy(v0))
    return chain.from_point(p0), chain.from_point(v0)


def run(n: int, L: float, T: float, precision: str, out: str, samples: int = 2000, animation: str | None = None,
        progress: ProgressArgument = None) -> dict:
    """Integrate the demo's motion, compare it with the hinge method, write the figure (and the animation).

    Returns the numbers that :func:`main` prints.
    """
    chain = Chain(n, L)
    h0, v0 = pole_start(chain)
    fp = PRECISIONS[precision]
    t0 = time.perf_counter()
    motion = free_motion(chain, h0, v0, T, method="charts", precision=Precision(fp), progress=progress)
    t_chart = time.perf_counter() - t0
    sol = motion.solution
    ts = np.linspace(0, T, samples)
    hinges, _ = motion(ts)
    t0 = time.perf_counter()
    # the recommended chart-free reference (docs/methods.md): the hinge method, in the same precision
    ref = free_motion(chain, h0, v0, T, method="hinges", precision=Precision(fp), save=SaveAt(ts, dense=False))
    t_ref = time.perf_counter() - t0
    assert ref.solution.points is not None  # t_eval was given
    # compared in the working precision: rounded to complex128 first, a long-double or quad difference would vanish
    gap = (sol(ts)[0] - ref.solution.points).astype(float).reshape(len(ts), n - 1, 2)
    distance = np.linalg.norm(gap, axis=-1).max(axis=-1)
    early = ts <= min(10.0, T)
    # the geodesic flow separates nearby paths exponentially: fit the rate where the distance is resolved
    grow = (distance > 1e-13) & (distance < 1e-2)
    rate = np.polyfit(ts[grow], np.log(distance[grow]), 1)[0] if grow.sum() > 10 else float("nan")
    stats = {
        "switches": sol.n_switches,
        "steps": sol.n_steps,
        "energy_error": sol.relative_energy_error,
        "early_horizon": float(min(10.0, T)),
        "hinge_distance_10": float(distance[early].max()),
        "separation_rate": float(rate),
        "hinge_distance": float(distance.max()),
        "hinge_energy_error": ref.relative_energy_error,
        "closure": float(chain.closure_residual(hinges).max()),
        "time_chart": t_chart,
        "time_hinges": t_ref,
    }
    figure(chain, motion, ts, distance, out)
    if animation is not None:
        animate(motion, animation)
    return stats


def figure(chain: Chain, motion: ChainMotion, ts: NDArray, distance: NDArray, out: str) -> None:
    """Write the demo's figure: the path on the sphere, snapshots, energy, charts, agreement with the reference."""
    fig = Figure(figsize=(16, 8.5))
    grid = fig.add_gridspec(2, 3)
    if chain.n >= 4:
        draw_sphere_path(fig.add_subplot(grid[:, 0], projection="3d"), motion, ts)
    else:  # n = 3: the configuration space is a circle; show the chain at the end instead
        draw_chain_at(fig.add_subplot(grid[:, 0]), motion, ts[-1])
    ax = fig.add_subplot(grid[0, 1])
    picks = np.linspace(0, min(len(ts) - 1, len(ts) // 20), 6).astype(int)
    draw_configurations(ax, list(motion(ts[picks])[0]), chain.L, labels=[f"t = {ts[k]:.2f}" for k in picks])
    ax.set_title(f"snapshots, n = {chain.n}, L = {chain.L}")
    draw_energy_error(fig.add_subplot(grid[0, 2]), motion)
    draw_chart_timeline(fig.add_subplot(grid[1, 1]), motion)
    ax = fig.add_subplot(grid[1, 2])
    ax.semilogy(ts[1:], np.maximum(distance[1:], 1e-17))
    for s in motion.solution.switches:
        ax.axvline(s.time, color="0.85", lw=0.5, zorder=0)
    ax.set_xlabel("t")
    ax.set_ylabel("max hinge distance, charts vs hinges")
    ax.set_title("agreement with the chart-free reference (grey: switches)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def main(argv: list[str] | None = None) -> None:
    """The command line ``linkage-demo`` / ``python -m linkage`` (``argv``: its arguments; default ``sys.argv``)."""
    parser = argparse.ArgumentParser(prog="linkage-demo", description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=4, help="number of rods, at least 3 (default 4)")
    parser.add_argument("--L", type=float, default=None, help="pin distance, n-2 < L < n (default n - 1.4)")
    parser.add_argument("--T", type=float, default=200.0, help="final time, > 0 (default 200)")
    parser.add_argument("--precision", choices=sorted(PRECISIONS), default="float64",
                        help="floating type of the integration (default float64)")
    parser.add_argument("--out", default="demo.png", help="PNG file to write (default demo.png)")
    parser.add_argument("--animation", default=None, metavar="FILE",
                        help="also write an animation of the motion (.gif; .mp4 needs ffmpeg)")
    parser.add_argument("--progress", action="store_true",
                        help="say what is compiled and show a progress bar of the solve (needs tqdm)")
    args = parser.parse_args(argv)
    if args.n < 3:  # n = 2 has a configuration space of dimension 0: no motion to draw
        parser.error(f"--n must be an integer >= 3 (a chain with a motion), got {args.n}")
    if not (np.isfinite(args.T) and args.T > 0):
        parser.error(f"--T must be a finite positive time, got {args.T}")
    L = args.n - 1.4 if args.L is None else args.L
    try:
        Chain(args.n, L)
    except ValueError as e:
        parser.error(str(e))
    print(f"free motion of {args.n} unit rods pinned at 0 and L = {L}, from an exact pole of chart 0, "
          f"T = {args.T}, {args.precision}")
    try:
        if args.animation is not None:
            animation_writer(args.animation)  # refuse a suffix or a missing ffmpeg before the run, not after
        progress = TqdmProgress() if args.progress else None
    except (ValueError, RuntimeError, ImportError) as e:
        parser.error(f"{e}")
    s = run(args.n, L, args.T, args.precision, args.out, animation=args.animation, progress=progress)
    print(f"chart switches          {s['switches']}  ({s['steps']} Taylor steps, {s['time_chart']:.2f} s)")
    print(f"relative energy error   {s['energy_error']:.2e}")
    print(f"closure residual        {s['closure']:.2e}  (max rod-length error along the path)")
    print(f"distance from hinges    {s['hinge_distance_10']:.2e} for t <= {s['early_horizon']:g}  (max hinge distance "
          f"to the chart-free hinge-coordinate method, in {args.precision}, {s['time_hinges']:.2f} s; its own energy "
          f"error {s['hinge_energy_error']:.1e})")
    if np.isfinite(s["separation_rate"]):
        print(f"  then it grows like exp({s['separation_rate']:.3f} t) up to {s['hinge_distance']:.2e} at t = {args.T}:"
              f" nearby geodesics separate exponentially, so no two methods can agree for ever")
    else:
        print(f"  and {s['hinge_distance']:.2e} at most up to t = {args.T} (too little growth to fit its exponential "
              "rate; nearby geodesics separate exponentially, so over long times no two methods agree)")
    print(f"wrote {args.out}" + ("" if args.animation is None else f" and {args.animation}"))


if __name__ == "__main__":
    main()
