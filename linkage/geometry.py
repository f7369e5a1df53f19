"""Riemannian geometry of a chain's configuration space: exp, parallel transport, Jacobi fields, log and distance.

They run in hinge coordinates, on the rod constraints of
:class:`linkage.constraints.ChainSystem` (no chart, so nothing is singular:
poles and folds of the suspension charts are ordinary points here), with the
quantities carried along the geodesic as :mod:`manifold.carried` terms in the
same heyoka Taylor integrator as the geodesic.  ``parallel_transport`` and
``jacobi_field`` also run in the suspension atlas (``method="charts"``): the
geodesic chart by chart, the same terms carried beside it in hinge space; by default
(``method="auto"``) they take the method :func:`~linkage.motion.free_motion` takes, the atlas on a nearly
stretched chain.  Hinges, velocities and
tangent vectors are complex, shape ``(n-1,)`` (a vector of hinge velocities);
several vectors at once have shape ``(k, n-1)``.  The kinetic metric is
``<u, w> = Re(u^H A w)`` with the chain's mass matrix ``A``.

The names follow Manifolds.jl where they fit: ``exp``, ``parallel_transport``
(``parallel_transport_direction`` there: the geodesic is given by its start
and velocity), ``jacobi_field`` (its start value and covariant derivative,
not a geodesic between two points), ``log`` and ``distance``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold import GeodesicIntegrationError, SolveStatus, solve_chart_exp_ode
from manifold.ambient_velocity import ChartCarried, ConstrainedVelocity
from manifold.carried import CarriedSolution, CarriedTerm, solve_carried
from manifold.constrained import ConstrainedGeometry, solve_constrained
from manifold.geodesic_solver import at_rest
from manifold.jacobi import JacobiField
from manifold.options import (DEFAULT_PRECISION, DEFAULT_SAVE, DEFAULT_START, PROJECTED_START, Precision, SaveAt,
                              StartCheck, check_group, takes_option_groups)
from manifold.precision import is_double
from manifold.transport import ParallelTransport
from manifold.validation import check_positive_int, check_real

from .chain import Chain
from .diagonal_path import DiagonalPath
from .constraints import ChainSystem, HingeConstraints, HingeStart, start_state
from .motion import (AUTO, CHART_STEPPER_OPTIONS, METHODS, check_method_options, choose_method,
                     default_chart_stepper)

__all__ = ["CarriedMotion", "JacobiFieldMotion", "LogResult", "TransportedVectors", "distance", "exp",
           "jacobi_field", "log", "parallel_transport", "tangent_basis"]


class CarriedMotion:
    """A chain's geodesic with quantities carried along it, sampled at :attr:`times` and callable at any time.

    Attributes
    ----------
    chain
        The chain.
    carried
        The :class:`manifold.carried.CarriedSolution` (working precision, stats, the solve's checks).
    times, hinges, velocities
        The sample times and the complex hinges and velocities there, ``(len(times), n-1)``.
    """

    def __init__(self, chain: Chain, carried: CarriedSolution, times: NDArray, single: bool) -> None:
        self.chain, self.carried, self._single = chain, carried, single
        self.times = np.asarray(times, dtype=float)
        x, v, values = carried(self.times)
        self.hinges, self.velocities = chain.from_point(x.astype(float)), chain.from_point(v.astype(float))
        self._values = {name: self._complex(a) for name, a in values[0].items()}

    def _complex(self, a: NDArray) -> NDArray:
        out = self.chain.from_point(a.astype(float))  # (..., k, n-1)
        return out[..., 0, :] if self._single else out

    def __repr__(self) -> str:
        sol = self.carried.solution
        return (f"{type(self).__name__}({self.chain!r}, t = 0 -> {float(sol.t_reached):g}, {len(self.times)} times, "
                f"{sol.n_steps} steps, energy error {sol.relative_energy_error:.1e})")

    def __call__(self, t: ArrayLike) -> CarriedMotion:
        """The same motion sampled at the time(s) ``t`` (1-d, within ``[0, T]``)."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        if ts.ndim != 1:
            raise ValueError(f"t must be a time or a 1-d array of times, got shape {ts.shape}")
        return type(self)(self.chain, self.carried, ts, self._single)


class TransportedVectors(CarriedMotion):
    """:func:`parallel_transport`'s result: :attr:`vectors`, shape ``(len(times), n-1)`` or ``(len(times), k, n-1)``."""

    @property
    def vectors(self) -> NDArray:
        """The transported vectors at :attr:`times` (complex hinge velocities)."""
        return self._values["vectors"]


class JacobiFieldMotion(CarriedMotion):
    """:func:`jacobi_field`'s result: :attr:`field` and :attr:`field_derivative` at :attr:`times`."""

    @property
    def field(self) -> NDArray:
        """``J(t)``, shape ``(len(times), n-1)`` or ``(len(times), k, n-1)``."""
        return self._values["field"]

    @property
    def field_derivative(self) -> NDArray:
        """The covariant derivative ``D_t J(t)``, the same shape."""
        return self._values["field_derivative"]


def _tangent_vectors(constraints: HingeConstraints, x0: NDArray, values: ArrayLike, name: str,
                     start: StartCheck) -> tuple[NDArray, bool]:
    """Complex tangent vectors at ``x0`` (shape ``(n-1,)`` or ``(k, n-1)``) as real rows ``(k, N)``, checked to
    ``start.tangent_tol`` (never projected: ``start.project_velocity`` is for the start velocity alone)."""
    chain = constraints.chain
    w = chain.as_hinges(values, name)
    if w.ndim not in (1, 2) or w.shape[-1] != chain.n - 1 or w.size == 0:
        raise ValueError(f"{name} must have shape (n - 1,) = ({chain.n - 1},) or (k, {chain.n - 1}), got {w.shape}")
    rows = np.atleast_2d(chain.to_point(w)).astype(float)
    residual = constraints.tangency_residual(np.broadcast_to(x0, rows.shape), rows)
    allowed = start.allowance(rows)
    bad = ~(residual <= allowed)
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ValueError(f"{name}{'' if w.ndim == 1 else f'[{k}]'} is not tangent to the configuration space: "
                         f"max_k l_k |(G w)_k| = {residual[k]:.3g} exceeds tangent_tol * max(1, |w|) = "
                         f"{allowed[k]:.3g}")
    return rows, w.ndim == 1


def _times(grid: NDArray | None, carried: CarriedSolution) -> NDArray:
    if grid is None:  # every step of the integrator
        return np.array([float(t) for t in carried.solution.energy_times])
    return grid


def checked_start(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, T: float, save: SaveAt,
                  start: StartCheck, method: str) -> tuple[HingeStart, NDArray | None]:
    """The start of a solve with terms carried by ``method``, checked once (:func:`linkage.constraints.start_state`,
    the time named ``T``), and the grid of ``save`` (or ``None``: every step)."""
    if method not in (*METHODS, AUTO):
        raise ValueError(f"method must be one of {(*METHODS, AUTO)}, got {method!r}")
    save = check_group("save", save, SaveAt)
    if not save.keeps_dense(True):
        raise TypeError("the carried values are read from dense output: save=SaveAt(dense=False) is not taken")
    hinge_start = start_state(chain, hinges0, velocity0, check_real("T", T, nonzero=True), start)
    return hinge_start, save.grid(hinge_start.t_final)


def _solve(start: HingeStart, term: CarriedTerm, grid: NDArray | None, precision: Precision, method: str,
           options: dict[str, Any], caller: str) -> tuple[CarriedSolution, NDArray]:
    """Integrate from a checked start with ``term`` carried, by ``method``; the solution and its sample times.
    ``caller`` is the public function's name, for an error naming an option the method does not take."""
    precision = check_group("precision", precision, Precision)
    chain, x0, v0, T = start.constraints.chain, start.x0, start.v0, start.t_final
    if method == AUTO:
        method = choose_method(chain, options)
    check_method_options(method, options, caller, also=("progress",))
    if method == "hinges":
        carried = solve_carried(ChainSystem(chain), x0, v0, T, [term], precision=precision, **options)
    else:
        carried = _solve_in_charts(chain, x0, v0, T, term, precision, options)
    return carried, _times(grid, carried)


def _solve_in_charts(chain: Chain, x0: NDArray, v0: NDArray, T: float, term: CarriedTerm, precision: Precision,
                     options: dict[str, Any]) -> CarriedSolution:
    """The geodesic in the atlas (Sundman's time, the state ``(a, J c)``) with ``term``'s ambient slots carried along,
    through every switch unchanged; the term's invariants checked over every step afterwards."""
    for name in ("stepper", "form"):
        if name in options:
            raise TypeError(f"method='charts' does not take {name}= here (the stepper carries the term in the state "
                            "(a, J c), with dense output)")
    system = ChainSystem(chain)
    if at_rest(x0, v0, T, precision.fp_type):
        # no chart motion to follow (Sundman's time would see no scale of time), but a Jacobi field still moves
        return solve_carried(system, x0, v0, T, [term], precision=precision,
                             **{k: v for k, v in options.items() if k not in ("q_out", *CHART_STEPPER_OPTIONS)})
    velocity = ConstrainedVelocity(system)
    stepper = default_chart_stepper(chain, precision.tol, velocity, options.get("compact_mode"),
                                    terms=(ChartCarried(term, velocity),))
    solution = solve_chart_exp_ode(chain.metric(), x0, v0, T, stepper=stepper, start=PROJECTED_START,
                                   precision=dataclasses.replace(precision, tol=None),
                                   **{k: v for k, v in options.items() if k not in CHART_STEPPER_OPTIONS})
    carried = CarriedSolution(solution, (term,), ConstrainedGeometry(system, solution.fp_type))
    violation = carried.violation(stepper.relative_tolerance(solution.fp_type))
    if violation is not None:
        solution.status, solution.message = SolveStatus.CARRIED_CHECK_FAILED, violation
        if options.get("throw", True):
            raise GeodesicIntegrationError(violation, solution)
    return carried


@takes_option_groups
def exp(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, t: float = 1.0, *,
        precision: Precision = DEFAULT_PRECISION, start: StartCheck = DEFAULT_START, **options: Any) -> NDArray:
    """The exponential map: the hinges at time ``t`` of the geodesic from ``hinges0`` with velocity ``velocity0``.

    Parameters
    ----------
    chain
        The chain (any generic lengths).
    hinges0, velocity0
        Complex hinges (closing to 1e-9) and a tangent hinge velocity, shape ``(n-1,)``.
    t
        The time (nonzero; negative runs backward).  ``exp(chain, h, v, t) = exp(chain, h, t v, 1)``.
    precision
        :class:`manifold.Precision` ``(fp_type, tol)``: the working precision and heyoka's tolerance.
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the tangency check of ``velocity0``
        (:func:`linkage.constraints.start_state`), and whether a non-tangent one is projected instead of refused.
    **options
        Passed to :func:`manifold.constrained.solve_constrained` (``rate``, ``throw``, ...).

    Returns
    -------
    numpy.ndarray
        Complex hinges, shape ``(n-1,)`` (rounded to complex128).
    """
    for name in ("save", "carry"):
        if name in options:
            raise TypeError(f"exp does not take {name}= (it returns the end point; see parallel_transport for a path)")
    check_method_options("hinges", options, "exp", also=("progress",))
    _, x0, v0, t = start_state(chain, hinges0, velocity0, check_real("t", t, nonzero=True), start)
    sol = solve_constrained(ChainSystem(chain), x0, v0, t, precision=precision, save=SaveAt(dense=False), **options)
    return chain.from_point(sol.end_state()[0].astype(float))


@takes_option_groups
def parallel_transport(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, vectors0: ArrayLike, T: float, *,
                       save: SaveAt = DEFAULT_SAVE, precision: Precision = DEFAULT_PRECISION, method: str = AUTO,
                       start: StartCheck = DEFAULT_START, **options: Any) -> TransportedVectors:
    """Transport tangent vectors parallel along the geodesic from ``(hinges0, velocity0)`` for the time ``T``.

    ``W' = -K^{-1} G^T M^{-1} ((dG/dt) W)`` in hinge coordinates
    (:class:`manifold.transport.ParallelTransport`), integrated with the
    geodesic.  The kinetic inner products of the vectors with each other and
    with the velocity are constant; the solve checks them at every step and
    raises :class:`manifold.GeodesicIntegrationError` if they drift beyond the
    energy bound.

    Parameters
    ----------
    chain, hinges0, velocity0
        As in :func:`exp`.
    vectors0
        Complex tangent vectors at ``hinges0``: shape ``(n-1,)`` or ``(k, n-1)``;
        tangent to ``start.tangent_tol`` (as ``velocity0``), else ``ValueError`` (never projected).
    T
        The time to transport for (nonzero; negative runs backward).
    save
        :class:`manifold.SaveAt` ``(t_eval)``: the times of :attr:`~CarriedMotion.times` (1-d, within
        ``[0, T]``, in order); default every step.  The result is always dense (callable at any time):
        ``dense=False`` is refused.
    precision
        :class:`manifold.Precision` ``(fp_type, tol)``: the working precision and heyoka's tolerance.
    method
        ``"auto"`` (default): the method :func:`~linkage.motion.free_motion` takes by default
        (:func:`~linkage.motion.choose_method`: the hinges, except on a nearly stretched chain with an atlas,
        where they lose digits, and where an option only the charts take is given).
        ``"hinges"``: in hinge coordinates with the rod constraints
        (:func:`manifold.carried.solve_carried`; any generic lengths).  ``"charts"``: the geodesic in the
        suspension atlas, in Sundman's time with the state ``(a, J c)``, the vectors carried in hinge space
        beside it (:class:`manifold.ambient_velocity.ChartCarried` after the state of
        :class:`~manifold.ambient_velocity.ConstrainedVelocity`), through every
        chart switch unchanged (they are ambient: no chart coefficients to map), and their invariants checked
        over every step afterwards; where the chain has an atlas.
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the tangency tolerance of ``velocity0``
        and ``vectors0``, and whether a non-tangent ``velocity0`` (only it) is projected instead of refused.
    **options
        Passed to :func:`manifold.carried.solve_carried` (``rate``, ``throw``, ``progress``, ...),
        or for ``"charts"`` to :func:`manifold.solve_chart_exp_ode` (``q_out``, ``throw``, ...); ``compact_mode``,
        both methods' compile option (the charts': their stepper's).  ``None`` (default) compiles compact for
        either method, unlike :func:`~linkage.motion.free_motion`'s hinges, which unroll up to n = 12: with a term
        carried unrolled code compiles far longer, once per machine, for faster calls.  Parallel transport with the
        hinges at n = 5: 6.4 s cold against 0.45 s, a T = 200 call 1.25x faster; a Jacobi field at n = 4 on the
        charts: 53-60 s against 3 s, a T = 20 call 1.4x faster.  ``compact_mode=False`` pays that for long or
        repeated runs.

    Returns
    -------
    TransportedVectors
        ``times``, ``hinges``, ``velocities``, ``vectors``; callable at other times.
    """
    hinge_start, grid = checked_start(chain, hinges0, velocity0, T, save, start, method)
    rows, single = _tangent_vectors(hinge_start.constraints, hinge_start.x0, vectors0, "vectors0", start)
    carried, times = _solve(hinge_start, ParallelTransport(rows), grid, precision, method, options,
                            "parallel_transport")
    return TransportedVectors(chain, carried, times, single)


@takes_option_groups
def jacobi_field(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, field0: ArrayLike, derivative0: ArrayLike,
                 T: float, *, save: SaveAt = DEFAULT_SAVE, precision: Precision = DEFAULT_PRECISION,
                 method: str = AUTO, start: StartCheck = DEFAULT_START, checked: bool = True,
                 **options: Any) -> JacobiFieldMotion:
    """The Jacobi field along the geodesic from ``(hinges0, velocity0)`` with ``J(0) = field0``, ``D_t J(0) = derivative0``.

    The linearised geodesic flow (:class:`manifold.jacobi.JacobiField`): ``J``
    solves ``D_t^2 J + R(J, v) v = 0``.  ``J(0) = 0`` gives the fields that
    vanish again at the points conjugate to the start.

    Parameters
    ----------
    chain, hinges0, velocity0, T, save, precision, method, start, **options
        As in :func:`parallel_transport`.
    field0, derivative0
        Complex tangent vectors at ``hinges0``, one shape: ``(n-1,)`` or ``(k, n-1)`` for ``k`` fields at once.
    checked
        Check the fields' invariants at every step (:class:`manifold.jacobi.JacobiField`); off for fields that
        grow by orders of magnitude (:func:`linkage.sensitivity.sensitivity`).

    Returns
    -------
    JacobiFieldMotion
        ``times``, ``hinges``, ``velocities``, ``field``, ``field_derivative``; callable at other times.
    """
    hinge_start, grid = checked_start(chain, hinges0, velocity0, T, save, start, method)
    return jacobi_field_from(hinge_start, field0, derivative0, grid, precision, method, start, checked, options)


def jacobi_field_from(hinge_start: HingeStart, field0: ArrayLike, derivative0: ArrayLike, grid: NDArray | None,
                      precision: Precision, method: str, start: StartCheck, checked: bool,
                      options: dict[str, Any], caller: str = "jacobi_field") -> JacobiFieldMotion:
    """:func:`jacobi_field` from a start that :func:`checked_start` has checked (with its grid, or ``None``): the
    fields are checked for tangency to ``start.tangent_tol``, the start is not checked again; ``caller``, the
    public function called, is named in an error about an option."""
    J, single = _tangent_vectors(hinge_start.constraints, hinge_start.x0, field0, "field0", start)
    U, _ = _tangent_vectors(hinge_start.constraints, hinge_start.x0, derivative0, "derivative0", start)
    if J.shape != U.shape:
        raise ValueError(f"field0 and derivative0 must have one shape, got {np.shape(field0)} and "
                         f"{np.shape(derivative0)}")
    carried, times = _solve(hinge_start, JacobiField(J, U, checked), grid, precision, method, options, caller)
    return JacobiFieldMotion(hinge_start.constraints.chain, carried, times, single)


class LogResult:
    """:func:`log`'s answer with its record.

    Attributes
    ----------
    velocity
        The velocity ``v`` at ``hinges0`` (complex, ``(n-1,)``) with ``exp(hinges0, v, 1) = hinges1``.
    distance
        Its kinetic length ``sqrt(v^H A v)``: the length of that geodesic (the distance below the injectivity radius).
    residual
        ``|exp(hinges0, v, 1) - hinges1|`` at the answer.
    iterations
        Newton steps taken for it.
    candidates
        The lengths of every geodesic found, one per first guess that converged (the shortest is returned).
    """

    def __init__(self, velocity: NDArray, distance: float, residual: float, iterations: int,
                 candidates: list[float]) -> None:
        self.velocity, self.distance, self.residual = velocity, distance, residual
        self.iterations, self.candidates = iterations, candidates

    def __repr__(self) -> str:
        return (f"LogResult(distance {self.distance:.6g}, |exp(v) - h1| = {self.residual:.1e}, "
                f"{self.iterations} Newton steps, {len(self.candidates)} geodesic(s) found)")


def tangent_basis(chain: Chain, hinges: ArrayLike) -> NDArray:
    """A basis of the tangent space at ``hinges``, orthonormal in the kinetic metric: complex, ``(n-2, n-1)``.

    The null space of the constraint Jacobian ``G`` (by SVD), orthonormalised
    in ``K`` by a Cholesky factor of its Gram matrix; ``n - 2`` vectors for
    generic lengths (``ValueError`` at a singular configuration, where ``G``
    loses rank).
    """
    x = chain.to_point(chain.check_one_configuration(hinges, "hinges")).astype(float)
    return tangent_basis_at(HingeConstraints(chain), x)


def tangent_basis_at(constraints: HingeConstraints, x: NDArray) -> NDArray:
    """:func:`tangent_basis` at a checked configuration ``x`` (real interleaved, ``(2(n-1),)``) of
    ``constraints.chain``."""
    chain = constraints.chain
    _, s, Vt = np.linalg.svd(constraints.jacobian(x))
    rank = int(np.sum(s > s[0] * 1e-12))
    if rank < chain.n:
        raise ValueError(f"hinges is a singular configuration (the rod constraints have rank {rank} < n = {chain.n} "
                         "there): no tangent space of dimension n - 2")
    null = Vt[rank:]
    C = np.linalg.cholesky(null @ chain.ambient_metric @ null.T)
    return chain.from_point(np.linalg.solve(C, null))


@takes_option_groups
def log(chain: Chain, hinges0: ArrayLike, hinges1: ArrayLike, *, velocity_guess: ArrayLike | None = None,
        rtol: float = 1e-12, max_iterations: int = 30, precision: Precision = DEFAULT_PRECISION,
        **options: Any) -> LogResult:
    """The logarithm: a velocity ``v0`` at ``hinges0`` with ``exp(chain, hinges0, v0, 1) = hinges1``.

    Newton's method on the shooting map ``c -> exp(sum_i c_i e_i)`` in the
    coordinates of a K-orthonormal tangent basis ``e_i`` at the start
    (:func:`tangent_basis`): its derivative is the Jacobi fields with
    ``J(0) = 0``, ``D_t J(0) = e_i`` at ``t = 1``, integrated with the geodesic
    (one solve per step); the step is the least-squares solution against the
    residual ``exp(v) - h1``, halved until the residual decreases (a full step
    from a poor guess can overshoot by a turn of the manifold).  ``hinges1`` is
    first projected onto the configuration space (it closes only to 1e-9, and no
    geodesic ends closer to it than that).

    Each first guess (``velocity_guess`` if given, and the K-orthogonal
    projection of ``hinges1 - hinges0`` onto the tangent space at ``hinges0``)
    is run; if none converges, a continuation follows the feasible path from
    ``hinges0`` to ``hinges1`` that is straight in the diagonals
    (:meth:`linkage.Chain.path`; the projected chord where that path is not
    built), each point's log the first guess of the next.  The shortest geodesic found is returned.  Below the injectivity
    radius it is the minimal one; beyond, it is the shortest found, not
    necessarily the shortest there is, and :attr:`LogResult.candidates` lists
    the lengths of all found.

    Parameters
    ----------
    chain
        The chain.
    hinges0, hinges1
        Complex configurations of the same connected component, shape ``(n-1,)``.
    velocity_guess
        A first guess for Newton's method: a tangent velocity at ``hinges0``, shape ``(n-1,)`` (tangent to the
        default tolerance of :class:`manifold.StartCheck`).
    rtol
        Convergence: ``|exp(v) - h1| <= rtol`` times the chain's mean rod length, ``> 0``.
    max_iterations
        Newton steps at most per guess, ``>= 1``.
    precision
        :class:`manifold.Precision` ``(tol=...)``: heyoka's tolerance of each shot.  The solve runs in
        float64 (the targets are float64 configurations): another ``fp_type`` is refused.
    **options
        Passed to :func:`manifold.carried.solve_carried` (``rate``, ...).

    Returns
    -------
    LogResult
        ``velocity``, ``distance``, ``residual``, ``iterations`` and ``candidates``.

    Raises
    ------
    linkage.diagonal_path.DifferentComponentsError
        If ``hinges1`` lies in another connected component (a ``ValueError``).
    RuntimeError
        If neither a guess nor the continuation converges, with the best residual of each.
    """
    rtol = check_real("rtol", rtol, positive=True)
    max_iterations = check_positive_int("max_iterations", max_iterations)
    for name in ("save", "carry"):
        if name in options:
            raise TypeError(f"log does not take {name}= (it shoots in float64 with dense output)")
    precision = check_group("precision", precision, Precision)
    if not is_double(precision.fp_type):
        raise ValueError(f"log shoots in float64 (the targets are float64 configurations), got "
                         f"precision=Precision(fp_type={precision.fp_type!r})")
    h0 = chain.check_one_configuration(hinges0, "hinges0")
    x0 = chain.to_point(h0).astype(float)
    constraints = HingeConstraints(chain)
    x1 = constraints.project_position(chain.to_point(chain.check_one_configuration(hinges1, "hinges1")).astype(float))
    basis = chain.to_point(tangent_basis(chain, h0))  # (n-2, N), K-orthonormal
    K = chain.ambient_metric
    guesses = []
    if velocity_guess is not None:
        guess, single = _tangent_vectors(constraints, x0, velocity_guess, "velocity_guess", DEFAULT_START)
        if not single:
            raise ValueError(f"velocity_guess must have shape (n - 1,) = ({chain.n - 1},), got "
                             f"{np.shape(velocity_guess)}")
        guesses.append(basis @ K @ guess[0])
    guesses.append(basis @ K @ (x1 - x0))  # the chord's tangential part, in the basis's coordinates
    target = rtol * float(np.mean(chain.lengths))
    system = ChainSystem(chain)

    def shooting(goal: NDArray) -> Callable[[NDArray], tuple[NDArray, NDArray]]:
        def shoot(c: NDArray) -> tuple[NDArray, NDArray]:
            """The residual ``exp(c) - goal`` and its derivative ``(N, n-2)``."""
            carried = solve_carried(system, x0, basis.T @ c, 1.0, [JacobiField(np.zeros_like(basis), basis)],
                                    precision=precision, **options)
            x, _, values = carried(np.array([1.0]))
            return x[0].astype(float) - goal, values[0]["field"][0].astype(float).T
        return shoot

    if np.linalg.norm(x1 - x0) <= target:  # the same configuration: the zero velocity, no geodesic to integrate
        return LogResult(np.zeros(chain.n - 1, dtype=complex), 0.0, float(np.linalg.norm(x1 - x0)), 0, [0.0])
    try:  # refuses another component first, at the cost of a few LPs
        path: DiagonalPath | None = chain.path(h0, chain.from_point(x1))
    except NotImplementedError:  # one component, joined only through a face where a diagonal vanishes
        path = None
    found, misses = [], []
    for c in guesses:
        c, size, iterations = _newton(shooting(x1), c, target, max_iterations)
        if size <= target:
            v = basis.T @ c
            found.append((float(np.sqrt(v @ K @ v)), v, size, iterations))
        else:
            misses.append(size)
    if not found:  # continuation along the feasible path from hinges0 to hinges1, straight in the diagonals
        c, size, iterations = np.zeros(len(basis)), np.inf, 0
        s, ds = 0.0, 0.25
        while ds >= 1.0 / 64:
            s_next = min(1.0, s + ds)
            if s_next == 1.0:
                goal = x1
            elif path is not None:
                goal = chain.to_point(path(s_next)).astype(float)
            else:  # the chord, projected onto the configuration space
                goal = constraints.project_position(x0 + s_next * (x1 - x0))
            trial, size, steps = _newton(shooting(goal), c, target, max_iterations)
            if size > target:
                ds /= 2
                continue
            c, s, iterations, ds = trial, s_next, iterations + steps, 1.5 * ds
            if s == 1.0:
                v = basis.T @ c
                found.append((float(np.sqrt(v @ K @ v)), v, size, iterations))
                break
        else:
            misses.append(size)
    if not found:
        raise RuntimeError(f"log did not converge: the best |exp(v) - hinges1| from each first guess was "
                           f"{', '.join(f'{m:.3g}' for m in misses)} (> rtol * mean rod length = {target:.3g}); "
                           "pass a velocity_guess closer to the geodesic wanted")
    length, v, size, iterations = min(found, key=lambda f: f[0])
    return LogResult(chain.from_point(v), length, size, iterations, sorted(f[0] for f in found))


def _newton(shoot: Callable[[NDArray], tuple[NDArray, NDArray]], c: NDArray, target: float,
            max_iterations: int) -> tuple[NDArray, float, int]:
    """Gauss-Newton on ``shoot(c) = (residual, derivative)`` from ``c``, each step halved (up to 8 times) until the
    residual decreases; stops at ``|residual| <= target`` (after one more full step, kept if it decreases the
    residual), after ``max_iterations`` steps, or when no halving decreases it.  Returns ``(c, |residual|, steps
    taken)``."""
    residual, jac = shoot(c)
    size = float(np.linalg.norm(residual))
    for iteration in range(max_iterations):
        if size <= target:  # one more step, kept if it helps: at quadratic convergence it reaches rounding
            step, *_ = np.linalg.lstsq(jac, -residual, rcond=None)
            polished = shoot(c + step)
            if np.linalg.norm(polished[0]) < size:
                return c + step, float(np.linalg.norm(polished[0])), iteration + 1
            return c, size, iteration
        step, *_ = np.linalg.lstsq(jac, -residual, rcond=None)
        for _ in range(8):
            trial = shoot(c + step)
            if np.linalg.norm(trial[0]) < size:
                break
            step = step / 2
        else:  # no decrease along the Newton direction: stagnation at the residual reached
            return c, size, iteration
        c, (residual, jac) = c + step, trial
        size = float(np.linalg.norm(residual))
    return c, size, max_iterations


@takes_option_groups
def distance(chain: Chain, hinges0: ArrayLike, hinges1: ArrayLike, **options: Any) -> float:
    """The geodesic distance ``sqrt(v0^H A v0)`` of :func:`log` ``(chain, hinges0, hinges1)`` (its caveats apply)."""
    return log(chain, hinges0, hinges1, **options).distance
