"""Figures of the spatial tutorial: bond diagrams, and linkages moving along their real curves.

Run ``python -m linkage.spatial.figures [output directory]`` (default ``docs/figures``).
Writes ``spatial_bond_diagrams.png`` and, for the Bennett linkage of Example 1, a
Goldberg 5R, Bricard's linkage (Example 13), a 6R from a cubic motion polynomial and
Waldron's double Bennett linkage, ``NAME_poses.png`` (eight poses) and ``NAME.gif`` (an animation beside its configuration
curve).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .draw import draw_bond_diagram, draw_linkage, link_segments
from .examples import (
    bennett,
    bricard_example_13,
    cubic_6r,
    double_bennett_6r,
    example_11,
    example_12,
    goldberg_5r,
    planar_four_bar,
    spherical_four_bar,
)


def bond_diagrams(path: Path) -> None:
    """Write the bond diagrams of Examples 1, 2, 3, 11, 12, 13, a Goldberg 5R, a cubic 6R and a double
    Bennett 6R to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chains = [
        ("Bennett (Ex. 1)", bennett()),
        ("spherical four-bar (Ex. 2)", spherical_four_bar()),
        ("planar four-bar (Ex. 3)", planar_four_bar()),
        ("6R of Example 11", example_11()),
        ("6R of Example 12", example_12()),
        ("Goldberg 5R (Fig. 1c)", goldberg_5r()[2]),
        ("Bricard (Ex. 13)", bricard_example_13()),
        ("6R from a cubic", cubic_6r()),
        ("double Bennett", double_bennett_6r()[2]),
    ]
    fig, axs = plt.subplots(3, 3, figsize=(9.6, 10.2))
    axs = axs.ravel()
    for ax, (title, chain) in zip(axs, chains):
        draw_bond_diagram(ax, chain.n, chain.connections(), title=title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def curve_frames(chain, count: int) -> list:
    """``count`` real configurations around one real component of the chain's curve.

    A rational curve is run through once with ``t = cot(phi/2)``, ``phi`` evenly spaced
    (``t = inf`` at ``phi = 0``).  On a curve ``w^2 = g(t)`` the longest bounded interval
    where ``g >= 0`` is an oval: branch ``w > 0`` from one root to the other, ``w < 0`` back.
    Frames where a joint is undetermined (a 0/0 base point of the formulas) are left out.
    """
    curve = chain.configuration_curve()
    if curve.is_rational:
        frames = []
        for phi in np.linspace(0, 2 * np.pi, count, endpoint=False):
            if np.isclose(np.sin(phi / 2), 0):
                frames.append(curve.places(complex("inf"))[0].joint_values())
            else:
                frames.append(curve(np.cos(phi / 2) / np.sin(phi / 2)))
    else:
        bounded = [(a, b) for a, b in curve.real_intervals() if np.isfinite(a) and np.isfinite(b)]
        if not bounded:
            raise NotImplementedError("no bounded real interval: the real curve passes t = inf only")
        a, b = max(bounded, key=lambda ab: ab[1] - ab[0])
        half = count // 2
        ts = a + (b - a) * (1 - np.cos(np.pi * (np.arange(half) + 0.5) / half)) / 2
        frames = [curve(t, 1) for t in ts] + [curve(t, -1) for t in ts[::-1]]
    return [f for f in frames if not any(np.isnan(complex(z)) for z in f)]


def _frame_axes(ax, chain, frames) -> None:
    """One cube around every pose, so that the animation does not rescale."""
    pts = np.array([p for joints in frames for seg in link_segments(chain, joints)[0] for p in seg])
    centre, half = (pts.max(0) + pts.min(0)) / 2, (pts.max(0) - pts.min(0)).max() / 2 + 1
    for set_lim, c in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), centre):
        set_lim(c - half, c + half)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_zticks([])


def poses_figure(path: Path, chain, title: str, count: int = 8) -> None:
    """Write ``count`` poses of ``chain`` along a real component of its curve to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    frames = curve_frames(chain, count)
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="3d")
    colors = plt.get_cmap("viridis")(np.linspace(0, 1, len(frames)))
    for joints, color in zip(frames, colors):
        draw_linkage(ax, chain, joints, color=color, alpha=0.8, axis_length=1.5)
    _frame_axes(ax, chain, frames)
    ax.set_title(title)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _angle(t: complex) -> float:
    """The joint angle ``phi`` in ``[0, 2 pi)`` of ``t = cot(phi / 2)`` (``t = inf``: ``phi = 0``)."""
    t = complex(t)
    return 0.0 if np.isinf(abs(t)) else float(2 * np.arctan2(1.0, t.real))


def animation(path: Path, chain, title: str, frames: int = 40) -> None:
    """Write ``chain`` moving once around a real component of its curve to ``path`` (a GIF).

    Left the linkage in space, right its configuration curve in the angles of joints 1
    and ``n`` (a torus, opened up) with the current configuration marked.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    poses = curve_frames(chain, frames)
    dense = curve_frames(chain, 8 * frames)
    fig = plt.figure(figsize=(8, 4))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax2 = fig.add_subplot(1, 2, 2)
    n = chain.n

    def update(k):
        ax.cla()
        draw_linkage(ax, chain, poses[k], axis_length=1.5)
        _frame_axes(ax, chain, poses)
        ax.set_title(title)
        ax2.cla()
        ax2.plot([_angle(p[0]) for p in dense], [_angle(p[n - 1]) for p in dense], ".", ms=1.5, color="0.6")
        ax2.plot([_angle(poses[k][0])], [_angle(poses[k][n - 1])], "o", color="C3")
        ax2.set_xlim(0, 2 * np.pi)
        ax2.set_ylim(0, 2 * np.pi)
        ax2.set_xlabel("phi_1")
        ax2.set_ylabel(f"phi_{n}")
        ax2.set_title("configuration curve")

    FuncAnimation(fig, update, frames=len(poses)).save(path, writer=PillowWriter(fps=12))
    plt.close(fig)


def main(argv: list[str]) -> None:
    """The command line: ``argv[0]`` is the output directory (default ``docs/figures``)."""
    out = Path(argv[0]) if argv else Path("docs/figures")
    out.mkdir(parents=True, exist_ok=True)
    bond_diagrams(out / "spatial_bond_diagrams.png")
    written = ["spatial_bond_diagrams.png"]
    moving = [
        ("bennett", bennett(), "Bennett linkage of Example 1"),
        ("goldberg", goldberg_5r()[2], "Goldberg 5R linkage"),
        ("bricard", bricard_example_13(), "Bricard's linkage (Example 13)"),
        ("cubic_6r", cubic_6r(), "6R from a cubic motion polynomial"),
        ("double_bennett", double_bennett_6r()[2], "Waldron's double Bennett linkage"),
    ]
    for name, chain, title in moving:
        poses_figure(out / f"{name}_poses.png", chain, f"{title}: poses along a real component")
        animation(out / f"{name}.gif", chain, title)
        written += [f"{name}_poses.png", f"{name}.gif"]
    print(f"wrote {', '.join(written)} to {out}")


if __name__ == "__main__":
    main(sys.argv[1:])
