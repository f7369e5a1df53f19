"""Geodesic equations of a chart family, built symbolically and compiled by heyoka.

For ``z(a)`` with ``J = dz/da``, ambient metric ``W = B (x) I_b`` and
velocity coefficients ``c = a'``:

* embedded form (production): ``g c' = -J^T W (sum_ab z_ab c^a c^b)``,
  ``g = J^T W J``; the second-derivative term is ``d(J c)/da . c``;
* Christoffel form (cross-check, as in the dynamics seed):
  ``g c' = -Gamma(c, c)`` with ``Gamma_lij = 1/2 (d_i g_lj + d_j g_li - d_l g_ij)``
  from symbolic derivatives of ``g``.

Runtime parameters (one compiled system serves every chart of a family):
``par[0 .. p-1]`` the family parameters ``theta``, then the upper triangle of
``B`` row by row, then the switch threshold ``q_out``.  Terminal events
``quality_m(a) - q_out`` (direction: decreasing) stop the integration before a
chart's singular set.

Compiled objects are cached in memory per ``(family, fp_type, tol, form)``;
heyoka also caches machine code on disk (``heyoka.llvm_state`` disk cache).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from .expression_linalg import cholesky_solve
from .precision import as_fp, event_fp_kwargs, heyoka_fp_kwargs
from .symbolic import ChartFamily

FORMS = ("embedded", "christoffel")


@dataclass(frozen=True)
class Layout:
    """Where things live in the state and parameter vectors of a family's system."""

    n_theta: int
    n_points: int  # M = point_dim / block: size of B

    @property
    def n_metric(self) -> int:
        return self.n_points * (self.n_points + 1) // 2

    @property
    def q_out_index(self) -> int:
        return self.n_theta + self.n_metric

    def metric_pars(self) -> list[list[hy.expression]]:
        """Symmetric matrix of parameter expressions for ``B``."""
        M = self.n_points
        out, k = [[None] * M for _ in range(M)], self.n_theta
        for r in range(M):
            for s in range(r, M):
                out[r][s] = out[s][r] = hy.par[k]
                k += 1
        return out

    def pack(self, theta: NDArray, B: NDArray, q_out: float, fp_type: type) -> NDArray:
        """Parameter vector for ``theta``, ``B`` and ``q_out``."""
        iu = np.triu_indices(self.n_points)
        vals = np.concatenate([np.asarray(theta, dtype=float), np.asarray(B, dtype=float)[iu], [q_out]])
        return as_fp(vals, fp_type)


def layout(family: ChartFamily) -> Layout:
    return Layout(family.n_params, family.point_dim // family.block)


def chart_variables(k: int) -> list:
    """The heyoka variables ``a0 .. a{k-1}`` of chart parameters."""
    return [hy.expression(f"a{i}") for i in range(k)]


def _variables(k: int) -> tuple[list, list]:
    return chart_variables(k), [hy.expression(f"c{i}") for i in range(k)]


def _dot(xs: list, ys: list) -> hy.expression:
    """``sum x_i y_i`` skipping Python zeros (entries a jet knows to vanish)."""
    terms = [x * y for x, y in zip(xs, ys) if not (_is_zero(x) or _is_zero(y))]
    return hy.sum(terms) if terms else hy.expression(0.0)


def _is_zero(x) -> bool:
    return isinstance(x, (int, float)) and x == 0


class _Pieces:
    """The shared symbolic pieces: ``z``, ``J`` (rows of length ``k``), ``J c``, ``h``, ``U = W J``, ``g``.

    ``h = sum_ab z_ab c^a c^b`` (the velocity-quadratic part of ``z''``).  With a
    family that provides :meth:`~manifold.symbolic.ChartFamily.point_jets`, all
    of them come from one forward sweep of second-order jets
    (:mod:`manifold.jets`); otherwise from heyoka's symbolic differentiation of
    the expanded ``z`` (twice for ``h``), which grows much faster with the size
    of the chart formula.
    """

    def __init__(self, family: ChartFamily, fp_type: type) -> None:
        lay = layout(family)
        self.a, self.c = _variables(family.dim)
        self.block, self.k, self.N = family.block, family.dim, family.point_dim
        self.B = lay.metric_pars()
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

    def _apply_W(self, x: list) -> list:
        """``(B (x) I_b) x`` for a column ``x`` of length ``N``."""
        b, M = self.block, self.N // self.block
        return [_dot([self.B[r][s] for s in range(M)], [x[s * b + beta] for s in range(M)])
                for r in range(M) for beta in range(b)]

    def dot_W_col(self, i: int, x: list) -> hy.expression:
        """``(W J)_i . x``."""
        return _dot(self.U[i], x)


def _embedded_acceleration(P: _Pieces) -> list:
    return cholesky_solve(P.g, [-P.dot_W_col(i, P.h) for i in range(P.k)])


def _christoffel_acceleration(P: _Pieces) -> list:
    k = P.k
    flat = [P.g[i][j] for i in range(k) for j in range(k)]
    dg = hy.diff_tensors(flat, P.a, diff_order=1).jacobian  # dg[i*k + j, l] = d_l g_ij

    def d(l: int, i: int, j: int) -> hy.expression:
        return dg[i * k + j, l]

    rhs = []
    for l in range(k):
        terms = []
        for i in range(k):
            for j in range(k):
                gamma = 0.5 * (d(i, l, j) + d(j, l, i) - d(l, i, j))
                terms.append(gamma * P.c[i] * P.c[j])
        rhs.append(-hy.sum(terms))
    return cholesky_solve(P.g, rhs)


@lru_cache(maxsize=None)
def _pieces(family: ChartFamily, fp_type: type) -> _Pieces:
    return _Pieces(family, fp_type)


def geodesic_equations(family: ChartFamily, fp_type: type = float, form: str = "embedded") -> list[tuple]:
    """The first-order system ``[(a_i, c_i), ..., (c_i, acc_i), ...]`` as heyoka expressions."""
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, got {form!r}")
    P = _pieces(family, fp_type)
    acc = _embedded_acceleration(P) if form == "embedded" else _christoffel_acceleration(P)
    return [(a, c) for a, c in zip(P.a, P.c)] + [(c, x) for c, x in zip(P.c, acc)]


def switch_events(family: ChartFamily, fp_type: type, backward: bool = False) -> list:
    """Terminal events: ``quality_m(a) - q_out`` (decreasing), then ``a_p -+ pi`` for periodic ``a_p``.

    The first ``len(family.quality_expressions(a))`` events ask for a chart
    switch; each periodic parameter ``a_p`` then has two: leaving ``[-pi, pi]``
    upward and downward (a wrap by ``-+ 2 pi``, same chart).  heyoka's event
    directions refer to increasing time, so a backward integration
    (``backward=True``) needs them mirrored.
    """
    P = _pieces(family, fp_type)
    q_out = hy.par[layout(family).q_out_index]
    up, down = hy.event_direction.positive, hy.event_direction.negative
    if backward:
        up, down = down, up
    fp = event_fp_kwargs(fp_type)
    events = [hy.t_event(e - q_out, direction=down, **fp) for e in family.quality_expressions(P.a)]
    for i in family.periodic:
        events += [
            hy.t_event(P.a[i] - hy.pi, direction=up, **fp),
            hy.t_event(P.a[i] + hy.pi, direction=down, **fp),
        ]
    return events


@lru_cache(maxsize=None)
def integrator(
    family: ChartFamily, fp_type: type = float, tol: float | None = None, form: str = "embedded", backward: bool = False
):
    """Compiled Taylor integrator (compact mode) of the family's geodesics, with switch events.

    ``backward=True`` mirrors the event directions for integration toward negative times.

    ``tol=None`` uses heyoka's default, the machine epsilon of ``fp_type``.  The integrator is shared:
    callers set ``state``, ``time`` and ``pars`` before each use.  ``pars`` has
    only as many entries as the system uses (``q_out`` is unused by a family
    without switch events): fill it with ``Layout.pack(...)[:len(ta.pars)]``.
    """
    sys = geodesic_equations(family, fp_type, form)
    kw = {} if tol is None else {"tol": fp_type(tol)}
    return hy.taylor_adaptive(
        sys,
        as_fp(np.zeros(2 * family.dim), fp_type),
        compact_mode=True,
        t_events=switch_events(family, fp_type, backward),
        **kw,
        **heyoka_fp_kwargs(fp_type),
    )


@lru_cache(maxsize=None)
def transfer_cfunc(family: ChartFamily, fp_type: type = float):
    """Compiled ``(a, c, u) -> (z(a), J c, g^{-1} J^T W u, 1/2 c^T g c)``.

    Outputs concatenated: ``N + N + k + 1`` values.  With ``u`` an embedded
    vector, ``g^{-1} J^T W u`` are its tangent coefficients (exact for tangent
    ``u``): the velocity transfer at a chart switch and the Gauss-Newton step
    of the inverse map.
    """
    P = _pieces(family, fp_type)
    u = [hy.expression(f"u{r}") for r in range(P.N)]
    proj = cholesky_solve(P.g, [P.dot_W_col(i, u) for i in range(P.k)])
    energy = 0.5 * hy.sum([P.c[i] * P.g[i][j] * P.c[j] for i in range(P.k) for j in range(P.k)])
    outs = list(P.z) + list(P.Jc) + proj + [energy]
    return hy.cfunc(outs, P.a + P.c + u, compact_mode=True, **heyoka_fp_kwargs(fp_type))


@lru_cache(maxsize=None)
def acceleration_cfunc(family: ChartFamily, fp_type: type = float, form: str = "embedded"):
    """Compiled right-hand side ``(a, c) -> c'`` (for scipy integrators and checks)."""
    sys = geodesic_equations(family, fp_type, form)
    P = _pieces(family, fp_type)
    rhs = [rhs for _, rhs in sys[family.dim:]]
    return hy.cfunc(rhs, P.a + P.c, compact_mode=True, **heyoka_fp_kwargs(fp_type))
