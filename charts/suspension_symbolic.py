"""The suspension chart as heyoka expressions: the chart family of the geodesic engine.

The expressions are symbolic in the chart parameters (variables ``a0 .. a{k-1}``,
``k = n - 2``, in the order ``(phi_n, ..., phi_4, t)``) and in ``L``
(runtime parameter ``par[0]``).  They give the hinges ``z`` of the chain in the
chart's own rod order as the interleaved real vector
``(x_1, y_1, ..., x_{n-1}, y_{n-1})``.  A rod relabeling is a constant linear
map applied afterwards, so one compiled function per ``(n, fp_type)`` serves
every chart and every ``L``.

Everything compiled from the family (integrator, Jacobian, quality, ...) is
built by :func:`manifold.compiled.compiled`, once per ``SuspensionFamily.key``.
"""

from __future__ import annotations

import heyoka as hy

from manifold.jets import Jet, JetOps
from manifold.family import ChartFamily

from . import suspension_formula as formula
from manifold.backends import Cx, HeyokaOps


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

    def inverse_expressions(self, z, fp_type):
        """The closed-form inverse (:func:`charts.suspension_formula.parameters`) of hinges ``z`` in chart rod order."""
        z = list(z)
        hinges = [Cx(z[2 * k], z[2 * k + 1]) for k in range(self.n - 1)]
        return formula.parameters(hinges, hy.par[0], HeyokaOps(fp_type))

    def quality_expressions(self, a):
        """``cos(phi_m)`` for every latitude (the poles), then the fold terms ``q_A``, ``q_B``
        (:func:`charts.suspension_formula.fold_qualities`)."""
        a = list(a)
        return [hy.cos(x) for x in a[:-1]] + formula.fold_qualities(a, hy.par[0], HeyokaOps(float))
