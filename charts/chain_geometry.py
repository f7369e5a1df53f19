"""Plain geometry of a closed chain, shared by charts and linkage.

Conventions: a chain of ``n`` rods from ``p_0 = 0`` to ``p_n = L`` (real); unit
rods unless a function takes ``lengths``.
A configuration is the complex array of interior hinges ``p_1 .. p_{n-1}``
(shape ``(..., n-1)``).  As a point of the embedding space ``R^(2(n-1))`` it is
the interleaved real vector ``(x_1, y_1, ..., x_{n-1}, y_{n-1})``.
"""

from __future__ import annotations

import numbers
from fractions import Fraction

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.constrained import START_ROUNDING_MARGIN
from manifold.validation import check_real


def validate_chain(n: object, L: object) -> tuple[int, float]:
    """Check that ``(n, L)`` is a chain whose configuration space is ``S^(n-2)``.

    Returns ``(int(n), float(L))``.  Raises ``ValueError`` naming the bad value
    and the valid range: ``n`` an integer ``>= 2`` and ``n - 2 < L < n`` finite.
    """
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise ValueError(f"n (number of rods) must be an integer >= 2, got {n!r}")
    n = int(n)
    if n < 2:
        raise ValueError(f"n (number of rods) must be an integer >= 2, got {n}")
    message = (f"L must be a finite real number with {n - 2} < L < {n} (the range where the configuration "
               f"space of {n} unit rods is the sphere S^{n - 2}), got L = {L!r}")
    try:
        Lf = check_real("L", L)
    except ValueError:
        raise ValueError(message) from None
    if not (n - 2 < Lf < n):
        raise ValueError(message)
    return int(n), Lf


def sphere_range(lengths: ArrayLike) -> tuple[float, float]:
    """``(R - 2 mu, R)``: the open range of ``L`` where the base is the dominant side of the polygon
    ``(l_1, ..., l_n, L)`` (``R = l_1 + ... + l_n``, ``mu = min l_k``), and the space the sphere ``S^(n-2)``.

    ``L < P/2 < L + l_k`` for every ``k`` (``P = R + L``) is ``R - 2 mu < L < R``; for unit rods ``n - 2 < L < n``.
    The ends are rounded to float64; :func:`validate_sphere_chain` decides membership exactly.
    """
    ls = [Fraction(float(x)) for x in np.asarray(lengths, dtype=float).ravel()]
    R = sum(ls)
    return float(R - 2 * min(ls)), float(R)


def dominant_side(lengths: ArrayLike, L: float) -> int | None:
    """The dominant side of the polygon ``(l_1, ..., l_n, L)``, decided exactly (in rationals), or ``None``.

    Side ``s_j`` dominates if ``s_j < P/2 < s_j + s_i`` for every other side ``s_i`` (``P`` the perimeter):
    the configuration space is then the sphere ``S^(n-2)``.  Index ``k - 1`` for the link ``l_k``, ``n`` for
    the base.  For ``n >= 3`` at most one side dominates; for ``n = 2`` (a triangle) every side does when
    any does, and the base is returned.
    """
    s = [Fraction(float(x)) for x in np.asarray(lengths, dtype=float).ravel()] + [Fraction(float(L))]
    P = sum(s)

    def dominates(j: int) -> bool:
        return 2 * s[j] < P < 2 * (s[j] + min(s[:j] + s[j + 1:]))

    return next((j for j in [len(s) - 1, *range(len(s) - 1)] if dominates(j)), None)


def validate_sphere_chain(lengths: int | ArrayLike, L: object) -> tuple[NDArray, float, int]:
    """Check that links ``lengths`` pinned ``L`` apart have the sphere ``S^(n-2)`` as configuration space.

    ``lengths`` is an integer ``n`` (unit rods: :func:`validate_chain`, ``n-2 < L < n``, the base
    dominant) or a sequence of at least 2 finite lengths ``> 0``; some side of the polygon must dominate
    (:func:`dominant_side`, decided exactly: a float64 sum of the lengths could misjudge an ``L`` within
    rounding of an end).  The base dominates for ``L`` in the open :func:`sphere_range`.
    Returns ``(lengths as a float array, float(L), the dominant side)``; raises ``ValueError``
    naming the bad value and the valid range.
    """
    if np.ndim(lengths) == 0:
        n, Lf = validate_chain(lengths, L)
        return np.ones(n), Lf, n
    try:
        ls = np.asarray(lengths, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"lengths must be an integer n >= 2 or a sequence of positive finite numbers, "
                         f"got {lengths!r}") from None
    if ls.ndim != 1 or ls.size < 2 or not np.all(np.isfinite(ls)) or not np.all(ls > 0):
        raise ValueError(f"lengths must be a sequence of at least 2 finite numbers > 0, got {lengths!r}")
    lo, hi = sphere_range(ls)
    message = (f"L must be a finite real number with {lo!r} < L < {hi!r} (R - 2 min l < L < R, R = sum of the "
               f"lengths: the range where L is the dominant side of the polygon and the configuration space of "
               f"links {tuple(float(x) for x in ls)} the sphere S^{ls.size - 2}), or such that a link is the "
               f"dominant side, got L = {L!r}")
    try:
        Lf = check_real("L", L)
    except ValueError:
        raise ValueError(message) from None
    base = dominant_side(ls, Lf) if Lf > 0 else None
    if base is None:
        raise ValueError(message)
    return ls, Lf, base


def side_orders(n: int, base: int) -> list[NDArray]:
    """The ``n`` cyclic orders of the sides other than ``base`` that follow it around the polygon.

    Sides are ``0 .. n-1`` (the links) and ``n`` (the pinned base ``L``).  For ``base = n`` these are the
    cyclic rod orders ``(s, s+1, ..., s-1)``; for a dominant link ``j`` they are the cyclic shifts of
    ``(j+1, ..., n-1, n, 0, ..., j-1)``.
    """
    after = np.array([(base + 1 + k) % (n + 1) for k in range(n)])
    return [np.roll(after, -s) for s in range(n)]


def to_real(hinges: ArrayLike) -> NDArray:
    """Complex hinges ``(..., n-1)`` to interleaved real points ``(..., 2(n-1))``."""
    h = np.asarray(hinges)
    return np.stack([h.real, h.imag], axis=-1).reshape(*h.shape[:-1], 2 * h.shape[-1])


def to_complex(points: ArrayLike) -> NDArray:
    """Interleaved real points ``(..., 2(n-1))`` to complex hinges ``(..., n-1)``."""
    p = np.asarray(points)
    if p.shape[-1] % 2:
        raise ValueError(f"a point has an even number of real coordinates, got {p.shape[-1]}")
    p = p.reshape(*p.shape[:-1], p.shape[-1] // 2, 2)
    return p[..., 0] + 1j * p[..., 1]


def rod_vectors(hinges: ArrayLike, L: float) -> NDArray:
    """Rod vectors ``e_k = p_k - p_{k-1}``, ``k = 1..n``, shape ``(..., n)`` (complex), with the pins ``p_0 = 0``
    and ``p_n = L``."""
    h = np.asarray(hinges)
    e = np.empty((*h.shape[:-1], h.shape[-1] + 1), dtype=h.dtype)
    e[..., 0] = h[..., 0]
    np.subtract(h[..., 1:], h[..., :-1], out=e[..., 1:-1])
    np.subtract(np.asarray(L, dtype=h.dtype), h[..., -1], out=e[..., -1])
    return e


def hinges_from_rods(rods: ArrayLike) -> NDArray:
    """Interior hinges ``p_1 .. p_{n-1}`` (cumulative sums) from rod vectors ``e_1 .. e_n``."""
    return np.cumsum(np.asarray(rods), axis=-1)[..., :-1]


def closure_residual(hinges: ArrayLike, L: float, lengths: ArrayLike = 1.0) -> NDArray:
    """``max_k | |e_k| - l_k | / l_k``: 0 for a configuration of the closed chain of rods ``lengths`` (default unit rods).

    Relative to each rod, so that a chain and the same chain scaled by any
    factor close equally well (for unit rods it is the absolute error).
    """
    ls = np.asarray(lengths, dtype=float)
    return np.max(np.abs(np.abs(rod_vectors(hinges, L)) - ls) / ls, axis=-1)


def rounding_floors(lengths: ArrayLike) -> NDArray:
    """Per rod, the relative closure error that rounding the hinges to float64 alone leaves: ``u R / l_k``
    (``u`` the unit roundoff; every hinge lies within ``R``, the sum of the lengths, of the pin ``0``, so its
    coordinates round by up to ``u R``, and a rod's length by about that).

    Numerical trap: at most ``u`` for rods of comparable lengths, but a 6e-9 link among unit rods rounds to
    1.1e-7 of its length, which no closure check below that can pass.
    """
    ls = np.asarray(lengths, dtype=float)
    return np.finfo(float).eps / 2 * float(np.sum(ls)) / ls


def closure_tolerances(lengths: ArrayLike, tol: float) -> NDArray:
    """Per rod, the relative closure error accepted: ``tol``, or :data:`manifold.constrained.START_ROUNDING_MARGIN`
    times the rod's :func:`rounding_floors` where that is larger (a link much shorter than the chain)."""
    return np.maximum(tol, START_ROUNDING_MARGIN * rounding_floors(lengths))


def closure_scales(lengths: ArrayLike, tol: float) -> NDArray:
    """Per rod, the absolute closure error accepted: ``l_k tol_k`` (``tol_k``: :func:`closure_tolerances`)."""
    ls = np.asarray(lengths, dtype=float)
    return ls * closure_tolerances(ls, tol)


def closure_excess(hinges: ArrayLike, L: float, lengths: ArrayLike, tol: float,
                   scales: NDArray | None = None) -> NDArray:
    """``max_k | |e_k| - l_k | / (l_k tol_k)`` (``tol_k``: :func:`closure_tolerances`): at most 1 where a
    configuration closes as well as asked (NaN for a non-finite one).  ``scales``, if given, must be
    :func:`closure_scales` ``(lengths, tol)`` (a caller that checks many configurations keeps them)."""
    ls = np.asarray(lengths, dtype=float)
    # the array's own max: np.max's dispatch costs a one-start check ~3 us
    return (np.abs(np.abs(rod_vectors(hinges, L)) - ls) / (closure_scales(ls, tol) if scales is None else scales)
            ).max(axis=-1)


def validate_side_order(order: ArrayLike, n: int, base: int) -> NDArray:
    """Check that ``order`` is a permutation of the sides other than ``base`` (``0 .. n-1`` the links, ``n``
    the pinned base ``L``; for ``base = n`` a permutation of ``0 .. n-1``); return it as an int array."""
    o = np.asarray(order)
    sides = [s for s in range(n + 1) if s != base]
    if o.shape != (n,) or not np.issubdtype(o.dtype, np.integer) or sorted(o.tolist()) != sides:
        what = f"0..{n - 1}" if base == n else f"the sides {sides} (links 0..{n - 1}, the base L {n}; not the base {base})"
        raise ValueError(f"rod order must be a permutation of {what}, got {order!r}")
    return o.astype(int)


def relabel_matrix(order: ArrayLike) -> NDArray:
    """Matrix ``P`` with ``p = P z + c L`` for the relabeling of :func:`relabel_hinges`.

    ``z`` are the hinges of the chain whose k-th rod is rod ``order[k]``, ``p``
    those of the chain in its own rod order; ``P`` is ``(n-1, n-1)`` with
    entries in ``{-1, 0, 1}``.  Only ``P`` enters velocities (``L`` is fixed).
    """
    n = np.asarray(order).size
    cols = [relabel_hinges(np.eye(n - 1)[k], order, 0.0) for k in range(n - 1)]
    return np.column_stack(cols).real


def relabel_hinges(z: ArrayLike, order: ArrayLike, L: float) -> NDArray:
    """Hinges of the chain in its own rod order from those of the relabeled chain.

    The relabeled chain's k-th rod is rod ``order[k]``: ``e[order[k]] = f[k]``.
    """
    f = rod_vectors(z, L)
    e = np.empty_like(f)
    e[..., np.asarray(order)] = f
    return hinges_from_rods(e)


def unlabel_hinges(p: ArrayLike, order: ArrayLike, L: float) -> NDArray:
    """Inverse of :func:`relabel_hinges`: ``f[k] = e[order[k]]``."""
    return hinges_from_rods(rod_vectors(p, L)[..., np.asarray(order)])
