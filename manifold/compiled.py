"""Everything compiled for one chart family, built once per ``family.key`` and shared safely.

:func:`compiled` returns the :class:`CompiledFamily` of a family.  It owns the
parameter :class:`~manifold.geodesic_system.Layout`, the symbolic pieces per
precision, and lazily compiled artefacts: the geodesic Taylor integrator, the
transfer, acceleration, quality, point, Jacobian, Hessian and inverse functions.  Charts derive their
numpy Jacobian, Hessian and quality from it, and solvers their integrators, so each
formula exists once.

Thread safety: artefacts are built under a lock; compiled functions are
stateless; integrators are stateful, so :meth:`CompiledFamily.integrator`
lends each caller its own copy from a pool (two solves never share one).

heyoka also caches machine code on disk (``heyoka.llvm_state`` disk cache,
default ``~/.cache/heyoka``): a second process skips LLVM's optimisation.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .artefacts import ArtefactStore
from .chart import gauss_newton
from .events import Event, event_slopes, heyoka_events
from .family import ChartFamily
from .geodesic_system import Layout, SymbolicPieces
from .precision import as_fp, heyoka_fp_kwargs, is_double, unit_roundoff
from .terms import ChartGeodesic, StateTerm, Term


#: Taylor tolerance used when none is given, per floating type (``benchmarks/taylor_options.py``): in float64,
#: 1e-14 gives the final hinge error and energy error of the machine epsilon (1e-14 and 1e-15 over T = 20,
#: n = 4..8) at 0.71-0.84x its cost; 1e-13 already loses a digit at n = 6 and 8.  Other types: the machine
#: epsilon of the type (heyoka's default), not measured.
DEFAULT_TOLERANCE = {float: 1e-14}
#: LLVM optimisation level of the compiled integrators (``benchmarks/taylor_options.py``): levels 1 and 2 step
#: 13-16 % faster than 3 in compact mode (n = 4..8, float64) and 1 compiles 1.6-2.2x faster than 3; 0 steps 2x slower.
DEFAULT_OPT_LEVEL = 1


def default_tolerance(fp_type: Any) -> float | None:
    """The Taylor tolerance used for ``fp_type`` when none is given (``None``: heyoka's, the machine epsilon)."""
    return DEFAULT_TOLERANCE[float] if is_double(fp_type) else None


class CompiledFamily(ArtefactStore):
    """Compiled artefacts of one chart family (use :func:`compiled` to get the shared instance).

    Attributes
    ----------
    family
        The :class:`~manifold.family.ChartFamily`.
    layout
        Where ``theta``, ``B`` and ``q_out`` live in the runtime parameters.
    n_quality
        Number of quality expressions (= switch events); 0 for a global chart.
    compile_seconds
        Wall time spent building artefacts so far (symbolic work and LLVM).
    """

    def __init__(self, family: ChartFamily) -> None:
        super().__init__(repr(family))
        self.family = family
        self.layout = Layout.of(family)
        self.n_quality = len(self.pieces(float).quality)

    def __repr__(self) -> str:
        return f"CompiledFamily({self.family!r}, {len(self._artefacts)} artefacts)"

    def pieces(self, fp_type: Any) -> SymbolicPieces:
        """The symbolic pieces with constants exact in ``fp_type``."""
        return self._get(("pieces", fp_type), lambda: SymbolicPieces(self.family, fp_type))

    def _cfunc(self, key: tuple, fp_type: Any, outputs: Callable[[SymbolicPieces], list], inputs: str) -> Any:
        def build() -> Any:
            P = self.pieces(fp_type)
            args = {"a": P.a, "ac": P.a + P.c}[inputs]
            outs = [o if isinstance(o, hy.expression) else hy.expression(float(o)) for o in outputs(P)]
            return hy.cfunc(outs, args, compact_mode=True, **heyoka_fp_kwargs(fp_type))
        return self._get(key, build)

    def transfer(self, fp_type: Any = float) -> Any:
        """Compiled ``(a, c, u) -> (z(a), J c, g^{-1} J^T W u, 1/2 c^T g c)``: ``N + N + k + 1`` outputs.

        With ``u`` an embedded vector, ``g^{-1} J^T W u`` are its tangent
        coefficients (exact for tangent ``u``): the velocity transfer at a
        chart switch and the Gauss-Newton step of the inverse map.
        """
        def build() -> Any:
            P = self.pieces(fp_type)
            u = [hy.expression(f"u{r}") for r in range(P.N)]
            outs = list(P.z) + list(P.Jc) + P.tangent_coefficients(u) + [P.energy()]
            return hy.cfunc(outs, P.a + P.c + u, compact_mode=True, **heyoka_fp_kwargs(fp_type))
        return self._get(("transfer", fp_type), build)

    def acceleration(self, fp_type: Any = float, form: str = "embedded") -> Any:
        """Compiled right-hand side ``(a, c) -> c'`` (for other steppers and checks)."""
        return self._cfunc(("acceleration", fp_type, form), fp_type, lambda P: P.acceleration(form), "ac")

    def quality(self, fp_type: Any = float) -> Any:
        """Compiled ``a -> (quality_1(a), ...)`` (``None`` for a global chart: no quality expressions)."""
        if self.n_quality == 0:
            return None
        return self._cfunc(("quality", fp_type), fp_type, lambda P: P.quality, "a")

    def events(self, wraps: bool = True) -> list[Event]:
        """The family's terminal events (:func:`manifold.events.chart_events`), in the canonical numbering; without
        the wraps (``wraps=False``) those its Taylor integrators declare (:meth:`composition`)."""
        return self.pieces(float).events(wraps=wraps)

    def event_values(self, fp_type: Any = float) -> Any:
        """Compiled ``(a, c) -> (g_1, ..., g_m, dg_1/dt, ..., dg_m/dt)``: the :meth:`events`' values and their rates
        along the motion ``a' = c``, for steppers whose events the loop locates on dense output
        (:func:`manifold.events.first_crossing`); the parameters are a chart's, up to ``q_out``."""
        def outputs(P: SymbolicPieces) -> list:
            events = P.events()
            return [e.expression for e in events] + event_slopes(events, P.a, P.c)
        return self._cfunc(("event values", fp_type), fp_type, outputs, "ac")

    def jacobian(self, fp_type: Any = float) -> Any:
        """Compiled ``a -> (z(a), dz/da)``: ``N`` values then the Jacobian row-major (``N x k``)."""
        return self._cfunc(("jacobian", fp_type), fp_type, lambda P: list(P.z) + [x for row in P.J for x in row], "a")

    def hessian(self, fp_type: Any = float) -> Any:
        """Compiled ``a -> d^2 z / da_i da_j`` for ``i <= j`` (row-major over ``z``, then ``(i, j)``): ``N k (k+1) / 2`` outputs.

        One symbolic differentiation of the Jacobian ``J`` (which a family with
        :meth:`~manifold.family.ChartFamily.point_jets` has from its jet sweep):
        the second fundamental form and the curvature need nothing more.
        """
        def outputs(P: SymbolicPieces) -> list:
            k = P.k
            flat = [x if isinstance(x, hy.expression) else hy.expression(float(x)) for row in P.J for x in row]
            d = hy.diff_tensors(flat, P.a, diff_order=1).jacobian  # d[r*k + i, j] = z_r,ij
            return [d[r * k + i, j] for r in range(P.N) for i in range(k) for j in range(i, k)]
        return self._cfunc(("hessian", fp_type), fp_type, outputs, "a")

    def inverse(self, fp_type: Any = float) -> Any:
        """Compiled ``z -> (a(z), quality_1(a(z)), ...)`` from the family's closed-form inverse; ``None`` without one.

        One evaluation ranks a chart at a point: its approximate parameters and
        its quality there, with no Jacobian and no polish.
        """
        def build() -> Any:
            z = [hy.expression(f"z{r}") for r in range(self.family.point_dim)]
            a = self.family.inverse_expressions(z, fp_type)
            if a is None:
                return None
            outs = [x if isinstance(x, hy.expression) else hy.expression(float(x))
                    for x in list(a) + list(self.family.quality_expressions(a))]
            return hy.cfunc(outs, z, compact_mode=True, **heyoka_fp_kwargs(fp_type))
        return self._get(("inverse", fp_type), build)

    def point(self, fp_type: Any = float) -> Any:
        """Compiled ``a -> z(a)``: the chart map alone (no Jacobian to compute and throw away)."""
        return self._cfunc(("point", fp_type), fp_type, lambda P: list(P.z), "a")

    def composition(self, fp_type: Any, terms: Sequence[Term] | None = None,
                    switches: Sequence[int] | None = None) -> tuple[list[tuple], list[Event]]:
        """The equations and terminal events of the composition ``terms`` (:mod:`manifold.terms`), built once.

        ``terms``, in order: a :class:`~manifold.terms.StateTerm` first (default: ``ChartGeodesic()``, the state
        ``(a, c)`` in the embedded form), each term's parameters after the previous one's from
        :attr:`~manifold.geodesic_system.Layout.terms_index`, its events after the family's (the atlas loop reads
        what each event index means here).  ``switches``: the qualities whose switch events are kept (``None``: all;
        :meth:`~manifold.family.ChartFamily.quality_floors`).  No wrap events: the Taylor steppers wrap the periodic
        parameters between steps (:func:`manifold.steppers.angle_wrap`).
        """
        terms = _checked_terms(terms)
        switches = None if switches is None else tuple(switches)

        def build() -> tuple[list[tuple], list[Event]]:
            P = self.pieces(fp_type)
            equations: list[tuple] = []
            events, offset = P.events(switches, wraps=False), self.layout.terms_index  # wrapped between steps
            for term in terms:
                equations = term.equations(P, equations, offset)
                events += term.events(equations, offset)
                offset += term.n_params
            return equations, events
        return self._get(("composition", fp_type, tuple(t.key for t in terms), switches), build)

    @contextmanager
    def integrator(self, fp_type: Any = float, tol: float | None = None, terms: Sequence[Term] | None = None,
                   backward: bool = False, compact_mode: bool = True,
                   opt_level: int = DEFAULT_OPT_LEVEL, switches: Sequence[int] | None = None) -> Iterator[Any]:
        """Lend a Taylor integrator of the geodesics with switch events; return it after use.

        The caller owns it inside the ``with`` block: set ``state``, ``time``
        and ``pars`` (:attr:`ChartNumerics.pars`, then each term's parameters) before each use.
        ``tol=None`` is :func:`default_tolerance` (1e-14 in float64, the
        machine epsilon of other types).  ``terms`` (:mod:`manifold.terms`) compose the equations
        (:meth:`composition`), with the switch events of ``switches`` only if given; no wrap events: a caller that
        runs it past ``+-pi`` in a periodic parameter wraps it between steps (:func:`manifold.steppers.angle_wrap`).
        ``backward=True`` mirrors the event directions for negative times.
        ``compact_mode`` and ``opt_level`` (LLVM's optimisation level, 0..3) are heyoka's compile options; each
        combination is a separate integrator.
        """
        terms = _checked_terms(terms)
        tol = default_tolerance(fp_type) if tol is None else tol
        switches = None if switches is None else tuple(switches)
        key = ("integrator", fp_type, tol, backward, compact_mode, opt_level, tuple(t.key for t in terms), switches)

        def build() -> Any:
            kw = {} if tol is None else {"tol": fp_type(tol)}
            equations, events = self.composition(fp_type, terms, switches)
            return hy.taylor_adaptive(equations, as_fp(np.zeros(len(equations)), fp_type), compact_mode=compact_mode,
                                      opt_level=opt_level, t_events=heyoka_events(events, backward, fp_type), **kw,
                                      **heyoka_fp_kwargs(fp_type))

        with self._lend(key, build) as ta:
            yield ta

    def transfer_at(self, fp_type: Any, pars: NDArray) -> Transfer:
        """The compiled :meth:`transfer` at one chart's parameters ``pars`` (:class:`Transfer`)."""
        return Transfer(self, fp_type, pars)

    def evaluate_inverse(self, theta: ArrayLike, z: ArrayLike) -> tuple[NDArray, NDArray]:
        """Approximate parameters ``a(z)`` (``(..., k)``) and the quality there (``(...)``), float64, batched.

        ``theta`` has shape ``(n_params,)`` or ``(..., n_params)``; requires
        :meth:`~manifold.family.ChartFamily.inverse_expressions`.
        """
        z = np.asarray(z, dtype=float)
        out = _batched(self.inverse(float), z, theta)
        k = self.family.dim
        q = np.min(out[..., k:], axis=-1) if self.n_quality else np.ones(z.shape[:-1])
        return out[..., :k], q

    def evaluate_point(self, theta: ArrayLike, a: ArrayLike) -> NDArray:
        """``z`` (``(..., N)``) at parameters ``a`` (float64, batched; ``theta`` of shape ``(..., n_params)``)."""
        a = np.asarray(a, dtype=float)
        return _batched(self.point(float), a, theta)

    def evaluate_jacobian(self, theta: ArrayLike, a: ArrayLike) -> tuple[NDArray, NDArray]:
        """``z`` (``(..., N)``) and ``dz/da`` (``(..., N, k)``) at parameters ``a`` (float64, batched)."""
        a = np.asarray(a, dtype=float)
        k, N = self.family.dim, self.family.point_dim
        out = _batched(self.jacobian(float), a, theta)
        return out[..., :N], out[..., N:].reshape(*a.shape[:-1], N, k)

    def evaluate_hessian(self, theta: ArrayLike, a: ArrayLike) -> NDArray:
        """``d^2 z / da_i da_j`` at parameters ``a``, shape ``(..., N, k, k)``, symmetric (float64, batched)."""
        a = np.asarray(a, dtype=float)
        k, N = self.family.dim, self.family.point_dim
        upper = _batched(self.hessian(float), a, theta).reshape(*a.shape[:-1], N, k * (k + 1) // 2)
        i, j = np.triu_indices(k)
        H = np.empty((*a.shape[:-1], N, k, k))
        H[..., i, j] = upper
        H[..., j, i] = upper
        return H

    def evaluate_quality(self, theta: ArrayLike, a: ArrayLike) -> NDArray:
        """``min_m quality_m(a)`` (float64, batched; ``theta`` broadcast against ``a``'s leading axes); 1 for a global chart."""
        a = np.asarray(a, dtype=float)
        cf = self.quality(float)
        if cf is None:
            return np.ones(a.shape[:-1])
        return np.min(_batched(cf, a, theta), axis=-1)


def _batched(cf: Any, a: NDArray, theta: ArrayLike) -> NDArray:
    """Evaluate a float64 cfunc of ``a`` over the leading axes of ``a`` (shape ``(..., k)``).

    ``theta`` (shape ``(n_params,)``, or ``(..., n_params)`` broadcast against
    those axes) gives the runtime parameters of each evaluation.
    """
    lead = a.shape[:-1]
    theta = np.asarray(theta, dtype=float)[..., : cf.nparams]
    flat = np.ascontiguousarray(a.reshape(-1, a.shape[-1]).T)
    if theta.ndim == 1:  # one theta for all: no broadcasting (a start or a switch evaluates one point at a time)
        pars = theta[:, None] if flat.shape[1] == 1 else np.repeat(theta[:, None], flat.shape[1], axis=1)
    else:
        pars = np.ascontiguousarray(np.broadcast_to(theta, (*lead, theta.shape[-1])).reshape(flat.shape[1], theta.shape[-1]).T)
    return cf(flat, pars=pars).T.reshape(*lead, -1)


def _checked_terms(terms: Sequence[Term] | None) -> tuple[Term, ...]:
    """``terms`` as a tuple (default: ``ChartGeodesic()``), refused unless a state term comes first and only there."""
    terms = (ChartGeodesic(),) if terms is None else tuple(terms)
    if not terms or not isinstance(terms[0], StateTerm) or not all(
            isinstance(t, Term) and not isinstance(t, StateTerm) for t in terms[1:]):
        raise TypeError(f"terms must be a manifold.terms.StateTerm followed by other Terms, got {terms!r}")
    return terms


_REGISTRY: dict[Hashable, CompiledFamily] = {}
_REGISTRY_LOCK = threading.Lock()


def compiled(family: ChartFamily) -> CompiledFamily:
    """The shared :class:`CompiledFamily` of ``family`` (one per ``family.key``)."""
    key = family.key
    with _REGISTRY_LOCK:
        if key not in _REGISTRY:
            _REGISTRY[key] = CompiledFamily(family)
        return _REGISTRY[key]


class Transfer:
    """The family's compiled transfer ``(a, c, u) -> (z, J c, g^{-1} J^T W u, E)`` at one chart's parameters
    ``pars``, in the working precision, batched over columns (``a``, ``c`` of shape ``(k, B)``, ``u`` ``(N, B)``)."""

    def __init__(self, family: CompiledFamily, fp_type: Any, pars: NDArray) -> None:
        self.cf, self.fp = family.transfer(fp_type), fp_type
        self.k, self.N = family.family.dim, family.family.point_dim
        self.pars = pars[: self.cf.nparams, None]  # theta and B: the transfer reads no q_out, map or span

    def __call__(self, a: NDArray, c: NDArray, u: NDArray) -> NDArray:
        """The ``N + N + k + 1`` outputs (rows) at each column."""
        args = np.ascontiguousarray(as_fp(np.concatenate([a, c, u]), self.fp))
        return self.cf(args, pars=np.repeat(self.pars, args.shape[1], axis=1))

    def coefficients(self, a: NDArray, u: NDArray) -> NDArray:
        """``c = g^{-1} J^T W u`` (shape ``(k, B)``): the W-orthogonal tangent coefficients of chart-frame vectors ``u``.

        The normal equations lose ``cond(g)`` (large for strongly unequal
        masses); one step of iterative refinement, ``c += g^{-1} J^T W (u - J c)``
        with the residual in the working precision, brings ``J c`` back to ``u``
        to rounding wherever ``cond(g) eps < 1``.
        """
        k, N = self.k, self.N
        zeros_c = np.zeros((k, a.shape[1]))
        c = self(a, zeros_c, u)[2 * N : 2 * N + k]
        Jc = self(a, c, np.zeros((N, a.shape[1])))[N : 2 * N]
        return c + self(a, zeros_c, u - Jc)[2 * N : 2 * N + k]


class ChartNumerics:
    """One chart ``p = M z(a; theta) + m`` in the working precision, for a given ambient metric.

    Parameters
    ----------
    chart
        A :class:`~manifold.symbolic.SymbolicChart`.
    K
        The ambient metric; it must pull back to ``B (x) I_block``.
    q_out
        Switch threshold packed into the parameters.
    fp_type
        Working precision.

    Attributes
    ----------
    pars
        The runtime parameters ``(theta, B, q_out, M, m, M^{-1})`` in ``fp_type`` (:class:`~manifold.geodesic_system.Layout`).
    """

    def __init__(self, chart: Any, K: NDArray, q_out: float, fp_type: Any) -> None:
        self._arguments = (chart, K, q_out, fp_type)
        self.fp, self.k, self.N = fp_type, chart.dim, chart.ambient_dim
        self.compiled = compiled(chart.family)
        self.M = as_fp(chart.linear_map, fp_type)
        self.M_inv = as_fp(chart.inverse_linear_map(), fp_type)
        self.m = chart.offset(fp_type)
        self.K = as_fp(K, fp_type)
        # theta, B, q_out, then the chart's map M, offset m and M^{-1} (read only in Sundman's time, manifold.sundman,
        # and with the ambient velocity as state, manifold.ambient_velocity)
        self.pars = np.concatenate([self.compiled.layout.pack(chart.family_parameters, chart.core_metric(K), q_out, fp_type),
                                    self.M.ravel(), self.m, self.M_inv.ravel()])
        for x in (self.M, self.M_inv, self.m, self.K, self.pars):  # shared by every solve on the chart (SymbolicChart.numerics)
            x.flags.writeable = False
        self._eval = Transfer(self.compiled, fp_type, self.pars)

    def __getstate__(self) -> dict:
        # the compiled family holds locks: a pickled solution (shipped to a worker) rebuilds its numerics
        return {"arguments": self._arguments}

    def __setstate__(self, state: dict) -> None:
        self.__init__(*state["arguments"])  # type: ignore[misc]

    def point_velocity_energy(self, a: NDArray, c: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """``p = M z(a) + m`` and ``v = M J c`` (shape ``(B, N)``) and ``E = 1/2 v^T K v`` (``(B,)``) for ``a, c`` of
        shape ``(k, B)``."""
        out = self._eval(a, c, np.zeros((self.N, a.shape[1])))
        z, v = out[: self.N], (self.M @ out[self.N : 2 * self.N]).T
        # numerical trap: 1/2 c^T g c sums entries of g that carry the heaviest mass's rounding; with hinge masses
        # spread over 1e7 the recorded energy scattered by 1e-11 from step to step while the motion held 4e-13.
        # 1/2 v^T K v of the embedded velocity sums positive terms for a diagonal K
        with np.errstate(over="ignore"):  # a huge velocity's energy is inf, which the callers refuse by name
            E = np.sum(v * (v @ self.K), axis=1) / 2  # (0.5 * x fails for real128 arrays)
        return (self.M @ z).T + self.m, v, E

    def point_velocity_states(self, states: NDArray) -> tuple[NDArray, NDArray]:
        """Points and embedded velocities ``(m, N)`` of chart states ``(a, c)`` stacked as rows ``(m, >= 2k)``."""
        p, v, _ = self.point_velocity_energy(states[:, : self.k].T, states[:, self.k : 2 * self.k].T)
        return p, v

    def coefficients(self, a: NDArray, v: NDArray) -> NDArray:
        """``c = g^{-1} J^T K v``: the K-orthogonal tangent coefficients of the embedded ``v``, refined once
        (:meth:`Transfer.coefficients`)."""
        return self._eval.coefficients(a[:, None], (self.M_inv @ v)[:, None])[:, 0]

    def _project(self, a: NDArray, u: NDArray) -> NDArray:
        """``g^{-1} J^T W u`` at one point ``a`` for a chart-space vector ``u`` (the Gauss-Newton step)."""
        return self._eval(a[:, None], np.zeros((self.k, 1)), u[:, None])[2 * self.N : 2 * self.N + self.k, 0]

    def polish(self, a: NDArray, p: NDArray) -> NDArray:
        """Gauss-Newton steps ``a += g^{-1} J^T W (z* - z(a))`` toward ``p`` in the working precision.

        None in float64, where the closed-form inverse is already backward
        stable.  Beyond, steps run until one is below 4 unit roundoffs: from a
        point on the manifold (a switch) they converge quadratically, from a
        float64 start off it by ~1e-16 per step, so 512 bits need ~10.
        """
        if is_double(self.fp):
            return a
        target = self.M_inv @ (p - self.m)

        def point(x: NDArray) -> NDArray:
            return self._eval(x[:, None], np.zeros((self.k, 1)), np.zeros((self.N, 1)))[: self.N, 0]

        max_steps = 2 + int(np.ceil(-np.log2(unit_roundoff(self.fp)) / 50))
        return gauss_newton(a, target, point, self._project, max_steps=max_steps, step_tol=4 * unit_roundoff(self.fp))
