"""Coupling spaces and coupling varieties of consecutive revolute axes ([HSS] Defs. 3-5).

For consecutive axes ``h_i, ..., h_j`` (unit lines, ``h^2 = -1``):

* the *coupling space* ``L_{i..j}`` (Def. 3) is the real linear span of all products
  ``h_k1 ... h_ks`` with ``i <= k1 < ... < ks <= j`` (the empty product is ``1``);
* the *coupling variety* ``X_{i..j}`` (Def. 5) is the set of all products
  ``(t_i - h_i) ... (t_j - h_j)``, ``t_k`` in ``P^1`` (``t_k = inf`` the factor ``1``),
  as points of ``P^7``.  It lies in the projectivised coupling space.

The *coupling equality* relates them to a closed chain ``(h_1, ..., h_n)``: the
coupling curve ``C_ij`` (the poses of link ``o_j`` relative to ``o_i``) is

    C_ij = X_{i+1, ..., j}  cap  X_{i, i-1, ..., j+1}

(indices mod ``n``): ``F_ij = (t_{i+1} - h_{i+1}) ... (t_j - h_j)`` is, by the closure
condition, proportional to ``G_ij = (t_i + h_i)(t_{i-1} + h_{i-1}) ... (t_{j+1} + h_{j+1})``
([HSS] eq. 4), and ``t + h = -((-t) - h)`` puts ``G_ij`` in the variety of the axes
``h_i, h_{i-1}, ..., h_{j+1}`` taken backwards.

Exact coefficients (sympy numbers, ``int``, ``Fraction``) are handled exactly;
floats by singular values relative to the largest one (``FLOAT_TOL``).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np
import sympy

from .dualquat import FLOAT_TOL, DualQuaternion, is_inexact

__all__ = ["coupling_space", "coupling_variety_parameters", "pose_product"]

INF = complex("inf")


def pose_product(axes: Sequence[DualQuaternion], joints: Sequence[Any]) -> DualQuaternion:
    """``(t_1 - h_1) ... (t_m - h_m)`` for ``axes = (h_1..h_m)``, ``joints = (t_1..t_m)``.

    A joint value ``inf`` (float or complex infinity) stands for the factor ``1``.
    """
    if len(axes) != len(joints):
        raise ValueError(f"joints must have one entry per axis ({len(axes)}); got {len(joints)}")
    r = DualQuaternion.scalar(1)
    for t, h in zip(joints, axes):
        if not _is_inf(t):
            r = r * (t - h)
    return r


def coupling_space(axes: Sequence[DualQuaternion]) -> list[DualQuaternion]:
    """The ``2^m`` products spanning the coupling space ``L`` of ``axes`` ([HSS] Def. 3).

    ``axes = (h_i, ..., h_j)``; returns ``1`` and all ``h_k1 ... h_ks`` with
    ``k1 < ... < ks`` in the given order.  Its dimension (the rank of these
    vectors) is the coupling dimension ``l_{i..j}`` (Def. 4).
    """
    out = []
    for s in range(len(axes) + 1):
        for combo in itertools.combinations(range(len(axes)), s):
            p = DualQuaternion.scalar(_one_like(axes))
            for k in combo:
                p = p * axes[k]
            out.append(p)
    return out


def coupling_variety_parameters(x: DualQuaternion, axes: Sequence[DualQuaternion]) -> tuple | None:
    """Joint values ``(t_1, ..., t_m)`` with ``x`` proportional to ``(t_1 - h_1) ... (t_m - h_m)``.

    This decides membership of the point ``x`` of ``P^7`` in the coupling variety
    ``X`` of ``axes = (h_1, ..., h_m)`` ([HSS] Def. 5): ``None`` when ``x`` is not
    in ``X``.  The last joint is peeled off first: ``x = Y (t_m - h_m)`` with ``Y``
    in ``X(h_1..h_{m-1})`` means ``x (t_m + h_m) = (t_m^2 + 1) Y`` lies in the coupling
    space of ``h_1..h_{m-1}``, a linear condition on ``(t_m : 1)`` in ``P^1``.

    Raises
    ------
    ValueError
        If ``x`` is zero.
    NotImplementedError
        If the linear condition leaves all of ``P^1`` (``x`` and ``x h_m`` both in the
        smaller coupling space, e.g. four general axes, whose first three span all of
        ``DH``): the fibre is not a single joint value.  Up to three axes in general
        position are always decided.
    """
    exact = not _is_float(x) and not any(_is_float(h) for h in axes)
    if all(_zero(c, exact, x) for c in x):
        raise ValueError("x must be a nonzero dual quaternion (a point of P^7)")
    return _parameters(x, list(axes), exact)


def _parameters(x: DualQuaternion, axes: list, exact: bool) -> tuple | None:
    if not axes:
        return () if all(_zero(c, exact, x) for c in x.coefficients[1:]) else None
    h = axes[-1]
    rest = axes[:-1]
    basis = coupling_space(rest)
    # u x + v (x h) in span(basis): the null space of [x, x h, -basis], projected onto (u, v)
    columns = [list(x), list(x * h)] + [list(-b) for b in basis]
    uv = _null_uv(columns, exact)
    if uv is None:
        return None
    u, v = uv
    if _zero(v, exact, (u, v)):
        t: Any = INF
        y = x
    else:
        t = sympy.simplify(u / v) if exact else complex(u / v)
        y = x * (t + h)
    if all(_zero(c, exact, y) for c in y):  # t^2 + 1 = 0 killed x: not a point of this fibre
        return None
    inner = _parameters(y, rest, exact)
    return None if inner is None else (*inner, t)


def _null_uv(columns: list, exact: bool) -> tuple | None:
    """The ``(u, v)`` part of the null space of the 8 x k matrix with the given columns.

    ``None`` if it is zero; raises NotImplementedError if it is two-dimensional.
    """
    if exact:
        m = sympy.Matrix(columns).T
        null = m.nullspace(simplify=True)
        uvs = sympy.Matrix([[vec[0], vec[1]] for vec in null]) if null else sympy.zeros(0, 2)
        rank = uvs.rank(simplify=True) if null else 0
        if rank == 0:
            return None
        if rank == 2:
            raise NotImplementedError(_WHOLE_LINE)
        row = next(r for r in range(uvs.rows) if any(sympy.simplify(e) != 0 for e in uvs.row(r)))
        return sympy.simplify(uvs[row, 0]), sympy.simplify(uvs[row, 1])
    a = np.array(columns, dtype=complex).T
    _, s, vh = np.linalg.svd(a)
    tol = FLOAT_TOL * 1e3 * s[0]  # the product x h carries a few more roundings than x
    null = vh[np.sum(s > tol) :].conj()
    if null.shape[0] == 0:
        return None
    uvs = null[:, :2]
    sv = np.linalg.svd(uvs, compute_uv=False)
    if sv[0] <= tol / s[0]:
        return None
    if len(sv) > 1 and sv[1] > 1e-6 * sv[0]:
        raise NotImplementedError(_WHOLE_LINE)
    k = int(np.argmax(np.linalg.norm(uvs, axis=1)))
    return uvs[k, 0], uvs[k, 1]


_WHOLE_LINE = (
    "every value of the last joint fits (x and x h both lie in the coupling space of the other axes, "
    "e.g. when that space is all of DH, as for four or more general axes): the fibre is not one joint "
    "value, and membership is decided here only when it is (in general for up to three axes)"
)


def _is_inf(t: Any) -> bool:
    return isinstance(t, (float, complex)) and bool(np.isinf(abs(t)))


def _is_float(h: Any) -> bool:
    return any(is_inexact(c) for c in h)


def _one_like(axes: Sequence[DualQuaternion]) -> Any:
    return 1.0 if any(_is_float(h) for h in axes) else sympy.Integer(1)


def _zero(c: Any, exact: bool, scale: Any) -> bool:
    if exact:
        return sympy.simplify(c) == 0
    return abs(complex(c)) <= FLOAT_TOL * 1e3 * max(abs(complex(y)) for y in scale)
