"""What ``animate(motion, "motion.gif")`` of the README example costs: ``python -m benchmarks.animate_cost [--rounds 3]``.

The README's motion (n = 5, ``L = 3.4``, rod densities 0.2, the chart method to T = 50: the chain and the
sphere panel) written two ways, interleaved round by round, CPU time of this process, the fastest of
``--rounds``, and the file's size:

* ``matplotlib``: :func:`linkage.draw.animation` saved by matplotlib's ``PillowWriter`` at 150 frames and 25
  fps (what ``animate`` did before: every frame redrawn whole, the 3-d panel included, and quantised by
  Pillow frame by frame with dithering);
* ``animate``: :func:`linkage.animate` with its defaults (100 frames at 20 fps, blitted frames, one palette).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from matplotlib.animation import PillowWriter

from linkage import Chain, animate, animation
from linkage.motion import ChainMotion, free_motion


def readme_motion() -> ChainMotion:
    """The README example's ``in_charts``."""
    chain = Chain(5, 3.4, hinge_masses=1.0, rod_densities=0.2)
    atlas = chain.atlas()
    p0 = atlas.get_point(0, np.array([np.pi / 2, 0.3, 1.0]))
    i = atlas.get_chart_index(p0)
    v0 = atlas.charts[i].tangent_vector(atlas.get_parameters(i, p0), np.array([1.0, -0.5, 0.3]))
    return free_motion(chain, chain.from_point(p0), chain.from_point(v0), 50.0, method="charts")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    motion = readme_motion()
    out = Path(tempfile.mkdtemp())
    ways = {
        "matplotlib": lambda path: animation(motion, frames=150, fps=25).save(path, writer=PillowWriter(fps=25),
                                                                             dpi=80),
        "animate": lambda path: animate(motion, path),
    }
    seconds: dict[str, list[float]] = {name: [] for name in ways}
    size: dict[str, int] = {}
    for _ in range(args.rounds):
        for name, write in ways.items():
            path = out / f"{name}.gif"
            t0 = time.process_time()
            write(path)
            seconds[name].append(time.process_time() - t0)
            size[name] = path.stat().st_size
    best = {name: min(s) for name, s in seconds.items()}
    print(f"README example, {args.rounds} interleaved rounds, fastest CPU time:")
    for name in ways:
        print(f"  {name:10s} {best[name]:7.2f} s  {size[name] / 1e6:6.2f} MB")
    print(f"  ratio      {best['matplotlib'] / best['animate']:7.1f}x faster, "
          f"{size['matplotlib'] / size['animate']:5.1f}x smaller")


if __name__ == "__main__":
    main()
