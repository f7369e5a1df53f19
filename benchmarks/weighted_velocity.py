"""The chart path's two velocity states side by side: ``(a, V)``, ``V = J c``, against the mass-weighted ``(a, w)``.

Run ``python -m benchmarks.weighted_velocity [--starts 8] [--repeats 3] [--T 20]``.  For each mass model and
n = 4, 5, 6: ``--starts`` chains and unit-speed starts (``L`` uniform in ``(n - 2 + 0.3, n - 0.3)``; hinge masses
log-uniform over 1e-4..1e3, the same with rod densities log-uniform over 1e-3..1, or unit masses), each solved over
T in Sundman's time (the default chart stepper) with the state ``(a, V)``
(:class:`manifold.ambient_velocity.ConstrainedVelocity`) and ``(a, w)``
(:class:`manifold.weighted_velocity.WeightedVelocity`), interleaved, the CPU time the minimum of ``--repeats``
runs (``--states V,w,c`` adds ``(a, c)``, the default with rod densities).  Prints per model and n: the relative
energy errors (median and largest over the starts; ``inf``: the run failed its own energy check) of each state, its
total CPU time and steps, and the last state's CPU time over the first's.  Compiles are made before the timing.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.time_factor import ChainTimeFactor
from manifold import SaveAt, solve_chart_exp_ode
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.sundman import SundmanStepper
from manifold.weighted_velocity import WeightedVelocity

from .starts import chart_start

MODELS = ("spread", "spread+rods", "unit")


def draw(n: int, model: str, rng: np.random.Generator) -> tuple[Chain, np.ndarray, np.ndarray]:
    """A chain of the mass ``model`` and a unit-speed start in chart 0 (complex hinges and velocities)."""
    L = rng.uniform(n - 2 + 0.3, n - 0.3)
    masses = np.ones(n - 1) if model == "unit" else 10.0 ** rng.uniform(-4, 3, n - 1)
    densities = 10.0 ** rng.uniform(-3, 0, n) if model == "spread+rods" else 0.0
    chain = Chain(n, L, hinge_masses=masses, rod_densities=densities)
    h0, v0 = chart_start(chain, rng)
    return chain, h0, v0


def steppers(chain: Chain, states: tuple[str, ...] = ("V", "w")) -> dict[str, SundmanStepper]:
    """The default chart stepper (Sundman's time) with each of the ``states``: ``V``, ``w``, and ``c`` (the state
    ``(a, c)``, the default with rod densities)."""
    system, factor = ChainSystem(chain), ChainTimeFactor(chain)
    velocities = {"V": lambda: ConstrainedVelocity(system), "w": lambda: WeightedVelocity(system, block=2),
                  "c": lambda: None}
    return {name: SundmanStepper(factor, velocity=velocities[name]()) for name in states}


def compare(n: int, model: str, starts: int, repeats: int, T: float, states: tuple[str, ...] = ("V", "w"),
            seed: int = 0) -> dict[str, list]:
    """Energy errors, steps and minimum CPU times of the ``states`` on ``starts`` draws (interleaved)."""
    rng = np.random.default_rng([seed, n, MODELS.index(model)])
    out: dict[str, list] = {key: [] for name in states for key in (name, f"{name}_cpu", f"{name}_steps")}
    for _ in range(starts):
        chain, h0, v0 = draw(n, model, rng)
        x0, u0 = chain.to_point(h0), chain.to_point(v0)
        runs = steppers(chain, states)
        for stepper in runs.values():  # compile outside the timing
            solve_chart_exp_ode(chain.metric(), x0, u0, 0.01, stepper=stepper)
        cpu: dict[str, list[float]] = {name: [] for name in runs}
        for _ in range(repeats):
            for name, stepper in runs.items():
                t0 = time.process_time()
                sol = solve_chart_exp_ode(chain.metric(), x0, u0, T, stepper=stepper, save=SaveAt(dense=False),
                                          throw=False)
                cpu[name].append(time.process_time() - t0)
                error = sol.relative_energy_error if sol.success else float("inf")
                if len(cpu[name]) == 1:
                    out[name].append(error)
                    out[f"{name}_steps"].append(sol.stats.n_steps if sol.stats is not None else 0)
        for name in runs:
            out[f"{name}_cpu"].append(min(cpu[name]))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--T", type=float, default=20.0)
    ap.add_argument("--ns", default="4,5,6")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--states", default="V,w", help="V: (a, J c); w: (a, R J c); c: (a, c)")
    args = ap.parse_args()
    states = tuple(args.states.split(","))
    print(f"T = {args.T:g}, {args.starts} starts per row, CPU time the minimum of {args.repeats} interleaved runs; "
          f"per state: energy error median / max, total CPU (s), total steps; the last, CPU / the first's")
    for model in args.models.split(","):
        for n in (int(x) for x in args.ns.split(",")):
            r = compare(n, model, args.starts, args.repeats, args.T, states)
            cells = [f"{s}: {np.median(r[s]):.1e} / {np.max(r[s]):.1e}, {sum(r[s + '_cpu']):.3f} s, "
                     f"{sum(r[s + '_steps'])}" for s in states]
            ratio = sum(r[states[-1] + "_cpu"]) / sum(r[states[0] + "_cpu"])
            print(f"{model:12s} n = {n}   {'   '.join(cells)}   ({ratio:.3f})", flush=True)
            for s in states:
                print(f"    per start, {s}: {' '.join(f'{e:.1e}' for e in r[s])}", flush=True)


if __name__ == "__main__":
    main()
