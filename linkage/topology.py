"""Topology of the configuration space of a planar closed chain of any link lengths.

The chain has rods ``l_1 .. l_n`` pinned at ``0`` and ``L``; its polygon has the
``n + 1`` sides ``s = (l_1, ..., l_n, L)`` (index ``k - 1`` is rod ``l_k``, index
``n`` the base) and perimeter ``P``.  The configuration space (modulo nothing: the
base is pinned) is ``M = { sum_k e_k = L, |e_k| = l_k }``, of dimension ``n - 2``
where it is a manifold.  Rules (Kapovich-Millson; Farber-Schuetz):

* empty if some side ``s_j > P/2``; a single (collinear) point if ``s_j = P/2``;
* generic, a closed smooth manifold, iff no signed sum ``sum_k eps_k l_k - L``
  vanishes; otherwise the collinear configurations ``e_k = eps_k l_k`` with
  ``sum_k eps_k l_k = L`` are singular points;
* the sphere ``S^(n-2)`` if some side ``s_j`` has ``s_j < P/2 < s_j + s_i`` for
  every other side ``s_i`` (the dominant side; for unit rods ``n - 2 < L < n``);
* two tori ``T^(n-2)`` if three sides are long (each pair sums to more than
  ``P/2``).  For ``n = 2`` (a triangle) both hold, ``S^0`` is two points ``T^0``,
  and the kind reported is 'sphere'; for ``n >= 3`` they exclude each other
  (one component against two);
* generic Betti numbers ``b_i = a_i + a_{n-2-i}``, ``i = 0..n-2``, where ``a_i``
  counts the short subsets (sum ``< P/2``) of ``i + 1`` sides that contain a
  fixed longest side.

Equalities are decided to within ``rtol * P``; subsets are enumerated, so the cost
is ``O(2^n)`` (``n <= MAX_RODS``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.validation import check_real

from .lengths import sides, validate_lengths

MAX_RODS = 20
#: Signed sums and ``max s_j - P/2`` within ``RTOL * P`` of zero count as zero.
RTOL = 1e-12
#: Largest ``rtol`` taken: a tolerance of a tenth of the perimeter would call distinct topologies one.
MAX_RTOL = 1e-3


@dataclass(frozen=True)
class Topology:
    """What the configuration space of a chain is.

    Attributes
    ----------
    kind
        One of ``'empty', 'point', 'sphere', 'tori', 'manifold', 'singular'``.
    generic
        True iff the space is a smooth closed manifold of dimension ``n - 2``
        (no signed sum of the sides vanishes; ``False`` for 'empty' and 'point').
    components
        Number of connected components (``b_0``); ``None`` for 'singular'.
    betti
        ``(b_0, ..., b_{n-2})`` in the generic case, ``(1,)`` for a point, ``()``
        if empty, ``None`` for 'singular'.
    dominant_side
        For 'sphere': the index ``j`` of the side with ``s_j < P/2 < s_j + s_i``
        for all ``i != j`` (``k - 1`` for rod ``l_k``, ``n`` for the base ``L``;
        for ``n = 2`` every side qualifies and the base is reported).  ``None``
        otherwise.
    long_sides
        For 'tori': the indices of the three long sides; ``()`` otherwise.
    collinear
        Sign vectors ``eps`` (entries ``+-1``) of the collinear configurations
        ``e_k = eps_k l_k``, ``sum_k eps_k l_k = L``: the singular points of a
        'singular' space, or the only point of a 'point'; ``()`` otherwise.
    lengths, L
        The chain.
    """

    kind: str
    generic: bool
    components: int | None
    betti: tuple[int, ...] | None
    dominant_side: int | None
    long_sides: tuple[int, ...]
    collinear: tuple[tuple[int, ...], ...]
    lengths: tuple[float, ...]
    L: float

    @property
    def n(self) -> int:
        """Number of rods."""
        return len(self.lengths)

    @property
    def euler_characteristic(self) -> int | None:
        """``sum_i (-1)^i b_i`` where the Betti numbers are known."""
        return None if self.betti is None else sum((-1) ** i * b for i, b in enumerate(self.betti))

    def side_name(self, j: int) -> str:
        """``'l_k'`` for rod index ``j = k - 1``, ``'L'`` for the base ``j = n``."""
        return "L" if j == self.n else f"l_{j + 1}"

    def summary(self) -> str:
        """One line: the chain, the kind, and its invariants."""
        chain = f"lengths {tuple(float(v) for v in self.lengths)}, L = {self.L:g}"
        d = self.n - 2
        if self.kind == "empty":
            what = "empty (a side exceeds half the perimeter)"
        elif self.kind == "point":
            what = f"a single collinear point, rods {_signs(self.collinear[0])} along the base"
        elif self.kind == "singular":
            confs = "; ".join(f"rods {_signs(e)} along the base" for e in self.collinear[:4])
            more = f"; ... ({len(self.collinear) - 4} more)" if len(self.collinear) > 4 else ""
            what = f"singular (not a manifold) at {len(self.collinear)} collinear configuration(s): {confs}{more}"
        else:
            assert self.betti is not None  # only a singular space has no Betti numbers
            if self.kind == "sphere":
                assert self.dominant_side is not None  # a sphere has its dominant side
                shape = f"sphere S^{d}, dominant side {self.side_name(self.dominant_side)}"
            elif self.kind == "tori":
                names = ", ".join(self.side_name(j) for j in self.long_sides)
                shape = f"two tori T^{d}, long sides {names}"
            elif d == 2:
                shape = f"closed orientable surface of genus {self.betti[1] // 2}"
            else:
                shape = f"closed orientable {d}-manifold"
            what = f"{shape}, {self.components} component(s), betti {self.betti}"
        return f"{chain}: {what}"

    def __str__(self) -> str:
        return self.summary()


def _signs(eps: tuple[int, ...]) -> str:
    return "(" + ", ".join("+" if e > 0 else "-" for e in eps) + ")"


def _subset_sums(values: NDArray) -> tuple[NDArray, NDArray]:
    """Sums and sizes of all ``2^len(values)`` subsets; bit ``k`` of the index selects ``values[k]``."""
    sums, sizes = np.zeros(1), np.zeros(1, dtype=int)
    for v in values:
        sums, sizes = np.concatenate([sums, sums + v]), np.concatenate([sizes, sizes + 1])
    return sums, sizes


def longest_side(lengths: NDArray, L: float) -> tuple[int, float]:
    """Index ``j`` of a longest side and its excess ``s_j - P/2`` over half the perimeter.

    The polygon closes iff the excess is ``<= 0`` (each side at most the sum of
    the others); at ``0`` only collinearly.  Takes validated ``lengths`` and ``L``
    (:func:`~linkage.lengths.validate_lengths`).
    """
    s = sides(lengths, L)
    j = int(np.argmax(s))
    return j, float(s[j]) - float(s.sum()) / 2


def _collinear(lengths: NDArray, L: float, tol: float) -> tuple[tuple[int, ...], ...]:
    """All ``eps`` with ``|sum_k eps_k l_k - L| <= tol`` (the subset ``{eps_k = +1}`` sums to ``(sum l + L)/2``)."""
    plus, _ = _subset_sums(lengths)
    signed = 2 * plus - lengths.sum()
    hits = np.flatnonzero(np.abs(signed - L) <= tol)
    n = lengths.size
    return tuple(tuple(1 if (m >> k) & 1 else -1 for k in range(n)) for m in hits)


def _betti(s: NDArray, half: float) -> tuple[int, ...]:
    """Farber-Schuetz: ``b_i = a_i + a_{d-i}``, ``a_i`` = short subsets of size ``i+1`` containing a longest side."""
    j = int(np.argmax(s))
    sums, sizes = _subset_sums(np.delete(s, j))
    d = s.size - 3
    a = [int(np.count_nonzero((sizes == i) & (s[j] + sums < half))) for i in range(d + 1)]
    return tuple(a[i] + a[d - i] for i in range(d + 1))


def topology(lengths: ArrayLike, L: float, rtol: float = RTOL) -> Topology:
    """The topology of the configuration space of rods ``lengths`` pinned ``L`` apart.

    Parameters
    ----------
    lengths
        ``l_1 .. l_n``, finite and ``> 0``, ``2 <= n <= MAX_RODS``.
    L
        Distance of the pins, finite and ``> 0``.
    rtol
        Signed sums and ``max s_j - P/2`` within ``rtol * P`` of zero count as zero; in ``[0, MAX_RTOL]``.

    Returns
    -------
    Topology
        ``kind``, ``generic``, ``components``, ``betti``, ``dominant_side`` and a
        readable :meth:`Topology.summary`.
    """
    ls, L = validate_lengths(lengths, L)
    rtol = check_real("rtol", rtol, at_most=MAX_RTOL)
    if rtol < 0:
        raise ValueError(f"rtol must be a real number in [0, {MAX_RTOL:g}], got {rtol!r}")
    if ls.size > MAX_RODS:
        raise ValueError(f"topology enumerates 2^n subsets: n = len(lengths) must be <= {MAX_RODS}, got {ls.size}")
    s = sides(ls, L)
    P = float(s.sum())
    half, tol = P / 2, rtol * P
    base: dict[str, Any] = dict(lengths=tuple(float(v) for v in ls), L=L, dominant_side=None, long_sides=(), collinear=())
    _, excess = longest_side(ls, L)
    if excess > tol:
        return Topology("empty", False, 0, (), **base)
    collinear = _collinear(ls, L, tol)
    if excess >= -tol:
        return Topology("point", False, 1, (1,), **{**base, "collinear": collinear})
    if collinear:
        return Topology("singular", False, None, None, **{**base, "collinear": collinear})
    betti = _betti(s, half)
    others_min = np.array([np.delete(s, j).min() for j in range(s.size)])
    dominant = np.flatnonzero((s < half) & (s + others_min > half))
    if dominant.size:
        j = s.size - 1 if dominant[-1] == s.size - 1 else int(dominant[0])
        return Topology("sphere", True, betti[0], betti, **{**base, "dominant_side": j})
    top3 = np.argsort(-s, kind="stable")[:3]
    if s[top3[1]] + s[top3[2]] > half:
        return Topology("tori", True, betti[0], betti, **{**base, "long_sides": tuple(sorted(int(j) for j in top3))})
    return Topology("manifold", True, betti[0], betti, **base)
