"""Dense linear algebra on heyoka expressions (small symmetric positive definite systems).

heyoka integrates explicit ODEs, so the solve in ``g a'' = rhs`` must be
written out as expressions.  ``g`` is a metric (symmetric positive definite),
so Cholesky without pivoting is stable.
"""

from __future__ import annotations

from collections.abc import Sequence

import heyoka as hy

Matrix = Sequence[Sequence[hy.expression]]


def cholesky_solve(g: Matrix, rhs: Sequence[hy.expression]) -> list[hy.expression]:
    """Solve ``g x = rhs`` for symmetric positive definite ``g`` (lower triangle read).

    ``g = R R^T`` with ``R`` lower triangular, then forward and back substitution.
    The pivots ``R_ii`` are kept as reciprocals, computed once.
    """
    k = len(rhs)
    R = [[None] * k for _ in range(k)]
    inv_diag = [None] * k
    for j in range(k):
        s = g[j][j] - hy.sum([R[j][m] * R[j][m] for m in range(j)]) if j else g[j][j]
        R[j][j] = hy.sqrt(s)
        inv_diag[j] = 1.0 / R[j][j]
        for i in range(j + 1, k):
            s = g[i][j] - hy.sum([R[i][m] * R[j][m] for m in range(j)]) if j else g[i][j]
            R[i][j] = s * inv_diag[j]
    y = [None] * k
    for i in range(k):
        s = rhs[i] - hy.sum([R[i][m] * y[m] for m in range(i)]) if i else rhs[i]
        y[i] = s * inv_diag[i]
    x = [None] * k
    for i in reversed(range(k)):
        later = [R[m][i] * x[m] for m in range(i + 1, k)]
        x[i] = (y[i] - hy.sum(later)) * inv_diag[i] if later else y[i] * inv_diag[i]
    return x
