"""The suspension chart as heyoka expressions, and compiled functions of it.

The expressions are symbolic in the chart parameters (variables ``a0 .. a{k-1}``,
``k = n - 2``, in the order ``(phi_n, ..., phi_4, t)``) and in ``L``
(runtime parameter ``par[0]``).  They give the hinges ``z`` of the chain in the
chart's own rod order as the interleaved real vector
``(x_1, y_1, ..., x_{n-1}, y_{n-1})``.  A rod relabeling is a constant linear
map applied afterwards, so one compiled function per ``(n, fp_type)`` serves
every chart and every ``L``.

Compiled functions are cached in memory here and by heyoka on disk (see the
README's note on heyoka's disk cache).
"""

from __future__ import annotations

from functools import lru_cache

import heyoka as hy
import numpy as np

from manifold.geodesic_system import chart_variables
from manifold.jets import Jet, JetOps
from manifold.precision import as_fp, heyoka_fp_kwargs
from manifold.symbolic import ChartFamily

from . import suspension_formula as formula
from .backends import HeyokaOps


def hinge_expressions(a: list, fp_type: type = float, L=hy.par[0]) -> list:
    """Interleaved real hinge coordinates of the suspension chart in variables ``a``: ``2(n-1)`` expressions."""
    z = formula.hinges(a, L, HeyokaOps(fp_type))
    return [c for h in z for c in (h.re, h.im)]


class SuspensionFamily(ChartFamily):
    """The suspension charts of ``n`` rods as a family: ``theta = (L,)``, ``z`` = hinges in chart rod order."""

    block = 2
    n_params = 1

    def __init__(self, n: int) -> None:
        if n < 3:
            raise ValueError(f"the suspension family has parameters only for n >= 3 rods, got n = {n}")
        self.n, self.dim, self.point_dim = n, n - 2, 2 * (n - 1)
        self.periodic = (self.dim - 1,)  # the circle angle t

    @property
    def key(self) -> tuple:
        return ("suspension", self.n)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SuspensionFamily) and other.n == self.n

    def __hash__(self) -> int:
        return hash(self.key)

    def __repr__(self) -> str:
        return f"SuspensionFamily(n={self.n})"

    def point_expressions(self, a, fp_type):
        return hinge_expressions(list(a), fp_type)

    def point_jets(self, a, c, fp_type):
        """The same formula pushed through second-order jets (``z``, ``J``, ``J c``, ``z_ab c^a c^b``)."""
        k = len(a)
        jets = [Jet.variable(ai, ci, i, k) for i, (ai, ci) in enumerate(zip(a, c))]
        z = formula.hinges(jets, hy.par[0], JetOps(HeyokaOps(fp_type)))
        return [part for h in z for part in (h.re, h.im)]

    def quality_expressions(self, a):
        """``cos(phi_m)`` for every latitude (none for ``n = 3``: the circle chart is global)."""
        return [hy.cos(x) for x in list(a)[:-1]]


@lru_cache(maxsize=None)
def jacobian_cfunc(n: int, fp_type: type = float):
    """Compiled ``a -> (z(a), dz/da)`` with ``L`` as ``par[0]``.

    Output: ``2(n-1)`` hinge coordinates followed by the Jacobian in row-major
    order (``2(n-1) x (n-2)`` entries).
    """
    a = chart_variables(n - 2)
    z = hinge_expressions(a, fp_type)
    jac = hy.diff_tensors(z, a, diff_order=1).jacobian
    outs = list(z) + [jac[r, c] for r in range(len(z)) for c in range(len(a))]
    return hy.cfunc(outs, a, compact_mode=True, **heyoka_fp_kwargs(fp_type))


def evaluate_jacobian(n: int, L: float, a: np.ndarray, fp_type: type = float) -> tuple[np.ndarray, np.ndarray]:
    """Hinges ``z`` (``(..., 2(n-1))``) and ``dz/da`` (``(..., 2(n-1), n-2)``) at parameters ``a``."""
    a = as_fp(a, fp_type)
    batch = a.shape[:-1]
    flat = a.reshape(-1, n - 2).T.copy()
    pars = as_fp(np.full((1, flat.shape[1]), L), fp_type)
    out = jacobian_cfunc(n, fp_type)(flat, pars=pars).T
    N = 2 * (n - 1)
    z = out[:, :N].reshape(*batch, N)
    J = out[:, N:].reshape(*batch, N, n - 2)
    return z, J
