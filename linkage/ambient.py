"""Chart-free reference integrator: the constrained motion of the chain in hinge space.

The chain moves freely in the hinge space ``R^(2(n-1))`` (interleaved real
hinge vector ``x = (x_1, y_1, ..., x_{n-1}, y_{n-1})``) under the ``n`` rod
constraints

.. math::

    c_k(x) = |e_k|^2 - 1 = 0, \\qquad e_1 = p_1,\\; e_k = p_k - p_{k-1},\\; e_n = L - p_{n-1}.

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
configuration sphere, traversed at constant kinetic energy ``1/2 x'^T K x'``.
No chart is used, so this is an independent reference for the chart-based
geodesics.  The constraints hold only to integration accuracy (the equation
keeps ``c'' = 0``, not ``c = 0``); ``project=True`` pulls the state back onto
the constraint and tangent manifolds at regular intervals.  The constraint
geometry (``c``, ``G``, the K-orthogonal corrections and projections) is
:class:`linkage.constraints.HingeConstraints`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from charts.chain_geometry import to_complex, to_real
from manifold.validation import check_real

from .chain import Chain
from .constraints import HingeConstraints

__all__ = ["AmbientSolution", "integrate_ambient", "start_state"]


class _DenseOutput:
    """Piecewise dense output: segment ``i`` owns ``[starts[i], starts[i+1])``; ``span[1]`` maps to ``final``."""

    def __init__(self, starts: list[float], interpolants: list, final: NDArray, span: tuple[float, float]) -> None:
        self.starts, self.interpolants, self.final, self.span = np.array(starts), interpolants, final, span

    def __call__(self, t: NDArray) -> NDArray:
        """Real states ``(len(t), 4(n-1))`` at the 1-d times ``t`` (assumed within ``span``)."""
        s = 1.0 if self.span[1] >= self.span[0] else -1.0
        seg = np.searchsorted(s * self.starts, s * t, side="right") - 1
        seg = np.clip(seg, 0, len(self.interpolants) - 1)
        out = np.empty((t.size, self.final.size))
        for i, interpolant in enumerate(self.interpolants):
            mask = seg == i
            if np.any(mask):
                out[mask] = interpolant(t[mask]).T
        out[t == self.span[1]] = self.final
        return out


@dataclass
class AmbientSolution:
    """Result of :func:`integrate_ambient`.

    Attributes
    ----------
    t
        Output times: ``t_eval`` if given, otherwise the solver's steps.
    hinges, velocities
        Complex hinges ``p_j(t)`` and velocities ``p_j'(t)``, shape ``(len(t), n-1)``.
    energy
        Kinetic energy ``1/2 v^T K v`` at each output time (conserved by the exact flow).
    constraint_residual
        ``max_k | |e_k| - 1 |`` at each output time (0 for the exact flow).
    nfev
        Right-hand-side evaluations, summed over all segments.
    success
        Whether the integration reached ``t_final``.
    message
        The solver's message (of the failing segment, if any).
    span
        ``(0, t_reached)``: the interval covered by the dense output.

    Calling the solution at times ``t`` (scalar or array) in ``span`` returns
    complex ``(hinges, velocities)`` from the solver's dense output.
    """

    t: NDArray
    hinges: NDArray
    velocities: NDArray
    energy: NDArray
    constraint_residual: NDArray
    nfev: int
    success: bool
    message: str
    span: tuple[float, float]
    _dense: _DenseOutput = field(repr=False)

    def __call__(self, t: ArrayLike) -> tuple[NDArray, NDArray]:
        """``(hinges, velocities)`` at ``t``: shape ``(n-1,)`` for scalar ``t``, else ``(*t.shape, n-1)``."""
        t = np.asarray(t, dtype=float)
        lo, hi = sorted(self.span)
        bad = ~((t >= lo) & (t <= hi))  # also catches NaN
        if np.any(bad):
            raise ValueError(
                f"t = {t[bad] if t.ndim else t} lies outside the integrated span "
                f"[{self.span[0]:g}, {self.span[1]:g}]"
            )
        h, v = np.split(to_complex(self._dense(t.ravel())), 2, axis=-1)
        return h.reshape(*t.shape, -1), v.reshape(*t.shape, -1)


def _segment_bounds(t_final: float, interval: float | None) -> NDArray:
    """``0 = b_0, b_1, ..., b_m = t_final`` spaced by ``interval`` (one segment if ``None``)."""
    T = abs(t_final)
    if interval is None or interval >= T:
        return np.array([0.0, t_final])
    b = np.append(np.arange(0.0, T, interval), T)
    if b[-1] - b[-2] < 1e-9 * interval:  # do not leave a sliver of a segment
        b = np.delete(b, -2)
    return b if t_final > 0 else 0.0 - b  # 0.0 - b: no -0.0 at the start


def start_state(
    chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, t_final: float, tangent_tol: float, project_velocity: bool
) -> tuple[HingeConstraints, NDArray, NDArray, float]:
    """Validate the start of a hinge-space integration (shared by every hinge-space method).

    Parameters
    ----------
    chain
        The chain.
    hinges0
        Complex initial hinges; must close to ``1e-9`` (else ``ConfigurationError``).
    velocity0
        Complex initial hinge velocities, ``n - 1`` finite entries, tangent:
        ``max_k |(G v)_k| <= tangent_tol * max(1, |v|)`` (else ``ValueError``)
        unless ``project_velocity``.
    t_final
        End time, finite and nonzero (:func:`manifold.validation.check_real`).
    tangent_tol
        Relative tolerance of the tangency check, ``> 0``.
    project_velocity
        Replace a non-tangent ``velocity0`` by its K-orthogonal projection
        :meth:`HingeConstraints.project_velocity` instead of refusing it.

    Returns
    -------
    tuple
        ``(constraints, x0, v0, t_final)``: the chain's :class:`HingeConstraints`,
        the real interleaved start position and velocity, and ``t_final`` as a float.
    """
    h0 = chain.check_configuration(hinges0, tol=1e-9)
    v0 = chain.as_hinges(velocity0, "velocity0")
    if v0.shape != (chain.n - 1,):
        raise ValueError(f"velocity0 must have n - 1 = {chain.n - 1} complex entries, got shape {v0.shape}")
    t_final = check_real("t_final", t_final, nonzero=True)
    tangent_tol = check_real("tangent_tol", tangent_tol, positive=True)
    system = HingeConstraints(chain)
    x0, v0 = to_real(h0).astype(float), to_real(v0).astype(float)
    residual = np.max(np.abs(system.jacobian(x0) @ v0))
    if residual > tangent_tol * max(1.0, np.linalg.norm(v0)):
        if not project_velocity:
            raise ValueError(
                f"velocity0 is not tangent to the configuration space: max_k |(G v)_k| = {residual:.3g} "
                f"exceeds tangent_tol * max(1, |v|) = {tangent_tol * max(1.0, np.linalg.norm(v0)):.3g} "
                "(pass project_velocity=True to project it)"
            )
        v0 = system.project_velocity(x0, v0)
    return system, x0, v0, t_final


def integrate_ambient(
    chain: Chain,
    hinges0: ArrayLike,
    velocity0: ArrayLike,
    t_final: float,
    *,
    t_eval: ArrayLike | None = None,
    method: str = "DOP853",
    rtol: float = 1e-12,
    atol: float = 1e-12,
    project: bool = False,
    projection_interval: float = 0.1,
    tangent_tol: float = 1e-9,
    project_velocity: bool = False,
) -> AmbientSolution:
    """Integrate the free motion of ``chain`` in hinge space with rod constraints.

    Solves ``K x'' = G^T lambda`` with ``G x'' = -2 |e'|^2`` (see the module
    docstring), i.e.

    .. math::

        x'' = K^{-1} G^T (G K^{-1} G^T)^{-1} (-2 |e'|^2),

    whose solutions are the constant-speed geodesics of the kinetic-energy
    metric on the configuration sphere.

    Parameters
    ----------
    chain
        The :class:`~linkage.Chain` (``n``, ``L`` and mass model ``K``).
    hinges0
        Complex initial hinges ``p_1 .. p_{n-1}``; must close to ``1e-9``
        (:meth:`Chain.check_configuration`, raises ``ConfigurationError``).
    velocity0
        Complex initial hinge velocities, finite and tangent:
        ``max_k |(G v)_k| <= tangent_tol * max(1, |v|)`` (``|v|`` Euclidean),
        else ``ValueError`` -- unless ``project_velocity``.
    t_final
        Finite, nonzero end time; negative integrates backward from ``t = 0``.
    t_eval
        Output times within ``[0, t_final]`` (evaluated from the dense output);
        default: the solver's steps.
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
    tangent_tol
        Relative tolerance of the tangency check of ``velocity0``.
    project_velocity
        If true, project ``velocity0`` K-orthogonally onto the tangent space
        instead of refusing a non-tangent one.

    Returns
    -------
    AmbientSolution
    """
    system, x0, v0, t_final = start_state(chain, hinges0, velocity0, t_final, tangent_tol, project_velocity)
    interval = check_real("projection_interval", projection_interval, positive=True) if project else None

    if t_eval is not None:
        t_eval = np.asarray(t_eval, dtype=float)
        lo, hi = sorted((0.0, t_final))
        if t_eval.ndim != 1 or not np.all((t_eval >= lo) & (t_eval <= hi)):
            raise ValueError(f"t_eval must be a 1-d array of times within [0, {t_final:g}], got {t_eval}")

    m = system.ambient_dim

    def rhs(t: float, y: NDArray) -> NDArray:
        """``(x, v)' = (v, x'')`` with ``x''`` from :meth:`HingeConstraints.acceleration`."""
        return np.concatenate([y[m:], system.acceleration(y[:m], y[m:])])

    bounds = _segment_bounds(t_final, interval)
    y = np.concatenate([x0, v0])
    starts, interpolants, ts, ys = [], [], [], []
    nfev, success, message, t_reached = 0, True, "", 0.0
    for a, b in zip(bounds[:-1], bounds[1:]):
        sol = solve_ivp(rhs, (a, b), y, method=method, rtol=rtol, atol=atol, dense_output=True)
        nfev += sol.nfev
        message = sol.message
        if sol.t.size < 2:  # failed on its very first step
            success = False
            break
        starts.append(a)
        interpolants.append(sol.sol)
        ts.append(sol.t[:-1])
        ys.append(sol.y[:, :-1])
        t_reached, y = sol.t[-1], sol.y[:, -1]
        if not sol.success:
            success = False
            break
        if project:
            y = system.project(y)
    if not interpolants:
        raise RuntimeError(f"integration failed at t = 0: {message}")

    dense_output = _DenseOutput(starts, interpolants, y, (0.0, float(t_reached)))
    if t_eval is None:
        t = np.append(np.concatenate(ts), t_reached)
        states = np.vstack([np.concatenate(ys, axis=1).T, y])
    else:  # after a failure, only the times reached
        t = t_eval[(t_eval * np.sign(t_final)) <= abs(t_reached)]
        states = dense_output(t)
    hinges, velocities = np.split(to_complex(states), 2, axis=-1)
    v = states[:, m:]
    return AmbientSolution(
        t=t,
        hinges=hinges,
        velocities=velocities,
        energy=0.5 * np.einsum("ti,ij,tj->t", v, system.K, v),
        constraint_residual=chain.closure_residual(hinges),
        nfev=nfev,
        success=success,
        message=message,
        span=dense_output.span,
        _dense=dense_output,
    )
