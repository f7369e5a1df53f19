"""Costs of the geodesic engine around the integrator: chart choice, start, switch, dense memory, evaluation.

Run ``python -m benchmarks.engine_costs [--n 4 8]`` (L = n - 1.4, warm caches).  For each n it prints:

* ``Atlas.best_chart``, fast (every chart ranked at its closed-form parameters in one compiled
  call, only the charts within ``QUALITY_MARGIN`` of the best polished) against the full definition
  (every chart inverted and polished, then the argmax: ``FullDefinitionAtlas``), called in turn,
  CPU time of this process, fastest of 30;
* a start (a solve to T = 1e-6, dense output on: validation, chart choice, transfer, one step) the
  same way, and a switch (chart choice, polish, velocity transfer; wall time per switch from the
  solver's own ``SolverStats`` over ``--T-switch``, fastest of 3 interleaved runs), each with the fast
  chart choice and with the full definition swapped in; the share of the wall time that starts and
  switches take over ``--T-switch`` and over T = 20;
* how far the polish moves a competitive chart quality (the reason ``QUALITY_MARGIN`` is safe):
  ``max |q(approximate) - q(polished)|`` over charts with either above 0.25, at points drawn at and
  near poles, near ``t = +-pi/2`` and with ``L`` within 1e-12 .. 1e-3 of both ends of its range;
* the decomposition size of the float64 integrator (the size a Taylor step's cost is proportional to);
* the dense output's bytes per Taylor step against the minimum ``(order + 1) * 2 dim * 8``;
* ``sol(ts)`` for 20,000 times; lines of code of the installed packages.

Absolute times are machine noise (a shared machine: CPU time and fastest-of runs damp it); compare
the ratios, measured side by side in one run.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from charts import SuspensionAtlas
from linkage import Chain
from manifold import InducedMetric, compiled, solve_chart_exp_ode
from manifold.atlas import QUALITY_MARGIN


class FullDefinitionAtlas(SuspensionAtlas):
    """The chart choice by its definition: every chart inverted and polished, then the argmax (the old cost)."""

    def chart_choice(self, p):
        params = [c.get_parameters(p) for c in self.charts]
        q = [float(c.quality(a)) for c, a in zip(self.charts, params)]
        i = int(np.argmax(q))
        return i, params[i], q[i]


def _median_seconds(fn, repeat: int = 20) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def _side_by_side(fns: list, repeat: int = 30) -> list[float]:
    """CPU seconds of each of ``fns``, called in turn ``repeat`` times (interleaved: load drifts hit all alike); the minimum."""
    best = [np.inf] * len(fns)
    for _ in range(repeat):
        for k, fn in enumerate(fns):
            t0 = time.process_time()
            fn()
            best[k] = min(best[k], time.process_time() - t0)
    return best


def switch_ms(metrics: list, p0, v0, T: float, repeat: int = 3) -> list[tuple[float, float, int]]:
    """Per metric: ms per switch and the share of the wall time in starts and switches over ``T`` (from
    ``SolverStats``, wall clock; the fastest of ``repeat`` interleaved runs) and the number of switches."""
    out = [(np.inf, np.inf, 0)] * len(metrics)
    for _ in range(repeat):
        for k, metric in enumerate(metrics):
            start = solve_chart_exp_ode(metric, p0, v0, 1e-6).stats.switch_seconds
            s = solve_chart_exp_ode(metric, p0, v0, T).stats
            per = 1e3 * (s.switch_seconds - start) / max(s.n_switches, 1)
            out[k] = (min(out[k][0], per), min(out[k][1], s.switch_seconds / s.wall_seconds), s.n_switches)
    return out


def polish_shift(n: int, samples: int = 300, seed: int = 0) -> float:
    """``max |q(approximate) - q(polished)|`` over charts whose quality is above 0.25 either way, at hard points."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for k in range(samples):
        gap = 10.0 ** rng.uniform(-12, -3)
        L = [n - 2 + gap, n - gap, rng.uniform(n - 2 + 1e-3, n - 1e-3)][k % 3]
        atlas = SuspensionAtlas(n, L)
        lat = rng.choice([np.pi / 2, -np.pi / 2, 0.0, 1.0], n - 3) - rng.choice([0.0, 1e-8, 1e-4, 1e-2], n - 3) * np.sign(
            rng.normal(size=n - 3))
        t = rng.choice([np.pi / 2, -np.pi / 2, rng.uniform(-np.pi, np.pi)]) + rng.choice([0.0, 1e-10, -1e-6])
        a = np.append(np.clip(lat, -np.pi / 2, np.pi / 2), t)
        p = atlas.get_point(int(rng.integers(n)), a)
        for chart in atlas.charts:
            rough = chart.approximate_parameters(p)
            q_rough, q_full = float(chart.quality(rough)), float(chart.quality(chart.polish_parameters(rough, p)))
            if max(q_rough, q_full) >= 0.25:
                worst = max(worst, abs(q_rough - q_full))
    return worst


def main(n: int = 4, L: float | None = None, T: float = 3000.0, T_switch: float = 300.0) -> dict:
    L = n - 1.4 if L is None else L
    chain = Chain(n, L)
    metric = chain.metric()
    atlas = metric.atlas
    full_metric = InducedMetric(FullDefinitionAtlas(n, L), chain.ambient_metric)
    a = np.append(np.full(n - 3, 0.3), 0.4)
    p0 = atlas.get_point(0, a)
    v0 = atlas.charts[0].tangent_vector(a, np.resize([0.7, -0.4], n - 2))
    v0 /= np.sqrt(2 * metric.ambient_kinetic_energy(v0))  # unit kinetic speed
    solve_chart_exp_ode(metric, p0, v0, 1.0)  # compile, warm every cache
    solve_chart_exp_ode(full_metric, p0, v0, 1.0)
    fast, full = _side_by_side([lambda: atlas.best_chart(p0), lambda: full_metric.atlas.chart_choice(p0)])
    start, start_full = _side_by_side([lambda: solve_chart_exp_ode(metric, p0, v0, 1e-6),
                                       lambda: solve_chart_exp_ode(full_metric, p0, v0, 1e-6)])
    (switch, share, n_sw), (switch_full, share_full, _) = switch_ms([metric, full_metric], p0, v0, T_switch)
    (_, share20, _), (_, share20_full, _) = switch_ms([metric, full_metric], p0, v0, 20.0)
    big = solve_chart_exp_ode(metric, p0, v0, T)
    with compiled(atlas.charts[0].family).integrator() as ta:
        order, decomposition = ta.order, len(ta.decomposition)
    minimum = (order + 1) * 2 * atlas.dim * 8
    ts = np.linspace(0, T, 20_000)
    evaluate = _median_seconds(lambda: big(ts), repeat=3)
    shift = polish_shift(n)
    root = Path(__file__).resolve().parent.parent
    loc = {pkg: sum(len(f.read_text().splitlines()) for f in (root / pkg).glob("*.py"))
           for pkg in ("manifold", "charts", "linkage")}
    out = {"best_chart_ms": 1e3 * fast, "best_chart_full_ms": 1e3 * full, "start_ms": 1e3 * start,
           "start_full_ms": 1e3 * start_full, "switch_ms": switch, "switch_full_ms": switch_full,
           "share": share, "share_full": share_full, "share_T20": share20, "share_T20_full": share20_full,
           "polish_shift": shift, "decomposition": decomposition,
           "dense_bytes_per_step": big.dense_nbytes / big.n_steps, "dense_minimum_bytes_per_step": minimum,
           "eval_20000_s": evaluate, "steps": big.n_steps, "switches": big.n_switches, "loc": loc}
    print(f"n = {n}, L = {L:g}, unit kinetic speed")
    print(f"  {'':40} {'fast':>9} {'full def.':>9} {'ratio':>6}")
    rows = [("best_chart (CPU ms)", 1e3 * fast, 1e3 * full), ("start (CPU ms, solve to T = 1e-6)", 1e3 * start, 1e3 * start_full),
            (f"switch (wall ms, {n_sw} switches to T = {T_switch:g})", switch, switch_full),
            (f"starts + switches, % of wall, T = {T_switch:g}", 100 * share, 100 * share_full),
            ("starts + switches, % of wall, T = 20", 100 * share20, 100 * share20_full)]
    for label, new, old in rows:
        print(f"  {label:40} {new:9.3f} {old:9.3f} {old / new:6.1f}")
    print(f"  T = {T:g}: {big.n_steps} steps, {big.n_switches} switches")
    print(f"  polish shift of a quality > 0.25         {shift:9.1e}   (QUALITY_MARGIN {QUALITY_MARGIN:g})")
    print(f"  integrator decomposition                 {decomposition:9d}   (order {order})")
    print(f"  dense output                             {out['dense_bytes_per_step']:9.0f} B/step (minimum {minimum} B)")
    print(f"  sol(ts), 20000 times                     {evaluate:9.3f} s")
    print(f"  lines of code                            {loc}", flush=True)
    return out


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, nargs="+", default=[4, 8])
    parser.add_argument("--L", type=float, default=None, help="base length (default n - 1.4)")
    parser.add_argument("--T", type=float, default=3000.0, help="horizon of the dense-output and sol(ts) run")
    parser.add_argument("--T-switch", type=float, default=300.0, help="horizon of the runs that time switches")
    args = parser.parse_args()
    for n in args.n:
        main(n, args.L, args.T, args.T_switch)
