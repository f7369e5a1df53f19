"""The suspension chart as heyoka expressions: the chart family of the geodesic engine.

The expressions are symbolic in the chart parameters (variables ``a0 .. a{k-1}``,
``k = n - 2``, in the order ``(phi_n, ..., phi_4, t)``) and in the chain
(runtime parameters: ``par[0] = L`` for unit rods; for links of any lengths
``par = (L, l_1, ..., l_n, hi, lo)`` in the chart's own link order, with the
whole chain's slacks ``hi = R_n - L``, ``lo = L - (R_n - 2 mu_n)`` exact to one
rounding, :func:`charts.suspension_formula.top_slacks`; with a dominant link
``l_j`` as the base, ``par = (l_j, c_1, ..., c_n, hi, lo, L, w_1, ..., w_n)``: the
other sides ``c`` in chart order, the pinned base ``L`` among them where the
one-hot ``w`` says, :func:`charts.suspension_formula.pinned_hinges`).  They give
the hinges ``z`` of the chain in the chart's own rod order as the interleaved
real vector ``(x_1, y_1, ..., x_{n-1}, y_{n-1})``.  A rod relabeling is a constant linear
map applied afterwards, so one compiled function per ``(n, fp_type)`` (and
per kind: unit rods, or any lengths) serves every chart, every ``L`` and
every length vector.

Everything compiled from the family (integrator, Jacobian, quality, ...) is
built by :func:`manifold.compiled.compiled`, once per ``SuspensionFamily.key``.
"""

from __future__ import annotations

from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from manifold.backends import Cx, HeyokaOps
from manifold.family import ChartFamily
from manifold.jets import Jet, JetOps
from manifold.precision import is_double

from . import suspension_formula as formula
from .suspension_velocity import chart_velocity


class SuspensionFamily(ChartFamily):
    """The suspension charts of ``n`` links as a family; ``z`` = hinges in chart rod order.

    Parameters
    ----------
    n
        Number of links, ``>= 3``.
    lengths
        ``False`` (default): unit rods, ``theta = (L,)``.  ``True``: links of any
        lengths, ``theta = (L, l_1, ..., l_n, hi, lo)`` (chart order).
    link_base
        ``True``: a dominant link is the chart's base (implies ``lengths``),
        ``theta = (l_j, c_1, ..., c_n, hi, lo, L, w_1, ..., w_n)``.
    """

    block = 2

    def __init__(self, n: int, lengths: bool = False, link_base: bool = False) -> None:
        if n < 3:
            raise ValueError(f"the suspension family has parameters only for n >= 3 rods, got n = {n}")
        self.n, self.dim, self.point_dim = n, n - 2, 2 * (n - 1)
        self.link_base = bool(link_base)
        self.lengths = bool(lengths) or self.link_base
        self.n_params = 2 * n + 4 if self.link_base else n + 3 if self.lengths else 1
        self.periodic = (self.dim - 1,)  # the circle angle t

    @property
    def key(self) -> tuple:
        kind = ("link-base",) if self.link_base else ("lengths",) if self.lengths else ()
        return ("suspension", self.n, *kind)

    def __repr__(self) -> str:
        kind = ", link_base=True" if self.link_base else ", lengths=True" if self.lengths else ""
        return f"SuspensionFamily(n={self.n}{kind})"

    def _hinges(self, a: list, ops: Any, fp_type: Any) -> list:
        """The chart's hinges: the suspension formula's, pinned at 0 and ``L`` where a dominant link is the base."""
        q, links = formula.chain_vectors(a, hy.par[0], ops, rods=self.rods(fp_type))
        if not self.link_base:
            return q
        n = self.n
        return formula.pinned_hinges(q, hy.par[0], hy.par[n + 3], [hy.par[n + 4 + k] for k in range(n)], links)

    def rods(self, fp_type: Any) -> formula.Rods:
        """The link lengths as runtime parameters (Python 1s for unit rods).

        In float64 the whole chain's slacks are the exact ones in ``par``; a
        wider ``fp_type`` forms them from ``L`` and the lengths, which in it is
        exact (or far closer than a float64 rounding).
        """
        if not self.lengths:
            return formula.Rods.unit(self.n)
        n = self.n
        slacks = (hy.par[n + 1], hy.par[n + 2]) if is_double(fp_type) else None
        return formula.Rods([hy.par[1 + k] for k in range(n)], HeyokaOps(fp_type), slacks)

    def point_expressions(self, a, fp_type):
        z = self._hinges(list(a), HeyokaOps(fp_type), fp_type)
        return [c for h in z for c in (h.re, h.im)]

    def point_jets(self, a, c, fp_type):
        """The same formula pushed through second-order jets (``z``, ``J``, ``J c``, ``z_ab c^a c^b``)."""
        k = len(a)
        jets = [Jet.variable(ai, ci, i, k) for i, (ai, ci) in enumerate(zip(a, c))]
        z = self._hinges(jets, JetOps(HeyokaOps(fp_type)), fp_type)
        return [part for h in z for part in (h.re, h.im)]

    def velocity_solve(self, a, V, fp_type):
        """``(a', J a')`` by the suspension's level recursion (:func:`charts.suspension_velocity.chart_velocity`);
        ``None`` with a dominant link as the base (its pinned map turns every hinge with every level: no block
        triangle)."""
        if self.link_base:
            return None
        hinges = [Cx(V[2 * k], V[2 * k + 1]) for k in range(self.n - 1)]
        a_dot, W = chart_velocity(list(a), hinges, hy.par[0], HeyokaOps(fp_type), self.rods(fp_type))
        return a_dot, [x for w in W for x in (w.re, w.im)]

    def inverse_expressions(self, z, fp_type):
        """The closed-form inverse (:func:`charts.suspension_formula.parameters`) of hinges ``z`` in chart rod order."""
        z = list(z)
        hinges = [Cx(z[2 * k], z[2 * k + 1]) for k in range(self.n - 1)]
        if self.link_base:
            n = self.n
            hinges = formula.chart_frame_hinges(hinges, hy.par[0], hy.par[n + 3], [hy.par[n + 4 + k] for k in range(n)])
        return formula.parameters(hinges, hy.par[0], HeyokaOps(fp_type), self.rods(fp_type))

    def quality_floors(self, theta: NDArray) -> NDArray:
        r"""Lower bounds of the qualities over every ``a`` at parameters ``theta``: -1 for each ``cos(phi_m)``, then

        .. math::

            q_A \ge \frac{lo}{lo + l_{max}/4}, \qquad q_B \ge \min\Big(1, \frac{lo}{2 l_{max}}\Big)^{1/4},

        with ``lo`` the whole chain's lower slack (``L - (n - 2)`` for unit rods) and ``l_max`` its longest link
        (of the sides other than the base).  The circle level's slack is at least ``lo`` (each level adds
        non-negative terms: :meth:`charts.suspension_formula.Base.inner_lo`), its ``D - l_3 >= lo``, and
        ``|p_2|^2 >= (D - l_3)^2`` give the first; ``cos^2(alpha/2) = (D + l_3 - R_2)(R_3 + D) / (4 D l_3)
        >= lo / (2 l_3)`` (``D <= R_3``) and ``q_B^2 >= cos(alpha/2)`` the second
        (:func:`charts.suspension_formula.fold_qualities`).  Far from the lower end of the range both lie above the
        default switch threshold 0.25 (``lo > l_max / 12``), so the fold events are not compiled there.
        """
        theta = np.asarray(theta, dtype=float)
        if self.lengths:
            lo, l_max = theta[self.n + 2], float(np.max(theta[1 : self.n + 1]))
        else:
            lo, l_max = theta[0] - (self.n - 2), 1.0
        fold = [lo / (lo + l_max / 4), min(1.0, lo / (2 * l_max)) ** 0.25]
        return np.array([-1.0] * (self.dim - 1) + fold)

    def quality_expressions(self, a):
        """``cos(phi_m)`` for every latitude (the poles), then the fold terms ``q_A``, ``q_B``
        (:func:`charts.suspension_formula.fold_qualities`)."""
        a = list(a)
        return [hy.cos(x) for x in a[:-1]] + formula.fold_qualities(a, hy.par[0], HeyokaOps(float), self.rods(float))
