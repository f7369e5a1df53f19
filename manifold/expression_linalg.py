"""Dense linear algebra on heyoka expressions (small symmetric positive definite systems).

heyoka integrates explicit ODEs, so the solve in ``g a'' = rhs`` must be
written out as expressions.  ``g`` is a metric (symmetric positive definite),
so Cholesky without pivoting is stable.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import heyoka as hy

Matrix = Sequence[Sequence[hy.expression]]


def cholesky_solve(g: Matrix, rhs: Sequence[hy.expression]) -> list[hy.expression]:
    """Solve ``g x = rhs`` for symmetric positive definite ``g`` (lower triangle read).

    ``g = R R^T`` with ``R`` lower triangular, then forward and back substitution.
    The pivots ``R_ii`` are kept as reciprocals, computed once.
    """
    k = len(rhs)
    R: list[list[Any]] = [[None] * k for _ in range(k)]
    inv_diag: list[Any] = [None] * k
    for j in range(k):
        s = g[j][j] - hy.sum([R[j][m] * R[j][m] for m in range(j)]) if j else g[j][j]
        R[j][j] = hy.sqrt(s)
        inv_diag[j] = 1.0 / R[j][j]
        for i in range(j + 1, k):
            s = g[i][j] - hy.sum([R[i][m] * R[j][m] for m in range(j)]) if j else g[i][j]
            R[i][j] = s * inv_diag[j]
    y: list[Any] = [None] * k
    for i in range(k):
        s = rhs[i] - hy.sum([R[i][m] * y[m] for m in range(i)]) if i else rhs[i]
        y[i] = s * inv_diag[i]
    x: list[Any] = [None] * k
    for i in reversed(range(k)):
        later = [R[m][i] * x[m] for m in range(i + 1, k)]
        x[i] = (y[i] - hy.sum(later)) * inv_diag[i] if later else y[i] * inv_diag[i]
    return x


SparseMatrix = Sequence[Sequence["hy.expression | None"]]


def ldl_solve(M: SparseMatrix, rhs: Sequence[hy.expression],
              pivots: Sequence[hy.expression] | None = None) -> list[hy.expression]:
    """Solve ``M x = rhs`` for symmetric positive definite ``M`` with structural zeros (``None``).

    ``M = L D L^T`` with ``L`` unit lower triangular (lower triangle of ``M``
    read), without square roots:

    .. math::

        D_j = M_{jj} - \\sum_{m<j} L_{jm}^2 D_m, \\qquad
        L_{ij} = \\Big(M_{ij} - \\sum_{m<j} L_{im} L_{jm} D_m\\Big) / D_j .

    An entry of ``L`` is ``None`` when every term of its sum is, so a banded
    ``M`` costs ``O(k b^2)`` nodes: a tridiagonal one is the Thomas recursion.
    Stable without pivoting because ``M`` is positive definite.  ``pivots``,
    if given, are the ``D_j`` written by the caller: the recursion above
    subtracts, and loses ``cond(M) eps`` when ``M`` is a Gram matrix of nearly
    dependent rows, which a caller that knows the rows can avoid.
    """
    k = len(rhs)
    # entries are hy.expression or None; heyoka publishes no types, and mypy cannot narrow L[i][m] by a test
    L: list[list[Any]] = [[None] * k for _ in range(k)]
    LD: list[list[Any]] = [[None] * k for _ in range(k)]  # L_im D_m, reused
    inv_D: list[hy.expression] = []
    for j in range(k):
        D = pivots[j] if pivots is not None else _minus_sum(M[j][j], [LD[j][m] * L[j][m] for m in range(j)
                                                                     if L[j][m] is not None])
        inv_D.append(1.0 / D)
        for i in range(j + 1, k):
            terms = [LD[i][m] * L[j][m] for m in range(j) if L[i][m] is not None and L[j][m] is not None]
            if M[i][j] is None and not terms:
                continue
            LD[i][j] = _minus_sum(M[i][j], terms)  # = L_ij D_j
            L[i][j] = LD[i][j] * inv_D[j]
    y: list[hy.expression] = []
    for i in range(k):
        y.append(_minus_sum(rhs[i], [L[i][m] * y[m] for m in range(i) if L[i][m] is not None]))
    x: list[Any] = [None] * k
    for i in reversed(range(k)):
        x[i] = _minus_sum(y[i] * inv_D[i], [L[m][i] * x[m] for m in range(i + 1, k) if L[m][i] is not None])
    return x


def _minus_sum(first: "hy.expression | None", terms: list[hy.expression]) -> hy.expression:
    """``first - sum(terms)`` (``first = None`` reads as 0)."""
    if not terms:
        return first
    total = terms[0] if len(terms) == 1 else hy.sum(terms)
    return -total if first is None else first - total


def is_structural_zero(x: Any) -> bool:
    """Whether a matrix entry is known to vanish: a Python zero, ``None``, or heyoka's constant 0."""
    if x is None:
        return True
    if isinstance(x, (int, float)):
        return x == 0
    return isinstance(x, hy.expression) and x == hy.expression(0.0)


def block_triangular_order(A: SparseMatrix, block: int) -> list[tuple[int, tuple[int, ...]]] | None:
    """An elimination order that makes the ``N x k`` matrix ``A`` block lower triangular, or ``None``.

    The rows come in blocks of ``block`` (the coordinates of one point of ``R^block``).  Column ``i`` is
    *isolated* by a row block whose nonzero columns, among those not yet eliminated, are ``i`` alone; the
    order lists each column with every block that isolates it when it is eliminated, so that a
    forward substitution reads ``x_i`` from those rows once the earlier columns are known.  ``None``
    when at some stage no block isolates a column (no such order: solve the normal equations instead).
    Blocks never used (their columns were all eliminated before them) are left out.
    """
    k = len(A[0]) if len(A) else 0
    blocks = [range(b, b + block) for b in range(0, len(A), block)]
    support = [{i for r in rows for i in range(k) if not is_structural_zero(A[r][i])} for rows in blocks]
    remaining, unused = set(range(k)), set(range(len(blocks)))
    order: list[tuple[int, tuple[int, ...]]] = []
    while remaining:
        isolating = {b: support[b] & remaining for b in unused if len(support[b] & remaining) == 1}
        if not isolating:
            return None
        column = min(next(iter(cols)) for cols in isolating.values())
        used = sorted(b for b, cols in isolating.items() if cols == {column})
        order.append((column, tuple(r for b in used for r in blocks[b])))
        remaining.discard(column)
        unused.difference_update(used)
    return order

