"""Geodesic equations of a chart family, as heyoka expressions (nothing compiled here).

For ``z(a)`` with ``J = dz/da``, ambient metric ``W = B (x) I_b`` and
velocity coefficients ``c = a'``:

* embedded form (production): ``g c' = -J^T W (sum_ab z_ab c^a c^b)``,
  ``g = J^T W J``; the second-derivative term is ``d(J c)/da . c``;
* Christoffel form (cross-check, as in the dynamics seed):
  ``g c' = -Gamma(c, c)`` with ``Gamma_lij = 1/2 (d_i g_lj + d_j g_li - d_l g_ij)``
  from symbolic derivatives of ``g``.

Runtime parameters (one compiled system serves every chart of a family):
``par[0 .. p-1]`` the family parameters ``theta``, then the upper triangle of
``B`` row by row, then the switch threshold ``q_out``, the chart's maps, and
the equation terms' (:class:`Layout`, :mod:`manifold.terms`).
Terminal events ``quality_m(a) - q_out`` (falling) stop the integration before a
chart's singular set (:mod:`manifold.events` declares them).  Compiling and caching is the job of
:mod:`manifold.compiled`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .events import Event, chart_events
from .expression_linalg import block_triangular_order, cholesky_solve
from .family import ChartFamily
from .precision import as_fp

FORMS = ("embedded", "christoffel")
#: Name of the segment-time variable ``u`` of :meth:`SymbolicPieces.sundman_equations`.
SUNDMAN_TIME = "sundman_u"


@dataclass(frozen=True)
class Layout:
    """Where the family parameters, the metric block ``B`` and ``q_out`` live in ``pars``."""

    n_theta: int
    n_points: int  # M = point_dim / block: size of B
    block: int = 1

    @classmethod
    def of(cls, family: ChartFamily) -> "Layout":
        """The layout for ``family``: ``family.n_params`` values of ``theta``, ``B`` of size ``point_dim / block``."""
        return cls(family.n_params, family.point_dim // family.block, family.block)

    @property
    def n_metric(self) -> int:
        """Entries of ``B`` stored: its upper triangle, ``M (M + 1) / 2`` for ``M = n_points``."""
        return self.n_points * (self.n_points + 1) // 2

    @property
    def q_out_index(self) -> int:
        """Index of ``q_out`` in ``pars``: right after ``theta`` and the upper triangle of ``B``."""
        return self.n_theta + self.n_metric

    @property
    def map_index(self) -> int:
        """Start of the chart's linear map ``M`` (``N x N``, row-major) in ``pars``, then its offset ``m``
        (``N``): the ambient point is ``p = M z + m``.  Only Sundman's time and the ambient-velocity equations
        read them (:meth:`SymbolicPieces.ambient_point`)."""
        return self.q_out_index + 1

    @property
    def inverse_map_index(self) -> int:
        """Start of ``M^{-1}`` (``N x N``, row-major) in ``pars``, after ``M`` and ``m``.  Only the ambient-velocity
        equations read it (:meth:`SymbolicPieces.ambient_velocity_equations`)."""
        N = self.n_points * self.block
        return self.map_index + N * N + N

    @property
    def terms_index(self) -> int:
        """Start of the equation terms' parameters (:mod:`manifold.terms`), after ``M``, ``m`` and ``M^{-1}``: the
        chart's own end here (:attr:`~manifold.compiled.ChartNumerics.pars`), and each term's block follows in the
        order of the composition."""
        N = self.n_points * self.block
        return self.inverse_map_index + N * N

    def metric_pars(self) -> list[list[hy.expression]]:
        """Symmetric matrix of parameter expressions for ``B``."""
        M = self.n_points
        out: list[list[Any]] = [[None] * M for _ in range(M)]
        k = self.n_theta
        for r in range(M):
            for s in range(r, M):
                out[r][s] = out[s][r] = hy.par[k]
                k += 1
        return out

    def pack(self, theta: ArrayLike, B: ArrayLike, q_out: float, fp_type: Any) -> NDArray:
        """Parameter vector for ``theta``, ``B`` and ``q_out`` in ``fp_type``."""
        iu = np.triu_indices(self.n_points)
        vals = np.concatenate([np.asarray(theta, dtype=float), np.asarray(B, dtype=float)[iu], [q_out]])
        return as_fp(vals, fp_type)


def chart_variables(k: int) -> list[hy.expression]:
    """The heyoka variables ``a0 .. a{k-1}`` of chart parameters."""
    return [hy.expression(f"a{i}") for i in range(k)]


def velocity_variables(k: int) -> list[hy.expression]:
    """The heyoka variables ``c0 .. c{k-1}`` of velocity coefficients."""
    return [hy.expression(f"c{i}") for i in range(k)]


def _is_zero(x: Any) -> bool:
    return isinstance(x, (int, float)) and x == 0


def _dot(xs: list, ys: list) -> hy.expression:
    """``sum x_i y_i`` skipping Python zeros (entries a jet knows to vanish)."""
    terms = [x * y for x, y in zip(xs, ys) if not (_is_zero(x) or _is_zero(y))]
    return hy.sum(terms) if terms else hy.expression(0.0)


class SymbolicPieces:
    """The symbolic pieces of a family in one precision: ``z``, ``J``, ``J c``, ``h``, ``W J``, ``g``.

    ``h = sum_ab z_ab c^a c^b`` (the velocity-quadratic part of ``z''``).  With a
    family that provides :meth:`~manifold.family.ChartFamily.point_jets`, all of
    them come from one forward sweep of second-order jets (:mod:`manifold.jets`);
    otherwise from heyoka's symbolic differentiation of the expanded ``z``
    (twice for ``h``), which grows much faster with the size of the formula.

    Attributes
    ----------
    a, c
        Variables of the parameters and velocity coefficients (``k`` each).
    z, J, Jc, h
        Lists of expressions: ``N`` values, ``N`` rows of ``k``, ``N``, ``N``.
    g
        ``k x k`` metric ``J^T W J``.
    quality
        The family's quality expressions in ``a``.
    """

    def __init__(self, family: ChartFamily, fp_type: Any) -> None:
        self.family, self.fp_type = family, fp_type
        self.layout = Layout.of(family)
        self.a, self.c = chart_variables(family.dim), velocity_variables(family.dim)
        self.block, self.k, self.N = family.block, family.dim, family.point_dim
        self.B = self.layout.metric_pars()
        jets = family.point_jets(self.a, self.c, fp_type)
        if jets is not None:
            self.z = [j.v for j in jets]
            self.J = [list(j.g) for j in jets]
            self.Jc = [j.d1 if not _is_zero(j.d1) else hy.expression(0.0) for j in jets]
            self.h = [j.d2 for j in jets]
        else:
            self.z = family.point_expressions(self.a, fp_type)
            jac = hy.diff_tensors(self.z, self.a, diff_order=1).jacobian
            self.J = [[jac[r, i] for i in range(self.k)] for r in range(self.N)]
            self.Jc = [_dot(row, self.c) for row in self.J]
            dw = hy.diff_tensors(self.Jc, self.a, diff_order=1).jacobian
            self.h = [_dot([dw[r, i] for i in range(self.k)], self.c) for r in range(self.N)]
        cols = [[self.J[r][i] for r in range(self.N)] for i in range(self.k)]
        self.U = [self._apply_W(col) for col in cols]  # U[i] = W J_i
        self.g = [[_dot(self.U[i], cols[j]) for j in range(self.k)] for i in range(self.k)]
        self.quality = family.quality_expressions(self.a)

    def _apply_W(self, x: list) -> list:
        """``(B (x) I_b) x`` for a column ``x`` of length ``N``."""
        b, M = self.block, self.N // self.block
        return [_dot([self.B[r][s] for s in range(M)], [x[s * b + beta] for s in range(M)])
                for r in range(M) for beta in range(b)]

    def tangent_coefficients(self, u: list) -> list:
        """``g^{-1} J^T W u``: the K-orthogonal tangent coefficients of an embedded vector ``u``."""
        return cholesky_solve(self.g, [_dot(self.U[i], u) for i in range(self.k)])

    def velocity_coefficients(self, u: list) -> list:
        r"""``c`` with ``J c = u`` for a tangent ``u``, by forward substitution where ``J`` is block triangular.

        :func:`~manifold.expression_linalg.block_triangular_order` finds an order of the columns in which each
        is isolated by row blocks ``R_i`` that move with the earlier columns only (an iterated suspension's hinge
        ``p_j`` moves with the levels above it, and with its own).  Then

        .. math::

            c_i = \frac{\sum_{r \in R_i} J_{ri} \big(u_r - (J c)_r|_{c_i = 0}\big)}{\sum_{r \in R_i} J_{ri}^2},

        with ``(J c)_r`` the jets' derivative along ``c`` (:attr:`Jc`), the earlier ``c_j`` substituted: one
        directional derivative through the chart formula and one column of ``J`` per level, ``O(N)`` nodes where
        ``g^{-1} J^T W u`` (:meth:`tangent_coefficients`, the fallback where no such order exists) costs
        ``O(N k^2 + k^3)``.  The two agree on tangent vectors; off them this is an oblique projection.
        """
        order = block_triangular_order(self.J, self.block)
        if order is None:
            return self.tangent_coefficients(u)
        solved: dict = {}
        for column, rows in order:
            weights = [self.J[r][column] for r in rows]
            moved = hy.subs([self.Jc[r] for r in rows], {**solved, self.c[column]: hy.expression(0.0)})
            # numerical trap: the denominator vanishes with the column's own derivative, which for a chart is
            # on its singular set; the quality events switch charts before it
            solved[self.c[column]] = (hy.sum([w * (u[r] - m) for w, r, m in zip(weights, rows, moved)])
                                      / hy.sum([w * w for w in weights]))
        return [solved[ci] for ci in self.c]

    def tangent_velocity(self, u: list, recursion: bool = True) -> tuple[list, list]:
        """``(c, J c)`` for an ambient velocity ``u``: the family's own recursion
        (:meth:`~manifold.family.ChartFamily.velocity_solve`) where it has one and ``recursion``, else
        :meth:`velocity_coefficients` and :meth:`along` (the same numbers, rounded otherwise)."""
        solved = self.family.velocity_solve(self.a, u, self.fp_type) if recursion else None
        if solved is not None:
            return solved
        c = self.velocity_coefficients(u)
        return c, self.along(c)

    def along(self, c: list) -> list:
        """``J c`` for coefficients ``c`` (expressions): the jets' derivative :attr:`Jc` with ``c`` substituted."""
        return hy.subs(self.Jc, dict(zip(self.c, c)))

    def energy(self) -> hy.expression:
        """``1/2 c^T g c``."""
        return 0.5 * hy.sum([self.c[i] * self.g[i][j] * self.c[j] for i in range(self.k) for j in range(self.k)])

    def acceleration(self, form: str = "embedded") -> list:
        """``c'`` of the geodesic equation in the given form (see the module docstring)."""
        if form not in FORMS:
            raise ValueError(f"form must be one of {FORMS}, got {form!r}")
        if form == "embedded":
            return cholesky_solve(self.g, [-_dot(self.U[i], self.h) for i in range(self.k)])
        k = self.k
        flat = [self.g[i][j] for i in range(k) for j in range(k)]
        dg = hy.diff_tensors(flat, self.a, diff_order=1).jacobian  # dg[i*k + j, l] = d_l g_ij
        rhs = []
        for l in range(k):
            terms = [0.5 * (dg[l * k + j, i] + dg[l * k + i, j] - dg[i * k + j, l]) * self.c[i] * self.c[j]
                     for i in range(k) for j in range(k)]
            rhs.append(-hy.sum(terms))
        return cholesky_solve(self.g, rhs)

    def equations(self, form: str = "embedded") -> list[tuple]:
        """The first-order system ``[(a_i, c_i), ..., (c_i, acc_i), ...]``."""
        acc = self.acceleration(form)
        return list(zip(self.a, self.c)) + list(zip(self.c, acc))

    def _par_matrix(self, start: int) -> list[list[hy.expression]]:
        """The ``N x N`` matrix of parameters ``par[start ..]``, row-major."""
        N = self.N
        return [[hy.par[start + r * N + s] for s in range(N)] for r in range(N)]

    def ambient_point(self) -> list[hy.expression]:
        """``p = M z(a) + m``: the chart's point in the ambient frame (``M``, ``m`` from ``pars``, so that one
        compiled system serves every chart of the family)."""
        lay, N = self.layout, self.N
        M = self._par_matrix(lay.map_index)
        return [hy.sum([M[r][s] * self.z[s] for s in range(N)] + [hy.par[lay.map_index + N * N + r]]) for r in range(N)]

    def ambient_velocity_equations(self, constrained: Any, n_constraint_pars: int, offset: int,
                                   recursion: bool = True, conserving: bool = False) -> list[tuple]:
        r"""The geodesic with the chart frame's ambient velocity ``V = J c`` as state: ``(a, V)`` instead of ``(a, c)``.

        .. math::

            J a' = V, \qquad V' = g - \sigma \frac{\langle g, V \rangle_W}{2 E} J a' - \gamma \big(\delta -
            \frac{\langle \delta, J a' \rangle_W}{2 E} J a'\big), \qquad g = M^{-1} f(M z(a) + m, M J a'),
            \qquad \delta = V - J a',

        with ``f(x, v)`` the constrained acceleration ``K^{-1} G^T M_G^{-1} (-(dG/dt) v)`` of a
        :class:`~manifold.constrained.ConstrainedSystem` whose zero set is the family's image (its ``x``, ``v`` in
        the ambient frame; ``constrained`` its :class:`~manifold.constrained.ConstrainedPieces`, whose
        ``n_constraint_pars`` parameters move to ``par[offset ..]``, and ``gamma`` and ``1 / (2 E)`` the two after
        them: :meth:`ambient_frame`).  The chart's
        second derivatives ``z_ab c^a c^b`` never appear: the constraints give the normal acceleration, and ``a'``
        needs only ``J``, which is why a step costs 0.6-0.7x the embedded one's Taylor recursions
        (:mod:`manifold.ambient_velocity`); ``a'`` and ``J a'`` are :meth:`tangent_velocity`: the family's own
        recursion where it has one and ``recursion``, else :meth:`velocity_coefficients` (forward substitution,
        ``O(n)``, where ``J`` is block triangular) and the jets' derivative along it (:meth:`along`).  ``f`` gets the
        tangent part ``J a'`` of ``V``: ``V`` itself would let rounding's normal drift feed back.  ``delta`` is that
        normal drift (0 on the exact solution), and the last term damps it: left alone it turns into tangent
        velocity as the tangent space turns, and the energy error grew like ``t^0.6..0.9`` instead of ``sqrt(t)``.
        The damping leaves out ``delta``'s part along ``J a'`` (``W`` the chart frame's metric, ``|J a'|_W^2 = 2 E``
        with ``E`` the segment's energy): it moves no energy, where damping all of ``delta`` pumped the rounding
        bias of ``J a'``'s length into it (``docs/math.md`` §7b).  With ``conserving`` (``sigma = 1``; else 0) the
        second term takes out ``g``'s part along ``V``: ``g`` is normal to the tangent space, so on the exact
        solution (``delta = 0``) that part is 0 and the term vanishes; off it, the energy's rate ``<V, V'>_W`` is of
        second order in ``delta`` and in the rounding of ``g``, where without the term it is of first order
        (``docs/math.md`` §7b).
        """
        lay, N = self.layout, self.N
        V = self.ambient_velocity()
        M_inv = self._par_matrix(lay.inverse_map_index)
        c, JC = self.tangent_velocity(V, recursion)
        moves = self.ambient_frame(constrained, n_constraint_pars, offset, recursion)
        f = hy.subs([rhs for _, rhs in constrained.equations(False)[N:]], moves)
        gamma, inverse_2E = hy.par[offset + n_constraint_pars], hy.par[offset + n_constraint_pars + 1]
        drift = [V[r] - JC[r] for r in range(N)]
        # numerical trap: J a' is V's tangent part only to rounding, longer or shorter on average by a few
        # hundredths of an eps (the jets' forward substitution too); damping the whole drift would pump that bias
        # into the energy, so the drift's part along J a' is left alone (K's inner product, |J a'|^2 = 2 E)
        along = _dot(drift, self._apply_W(JC)) * inverse_2E
        g = [hy.sum([M_inv[r][s] * f[s] for s in range(N)]) for r in range(N)]
        if conserving:
            # numerical trap: float64 rounding leaves g a part along V (the right-hand side shortened V by 0.006 eps
            # a step), and the states it reaches gain under the exact flow (+0.004): two first-order channels into
            # the energy, whose remainder drifted +0.0016 eps a step (T = 1.2e5: 7 standard errors); taken out here
            tangential = _dot(g, self._apply_W(V)) * inverse_2E
            g = [g[r] - tangential * JC[r] for r in range(N)]
        return list(zip(self.a, c)) + [(V[r], g[r] - gamma * (drift[r] - along * JC[r])) for r in range(N)]

    def ambient_velocity(self) -> list[hy.expression]:
        """The state variables ``V`` of :meth:`ambient_velocity_equations` (the chart frame's ambient velocity)."""
        return [hy.expression(f"V{r}") for r in range(self.N)]

    def ambient_frame(self, constrained: Any, n_constraint_pars: int, offset: int, recursion: bool = True) -> dict:
        """The substitutions that put ``constrained``'s expressions (:class:`~manifold.constrained.ConstrainedPieces`)
        on the state ``(a, V)`` of :meth:`ambient_velocity_equations`: its point ``x -> M z(a) + m``, its velocity
        ``v -> M J a'`` (``a'`` read from ``V`` by :meth:`tangent_velocity` with ``recursion``), its
        ``n_constraint_pars`` parameters ``par[j] -> par[offset + j]``.
        """
        lay, N = self.layout, self.N
        M = self._par_matrix(lay.map_index)
        JC = self.tangent_velocity(self.ambient_velocity(), recursion)[1]
        v = [hy.sum([M[r][s] * JC[s] for s in range(N)]) for r in range(N)]
        moves = {hy.par[j]: hy.par[offset + j] for j in range(n_constraint_pars)}
        moves.update({xi: pi for xi, pi in zip(constrained.x, self.ambient_point())})
        moves.update({vi: wi for vi, wi in zip(constrained.v, v)})
        return moves

    def sundman_equations(self, factor: Any, equations: list[tuple], offset: int) -> list[tuple]:
        """Geodesic ``equations`` in Sundman's time: ``dy/dtau = s(p) dy/dt`` and ``du/dtau = s(p) / (t_final - origin)``.

        ``s`` is ``factor.expression`` (a :class:`manifold.sundman.TimeFactor`) of the ambient point
        ``p = M z(a) + m`` (:meth:`ambient_point`); ``1 / (t_final - origin)`` is ``par[offset]``, the factor's
        parameters follow it.
        ``u = (t - origin) / (t_final - origin)`` is the segment's time (``origin``: its start, moved forward by
        the stepper's restarts), in ``[0, 1]`` so that it does not widen heyoka's error norm (which is relative
        to the state's largest component); the variable is the last of the state.
        """
        s = factor.expression(self.ambient_point(), [hy.par[offset + 1 + j] for j in range(factor.n_params)])
        u = hy.expression(SUNDMAN_TIME)
        return [(lhs, s * rhs) for lhs, rhs in equations] + [(u, s * hy.par[offset])]

    def events(self, switches: Sequence[int] | None = None, wraps: bool = True) -> list[Event]:
        """The family's terminal events (:func:`manifold.events.chart_events`): switch events
        ``quality_m(a) - q_out`` (those of ``switches`` only, if given), then two wraps per periodic parameter
        (with ``wraps``)."""
        return chart_events(self, switches, wraps)
