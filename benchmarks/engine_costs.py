"""Costs of the geodesic engine around the integrator: start, switch, dense memory, evaluation.

Run ``python -m benchmarks.engine_costs`` (n = 4, L = 2.6, warm caches).  Prints:

* the cost of a start (validation, best chart, transfer) and of a switch (best
  chart, polish, velocity transfer), from the solver's own ``SolverStats``;
* ``Atlas.best_chart`` alone;
* the dense output's bytes per Taylor step against the minimum
  ``(order + 1) * 2 dim * 8``;
* ``sol(ts)`` for 20,000 times;
* lines of code of the installed packages.

Absolute times are machine noise; compare ratios measured in one run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from linkage import Chain
from manifold import compiled, solve_chart_exp_ode


def _median_seconds(fn, repeat: int = 20) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(n: int = 4, L: float = 2.6, T: float = 3000.0) -> dict:
    chain = Chain(n, L)
    metric = chain.metric()
    atlas = metric.atlas
    a = np.append(np.full(n - 3, 0.3), 0.4)
    p0 = atlas.get_point(0, a)
    v0 = atlas.charts[0].tangent_vector(a, np.resize([0.7, -0.4], n - 2))
    solve_chart_exp_ode(metric, p0, v0, 20.0)  # compile, warm every cache
    start = _median_seconds(lambda: solve_chart_exp_ode(metric, p0, v0, 1e-6, dense=False))
    start_only = solve_chart_exp_ode(metric, p0, v0, 1e-6, dense=False).stats.switch_seconds
    best = _median_seconds(lambda: atlas.best_chart(p0))
    big = solve_chart_exp_ode(metric, p0, v0, T)
    s = big.stats
    with compiled(atlas.charts[0].family).integrator() as ta:
        order = ta.order
    minimum = (order + 1) * 2 * atlas.dim * 8
    ts = np.linspace(0, T, 20_000)
    evaluate = _median_seconds(lambda: big(ts), repeat=3)
    root = Path(__file__).resolve().parent.parent
    loc = {pkg: sum(len(f.read_text().splitlines()) for f in (root / pkg).glob("*.py"))
           for pkg in ("manifold", "charts", "linkage")}
    out = {
        "start_ms": 1e3 * start,
        "switch_ms": 1e3 * (s.switch_seconds - start_only) / max(s.n_switches, 1),
        "best_chart_ms": 1e3 * best,
        "dense_bytes_per_step": big.dense_nbytes / big.n_steps,
        "dense_minimum_bytes_per_step": minimum,
        "eval_20000_s": evaluate,
        "steps": big.n_steps,
        "switches": big.n_switches,
        "switch_share_of_wall": s.switch_seconds / s.wall_seconds,
        "loc": loc,
    }
    print(f"n = {n}, L = {L}: T = {T:g}, {big.n_steps} steps, {big.n_switches} switches")
    print(f"  start                {out['start_ms']:8.2f} ms   (whole solve with T = 1e-6)")
    print(f"  switch               {out['switch_ms']:8.2f} ms   (SolverStats.switch_seconds per switch)")
    print(f"  best_chart           {out['best_chart_ms']:8.2f} ms")
    print(f"  starts and switches  {100 * out['switch_share_of_wall']:8.1f} % of the wall time")
    print(f"  dense output         {out['dense_bytes_per_step']:8.0f} B/step (minimum {minimum} B)")
    print(f"  sol(ts), 20000 times {out['eval_20000_s']:8.3f} s")
    print(f"  lines of code        {loc}")
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=4)
    parser.add_argument("--L", type=float, default=2.6)
    parser.add_argument("--T", type=float, default=3000.0)
    args = parser.parse_args()
    main(args.n, args.L, args.T)
