"""Geodesics of a submanifold given by constraint equations, integrated in ambient coordinates.

A :class:`ConstrainedSystem` is the set ``{x in R^N : c(x) = 0}`` of ``m``
constraints with full-rank Jacobian ``G = dc/dx``, in ``R^N`` with a constant
metric ``K``.  Its geodesics (free motion at constant kinetic energy
``1/2 v^T K v``) solve the Lagrange-multiplier equations

.. math::

    K x'' = G^T \\lambda, \\qquad G x'' = -\\dot G v
    \\quad\\Longrightarrow\\quad
    x'' = K^{-1} G^T M^{-1} (-\\dot G v), \\qquad M = G K^{-1} G^T,

with ``(\\dot G v)_k = v^T (\\nabla^2 c_k) v``.  No chart is used, so nothing
is singular: these are ``+``, ``*`` and ``/`` only, and ``M`` is solved by a
square-root-free ``L D L^T`` that skips structural zeros (a chain's ``M`` is
tridiagonal).  The equations keep ``c'' = 0``, not ``c = 0``, so integration
errors drift off the constraints; :func:`solve_constrained` stabilises them
either way the literature does:

* ``"baumgarte"`` -- replace ``-\\dot G v`` by ``-\\dot G v - 2 \\alpha G v - \\alpha^2 c``,
  so that ``c'' + 2 alpha c' + alpha^2 c = 0``: a drift is damped critically
  at rate ``alpha`` (a runtime parameter, ``rate`` times the speed scale of
  the fastest motion ``sqrt(v^T K v tr(K^-1)) / N`` over the system's ``length_scale``, so a rate that
  does not change when the system is scaled; negated for backward runs, where time reversal
  would turn the damping into growth); all in the equations, so in every
  precision at no extra cost per step;
* ``"projection"`` -- every ``projection_interval`` project ``x`` onto
  ``c = 0`` (Gauss-Newton with the K-smallest step ``K^{-1} G^T M^{-1} c``) and
  ``v`` K-orthogonally onto ``ker G``, in the working precision;
* ``"none"`` -- for studies of the drift.

A system provides its constraints (and, optionally, hand-written ``G``, ``G v``,
``\\dot G v``, the Baumgarte term, the forces ``G^T lambda`` and multiplier pivots) as heyoka expressions; everything else is generic.
"""

from __future__ import annotations

import functools
import math
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable
from contextlib import AbstractContextManager
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, TypeAlias

import heyoka as hy
import mpmath
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .artefacts import ArtefactStore
from .budget import DEFAULT_BUDGET, Budget, spending, spent_message
from .carried import CarriedTerm, carried_violation, slot_ranges
from .expression_linalg import ldl_solve
from .interrupt import BUDGET, INTERRUPTED, SolveInterrupted, interruptible, settled
from .metric import InducedMetric
from .options import DEFAULT_PRECISION, DEFAULT_SAVE, Precision, SaveAt, StartCheck, check_group, takes_option_groups
from .precision import MultiPrecision, as_fp, heyoka_fp_kwargs, is_double, unit_roundoff
from .progress import ProgressArgument, as_callback, reporting, solve_progress
from .solution import GeodesicIntegrationError, GeodesicSolution, Segment, SolverStats, SolveStatus
from .steppers import taylor_advance, taylor_relative_tolerance
from .validation import check_bool, check_real, check_time_grid, real_array

__all__ = ["STABILISATIONS", "CompiledConstrained", "ConstrainedGeometry", "ConstrainedLayout", "ConstrainedSystem",
           "StartRefused",
           "compiled_constrained", "constraint_bound", "damping_rate", "default_compact_mode", "solve_constrained",
           "floor_scales", "speed_scale", "verdict"]

Expr: TypeAlias = hy.expression
#: How drift off the constraints is held back (see the module docstring).
STABILISATIONS = ("baumgarte", "projection", "none")
#: Largest ambient dimension integrated with unrolled (non-compact) code by default, in float64 (``N = 22``: a chain
#: of 12 rods) and in long double (``N = 8``: 5 rods), whose unrolled code compiles 3-4x slower; see
#: :func:`default_compact_mode`.
UNROLL_MAX_DIM = {"float64": 22, "long double": 8}
#: A start farther than this from ``c = 0`` (``max_k |c_k|``) is refused rather than moved, unless a constraint's
#: rounding floor (:meth:`ConstrainedGeometry.floors`) times :data:`START_ROUNDING_MARGIN` is larger.
START_CONSTRAINT_TOLERANCE = 1e-9
#: A float64 start is accepted up to this many times each constraint's rounding floor (where that exceeds
#: :data:`START_CONSTRAINT_TOLERANCE`: a chain's 6e-9 link, whose float64 rounding alone gives ``|c_k|`` ~ 2e-7).
START_ROUNDING_MARGIN = 100
#: A constraint residual below this many unit roundoffs is rounding (a rod's ``c_k`` sums several rounded terms: a
#: correctly rounded configuration showed 5 of them), and the projection leaves the point alone.  Numerical trap:
#: near a singular configuration (``L`` near ``n``) ``G`` loses rank, and projecting a rounding-level residual moved
#: a float64 start by ``eps / sigma_min(G)``, 6.7e-13 at ``L = 4 - 1e-9``, and its velocity by 6e-9 with the turned
#: tangent space.
ROUNDING_RESIDUAL = 16


class StartRefused(ValueError):
    """The start check of :meth:`ConstrainedGeometry.start` refused a start (off the constraints, a velocity off the
    tangent space, or a non-finite energy): a ``ValueError`` whose message names the row and the bound."""


class ConstrainedSystem(ABC):
    """A submanifold ``c(x) = 0`` of ``R^N`` with a constant metric ``K`` (see the module docstring).

    Subclasses set ``ambient_dim`` (``N``) and ``n_constraints`` (``m``) and
    implement :attr:`key`, :attr:`metric_matrix` and :meth:`constraint_expressions`.
    Numbers that vary between systems of one kind (a chain's ``L``) are
    runtime :attr:`parameters`, and so are the entries of ``K`` and ``K^{-1}``:
    code is compiled once per :attr:`key` and sparsity pattern of ``K``.
    A system's numbers (parameters, ``K``) must not change once it is solved: its
    :class:`ConstrainedGeometry` is built once per system object (:meth:`ConstrainedGeometry.of`).
    """

    ambient_dim: int
    n_constraints: int

    def __getstate__(self) -> dict:
        # the geometries built on the system (ConstrainedGeometry.of) are caches that hold it: rebuilt where unpickled
        return {name: value for name, value in vars(self).items() if name != "_geometries"}

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """Identity of the compiled code: equal keys mean equal constraint expressions in the parameters."""

    @property
    def parameters(self) -> NDArray:
        """Runtime constants of :meth:`constraint_expressions`, taken exact: float64 values or
        :class:`fractions.Fraction` s (derived constants, rounded once to the working precision); default none."""
        return np.zeros(0)

    @property
    def length_scale(self) -> float:
        """A typical length of the manifold in the ambient coordinates (default 1).

        The Baumgarte rate is ``rate * speed / length_scale``: a rate (1 / time)
        that does not change when the system is scaled.  Numerical trap: with the
        speed alone, a system scaled up by ``s`` gets an ``s`` times stiffer
        damping term and ``s`` times more steps (8885 against 53 at ``s = 1e4``).
        """
        return 1.0

    @property
    def rounding_scales(self) -> NDArray:
        """Per constraint, how far rounding a point of ``c = 0`` to the working precision can move ``c_k``, in unit
        roundoffs: shape ``(m,)``, default ones (constraints written relative, of values near 1).

        Every tolerance on ``c_k`` (the start check, the projection's target, the drift check) is judged against
        ``max(ROUNDING_RESIDUAL, scale_k)`` unit roundoffs.  Numerical trap: a constraint relative to a length much
        shorter than the coordinates (a chain's rod of 6e-9 between hinges at distance 6) rounds to
        ``eps |x| / l_k``, 1e8 times the others' floor; judged by the common floor, such a point could never
        pass.
        """
        return np.ones(self.n_constraints)

    @property
    def start_tolerances(self) -> NDArray:
        """Per constraint, the largest ``|c_k(x0)|`` a float64 start may have, shape ``(m,)``: by default
        :data:`START_CONSTRAINT_TOLERANCE`, or :data:`START_ROUNDING_MARGIN` times the constraint's rounding floor
        (:attr:`rounding_scales` unit roundoffs of float64, at least :data:`ROUNDING_RESIDUAL`) where that is larger.

        A system whose users check their starts in another measure (a chain's relative rod lengths) overrides it
        with that check's bound on ``c``, so that the solver takes every start the system's own check takes.
        """
        return np.maximum(START_CONSTRAINT_TOLERANCE, START_ROUNDING_MARGIN * floor_scales(self) * unit_roundoff(float))

    @property
    def tangency_weights(self) -> NDArray:
        """Per constraint, the weight ``w_k`` of its rate in the tangency check of a start velocity ``v`` (a
        :class:`~manifold.options.StartCheck` given to :func:`solve_constrained`): ``max_k w_k |(G v)_k|`` must not
        exceed :meth:`StartCheck.allowance <manifold.options.StartCheck.allowance>`; shape ``(m,)``, default ones.
        A system whose constraints are relative (a chain's ``|e_k|^2 / l_k^2 - 1``) weighs them back to velocities."""
        return np.ones(self.n_constraints)

    def rounding_hint(self, fp_type: Any, tol: float, remedy: bool = True) -> str | None:
        """What to add to a failed energy or constraint check of a solve in ``fp_type`` at tolerance ``tol`` where this
        system's coordinates are known to lose digits (a constraint held far less well than the others,
        :attr:`rounding_scales`, or a nearly singular constraint matrix), and, with ``remedy`` (a caller that can
        change the precision or the method), what would hold it; ``None`` (the default): nothing to add.  The
        solvers append it to the check's message (:func:`verdict`)."""
        return None

    @property
    @abstractmethod
    def metric_matrix(self) -> NDArray:
        """The constant ambient metric ``K``, ``(N, N)`` symmetric positive definite (float64 entries, taken exact)."""

    @abstractmethod
    def constraint_expressions(self, x: list[Expr], p: list[Expr], fp_type: Any) -> list[Expr]:
        """``c(x)``: ``m`` heyoka expressions of the variables ``x`` and the :attr:`parameters` ``p``
        (given as ``heyoka.par`` expressions); other constants made in ``fp_type``."""

    def jacobian_expressions(self, x: list[Expr], p: list[Expr], c: list[Expr]) -> list[list[Expr | None]]:
        """``G = dc/dx`` as rows of expressions, ``None`` where ``c_k`` does not involve ``x_j``.

        Default: heyoka's symbolic derivative; override with a hand-written
        sparse form when it is smaller.
        """
        names = [str(xi) for xi in x]
        rows = []
        for ck in c:
            used = set(hy.get_variables(ck))
            rows.append([hy.diff(ck, xj) if n in used else None for xj, n in zip(x, names)])
        return rows

    def multiplier_pivots(self, x: list[Expr], p: list[Expr], inverse_metric: list[list[Expr | None]],
                          fp_type: Any) -> list[Expr] | None:
        """The pivots ``D_k`` of ``M = G K^{-1} G^T = L D L^T``, written without cancellation, or ``None``.

        The generic recursion ``D_k = M_kk - L_{k,k-1}^2 D_{k-1}`` subtracts,
        and loses ``cond(M) eps`` where constraint gradients are nearly
        dependent; a system that knows its rows can write ``D_k`` as a sum of
        non-negative terms instead.  Default ``None``: the generic recursion.

        Parameters
        ----------
        x, p
            The variables and the :attr:`parameters`, as in :meth:`constraint_expressions`.
        inverse_metric
            ``K^{-1}`` as ``heyoka.par`` entries, ``None`` off its sparsity pattern.
        fp_type
            The precision of constants.
        """
        return None

    def constraint_rate_expressions(self, x: list[Expr], v: list[Expr], p: list[Expr],
                                    G: list[list[Expr | None]]) -> list[Expr]:
        """``G v``, the rates ``dc_k/dt`` of the constraints.

        Default: the products of ``G``'s rows with ``v``.  Override with a
        shorter form (each product of two variables is a full Taylor
        recursion); it must equal ``G(x) v`` identically in ``x`` and ``v``,
        not only on ``c = 0``, because the default :meth:`velocity_term_expressions`
        and the phase-space Jacobian differentiate it.

        Parameters
        ----------
        x, v, p
            The variables, velocities and :attr:`parameters` (``heyoka.par``).
        G
            The rows of :meth:`jacobian_expressions`.
        """
        return [hy.sum([g * vj for g, vj in zip(row, v) if g is not None]) for row in G]

    def velocity_term_expressions(self, x: list[Expr], v: list[Expr], p: list[Expr],
                                  G: list[list[Expr | None]]) -> list[Expr]:
        """``(dG/dt) v``, i.e. ``v^T (nabla^2 c_k) v`` for each ``k`` (default: differentiate ``G v`` along ``v``)."""
        out = []
        for Gv in self.constraint_rate_expressions(x, v, p, G):
            used = set(hy.get_variables(Gv))
            out.append(hy.sum([hy.diff(Gv, xi) * vi for xi, vi in zip(x, v) if str(xi) in used]))
        return out

    def transpose_product_expressions(self, x: list[Expr], p: list[Expr], G: list[list[Expr | None]],
                                      lam: list[Expr]) -> list[Expr | None]:
        """``G^T lambda``, the constraint forces of multipliers ``lambda`` (``None`` where no row of ``G`` acts).

        Default: a product per nonzero of ``G``.  Override where rows share
        entries up to sign (heyoka computes ``(-g) lambda`` apart from ``g lambda``).

        Parameters
        ----------
        x, p
            The variables and :attr:`parameters` (``heyoka.par``).
        G
            The rows of :meth:`jacobian_expressions`.
        lam
            The multipliers, one per constraint.
        """
        return [_sum_or_none([row[j] * lk for row, lk in zip(G, lam) if row[j] is not None]) for j in range(len(x))]

    def baumgarte_term_expressions(self, x: list[Expr], v: list[Expr], p: list[Expr], c: list[Expr],
                                   Gv: list[Expr], curvature: list[Expr], alpha: Expr) -> list[Expr]:
        """``(dG/dt) v + 2 alpha G v + alpha^2 c``: minus the right-hand side ``r`` of ``G x'' = r`` under
        Baumgarte's ``c'' + 2 alpha c' + alpha^2 c = 0``.

        Default: the three terms combined as given.  Override with a shorter form that equals it identically
        in ``x``, ``v`` and ``alpha``.

        Parameters
        ----------
        x, v, p
            The variables, velocities and :attr:`parameters` (``heyoka.par``).
        c, Gv, curvature
            The constraints, :meth:`constraint_rate_expressions` and :meth:`velocity_term_expressions`, as
            already built (the default velocity term is a symbolic derivative: not worth building twice).
        alpha
            The Baumgarte rate, a ``heyoka.par``.
        """
        return [q + alpha * (2.0 * gv + alpha * ck) for q, gv, ck in zip(curvature, Gv, c)]


def _matrix_key(K: ArrayLike) -> tuple[int, bytes]:
    """``(N, bytes)`` of a float64 ``N x N`` matrix: the key under which what a solve derives from ``K`` is cached
    (a tuple of its entries cost 20 microseconds at N = 6, its bytes under one)."""
    K = np.ascontiguousarray(K, dtype=float)
    return K.shape[0], K.tobytes()


def _exact_inverse(K: NDArray) -> list[list[Fraction]]:
    """``K^{-1}`` in exact rationals (Gauss-Jordan on the float64 entries taken exact), cached per ``K``."""
    return _exact_inverse_of(*_matrix_key(K))


@functools.lru_cache(maxsize=256)
def _exact_inverse_of(n: int, data: bytes) -> list[list[Fraction]]:
    # rational arithmetic costs ~1 ms per entry at N = 14: solves reuse the result instead of redoing it
    entries = np.frombuffer(data, dtype=float)
    A = [[Fraction(float(entries[i * n + j])) for j in range(n)] + [Fraction(int(i == j)) for j in range(n)]
         for i in range(n)]
    for col in range(n):
        piv = max(range(col, n), key=lambda r: abs(A[r][col]))
        if A[piv][col] == 0:
            raise ValueError("the metric matrix K is singular")
        A[col], A[piv] = A[piv], A[col]
        p = A[col][col]
        A[col] = [a / p for a in A[col]]
        for r in range(n):
            if r != col and A[r][col] != 0:
                f = A[r][col]
                A[r] = [a - f * b for a, b in zip(A[r], A[col])]
    return [row[n:] for row in A]


def _fraction_to_fp(q: Fraction, fp_type: Any) -> Any:
    """A rational rounded once to ``fp_type`` (through a 40-digit-margin decimal string)."""
    if q.denominator == 1 or is_double(fp_type):
        return fp_type(float(q)) if is_double(fp_type) else fp_type(q.numerator)
    bits = int(-np.log2(unit_roundoff(fp_type))) + 64
    with mpmath.workprec(bits):
        text = mpmath.nstr(mpmath.mpf(q.numerator) / q.denominator, int(bits * 0.302) + 2, strip_zeros=False)
    if isinstance(fp_type, MultiPrecision):
        return hy.real(text, fp_type.bits)
    return fp_type(text)


@dataclass(frozen=True)
class ConstrainedLayout:
    """Where the runtime parameters live: ``(alpha, system parameters, K^{-1} entries, K entries)``.

    Only the structurally nonzero entries of the lower triangles of ``K^{-1}``
    and ``K`` are parameters; their pattern is part of the compiled code.
    """

    n_parameters: int
    inverse_pattern: tuple[tuple[int, int], ...]
    metric_pattern: tuple[tuple[int, int], ...]

    @classmethod
    def of(cls, system: ConstrainedSystem) -> "ConstrainedLayout":
        """The layout of ``system``: its parameter count and the nonzero patterns of ``K^{-1}`` (exact) and ``K``."""
        return _layout_of(len(system.parameters), *_matrix_key(system.metric_matrix))

    def matrices(self, N: int) -> tuple[list[list[Expr | None]], list[list[Expr | None]]]:
        """Symmetric ``K^{-1}`` and ``K`` of ``heyoka.par`` entries (``None`` off the patterns)."""
        out = []
        offset = 1 + self.n_parameters
        for pattern in (self.inverse_pattern, self.metric_pattern):
            A: list[list[Expr | None]] = [[None] * N for _ in range(N)]
            for m, (i, j) in enumerate(pattern):
                A[i][j] = A[j][i] = hy.par[offset + m]
            offset += len(pattern)
            out.append(A)
        return out[0], out[1]

    def pack(self, system: ConstrainedSystem, alpha: float, fp_type: Any) -> NDArray:
        """The parameter values in ``fp_type``: ``K^{-1}`` rounded once from its exact rational value (all but
        ``alpha`` cached per system values and precision: the rational roundings cost ~0.2 ms a solve at n = 4)."""
        out = _packed(self, tuple(system.parameters), *_matrix_key(system.metric_matrix), fp_type).copy()
        out[0] = fp_type(alpha)
        return out


@functools.lru_cache(maxsize=256)
def _layout_of(n_parameters: int, N: int, data: bytes) -> ConstrainedLayout:
    K = np.frombuffer(data, dtype=float).reshape(N, N)
    Ki = _exact_inverse_of(N, data)
    return ConstrainedLayout(n_parameters, tuple((i, j) for i in range(N) for j in range(i + 1) if Ki[i][j] != 0),
                             tuple((i, j) for i in range(N) for j in range(i + 1) if K[i, j] != 0))


@functools.lru_cache(maxsize=256)
def _packed(layout: ConstrainedLayout, parameters: tuple, N: int, data: bytes, fp_type: Any) -> NDArray:
    """:meth:`ConstrainedLayout.pack` with ``alpha = 0`` (read-only: callers copy)."""
    K = np.frombuffer(data, dtype=float).reshape(N, N)
    Ki = _exact_inverse_of(N, data)
    values = [fp_type(0.0)] + [_fraction_to_fp(x if isinstance(x, Fraction) else Fraction(float(x)), fp_type)
                               for x in parameters]
    values += [_fraction_to_fp(Ki[i][j], fp_type) for i, j in layout.inverse_pattern]
    values += [fp_type(float(K[i, j])) for i, j in layout.metric_pattern]
    out = as_fp(np.array(values, dtype=object), fp_type)
    out.flags.writeable = False
    return out


class ConstrainedPieces:
    """The symbolic equations of one system in one precision: nothing compiled.

    Attributes
    ----------
    x, v
        Position and velocity variables ``x0..``, ``v0..``.
    c, G, Gv
        Constraints, sparse Jacobian rows and ``G v``.
    curvature, damped
        ``(dG/dt) v`` and the Baumgarte-damped ``(dG/dt) v + 2 alpha G v + alpha^2 c`` (``alpha = par[0]``).
    M
        The multiplier matrix ``G K^{-1} G^T`` (lower triangle), ``None`` for structural zeros.
    pivots
        The system's :meth:`ConstrainedSystem.multiplier_pivots` of ``M``, or ``None``.
    system, params
        The system and its :attr:`~ConstrainedSystem.parameters` as ``heyoka.par`` expressions.
    """

    def __init__(self, system: ConstrainedSystem, layout: ConstrainedLayout, fp_type: Any) -> None:
        N = system.ambient_dim
        self.fp = fp_type
        self.x = [hy.expression(f"x{i}") for i in range(N)]
        self.v = [hy.expression(f"v{i}") for i in range(N)]
        params = [hy.par[1 + i] for i in range(layout.n_parameters)]
        self.c = system.constraint_expressions(self.x, params, fp_type)
        if len(self.c) != system.n_constraints:
            raise ValueError(f"constraint_expressions gave {len(self.c)} constraints, the system declares "
                             f"{system.n_constraints}")
        self.G = system.jacobian_expressions(self.x, params, self.c)
        self.Gv = system.constraint_rate_expressions(self.x, self.v, params, self.G)
        self.curvature = system.velocity_term_expressions(self.x, self.v, params, self.G)
        self.damped = system.baumgarte_term_expressions(self.x, self.v, params, self.c, self.Gv, self.curvature,
                                                        hy.par[0])
        Kinv, self.K = layout.matrices(N)
        self.system, self.params, self._Kinv = system, params, Kinv
        m = len(self.c)
        # W = K^{-1} G^T (N x m) and M = G W (m x m), keeping structural zeros
        W = [[_sum_or_none([kij * gkj for kij, gkj in zip(Kinv[i], self.G[k])
                                 if kij is not None and gkj is not None]) for k in range(m)]
                  for i in range(N)]
        self.M = [[_sum_or_none([gki * wil for gki, wil in zip(self.G[k], [row[l] for row in W])
                                 if gki is not None and wil is not None]) if l <= k else None
                   for l in range(m)] for k in range(m)]
        self.pivots = system.multiplier_pivots(self.x, params, Kinv, fp_type)
        if self.pivots is not None and len(self.pivots) != m:
            raise ValueError(f"multiplier_pivots gave {len(self.pivots)} pivots, the system declares {m} constraints")

    def correction(self, r: list[Expr]) -> list[Expr]:
        """``K^{-1} G^T M^{-1} r``: the K-smallest ``d`` with ``G d = r`` (``G^T lambda`` first: products with the
        parameters ``K^{-1}`` cost O(order), products with ``W = K^{-1} G^T`` the O(order^2) of two variables)."""
        force = self.system.transpose_product_expressions(self.x, self.params, self.G,
                                                          ldl_solve(self.M, r, self.pivots))
        return [_sum_or_none([kij * fj for kij, fj in zip(row, force) if kij is not None and fj is not None])
                or hy.expression(self.fp(0)) for row in self._Kinv]

    def rates(self, w: list[Expr]) -> list[Expr]:
        """``G(x) w``: the constraints' rates along ``w`` (:meth:`ConstrainedSystem.constraint_rate_expressions`)."""
        return self.system.constraint_rate_expressions(self.x, w, self.params, self.G)

    def bilinear(self, w: list[Expr]) -> list[Expr]:
        """``v^T (nabla^2 c_k) w`` for each ``k``: ``(dG/dt) w`` along the velocity ``v``, symmetric in ``v`` and ``w``.

        Written as the derivative of ``G v`` along ``w`` (``G v`` is exact off the constraints,
        :meth:`ConstrainedSystem.constraint_rate_expressions`); at ``w = v`` it is the velocity term.
        """
        out = []
        for Gv in self.Gv:
            used = set(hy.get_variables(Gv))
            terms = [hy.diff(Gv, xi) * wi for xi, wi in zip(self.x, w) if str(xi) in used]
            out.append(hy.sum(terms) if terms else hy.expression(self.fp(0)))
        return out

    def equations(self, stabilised: bool) -> list[tuple[Expr, Expr]]:
        """``x' = v``, ``v' = K^{-1} G^T M^{-1} r`` with ``r = -(dG/dt) v`` (minus ``2 alpha G v + alpha^2 c``
        if ``stabilised``; ``alpha = par[0]``)."""
        acc = self.correction([-q for q in (self.damped if stabilised else self.curvature)])
        return list(zip(self.x, self.v)) + list(zip(self.v, acc))

    def energy(self, v: list[Expr] | None = None) -> Expr:
        """``1/2 v^T K v`` (of the velocity variables, or of the expressions ``v``)."""
        v = self.v if v is None else v
        N = len(v)
        terms = [self.K[i][j] * v[i] * v[j] for i in range(N) for j in range(N) if self.K[i][j] is not None]
        return hy.expression(self.fp(0.5)) * hy.sum(terms)


def _sum_or_none(terms: list[Expr]) -> Expr | None:
    if not terms:
        return None
    return terms[0] if len(terms) == 1 else hy.sum(terms)


class CompiledConstrained(ArtefactStore):
    """Compiled artefacts of one :class:`ConstrainedSystem` (get the shared one from :func:`compiled_constrained`).

    Attributes
    ----------
    system
        The first system of this key and layout (any other builds the same expressions).
    layout
        The :class:`ConstrainedLayout` of the runtime parameters.
    """

    def __init__(self, system: ConstrainedSystem, layout: ConstrainedLayout) -> None:
        super().__init__(repr(system))
        self.system, self.layout = system, layout

    def __repr__(self) -> str:
        return f"CompiledConstrained({self.system!r}, {len(self._artefacts)} artefacts)"

    def pieces(self, fp_type: Any) -> ConstrainedPieces:
        """The symbolic equations, constants in ``fp_type``, numbers of the system as ``heyoka.par``."""
        return self._get(("pieces", fp_type), lambda: ConstrainedPieces(self.system, self.layout, fp_type))

    def geometry(self, fp_type: Any = float) -> Any:
        """Compiled ``(x, v, r) -> (c(x), G(x) v, K^{-1} G^T M^{-1} r, 1/2 v^T K v)``: ``m + m + N + 1`` outputs."""
        def build() -> Any:
            P = self.pieces(fp_type)
            r = [hy.expression(f"r{k}") for k in range(len(P.c))]
            outs = P.c + P.Gv + P.correction(r) + [P.energy()]
            return hy.cfunc(outs, P.x + P.v + r, compact_mode=True, **heyoka_fp_kwargs(fp_type))
        return self._get(("geometry", fp_type), build)

    def projection(self, fp_type: Any = float) -> Any:
        """Compiled ``(x, v) -> (c(x), G(x) v, u, 1/2 u^T K u)`` with ``u = v - K^{-1} G^T M^{-1} G v``, ``v``
        projected K-orthogonally onto ``ker G(x)``: ``m + m + N + 1`` outputs.

        What :meth:`geometry` gives in three calls, each needing the last (``c`` and ``G v``; the correction of
        ``r = G v``; the energy at ``u``), in one (a solve's start pays heyoka's call overhead once instead of three
        times): the same operations in the same order, so ``c``, ``G v`` and the energy of ``u`` are the same
        numbers, and ``u`` is to rounding: within one function the compiler may fuse ``v - K^{-1} f`` into one
        multiply-add (in float64 up to 2.4 ulp of ``max |v|`` for velocities far off the tangent space; none seen for
        a start's normal part of 1e-9, nor in long double).
        """
        def build() -> Any:
            P = self.pieces(fp_type)
            u = [vi - di for vi, di in zip(P.v, P.correction(P.Gv))]
            return hy.cfunc(P.c + P.Gv + u + [P.energy(u)], P.x + P.v, compact_mode=True,
                            **heyoka_fp_kwargs(fp_type))
        return self._get(("projection", fp_type), build)

    def acceleration(self, fp_type: Any = float, stabilised: bool = True) -> Any:
        """Compiled right-hand side ``(x, v) -> x''`` (parameters as the integrator's), for other steppers and checks."""
        def build() -> Any:
            P = self.pieces(fp_type)
            acc = [rhs for _, rhs in P.equations(stabilised)[len(P.x):]]
            return hy.cfunc(acc, P.x + P.v, **heyoka_fp_kwargs(fp_type))
        return self._get(("acceleration", fp_type, stabilised), build)

    def bilinear(self, fp_type: Any = float) -> Any:
        """Compiled ``(x, v, w) -> v^T (nabla^2 c_k) w`` (:meth:`ConstrainedPieces.bilinear`), ``m`` outputs."""
        def build() -> Any:
            P = self.pieces(fp_type)
            w = [hy.expression(f"w{i}") for i in range(len(P.x))]
            return hy.cfunc(P.bilinear(w), P.x + P.v + w, compact_mode=True, **heyoka_fp_kwargs(fp_type))
        return self._get(("bilinear", fp_type), build)

    def integrator(self, fp_type: Any = float, tol: float | None = None, stabilised: bool = True,
                   compact_mode: bool = False, carry: tuple[CarriedTerm, ...] = ()) -> AbstractContextManager[Any]:
        """Lend a Taylor integrator of the constrained equations, with the equations of the terms ``carry``
        (:mod:`manifold.carried`) after ``(x, v)``; set ``pars`` (:meth:`ConstrainedLayout.pack`) before use."""
        def build() -> Any:
            P = self.pieces(fp_type)
            equations = P.equations(stabilised)
            for j, term in enumerate(carry):
                y = [hy.expression(f"carried{j}_{i}") for i in range(term.size(len(P.x)))]
                equations += list(zip(y, term.equations(P, y, stabilised)))
            kw = {} if tol is None else {"tol": fp_type(tol)}
            return hy.taylor_adaptive(equations, as_fp(np.zeros(len(equations)), fp_type),
                                      compact_mode=compact_mode, **kw,
                                      **heyoka_fp_kwargs(fp_type))

        key = ("integrator", fp_type, tol, stabilised, compact_mode, tuple(term.key for term in carry))
        return self._lend(key, build)  # the store's own context manager: a generator around it costs ~2.5 us a solve

    def phase_jacobian(self, fp_type: Any = float) -> Any:
        """Compiled ``(x, v) -> d(c, G v) / d(x, v)``, the ``2m x 2N`` Jacobian (row-major) of the functions whose
        zeros are the phase space ``{c = 0, G v = 0}``; its null space is that space's tangent space."""
        def build() -> Any:
            P = self.pieces(fp_type)
            zero = hy.expression(fp_type(0.0))
            rows = []
            for f in P.c + P.Gv:
                used = set(hy.get_variables(f))
                rows += [hy.diff(f, y) if str(y) in used else zero for y in P.x + P.v]
            return hy.cfunc(rows, P.x + P.v, compact_mode=True, **heyoka_fp_kwargs(fp_type))
        return self._get(("phase jacobian", fp_type), build)

    def tangent_integrator(self, k: int, tol: float | None = None,
                           compact_mode: bool = True) -> AbstractContextManager[Any]:
        """Lend a float64 Taylor integrator of the Baumgarte-stabilised equations ``y' = f(y)``, ``y = (x, v)``,
        with ``k`` deviations carried by their variational equations ``d_a' = (df/dy) d_a``: state
        ``(x, v, d_1, ..., d_k)``.

        Each ``(df/dy) d_a`` is written as ``d/de f(y + e d_a)`` at ``e = 0``
        (forward mode, a few times the cost of ``f``).  ``heyoka.var_ode_sys``
        builds the whole ``2N x 2N`` matrix ``dy(t)/dy(0)`` instead: at
        ``n = 4`` (``N = 6``) that costs 5x more per step for one deviation
        (900 against 180 microseconds, compact mode).
        """
        def build() -> Any:
            P = self.pieces(float)
            equations = P.equations(True)
            y = [lhs for lhs, _ in equations]
            e = hy.expression("lin_e")
            rows = list(equations)
            for a in range(k):
                d = [hy.expression(f"dev{a}_{i}") for i in range(len(y))]
                shifted = hy.subs([rhs for _, rhs in equations], {str(yi): yi + e * di for yi, di in zip(y, d)})
                rows += [(di, hy.subs(hy.diff(g, e), {"lin_e": hy.expression(0.0)})) for di, g in zip(d, shifted)]
            kw = {} if tol is None else {"tol": float(tol)}
            return hy.taylor_adaptive(rows, np.zeros(len(rows)), compact_mode=compact_mode, **kw)

        return self._lend(("tangent integrator", float, k, tol, compact_mode), build)

    def batch_integrator(self, batch_size: int, tol: float | None = None,
                         compact_mode: bool = False) -> AbstractContextManager[Any]:
        """Lend a float64 SIMD batch integrator (``heyoka.taylor_adaptive_batch``) of the Baumgarte-stabilised
        equations, ``batch_size`` trajectories per step; parameters are columns, one per lane."""
        def build() -> Any:
            P = self.pieces(float)
            kw = {} if tol is None else {"tol": float(tol)}
            return hy.taylor_adaptive_batch(P.equations(True), np.zeros((2 * len(P.x), batch_size)),
                                            compact_mode=compact_mode, **kw)

        return self._lend(("batch integrator", float, batch_size, tol, compact_mode), build)


_REGISTRY: dict[Hashable, CompiledConstrained] = {}
_REGISTRY_LOCK = threading.Lock()


def compiled_constrained(system: ConstrainedSystem) -> CompiledConstrained:
    """The shared :class:`CompiledConstrained` of ``system`` (one per ``system.key`` and pattern of ``K``)."""
    layout = ConstrainedLayout.of(system)
    key = (system.key, layout)
    with _REGISTRY_LOCK:
        if key not in _REGISTRY:
            _REGISTRY[key] = CompiledConstrained(system, layout)
        return _REGISTRY[key]


class ConstrainedGeometry:
    """The geometry cfunc of one system in the working precision, with the projections and start checks built on it.

    Shared by :func:`solve_constrained` and the ensemble solver
    (:mod:`manifold.constrained_batch`), so that both start every
    trajectory from the same state.

    Parameters
    ----------
    system
        The :class:`ConstrainedSystem`.
    fp_type
        The working precision.
    """

    def __init__(self, system: ConstrainedSystem, fp_type: Any) -> None:
        comp = compiled_constrained(system)
        self.fp, self.cf = fp_type, comp.geometry(fp_type)
        self.pars = comp.layout.pack(system, 0.0, fp_type)
        self.N, self.m = system.ambient_dim, system.n_constraints
        self.eps = unit_roundoff(fp_type)
        self.speed_scale = speed_scale(system)
        self.K = as_fp(np.asarray(system.metric_matrix, dtype=float), fp_type)  # float64 entries: exact in fp_type
        scales = floor_scales(system)
        if scales.shape != (self.m,) or not np.all(np.isfinite(scales)):
            raise ValueError(f"{system!r}.rounding_scales must be {self.m} finite numbers, got {scales!r}")
        #: each constraint's floor over the common one (ROUNDING_RESIDUAL unit roundoffs), >= 1: drift is judged by it
        self.weights = scales / ROUNDING_RESIDUAL
        self.floors = scales * self.eps
        self.tangency_weights = np.asarray(system.tangency_weights, dtype=float)
        if self.tangency_weights.shape != (self.m,) or not np.all(self.tangency_weights >= 0) \
                or not np.all(np.isfinite(self.tangency_weights)):
            raise ValueError(f"{system!r}.tangency_weights must be {self.m} finite numbers >= 0, "
                             f"got {self.tangency_weights!r}")
        self.start_tolerances = np.asarray(system.start_tolerances, dtype=float)
        if self.start_tolerances.shape != (self.m,) or not np.all(self.start_tolerances > 0) \
                or not np.all(np.isfinite(self.start_tolerances)):
            raise ValueError(f"{system!r}.start_tolerances must be {self.m} finite numbers > 0, "
                             f"got {self.start_tolerances!r}")
        self.system, self._compiled = system, comp
        self._one_column = np.ascontiguousarray(self.pars[:, None])  # the parameters of a single row
        # numpy's dtype of fp_type (None for multiprecision, whose numbers as_fp rebuilds at exactly its bits)
        self._dtype = None if isinstance(fp_type, MultiPrecision) else np.dtype(fp_type)
        self._max_steps = 3 + int(np.ceil(-np.log2(self.eps) / 50))  # Gauss-Newton steps of the projection, at most

    @classmethod
    def of(cls, system: ConstrainedSystem, fp_type: Any) -> ConstrainedGeometry:
        """The geometry of ``system`` in ``fp_type``, built once per system object and precision (its packed
        parameters, speed scale and ``K`` cost ~30 us at n = 4, more than evaluating it) and shared after."""
        # kept on the system itself (a weak-keyed table would be kept alive by its geometries, which hold the system)
        cached = vars(system).setdefault("_geometries", {})
        try:
            return cached[fp_type]
        except KeyError:
            return cached.setdefault(fp_type, cls(system, fp_type))

    def __getstate__(self) -> dict:
        # the compiled store holds locks: a pickled geometry (a result shipped to a worker) rebuilds from its system
        return {"system": self.system, "fp": self.fp}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["system"], state["fp"])  # type: ignore[misc]

    def __call__(self, x: NDArray, v: NDArray, r: NDArray | None = None) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Batched ``(c, G v, correction(r), E)`` for ``x, v`` of shape ``(B, N)``."""
        r = np.zeros((x.shape[0], self.m)) if r is None else r
        return self._evaluate(self.cf, [x.T, v.T, r.T])

    def projection(self, x: NDArray, v: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Batched ``(c, G v, u, E(u))`` for ``x, v`` of shape ``(B, N)``: ``u = v - correction(G v)``, ``v``
        projected K-orthogonally onto ``ker G(x)``, and its energy, in one compiled call
        (:meth:`CompiledConstrained.projection`: ``v - self(x, v, G v)[2]`` to rounding, and ``self(x, u)[3]``)."""
        return self._evaluate(self._projection, [x.T, v.T])

    @functools.cached_property
    def _projection(self) -> Any:
        return self._compiled.projection(self.fp)  # compiled when first needed: not every user of a geometry starts

    def _evaluate(self, cf: Any, columns: list[NDArray]) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """``cf`` (outputs ``m``, ``m``, ``N``, ``1``) on the rows stacked as ``columns``, split into its outputs."""
        B = columns[0].shape[1]
        args = np.ascontiguousarray(np.concatenate(columns))  # C-ordered (transposed rows concatenate F-ordered)
        if self._dtype is None or args.dtype != self._dtype:  # rows in fp_type need no second copy; mp always converts
            args = as_fp(args, self.fp)
        one = self._one_column[: cf.nparams]
        out = cf(args, pars=one if B == 1 else np.ascontiguousarray(np.repeat(one, B, axis=1)))
        m, N = self.m, self.N
        return out[:m].T, out[m : 2 * m].T, out[2 * m : 2 * m + N].T, out[-1]

    def drift(self, c: NDArray) -> NDArray:
        """``max_k |c_k| / w_k`` over the last axis, ``w_k >= 1`` each constraint's rounding floor over the common one
        (:attr:`ConstrainedSystem.rounding_scales`): the number every drift check compares with
        :func:`constraint_bound` (NaN stays NaN, and fails it; no constraints: 0)."""
        if not c.shape[-1]:
            return np.zeros(c.shape[:-1])
        return (np.abs(np.asarray(c, dtype=float)) / self.weights).max(axis=-1)  # the method: no np.max dispatch

    def packed(self, alpha: Any) -> NDArray:
        """The integrator's parameters (:meth:`ConstrainedLayout.pack`) with the Baumgarte rate ``alpha``."""
        out = self.pars.copy()
        out[0] = self.fp(alpha)
        return out

    def inner(self, a: NDArray, b: NDArray) -> NDArray:
        """``a^T K b`` over the last axis, in the working precision."""
        return np.sum((a @ self.K) * b, axis=-1)

    def tangent(self, x: NDArray, w: NDArray) -> NDArray:
        """Rows ``(B, N)``: the K-orthogonal projection ``w - K^{-1} G^T M^{-1} G w`` of ``w`` onto ``ker G(x)``."""
        _, Gw, _, _ = self(x, w)
        return w - self(x, w, Gw)[2]

    def bilinear(self, x: NDArray, v: NDArray, w: NDArray) -> NDArray:
        """``v^T (nabla^2 c_k) w`` for rows ``x, v, w`` of shape ``(B, N)``: shape ``(B, m)`` (:meth:`ConstrainedPieces.bilinear`)."""
        cf = self._compiled.bilinear(self.fp)
        args = np.ascontiguousarray(as_fp(np.concatenate([x, v, w], axis=1).T, self.fp))
        return cf(args, pars=np.ascontiguousarray(np.repeat(self.pars[: cf.nparams, None], x.shape[0], axis=1))).T

    def project(self, x: NDArray, v: NDArray) -> tuple[NDArray, NDArray]:
        """Rows ``(B, N)``: Gauss-Newton ``x -= K^{-1} G^T M^{-1} c(x)`` until every ``|c_k|`` is within its
        rounding floor (:data:`ROUNDING_RESIDUAL` ``eps``, or more: :attr:`ConstrainedSystem.rounding_scales`),
        row by row, then ``v -= K^{-1} G^T M^{-1} G v``.

        A row that has converged is left alone while the others iterate, and
        the compiled function evaluates columns independently, so each row
        gets exactly what projecting it alone gives.
        """
        projected = self.projection(x, v)
        x, v, _ = self._projected(x.copy(), v, projected, np.abs(projected[0].astype(float)))
        return x, v

    def _projected(self, x: NDArray, v: NDArray, projected: tuple[NDArray, NDArray, NDArray, NDArray],
                   c_abs: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """:meth:`project` of rows ``x, v`` (``x`` the caller's copy, changed in place) given :meth:`projection`
        there and ``|c|`` (as floats); also the energies of the projected velocities."""
        c, _, u, E = projected
        if (c_abs <= self.floors).all():  # most starts already lie within the floors: no row moves
            return x, u, E
        active = np.arange(x.shape[0])
        for step in range(self._max_steps):
            if step:
                c = self(x[active], v[active])[0]
                c_abs = np.abs(c.astype(float))
            moving = ~(c_abs <= self.floors).all(axis=1)
            active, c = active[moving], c[moving]
            if not active.size:
                break
            x[active] = x[active] - self(x[active], v[active], c)[2]
        _, _, u, E = self.projection(x, v)  # x moved: v projected at the new x
        return x, u, E

    def start(self, x0: NDArray, v0: NDArray, t_final: float, rate: float, first_index: int | None = None,
              check: StartCheck | None = None) -> tuple[NDArray, NDArray, NDArray, NDArray]:
        """Check float64 starts (rows ``(B, N)``) and complete them to the working precision.

        Returns ``(x, v, E0, alpha)`` per row: ``x0`` projected onto ``c = 0``
        and ``v0`` K-orthogonally onto ``ker G`` (:meth:`project`), the kinetic
        energy there, and the Baumgarte rate ``alpha = sign(t_final) rate
        sqrt(2 E0 tr(K^-1)) / (N length_scale)`` (:attr:`ConstrainedSystem.length_scale`).
        Raises :class:`StartRefused` if some ``|c_k(x0)|`` exceeds its bound (:attr:`ConstrainedSystem.start_tolerances`),
        an energy is not finite or, with a ``check``, a ``v0`` is off the tangent space: ``max_k w_k |(G v0)_k|``
        (:attr:`ConstrainedSystem.tangency_weights`) above :meth:`StartCheck.allowance
        <manifold.options.StartCheck.allowance>` (unless ``check.project_velocity``); the row is named
        ``x0[first_index + k]`` (``x0`` alone if ``first_index`` is ``None``).  All from the one compiled call
        that projects (:meth:`projection`), so a start is checked once.
        """
        def name(k: int, what: str = "x0") -> str:
            return what if first_index is None else f"{what}[{first_index + k}]"

        x, v = as_fp(x0, self.fp), as_fp(v0, self.fp)  # new arrays: the projection changes x in place
        projected = self.projection(x, v)  # the check's c and G v are the projection's first
        c0 = np.abs(projected[0].astype(float))
        if not (c0 <= self.start_tolerances).all():  # NaN fails too
            bad = ~(c0 <= self.start_tolerances).all(axis=1)
            k = int(np.argmax(bad))
            j = int(np.argmax(~(c0[k] <= self.start_tolerances)))
            raise StartRefused(f"{name(k)} is not on the constraint manifold: |c_{j}(x0)| = {c0[k, j]:.3g} exceeds "
                               f"{self.start_tolerances[j]:.3g}")
        off = np.zeros(len(x0), dtype=bool)  # rows whose v0 is off the tangent space beyond the check's allowance
        if check is not None:
            residual = (np.abs(projected[1].astype(float)) * self.tangency_weights).max(axis=1, initial=0.0)
            off = ~(residual <= check.allowance(v0))
            if off.any() and not check.project_velocity:
                k = int(np.argmax(off))
                raise StartRefused(f"{name(k, 'v0')} is not tangent to the constraint manifold: max_k w_k |(G v0)_k| = "
                                   f"{residual[k]:.3g} exceeds tangent_tol * max(1, |v0|) = {check.allowance(v0[k]):.3g}")
        x, v, E0 = self._projected(x, v, projected, c0)
        if off.any():
            # a second pass: one leaves ~cond(G) eps of a large normal part, which Baumgarte's term turned into an
            # energy error 700x its bound (a push of 1e6 |v| off the tangent space, L = 4 - 1e-6)
            _, _, v[off], E0[off] = self.projection(x[off], v[off])
        E0f = np.array([float(e) for e in E0])
        if not np.isfinite(E0f).all():
            k = int(np.argmax(~np.isfinite(E0f)))
            raise StartRefused(f"{name(k, 'v0')} gives a non-finite kinetic energy (max |v0| = {np.max(np.abs(v0[k])):.3g})")
        return x, v, E0, damping_rate(self.speed_scale, rate, E0f, t_final)


def floor_scales(system: ConstrainedSystem) -> NDArray:
    """Each constraint's rounding floor in unit roundoffs, ``max(ROUNDING_RESIDUAL, rounding_scales[k])``: the one
    rule behind the start check, the projection's target and the drift check."""
    return np.maximum(ROUNDING_RESIDUAL, np.asarray(system.rounding_scales, dtype=float))


def speed_scale(system: ConstrainedSystem) -> float:
    """``sqrt(tr(K^-1)) / (N length_scale)``: times ``sqrt(2 E)``, the speed scale of the fastest motion over the
    system's length (a constant of the system, for :func:`damping_rate`).

    With ``sqrt(2 E / tr K)``, the heavy masses' speed, hinge masses 1e-3 and 1e2 (n = 3) were damped 160x too
    slowly and drifted off ``c = 0`` by 3.3e-12 over T = 20 (unit masses: 9e-16); for equal masses the two agree.
    """
    N, data = _matrix_key(system.metric_matrix)
    return _root_trace_inverse(N, data) / N / float(system.length_scale)


@functools.lru_cache(maxsize=256)
def _root_trace_inverse(N: int, data: bytes) -> float:
    """``sqrt(tr K^-1)`` from the exact inverse (the layout's, cached)."""
    return float(np.sqrt(float(sum(row[i] for i, row in enumerate(_exact_inverse_of(N, data))))))


def damping_rate(scale: float, rate: float, energy: Any, direction: float) -> Any:
    """``sign(direction) rate sqrt(2 E) scale``: a damping rate (1 / time) of drift off the manifold at kinetic
    energy ``energy`` (a number or an array), ``scale`` the system's :func:`speed_scale`; scale-free in lengths,
    masses and speed.  A damping term must damp in the direction of integration: backward (``direction < 0``)
    the rate flips sign."""
    return float(np.sign(direction)) * rate * np.sqrt(2 * energy) * scale


def default_compact_mode(system: ConstrainedSystem, fp_type: Any) -> bool:
    """heyoka's compact mode by default, chosen by measurement: off (unrolled code) up to ``N =``
    :data:`UNROLL_MAX_DIM` (22 in float64, 8 in long double), on beyond and for software floating types.

    Unrolled code steps 1.5-2.2x faster (float64, n = 4..12; long double 1.8-2.0x) and its cold compile grows
    about linearly with ``n``: in float64 6-9 s of CPU at n = 8, 11 s at n = 10 and 15 s at n = 12 (a SIMD batch
    15 s at n = 10 and 12), paid once per machine, since heyoka keeps the code in its disk cache and loads it from
    there in 0.05-0.25 s; at n = 10 and 12 it made a T = 20 call 1.7-1.8x faster.  Long double compiles 3-5x
    slower (12-13 s at n = 4, 30 s at n = 6), so it unrolls only to n = 5.  In real128 and multiprecision the
    software arithmetic dominates the step and unrolled code only costs compile time (at 150 bits it exhausted
    memory).  docs/methods.md, "Compile options", has the measurements.
    """
    if is_double(fp_type):
        return system.ambient_dim > UNROLL_MAX_DIM["float64"]
    if fp_type is np.longdouble:
        return system.ambient_dim > UNROLL_MAX_DIM["long double"]
    return True


def constraint_bound(n_steps: int, eps: float) -> float:
    """The bound on ``max_k |c_k|`` after ``n_steps`` steps at relative tolerance ``eps``: ``1000 sqrt(n_steps + 1) eps``."""
    return float(1e3 * math.sqrt(n_steps + 1) * eps)  # math: no numpy scalar round trip


def verdict(energy_violation: str | None, drift: float, n_steps: int, eps: float, t: float,
            failure: str | None, hint: Callable[[float], str | None] | None = None) -> tuple[SolveStatus, str]:
    """How a stretch of a constrained solve ended: the checks in the order every constrained solver applies them.

    Parameters
    ----------
    energy_violation
        The energy check's sentence (:func:`manifold.solution.energy_violation`), ``None`` if it passed.
    drift
        ``max_k |c_k| / w_k`` over the states checked (:meth:`ConstrainedGeometry.drift`; NaN fails).
    n_steps
        Steps taken so far.
    eps
        The relative tolerance.
    t
        Time reached.
    failure
        Why the integrator stopped early (``None`` if it did not).
    hint
        The sentence for a failed energy or constraint check, from the tolerance ``eps``
        (:meth:`ConstrainedSystem.rounding_hint`); asked only when a check fails.

    Returns
    -------
    tuple
        ``(status, message)``: :attr:`SolveStatus.SUCCESS` and ``"reached t_final"``,
        else the energy failure, the constraint failure, an interrupt (:data:`manifold.interrupt.INTERRUPTED`) or
        the stepper failure (in that order).
    """
    def note() -> str:
        sentence = None if hint is None else hint(eps)
        return "" if sentence is None else f"; {sentence}"

    if energy_violation is not None:
        return SolveStatus.ENERGY_CHECK_FAILED, energy_violation + note()
    bound = constraint_bound(n_steps, eps)
    if not drift <= bound:
        return SolveStatus.CONSTRAINT_CHECK_FAILED, (
            f"constraint check failed by t = {t:.6g}: max_k |c_k| / w_k = {drift:.3g} (w_k >= 1: each constraint's "
            f"rounding floor over the common one) exceeds "
            f"1000 sqrt(steps + 1) tol = {bound:.3g}{note()}")
    if failure == INTERRUPTED:
        return SolveStatus.INTERRUPTED, f"{INTERRUPTED} at t = {t}"
    if failure == BUDGET:  # the solver words it (manifold.budget.spent_message): it knows the budget and t_final
        return SolveStatus.BUDGET_EXCEEDED, f"{BUDGET} at t = {t}"
    if failure is not None:
        return SolveStatus.STEPPER_FAILED, f"integration failed at t = {t}: {failure}"
    return SolveStatus.SUCCESS, "reached t_final"


@takes_option_groups
def solve_constrained(
    system: ConstrainedSystem,
    x0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    precision: Precision = DEFAULT_PRECISION,
    stabilisation: str = "baumgarte",
    rate: float = 1.0,
    projection_interval: float = 10.0,
    compact_mode: bool | None = None,
    save: SaveAt = DEFAULT_SAVE,
    metric: InducedMetric | None = None,
    throw: bool = True,
    progress: ProgressArgument = None,
    carry: tuple[CarriedTerm, ...] = (),
    budget: Budget = DEFAULT_BUDGET,
    start: StartCheck | None = None,
) -> GeodesicSolution:
    """Integrate the geodesic of ``system`` from ``(x0, v0)`` with heyoka's Taylor method, in ambient coordinates.

    Parameters
    ----------
    system
        The :class:`ConstrainedSystem`.
    x0, v0
        Start point (each ``|c_k(x0)|`` within :attr:`ConstrainedSystem.start_tolerances`: by default ``1e-9``, or
        100 times the constraint's float64 rounding floor where that is larger; else ``ValueError``) and
        velocity (shape ``(N,)``).  Both are completed to the working precision:
        ``x0`` projected onto ``c = 0``, ``v0`` K-orthogonally onto ``ker G``
        (so a float64 start is an exact start for a quad-precision run).
        Without ``start``, check tangency before calling: this projection only removes rounding.
    t_final
        Final time, finite and nonzero; negative integrates backward.
    precision
        :class:`~manifold.options.Precision` ``(fp_type, tol)``: ``float`` (default), ``numpy.longdouble``,
        ``heyoka.real128``, :class:`~manifold.precision.MultiPrecision`, or a name (``"float64"``,
        ``"longdouble"``, ``"real128"``, ``"mp<bits>"``); heyoka's tolerance, in ``(0, 1e-2]``, ``None`` (default)
        the machine epsilon of ``fp_type``.
    stabilisation
        ``"baumgarte"`` (default), ``"projection"`` or ``"none"`` (module docstring).
    rate
        Baumgarte rate ``alpha`` in units of ``sqrt(v^T K v tr(K^-1)) / (N system.length_scale)``, ``> 0``.
    projection_interval
        Time between projections for ``"projection"``, ``> 0``.
    compact_mode
        heyoka's compact mode; ``None`` (default) chooses by measurement (:func:`default_compact_mode`;
        docs/methods.md, "Compile options"): unrolled code up to ``N = 22`` (a chain of 12 rods) in float64 and
        ``N = 8`` (5 rods) in long double, where it steps 1.5-2.2x faster for a cold compile of 2-15 s of CPU
        in float64 (12-13 s in long double at n = 4) paid once per machine (heyoka keeps it in its disk cache);
        compact beyond, for real128 and :class:`~manifold.precision.MultiPrecision`, whose software arithmetic
        dominates the step, and with terms carried (``carry``; a Jacobi field at n = 4 took 52 s to compile
        unrolled, 1.1 s compact).
    save
        :class:`~manifold.options.SaveAt` ``(t_eval, dense)``: times (within ``[0, t_final]``, in integration
        order) recorded in ``sol.points`` and ``sol.velocities``, and whether to keep the Taylor coefficients
        of every step (default), for ``sol(t)`` at any time.
    metric
        The :class:`~manifold.metric.InducedMetric` of the same manifold, if it
        has an atlas: then ``sol.parameters(t)`` reads chart parameters on demand.
    throw
        Raise :class:`~manifold.solution.GeodesicIntegrationError` with the
        partial solution on failure (default), or return it with ``status`` set.
    progress
        Report compiles and the time reached, as in
        :func:`manifold.solve_chart_exp_ode`: ``True`` (a tqdm bar), a
        callable taking a :class:`~manifold.progress.ProgressUpdate`,
        ``False``, or ``None`` (only inside a :func:`manifold.progress.reporting` block).
    budget
        The :class:`~manifold.budget.Budget` of Taylor steps and dense-output bytes (default
        :data:`~manifold.budget.DEFAULT_BUDGET`); spent, the solve stops with status ``BUDGET_EXCEEDED``.
    carry
        :class:`~manifold.carried.CarriedTerm` s integrated along (use :func:`manifold.carried.solve_carried`,
        which reads them back); their invariants are checked at every recorded step.  Not with
        ``"projection"``, which would have to project them too.
    start
        A :class:`~manifold.options.StartCheck` ``(tangent_tol, project_velocity)``: ``v0`` is also checked for
        tangency, ``max_k w_k |(G v0)_k| <= tangent_tol * max(1, |v0|)`` (:attr:`ConstrainedSystem.tangency_weights`),
        from the same compiled call as the closure check and the projection, and refused unless
        ``project_velocity`` (then projected K-orthogonally, in a second pass where it failed the check);
        ``None`` (default): the caller has checked it.

    Returns
    -------
    GeodesicSolution
        With segments in ambient coordinates (``chart = None``).  Energies are
        recorded at every step and checked against the solvers' bound;
        ``max_k |c_k|`` likewise (status ``CONSTRAINT_CHECK_FAILED``), and the
        carried terms' invariants (``CARRIED_CHECK_FAILED``).  Without dense output
        (``SaveAt(dense=False)``) the energy and ``max_k |c_k|`` are checked at the kept states only, with the same
        bound (it counts every step): the ``t_eval`` times, which heyoka samples as it steps (no Python per step,
        unless terms are carried: their invariants are checked at every step), and each segment's end.
    """
    wall0 = time.perf_counter()
    precision, save = check_group("precision", precision, Precision), check_group("save", save, SaveAt)
    fp_type, tol, dense, t_eval = precision.fp_type, precision.tol, save.keeps_dense(True), save.t_eval
    if start is not None:
        start = check_group("start", start, StartCheck)
    report = as_callback(progress)
    t_final = check_real("t_final", t_final, nonzero=True)
    if stabilisation not in STABILISATIONS:
        raise ValueError(f"stabilisation must be one of {STABILISATIONS}, got {stabilisation!r}")
    carry = tuple(carry)
    if not all(isinstance(term, CarriedTerm) for term in carry):
        raise TypeError(f"carry must hold CarriedTerm objects, got {carry!r}")
    if carry and stabilisation == "projection":
        raise ValueError("carry cannot be used with stabilisation='projection' (the carried quantities would need "
                         "projecting too): use 'baumgarte' or 'none'")
    rate = check_real("rate", rate, positive=True)
    interval = check_real("projection_interval", projection_interval, positive=True)
    if compact_mode is None:
        # with a Jacobi field carried, unrolled code took 52 s to compile at n = 4 (compact: 1.1 s)
        compact_mode = default_compact_mode(system, fp_type) or bool(carry)
    compact_mode, throw = check_bool("compact_mode", compact_mode), check_bool("throw", throw)
    N = system.ambient_dim
    x0, v0 = real_array("x0", x0), real_array("v0", v0)
    for name, arr in (("x0", x0), ("v0", v0)):
        if arr.shape != (N,):
            raise ValueError(f"{name} must have shape ({N},), got {arr.shape}")
    grid = None
    if t_eval is not None:
        grid = check_time_grid(t_eval, t_final)

    t_compile = time.perf_counter()
    with reporting(report):  # compiles the geometry function
        geo = ConstrainedGeometry.of(system, fp_type)
    comp = geo._compiled  # compiled_constrained(system), held by the geometry
    xs, vs, E0s, alphas = geo.start(x0[None, :], v0[None, :], t_final, rate, check=start)
    x, v, E0, alpha = xs[0], vs[0], E0s[0], float(alphas[0])
    carried = np.concatenate([np.zeros(0, dtype=x.dtype)] + [term.start(geo, x, v) for term in carry])
    first = np.concatenate([x, v, carried])
    slots = slot_ranges(carry, N)

    sol = GeodesicSolution(metric, fp_type, f"constrained-taylor ({stabilisation})", (0.0, t_final), {})
    sol.t_eval, sol.ambient_dim = grid, N
    sol.energy_times.append(fp_type(0.0))
    sol.energies.append(E0)
    eps = taylor_relative_tolerance(tol, fp_type)
    sign = float(np.sign(t_final))
    ends = [t_final] if stabilisation != "projection" else _chunk_ends(t_final, interval)
    n_grid, project_seconds = 0, 0.0
    # without dense output heyoka samples the grid itself; carried terms' invariants are checked at every step
    sampled = grid is not None and not dense and not carry
    t = fp_type(0.0)
    with solve_progress(report, sol) as reports, comp.integrator(fp_type, tol, stabilisation == "baumgarte",
                                                                      compact_mode, carry) as ta, \
            interruptible() as pressed, spending(budget) as account:
        compile_seconds = time.perf_counter() - t_compile
        pars = geo.packed(alpha)
        for end in ends:
            # x' = v: without carried terms the positions' polynomials hold the velocities' (half the bytes)
            times = _segment_grid(grid, n_grid, end, sign, fp_type) if grid is not None and sampled else None
            adv = taylor_advance(ta, t, np.concatenate([x, v, carried]), fp_type(end), pars,
                                 dense or (grid is not None and not sampled), fp_type,
                                 positions=0 if carry else N, grid=times)
            sol.segments.append(Segment(None, t, adv.t, adv.n_steps, adv.dense if dense else None))
            c, _, _, E = geo(adv.step_states[:, :N], adv.step_states[:, N : 2 * N])
            recorded = len(sol.energies)
            sol.energy_times.extend(adv.step_times)
            sol.energies.extend(np.atleast_1d(E))
            if grid is not None:
                n_grid = sol.record_grid(grid, n_grid, adv, sign, lambda s: (s[:, :N], s[:, N : 2 * N]))
            t, x, v, carried = adv.t, adv.y[:N], adv.y[N : 2 * N], adv.y[2 * N :]
            if reports is not None:
                reports.segment(t, "ambient coordinates")
            drift = float(geo.drift(c).max(initial=0.0))
            status, message = verdict(sol.energy_violation(recorded, eps, "ambient coordinates"), drift,
                                      sol.n_steps, eps, float(t), adv.failure,
                                      lambda tol: system.rounding_hint(fp_type, tol))
            for term, sl in zip(carry, slots):
                violation = carried_violation(term, geo, adv.step_states, first, sl, adv.step_times, sol.n_steps, eps)
                if status is SolveStatus.SUCCESS and violation is not None:
                    status, message = SolveStatus.CARRIED_CHECK_FAILED, violation
            if status is SolveStatus.BUDGET_EXCEEDED:
                message = spent_message(account, float(t), t_final)
            if status is SolveStatus.SUCCESS and pressed():  # Ctrl-C between segments: stop at a whole one
                status, message = SolveStatus.INTERRUPTED, f"{INTERRUPTED} at t = {float(t)}"
            if status is not SolveStatus.SUCCESS:
                break
            if stabilisation == "projection" and end != ends[-1]:
                p0 = time.perf_counter()
                xs, vs = geo.project(x[None, :], v[None, :])
                x, v = xs[0], vs[0]
                project_seconds += time.perf_counter() - p0
        pressed_at_all = pressed()  # also where another failure ended the run: a Ctrl-C is never swallowed
    status, message = settled(pressed_at_all, status, message, t)
    sol.final_state = (None, x, v)
    sol.status, sol.message = status, message
    sol.stats = SolverStats(sol.n_steps, 0, 0, compile_seconds, project_seconds, time.perf_counter() - wall0)
    if reports is not None:
        reports.done(t, message)
    if status is SolveStatus.INTERRUPTED:
        raise SolveInterrupted(message, sol)
    if status is not SolveStatus.SUCCESS and throw:
        raise GeodesicIntegrationError(message, sol)
    return sol


def _segment_grid(grid: NDArray, done: int, end: float, sign: float, fp_type: Any) -> NDArray:
    """The times of ``grid`` from ``done`` up to a segment's ``end`` (inclusive), in the working precision."""
    upto = int(np.searchsorted(sign * grid, sign * end, side="right"))
    return as_fp(grid[done:upto], fp_type)


def _chunk_ends(t_final: float, interval: float) -> list[float]:
    """``interval, 2 interval, ..., t_final`` (signed like ``t_final``; no sliver at the end)."""
    n = max(1, int(np.ceil(abs(t_final) / interval - 1e-9)))
    return [t_final * (j / n) for j in range(1, n + 1)]
