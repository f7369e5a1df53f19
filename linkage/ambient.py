"""Chart-free reference integrator: the constrained motion of the chain in hinge space.

The chain moves freely in the hinge space ``R^(2(n-1))`` (interleaved real
hinge vector ``x = (x_1, y_1, ..., x_{n-1}, y_{n-1})``) under the ``n`` rod
constraints

.. math::

    c_k(x) = |e_k|^2 / l_k^2 - 1 = 0, \\qquad e_1 = p_1,\\; e_k = p_k - p_{k-1},\\; e_n = L - p_{n-1}.

With the constant kinetic-energy metric ``K = A (x) I_2`` of
:attr:`Chain.ambient_metric` and ``G = dc/dx`` (``n x 2(n-1)``), the
equations of motion with Lagrange multipliers ``lambda`` are

.. math::

    K x'' = G(x)^T \\lambda, \\qquad G x'' = -\\dot G x' = -2 |e'|^2,

the second being the constraints differentiated twice
(``c_k'' = 2 e_k . e_k'' + 2 |e_k'|^2 = 0``).  Eliminating ``lambda``:

.. math::

    x'' = K^{-1} G^T (G K^{-1} G^T)^{-1} (-2 |e'|^2).

Its solutions are the geodesics of the induced metric ``g = J^T K J`` on the
configuration space (any generic lengths, whatever its topology), traversed at constant kinetic energy ``1/2 x'^T K x'``.
No chart is used, so this is an independent reference for the chart-based
geodesics.  The constraints hold only to integration accuracy (the equation
keeps ``c'' = 0``, not ``c = 0``); ``project=True`` pulls the state back onto
the constraint and tangent manifolds at regular intervals.  The constraint
geometry (``c``, ``G``, the K-orthogonal corrections and projections) is
:class:`linkage.constraints.HingeConstraints`.
"""

from __future__ import annotations

import time

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from manifold import CallableDense, GeodesicIntegrationError, GeodesicSolution, Segment, SolverStats, SolveStatus
from manifold.options import DEFAULT_SAVE, DEFAULT_START, SaveAt, StartCheck, check_group, takes_option_groups
from manifold.validation import check_bool, check_real

from .chain import Chain
from .constraints import start_state
from .motion import ChainMotion, chart_metric

__all__ = ["integrate_ambient"]


def _energy(v: NDArray, K: NDArray) -> NDArray:
    """Kinetic energy ``1/2 v^T K v`` of real hinge velocities ``(..., 2(n-1))``."""
    return 0.5 * np.einsum("...i,ij,...j->...", v, K, v)


def _segment_bounds(t_final: float, interval: float | None) -> NDArray:
    """``0 = b_0, b_1, ..., b_m = t_final`` spaced by ``interval`` (one segment if ``None``)."""
    T = abs(t_final)
    if interval is None or interval >= T:
        return np.array([0.0, t_final])
    b = np.append(np.arange(0.0, T, interval), T)
    if b[-1] - b[-2] < 1e-9 * interval:  # do not leave a sliver of a segment
        b = np.delete(b, -2)
    return b if t_final > 0 else 0.0 - b  # 0.0 - b: no -0.0 at the start


@takes_option_groups
def integrate_ambient(
    chain: Chain,
    hinges0: ArrayLike,
    velocity0: ArrayLike,
    t_final: float,
    *,
    save: SaveAt = DEFAULT_SAVE,
    method: str = "DOP853",
    rtol: float = 1e-12,
    atol: float = 1e-12,
    project: bool = False,
    projection_interval: float = 0.1,
    start: StartCheck = DEFAULT_START,
    throw: bool = True,
) -> ChainMotion:
    """Integrate the free motion of ``chain`` in hinge space with rod constraints.

    Solves ``K x'' = G^T lambda`` with ``G x'' = -2 |e'|^2`` (see the module
    docstring), i.e.

    .. math::

        x'' = K^{-1} G^T (G K^{-1} G^T)^{-1} (-2 |e'|^2),

    whose solutions are the constant-speed geodesics of the kinetic-energy
    metric on the configuration space.

    Parameters
    ----------
    chain
        The :class:`~linkage.Chain` (``n``, ``L``, rod lengths and mass model
        ``K``); generic lengths (:meth:`Chain.check_generic`).
    hinges0
        Complex initial hinges ``p_1 .. p_{n-1}``; must close to ``1e-9``
        (:meth:`Chain.check_configuration`, raises ``ConfigurationError``).
    velocity0
        Complex initial hinge velocities, finite and tangent:
        ``max_k l_k |(G v)_k| <= start.tangent_tol * max(1, |v|)`` (``|v|`` Euclidean),
        else ``ValueError`` -- unless ``start.project_velocity``.
    t_final
        Finite, nonzero end time; negative integrates backward from ``t = 0``.
    save
        :class:`manifold.SaveAt` ``(t_eval)``: output times within ``[0, t_final]``, in integration order
        (evaluated from the dense output); default: the solver's steps.  Recorded in ``motion.times``,
        ``motion.hinges``, ``motion.velocities``.  The dense output is always kept (the grid is read from it):
        ``dense=False`` is refused.
    method, rtol, atol
        Passed to :func:`scipy.integrate.solve_ivp` (any of its methods).
    project
        If true, integrate in segments of length ``projection_interval`` and
        after each one project the position onto ``c = 0`` (Gauss-Newton,
        ``x <- x - K^{-1} G^T (G K^{-1} G^T)^{-1} c(x)``) and the velocity
        K-orthogonally onto the tangent space
        (``v <- v - K^{-1} G^T (G K^{-1} G^T)^{-1} G v``).  The dense output
        is piecewise, each piece starting from a projected state.
    projection_interval
        Segment length for ``project``, finite and ``> 0``.
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the relative tolerance of the
        tangency check of ``velocity0``, and whether a non-tangent one is projected K-orthogonally onto the
        tangent space instead of refused.
    throw
        If true (default), a run that fails before ``t_final`` raises
        :class:`~manifold.GeodesicIntegrationError` with the partial solution;
        if false, it is returned with ``status`` saying why.

    Returns
    -------
    ChainMotion
        Complex-hinge view of a :class:`~manifold.GeodesicSolution` whose
        segments are in hinge coordinates (``chart=None``): chart parameters
        come on demand from the best chart of the atlas, where the chain has one.
    """
    save = check_group("save", save, SaveAt)
    if not save.keeps_dense(True):
        raise TypeError("integrate_ambient reads its grid from dense output: save=SaveAt(dense=False) is not taken")
    system, x0, v0, t_final = start_state(chain, hinges0, velocity0, t_final, start)
    t_eval = save.grid(t_final)
    interval = check_real("projection_interval", projection_interval, positive=True) if project else None
    rtol, atol = check_real("rtol", rtol, positive=True), check_real("atol", atol, positive=True)
    project, throw = check_bool("project", project), check_bool("throw", throw)

    m = system.ambient_dim

    def rhs(t: float, y: NDArray) -> NDArray:
        """``(x, v)' = (v, x'')`` with ``x''`` from :meth:`HingeConstraints.acceleration`."""
        return np.concatenate([y[m:], system.acceleration(y[:m], y[m:])])

    wall0 = time.perf_counter()
    bounds = _segment_bounds(t_final, interval)
    y = np.concatenate([x0, v0])
    solution = GeodesicSolution(chart_metric(chain), float, f"ambient-{method}", (0.0, t_final), {})
    solution.energy_times.append(0.0)
    solution.energies.append(_energy(v0, system.K))
    times, states = [0.0], [y]
    status, message = SolveStatus.SUCCESS, "reached t_final"
    for a, b in zip(bounds[:-1], bounds[1:]):
        sol = solve_ivp(rhs, (a, b), y, method=method, rtol=rtol, atol=atol, dense_output=True)
        if sol.t.size >= 2:
            solution.segments.append(Segment(None, a, sol.t[-1], sol.t.size - 1, CallableDense(sol.sol, sol.t.size - 1, 2 * m)))
            solution.energy_times.extend(sol.t[1:])
            solution.energies.extend(_energy(sol.y[m:, 1:].T, system.K))
            y = sol.y[:, -1]
            if project:
                y = system.project(y)
            times.extend(sol.t[1:])
            states.extend(sol.y[:, 1:-1].T)
            states.append(y)
        if not sol.success or sol.t.size < 2:
            status, message = SolveStatus.STEPPER_FAILED, f"{method} failed at t = {sol.t[-1]}: {sol.message}"
            break
    solution.final_state = (None, y[:m], y[m:])
    if t_eval is None:
        solution.t_eval, recorded = np.array(times), np.array(states)
    else:  # after a failure, only the times reached
        t_reached = float(solution.t_reached)
        solution.t_eval = t_eval[(t_eval * np.sign(t_final)) <= abs(t_reached)]
        recorded = np.concatenate(solution(solution.t_eval), axis=-1) if solution.segments else np.empty((0, 2 * m))
        recorded[solution.t_eval == t_reached] = y  # the end is the last (projected) state
    solution.points, solution.velocities = recorded[:, :m], recorded[:, m:]
    solution.status, solution.message = status, message
    solution.stats = SolverStats(solution.n_steps, 0, 0, 0.0, 0.0, time.perf_counter() - wall0)
    if status is not SolveStatus.SUCCESS and throw:
        raise GeodesicIntegrationError(message, solution)
    return ChainMotion(chain, solution)
