"""Motion between two configurations: a continuous feasible path, straight in the diagonals.

A configuration is a point ``x`` of the diagonal polytope ``D`` with a flip
vector ``sigma`` (:mod:`linkage.diagonals`).  With the flips fixed, a straight
segment of ``D`` (convex) is a continuous path of closed configurations.  Flip
``sigma_k`` can change only where fan triangle ``T_k`` is flat (one of its slacks
``u_k, v_k, w_k`` is 0: there both flips give the same configuration), so a path
from ``(x0, sigma0)`` to ``(x1, sigma1)`` goes straight to a point of ``D``
where ``T_k`` is flat, changes ``sigma_k`` there, and so on for each flip that
differs, then straight to ``x1``.

The configuration space is ``2^(n-1)`` copies of ``D`` glued along those flat
facets, so two configurations lie in one connected component exactly when their
flips differ only at triangles that can be flat somewhere in ``D``.  A triangle
that is never flat keeps its flip on the whole component: configurations whose
flips differ there are in different components, and no path exists.

The flat point of ``T_k`` is the centre of the facet (the point of the facet
farthest from ``D``'s other walls, by a linear program), with the facet's
equation then made exact by recomputing one diagonal: a flip taken where the
triangle is flat only to the program's 1e-9 would jump by ``sqrt(1e-9)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linprog

from .diagonals import WALL_RTOL, DiagonalSpace, diagonals, from_diagonals, triangle_slacks

__all__ = ["DiagonalPath", "DifferentComponentsError", "diagonal_path"]

_SLACKS = ("u", "v", "w")


class DifferentComponentsError(ValueError):
    """Two configurations lie in different connected components of the configuration space: no path joins them."""


@dataclass(frozen=True)
class DiagonalPath:
    """A continuous path of closed configurations, straight in the diagonals within each flip vector.

    Attributes
    ----------
    space
        The :class:`~linkage.diagonals.DiagonalSpace` of the chain.
    corners
        The free diagonals at the ends of the straight pieces, ``(m + 1, n-2)``.
    flips
        The flip vector of each piece, ``(m, n-1)``; consecutive pieces differ in at most one flip,
        changed at a corner where that triangle is flat.
    ends
        The configurations joined, ``(2, n-1)`` complex, returned exactly at ``s = 0`` and ``s = 1`` rather than
        rebuilt from the end corners: rebuilding a configuration from its own diagonals amplifies their rounding
        near a wall, at a triangle slack of 3e-7 (``L = 0.001``) by 4e4, to 1.7e-11.
    """

    space: DiagonalSpace
    corners: NDArray
    flips: NDArray
    ends: NDArray

    @property
    def lengths(self) -> NDArray:
        """The Euclidean length of each piece in the diagonals."""
        return np.linalg.norm(np.diff(self.corners, axis=0), axis=1)

    def __repr__(self) -> str:
        return (f"DiagonalPath({len(self.flips)} pieces, {int(np.sum(np.any(np.diff(self.flips, axis=0), axis=1)))} "
                f"flip changes, length {float(self.lengths.sum()):.4g} in the diagonals)")

    def __call__(self, s: ArrayLike) -> NDArray:
        """Complex hinges at path parameters ``s`` in ``[0, 1]`` (proportional to length in the diagonals), shape
        ``s.shape + (n-1,)``."""
        ss = np.asarray(s, dtype=float)
        bad = ~((ss >= 0) & (ss <= 1))
        if np.any(bad):
            raise ValueError(f"s must lie in [0, 1], got {ss[bad].ravel()[0]!r}")
        ends = np.concatenate([[0.0], np.cumsum(self.lengths)])
        total = ends[-1]
        at = ss.ravel() * total
        piece = np.clip(np.searchsorted(ends, at, side="right") - 1, 0, len(self.flips) - 1)
        span = np.where(self.lengths[piece] > 0, self.lengths[piece], 1.0)
        frac = np.clip((at - ends[piece]) / span, 0.0, 1.0)[:, None]
        x = (1 - frac) * self.corners[piece] + frac * self.corners[piece + 1]
        hinges = from_diagonals(self.space.lengths, self.space.L, x, self.flips[piece])
        flat = ss.ravel()
        hinges[flat == 0.0] = self.ends[0]
        hinges[flat == 1.0] = self.ends[1]
        return hinges.reshape(*ss.shape, -1)


def _flat_point(space: DiagonalSpace, k: int) -> tuple[NDArray | None, bool]:
    """A point of ``D`` where fan triangle ``T_k`` (``k = 2..n``) is flat, exactly, or ``None``; and whether ``T_k``
    is flat anywhere in ``D`` at all.

    For each slack ``j`` of ``T_k``: maximise the distance ``t`` to ``D``'s other walls on the facet ``slack_j = 0``;
    take the facet with the largest ``t > 0``, then make its equation exact.  A facet that meets ``D`` only with
    ``t = 0`` (a face of lower dimension: there a diagonal vanishes, ``p_k`` passes through the pin ``0``, and the
    fan angles are undefined) counts as flat but gives no point.
    """
    rows = 3 * (k - 2) + np.arange(3)
    norms = np.linalg.norm(space.A, axis=1)
    best, margin, touches = None, WALL_RTOL * (space.lengths.sum() + space.L), False
    for j, row in enumerate(rows):
        if not np.any(space.A[row]):
            continue  # a slack of the fixed ends alone (n = 2 only)
        others = np.array([r for r in range(len(space.b)) if r != row])
        cost = np.zeros(space.dim + 1)
        cost[-1] = -1.0
        res = linprog(cost, A_ub=np.column_stack([space.A[others], norms[others]]), b_ub=space.b[others],
                      A_eq=np.append(space.A[row], 0.0)[None, :], b_eq=[space.b[row]],
                      bounds=[(None, None)] * space.dim + [(0, None)])
        touches |= bool(res.success)
        if res.success and res.x[-1] > margin:
            best, margin = _exact_on_facet(space, k, j, res.x[:-1]), res.x[-1]
    return best, touches


def _exact_on_facet(space: DiagonalSpace, k: int, j: int, x: NDArray) -> NDArray:
    """``x`` with slack ``j`` of ``T_k`` exactly 0: ``d_k = d_{k-1} + l_k`` (u), ``d_{k-1} = d_k + l_k`` (v),
    ``d_{k-1} + d_k = l_k`` (w), solved for a free diagonal (``d_k`` unless it is the fixed base ``L``)."""
    n, l = space.n, space.lengths[k - 1]
    d = np.concatenate([[space.lengths[0]], x, [space.L]])  # d[m - 1] = d_m, m = 1..n
    a, c = d[k - 2], d[k - 1]
    free = k - 1 if k < n else k - 2  # solve for c = d_k, or for a = d_{n-1} where d_n = L is fixed
    d[free] = ({0: a + l, 1: a - l, 2: l - a} if k < n else {0: c - l, 1: c + l, 2: l - c})[j]
    # Numerical trap: the rounded solution can leave the slack at +1 ulp, and a slack of 1e-16 is an angle of 1e-8:
    # step the diagonal by ulps until the slack is <= 0 (from_diagonals then takes the triangle as exactly flat)
    # d slack_j / d free: u = a + l - c, v = c + l - a, w = a + c - l
    rises = {0: free != k - 1, 1: free == k - 1, 2: True}[j]
    for _ in range(8):
        if triangle_slacks(d[k - 2], l, d[k - 1])[j] <= 0:
            break
        d[free] = np.nextafter(d[free], -np.inf if rises else np.inf)
    return d[1:-1]


def diagonal_path(space: DiagonalSpace, hinges0: ArrayLike, hinges1: ArrayLike) -> DiagonalPath:
    """A continuous path from ``hinges0`` to ``hinges1`` (complex, ``(n-1,)``): see the module docstring.

    Raises
    ------
    DifferentComponentsError
        If the configurations lie in different connected components (a triangle
        whose flips differ is flat nowhere in ``D``), naming the triangle.
    NotImplementedError
        If a triangle whose flips differ is flat only on a face of lower dimension (where a
        diagonal vanishes): the configurations are in one component, but that crossing is not built.
    """
    x0, s0 = diagonals(space.lengths, space.L, hinges0)
    x1, s1 = diagonals(space.lengths, space.L, hinges1)
    if x0.ndim != 1 or x1.ndim != 1:
        raise ValueError(f"hinges0 and hinges1 must each be one configuration, shape (n - 1,); got {np.shape(hinges0)} "
                         f"and {np.shape(hinges1)}")
    corners, flips = [x0], [s0]
    for t in np.nonzero(s0 != s1)[0]:
        k = int(t) + 2
        flat, touches = _flat_point(space, k)
        if flat is None and touches:
            raise NotImplementedError(
                f"fan triangle T_{k} is flat only where a diagonal vanishes (p_{k - 1} or p_{k} at the pin 0, a face of "
                f"lower dimension of the diagonal space): hinges0 and hinges1 lie in one component, but a path through "
                f"that face is not built")
        if flat is None:
            raise DifferentComponentsError(
                f"hinges0 and hinges1 lie in different connected components: fan triangle T_{k} (0, p_{k - 1}, p_{k}) "
                f"turns one way in hinges0 and the other in hinges1 (flips {int(s0[t]):+d}, {int(s1[t]):+d}), and it "
                f"is flat nowhere in the diagonal space of lengths {tuple(float(v) for v in space.lengths)}, "
                f"L = {space.L:g}")
        changed = flips[-1].copy()
        changed[t] = s1[t]
        corners.append(flat)
        flips.append(changed)
    corners.append(x1)
    ends = np.array([np.asarray(hinges0, dtype=complex), np.asarray(hinges1, dtype=complex)])
    return DiagonalPath(space, np.array(corners), np.array(flips), ends)
