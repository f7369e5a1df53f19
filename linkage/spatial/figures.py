"""Figures of the spatial tutorial: bond diagrams of the paper's examples, a moving Bennett linkage.

Run ``python -m linkage.spatial.figures [output directory]`` (default ``docs/figures``).
Writes ``spatial_bond_diagrams.png``, ``bennett_poses.png`` and ``bennett.gif``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .draw import draw_bond_diagram, draw_linkage, link_segments
from .examples import bennett, example_11, example_12, planar_four_bar, spherical_four_bar


def bond_diagrams(path: Path) -> None:
    """Write the bond diagrams of Examples 1, 2, 3, 11 and 12 side by side to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chains = [
        ("Bennett (Ex. 1)", bennett()),
        ("spherical four-bar (Ex. 2)", spherical_four_bar()),
        ("planar four-bar (Ex. 3)", planar_four_bar()),
        ("6R of Example 11", example_11()),
        ("6R of Example 12", example_12()),
    ]
    fig, axs = plt.subplots(1, len(chains), figsize=(3.2 * len(chains), 3.4))
    for ax, (title, chain) in zip(axs, chains):
        draw_bond_diagram(ax, chain.n, chain.connections(), title=title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _bennett_frames(count: int):
    """Real configurations ``t = t_4 = cot(phi/2)`` for ``phi`` evenly spaced (``t = inf`` at ``phi = 0``)."""
    chain = bennett()
    curve = chain.configuration_curve()
    phis = np.linspace(0, 2 * np.pi, count, endpoint=False)
    frames = []
    for phi in phis:
        if np.isclose(np.sin(phi / 2), 0):
            frames.append(curve.places(complex("inf"))[0].joint_values())
        else:
            frames.append(curve(np.cos(phi / 2) / np.sin(phi / 2)))
    return chain, frames


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


def bennett_poses(path: Path) -> None:
    """Write eight poses of the Bennett linkage of Example 1 along its real curve to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    chain, frames = _bennett_frames(8)
    fig = plt.figure(figsize=(6, 6))
    ax = fig.add_subplot(projection="3d")
    colors = plt.get_cmap("viridis")(np.linspace(0, 1, len(frames)))
    for joints, color in zip(frames, colors):
        draw_linkage(ax, chain, joints, color=color, alpha=0.8, axis_length=1.5)
    _frame_axes(ax, chain, frames)
    ax.set_title("Bennett linkage of Example 1: eight poses along its real curve")
    fig.savefig(path, dpi=110)
    plt.close(fig)


def bennett_animation(path: Path, frames: int = 48) -> None:
    """Write the Bennett linkage moving once around its real curve to ``path`` (a GIF of ``frames`` frames)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    chain, poses = _bennett_frames(frames)
    fig = plt.figure(figsize=(5, 5))
    ax = fig.add_subplot(projection="3d")

    def update(k):
        ax.cla()
        draw_linkage(ax, chain, poses[k], axis_length=1.5)
        _frame_axes(ax, chain, poses)
        t4 = poses[k][3]
        ax.set_title(f"Bennett linkage, t4 = {t4.real:+.2f}" if np.isfinite(abs(t4)) else "Bennett linkage, t4 = inf")

    FuncAnimation(fig, update, frames=len(poses)).save(path, writer=PillowWriter(fps=12))
    plt.close(fig)


def main(argv: list[str]) -> None:
    """The command line: ``argv[0]`` is the output directory (default ``docs/figures``)."""
    out = Path(argv[0]) if argv else Path("docs/figures")
    out.mkdir(parents=True, exist_ok=True)
    bond_diagrams(out / "spatial_bond_diagrams.png")
    bennett_poses(out / "bennett_poses.png")
    bennett_animation(out / "bennett.gif")
    print(f"wrote spatial_bond_diagrams.png, bennett_poses.png, bennett.gif to {out}")


if __name__ == "__main__":
    main(sys.argv[1:])
