"""Worked example of a chain of unequal rods: topology as ``L`` varies, the diagonal polytope, sampling.

Run ``python -m linkage.diagonal_demo`` (default lengths ``(1, 2, 1.5, 2.5, 1.2)``,
``L = 3``).  It prints the topology on every interval of ``L`` between the
critical values (where a signed sum ``sum_k eps_k l_k = L`` makes the space
singular), the volume of ``D``, samples in both measures, and writes
``docs/figures/diagonal_polytope.png``.  The outputs in ``docs/diagonals.md``
come from this script.  matplotlib is imported only inside :func:`plot_diagonal_polytope`.
"""

from __future__ import annotations

import argparse
import itertools
import os
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from .diagonals import DiagonalSample, DiagonalSpace
from .topology import Topology, topology

EXAMPLE = (1.0, 2.0, 1.5, 2.5, 1.2)
FIGURE = Path(__file__).resolve().parent.parent / "docs" / "figures" / "diagonal_polytope.png"


def critical_bases(lengths: ArrayLike) -> np.ndarray:
    """The ``L > 0`` at which the space is not generic: ``|sum_k eps_k l_k|``, sorted, distinct."""
    ls = np.asarray(lengths, dtype=float)
    sums = {round(abs(float(np.dot(eps, ls))), 12) for eps in itertools.product((-1, 1), repeat=ls.size)}
    return np.array(sorted(v for v in sums if v > 0))


def topology_table(lengths: ArrayLike) -> list[tuple[str, Topology]]:
    """``(range of L, topology)``: at each critical ``L`` and at the midpoint of each interval between them."""
    crit = critical_bases(lengths)
    rows, prev = [], 0.0
    for c in crit:
        rows.append((f"{prev:g} < L < {c:g}", topology(lengths, (prev + c) / 2)))
        rows.append((f"L = {c:g}", topology(lengths, c)))
        prev = c
    rows.append((f"L > {prev:g}", topology(lengths, prev + 1)))
    return rows


def polytope_edges(space: DiagonalSpace) -> list[tuple[np.ndarray, np.ndarray]]:
    """Edges of ``D``: vertex pairs whose common tight constraints have rank ``dim - 1``.

    The constraints tight at both ends are those tight at the midpoint of the
    segment, i.e. the equality set of the smallest face containing it, whose
    dimension is ``dim - rank``.
    """
    v = space.vertices()
    tight = space.slacks(v) <= 1e-9 * (space.lengths.sum() + space.L)
    edges = []
    for i, j in itertools.combinations(range(len(v)), 2):
        common = tight[i] & tight[j]
        if common.any() and np.linalg.matrix_rank(space.A[common]) == space.dim - 1:
            edges.append((v[i], v[j]))
    return edges


def plot_diagonal_polytope(space: DiagonalSpace, samples: dict[str, DiagonalSample], path: Path) -> None:
    """3-D scatter of ``x = (d_2, d_3, d_4)`` per sample set (one panel each), coloured by flip vector, with the edges of ``D``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import BoundaryNorm

    if space.dim != 3:
        raise ValueError(f"the polytope picture is 3-D: it needs n = 5 rods, got n = {space.n}")
    m = space.n - 1
    codes = 2 ** np.arange(m)[::-1]
    labels = ["".join("+" if (c >> (m - 1 - k)) & 1 else "-" for k in range(m)) for c in range(2**m)]
    norm = BoundaryNorm(np.arange(2**m + 1) - 0.5, 2**m)
    edges = polytope_edges(space)
    fig = plt.figure(figsize=(6.2 * len(samples) + 1.5, 5.8))
    for i, (title, s) in enumerate(samples.items()):
        ax = fig.add_subplot(1, len(samples), i + 1, projection="3d")
        colour = ((s.flips > 0) * codes).sum(axis=1)  # flip vector (sigma_2..sigma_5) read as binary, + = 1
        sc = ax.scatter(*s.x.T, c=colour, cmap="tab20", norm=norm, s=3, alpha=0.7, linewidths=0)
        for a, b in edges:
            ax.plot(*np.stack([a, b]).T, color="k", lw=0.8)
        ax.set_xlabel("$d_2$")
        ax.set_ylabel("$d_3$")
        ax.set_zlabel("$d_4$")
        ax.view_init(elev=22, azim=-58)
        ax.set_title(title, fontsize=10)
    cbar = fig.colorbar(sc, ax=fig.axes, shrink=0.75, pad=0.06, ticks=np.arange(2**m))
    cbar.ax.set_yticklabels(labels, fontsize=7, family="monospace")
    cbar.set_label(r"flip vector $(\sigma_2, \sigma_3, \sigma_4, \sigma_5)$")
    lengths = ", ".join(f"{v:g}" for v in space.lengths)
    n_each = len(next(iter(samples.values())))
    fig.suptitle(f"Diagonal polytope D of rods ({lengths}), L = {space.L:g}: {n_each} samples per panel, edges of D in black")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    """The command line ``python -m linkage.diagonal_demo`` (``argv``: its arguments; default ``sys.argv``)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lengths", type=float, nargs="+", default=list(EXAMPLE))
    parser.add_argument("--L", type=float, default=3.0)
    parser.add_argument("--samples", type=int, default=6000)
    parser.add_argument("--out", type=Path, default=FIGURE)
    args = parser.parse_args(argv)

    print("topology as L varies:")
    for label, t in topology_table(args.lengths):
        kind = t.kind if t.betti is None else f"{t.kind}, betti {t.betti}"
        print(f"  {label:>20}: {kind}")
    t = topology(args.lengths, args.L)
    print(f"\nL = {args.L:g}: {t}")
    space = DiagonalSpace(args.lengths, args.L)
    box = float(np.prod(space.upper - space.lower))
    print(f"{space}: cuboid {np.round(space.lower, 3)} .. {np.round(space.upper, 3)}, "
          f"volume {space.volume():.6g} of the cuboid's {box:.6g}")
    rng = np.random.default_rng(0)
    samples = {
        "x uniform in D (measure='lebesgue')": space.sample(args.samples, rng),
        "uniform in Riemannian volume (measure='riemannian')": space.sample(args.samples, rng, measure="riemannian"),
    }
    for s in samples.values():
        print(f"{s!r}: mean x = {np.round(s.x.mean(axis=0), 4)}")
    if space.dim == 3:
        plot_diagonal_polytope(space, samples, args.out)
        print(f"wrote {os.path.relpath(args.out)}")


if __name__ == "__main__":
    main()
