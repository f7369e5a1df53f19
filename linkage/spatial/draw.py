"""Drawings: bond diagrams and poses of spatial linkages (matplotlib, imported lazily).

Nothing here imports matplotlib at module import time; the functions take a
matplotlib ``Axes`` made by the caller (a 3-d one for :func:`draw_linkage`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["draw_bond_diagram", "draw_linkage", "link_segments"]


def draw_bond_diagram(
    ax: Any, n: int, connections: dict[tuple[int, int], int], title: str | None = None, color: str = "C3"
) -> Any:
    """Draw a bond diagram ([HSS] Section 3.4) on ``ax``.

    The links ``o_1 .. o_n`` are the vertices of a regular polygon, the joint
    ``h_i`` is the edge between ``o_{i-1}`` and ``o_i``.  For each entry
    ``(i, j): k`` of ``connections`` (``RevoluteChain.connections()``), ``|k|``
    curves join the midpoints of the edges ``h_i`` and ``h_j``, dashed when ``k < 0``.

    Parameters
    ----------
    ax
        A matplotlib ``Axes``.
    n
        Number of joints, ``>= 3``.
    connections
        ``{(i, j): k}`` with 1-based joints ``1 <= i < j <= n``.
    """
    if not isinstance(n, (int, np.integer)) or n < 3:
        raise ValueError(f"n must be an integer >= 3; got {n!r}")
    for (i, j), k in connections.items():
        if not (1 <= i <= n and 1 <= j <= n and i != j):
            raise ValueError(f"connection {(i, j)} names joints outside 1..{n}")
    angle = np.pi / 2 + 2 * np.pi * np.arange(n) / n
    vertex = np.exp(1j * angle)  # vertex[i-1] = o_i
    mid = {i: (vertex[(i - 2) % n] + vertex[i - 1]) / 2 for i in range(1, n + 1)}  # edge h_i
    closed = np.append(vertex, vertex[0])
    ax.plot(closed.real, closed.imag, "k-", lw=2)
    ax.plot(vertex.real, vertex.imag, "ko", ms=7)
    for i in range(1, n + 1):
        ax.annotate(f"$o_{{{i}}}$", (1.16 * vertex[i - 1].real, 1.16 * vertex[i - 1].imag), ha="center", va="center")
        ax.annotate(f"$h_{{{i}}}$", (1.1 * mid[i].real, 1.1 * mid[i].imag), ha="center", va="center", color="0.35")
    for (i, j), k in sorted(connections.items()):
        a, b = mid[i], mid[j]
        for m in range(abs(k)):
            bend = 0.18 * (m - (abs(k) - 1) / 2)  # several lines fan out
            ctrl = (a + b) / 2 + bend * 1j * (b - a)
            s = np.linspace(0, 1, 40)
            curve = (1 - s) ** 2 * a + 2 * s * (1 - s) * ctrl + s**2 * b
            ax.plot(curve.real, curve.imag, "--" if k < 0 else "-", color=color, lw=1.5)
        ax.plot([a.real, b.real], [a.imag, b.imag], "o", color=color, ms=4)
    ax.set_aspect("equal")
    ax.axis("off")
    if title:
        ax.set_title(title)
    return ax


def _line_points(h) -> tuple:
    d = np.array([float(x) for x in h.primal[1:]])
    m = -np.array([float(x) for x in h.dual[1:]])
    return np.cross(d, m), d  # closest point to the origin, direction


def _common_normal_foot(p1, d1, p2, d2) -> np.ndarray:
    """Point of line 1 closest to line 2 (the foot of the common normal; any point if parallel)."""
    b = float(d1 @ d2)
    w0 = p1 - p2
    if abs(1 - b * b) < 1e-12:
        return p1
    s = (b * float(d2 @ w0) - float(d1 @ w0)) / (1 - b * b)
    return p1 + s * d1


def link_segments(chain: Any, joints: Sequence[Any]) -> tuple[list, list]:
    """Links and joint axes at a configuration, as 3-d segments in the frame of link ``o_n``.

    Link ``o_j`` carries the axes ``h_j`` and ``h_{j+1}``; it is drawn as the
    common normal of the two in the home pose, moved by
    ``F_nj = prod_{k=1..j} (t_k - h_k)`` (the pose of ``o_j`` relative to ``o_n``).

    Returns
    -------
    links, axes
        ``links[j-1] = (start, end)`` for ``o_j``; ``axes[k-1] = (point, unit direction)``
        for the axis ``h_k`` in its current position.
    """
    from .dualquat import DualQuaternion

    n = chain.n
    lines = [_line_points(h) for h in chain.axes]
    hs = [h.map(float) for h in chain.axes]
    poses = []  # poses[j-1]: pose of o_j relative to o_n
    pose = DualQuaternion.scalar(1.0)
    for j in range(1, n + 1):
        t = complex(joints[j - 1])
        if not np.isinf(abs(t)):
            pose = pose * (t.real - hs[j - 1])
        poses.append(pose if j < n else DualQuaternion.scalar(1.0))

    def move(h, x):
        return np.array(h.act([float(v) for v in x]), dtype=float)

    links, axes = [], []
    for j in range(1, n + 1):
        (p1, d1), (p2, d2) = lines[j - 1], lines[j % n]
        a, b = _common_normal_foot(p1, d1, p2, d2), _common_normal_foot(p2, d2, p1, d1)
        links.append((move(poses[j - 1], a), move(poses[j - 1], b)))
        p, d = lines[j % n]  # axis h_{j+1}, carried by o_j
        q0, q1 = move(poses[j - 1], b), move(poses[j - 1], b + d)
        axes.append((q0, q1 - q0))
    return links, axes[-1:] + axes[:-1]


def draw_linkage(
    ax: Any, chain: Any, joints: Sequence[Any], color: str = "C0", alpha: float = 1.0, axis_length: float = 1.0
) -> Any:
    """Draw links (thick), offsets along the axes (thick) and the axes (thin) on a 3-d ``Axes``."""
    links, axes = link_segments(chain, joints)
    n = chain.n
    for j, (a, b) in enumerate(links):
        nxt = links[(j + 1) % n][0]  # o_{j+1} starts on the axis where o_j ends
        ax.plot(*np.array([a, b, nxt]).T, "-", color=color, lw=3, alpha=alpha)
    for point, direction in axes:
        ends = np.array([point - axis_length * direction, point + axis_length * direction])
        ax.plot(*ends.T, "k-", lw=0.8, alpha=alpha)
    return ax
