"""Matplotlib drawings of chain configurations (pins, rods, hinges).

matplotlib is imported inside the functions that need it, so that
``import linkage`` does not load a plotting library.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def _full_chain(hinges: ArrayLike, L: float) -> np.ndarray:
    h = np.asarray(hinges, dtype=complex)
    return np.concatenate([[0.0], h, [L]])


def draw_configuration(
    ax: Axes, hinges: ArrayLike, L: float, color: str = "C0", alpha: float = 1.0, label: str | None = None
) -> Axes:
    """Draw one configuration on ``ax``: rods as lines, hinges as dots, pins as triangles.

    Parameters
    ----------
    ax
        A matplotlib ``Axes``.
    hinges
        Complex interior hinges ``p_1 .. p_{n-1}``.
    L
        Position of the right pin on the real axis.
    color, alpha, label
        Passed to ``ax.plot`` for the rods (the hinges share color and alpha).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``, with equal aspect.
    """
    p = _full_chain(hinges, L)
    ax.plot(p.real, p.imag, "-", color=color, lw=2, alpha=alpha, label=label)
    ax.plot(p.real[1:-1], p.imag[1:-1], "o", color=color, ms=4, alpha=alpha)
    ax.plot([0, L], [0, 0], "k^", ms=9)
    ax.set_aspect("equal")
    return ax


def draw_configurations(
    ax: Axes, configurations: Sequence[ArrayLike], L: float, cmap: str = "viridis", labels: Sequence[str] | None = None
) -> Axes:
    """Overlay several configurations on ``ax``, coloured along ``cmap`` in order.

    Parameters
    ----------
    ax
        A matplotlib ``Axes``.
    configurations
        Complex interior hinges of each configuration.
    L
        Position of the right pin on the real axis.
    cmap
        Name of a matplotlib colormap; configuration ``k`` of ``m`` gets its colour at ``k / (m - 1)``.
    labels
        One legend label per configuration (no legend if ``None``).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.
    """
    import matplotlib  # here, not at module level: ``import linkage`` must not load a plotting library

    colors = matplotlib.colormaps[cmap](np.linspace(0, 1, max(len(configurations), 1)))
    for k, h in enumerate(configurations):
        draw_configuration(ax, h, L, color=colors[k], alpha=0.85, label=None if labels is None else labels[k])
    if labels is not None:
        ax.legend(fontsize="small")
    return ax
