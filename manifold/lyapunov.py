"""Finite-time Lyapunov exponents of geodesics of a constrained system, from the variational equations.

The geodesic flow of :mod:`manifold.constrained` lives on the phase space
``P = {(x, v) : c(x) = 0, G(x) v = 0}`` inside ``R^N x R^N``.  A deviation
``d = (dx, dv)`` of the state is carried by the variational equations
``d' = (df/dy) d``, integrated by heyoka alongside the trajectory, ``k``
deviations at once (:meth:`~manifold.constrained.CompiledConstrained.tangent_integrator`;
the tests check them against ``heyoka.var_ode_sys``, which builds the whole
fundamental matrix at five times the cost).  Deviations are kept

* tangent to ``P``: ``G dx = 0`` and ``d(G v)/dx dx + G dv = 0`` (the null
  space of ``d(c, G v)/d(x, v)``), which the exact flow preserves; the
  Baumgarte terms of the equations damp any normal part, and each
  renormalisation projects it away;
* with ``deviations="perpendicular"`` (default) also ``v^T K dx = 0`` and
  ``v^T K dv = 0``: perpendicular to the flow direction (``v^T K dx`` is
  conserved along a geodesic, since the acceleration is normal) and at
  fixed energy (``v^T K dv = dE``).  The exponents of the flow direction and
  of the energy direction are 0, but along them a deviation grows linearly
  (a faster geodesic drifts ahead), which biases a finite-time estimate by
  ``log(t) / t``; perpendicular deviations leave ``2 (N - m) - 2`` exponents,
  in pairs ``+-lambda`` (the flow is symplectic).  ``"tangent"`` keeps the
  whole tangent space of ``P`` (``2 (N - m)`` exponents, two of them 0).

Benettin's method: every ``interval`` the fundamental matrix of the interval
maps the ``k`` deviations, they are projected, and a QR factorisation (Gram-
Schmidt) in the norm ``|d|^2 = dx^T K dx + dv^T K dv / s^2`` (``s`` the speed,
so both halves have the units of length) renormalises them; the running means
of ``log R_ii`` are the exponent estimates.  Exponents are in units of 1/time
and scale with the speed: the geodesic at speed ``s`` is the unit-speed one run
``s`` times faster.

What the estimates are at a finite ``t``: the product of the intervals'
triangular factors is the triangular factor of ``Phi(t) Y_0`` (``Phi`` the
flow's fundamental matrix, ``Y_0`` the ``k`` initial deviations), so the
``j``-th estimate is ``log(vol_j(t) / vol_j(0)) / t - log(vol_{j-1}(t) /
vol_{j-1}(0)) / t``, ``vol_j`` the ``j``-volume spanned by the first ``j``
evolved deviations, whatever ``interval`` (which only keeps the numbers far
from overflow).  The first is the growth rate of one deviation, the sum of
the first ``j`` that of a ``j``-volume.  They are in Gram-Schmidt order, not
sorted: as ``t -> oo`` they tend to the exponents largest first, but at a
finite ``t`` a deviation that starts near a contracting direction grows less
than the next one's share of the volume (at ``t = 5``, n = 4 and ``L = 2.6``,
the initial deviations of ``seed=25`` give ``(-0.288, 0.299)``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .budget import Budget, allowance, spend, spending, spent_message
from .constrained import ConstrainedGeometry, ConstrainedSystem, compiled_constrained, verdict
from .interrupt import BUDGET, INTERRUPTED, SolveInterrupted, interruptible, propagate_until, settled
from .options import DEFAULT_PRECISION, Precision, check_group, takes_option_groups
from .precision import is_double
from .solution import SolveStatus, energy_violation
from .steppers import taylor_relative_tolerance
from .validation import check_bool, check_positive_int, check_real, real_array

__all__ = ["DEVIATIONS", "LYAPUNOV_BUDGET", "LyapunovError", "LyapunovResult", "float64_precision", "lyapunov_spectrum"]

#: Which deviations are followed (see the module docstring).
DEVIATIONS = ("perpendicular", "tangent")
#: The default budget of an estimate: 1e6 steps, about a minute of CPU at 70 us a step of the variational system
#: (n = 5, k = 1); the documented n = 4 estimate over T = 800 (k = 2) takes 10,114.  Near the stretched chain
#: (n = 5, L = 5 - 1e-9: 250,000 steps per unit time) an estimate over T = 40 would have run for 8 minutes.
LYAPUNOV_BUDGET = Budget(steps=10**6)


@dataclass
class LyapunovResult:
    """Finite-time Lyapunov exponents of one geodesic and how their estimates converged.

    Attributes
    ----------
    exponents
        The ``k`` estimates at ``t_final`` (1/time), in Gram-Schmidt order: the sum of the first ``j`` is the
        growth rate of the ``j``-volume of the first ``j`` deviations; largest first only in the limit (module
        docstring).
    times, history
        Renormalisation times ``(m,)`` and the running estimates there ``(m, k)``:
        the convergence of the exponents.
    deviations
        ``"perpendicular"`` or ``"tangent"``.
    interval
        Time between renormalisations.
    speed
        ``sqrt(v^T K v)`` of the geodesic (the exponents scale with it).
    n_steps
        Taylor steps taken.
    relative_energy_error
        ``max |E - E0| / E0`` over the renormalisation times.
    status, message
        Whether the trajectory passed the solvers' energy and constraint checks, and a sentence.
    """

    exponents: NDArray
    times: NDArray = field(repr=False)
    history: NDArray = field(repr=False)
    deviations: str
    interval: float
    speed: float
    n_steps: int
    relative_energy_error: float
    status: SolveStatus
    message: str

    def __repr__(self) -> str:
        t = float(self.times[-1]) if len(self.times) else 0.0
        return (f"LyapunovResult(exponents {np.array2string(self.exponents, precision=4)}, {self.deviations}, "
                f"t = {t:g}, {self.n_steps} steps, energy error {self.relative_energy_error:.1e}, "
                f"{self.status.value})")

    @property
    def exponent(self) -> float:
        """The first estimate, the growth rate of one deviation: the maximal exponent ``lambda_1`` in the limit."""
        return float(self.exponents[0])

    @property
    def success(self) -> bool:
        return self.status is SolveStatus.SUCCESS

    def plot(self, ax: Any = None, **kwargs: Any) -> Any:
        """Convergence plot: every exponent estimate against time (matplotlib, imported here).

        Returns the ``Axes`` (a new figure's if ``ax`` is ``None``); ``kwargs`` go to ``ax.plot``.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6, 3.5))
        for i in range(self.history.shape[1]):
            ax.plot(self.times, self.history[:, i], label=f"$\\lambda_{i + 1}$", **kwargs)
        ax.axhline(0.0, color="0.6", lw=0.8)
        ax.set_xscale("log")
        ax.set_xlabel("t")
        ax.set_ylabel("finite-time exponent estimate")
        ax.legend()
        return ax


class LyapunovError(RuntimeError):
    """The trajectory under a Lyapunov estimate failed a check; ``result`` holds what was computed."""

    def __init__(self, message: str, result: LyapunovResult) -> None:
        super().__init__(message)
        self.result = result


def float64_precision(precision: Precision) -> Precision:
    """``precision`` if it is a :class:`~manifold.options.Precision` in float64 (by any name), the type of the
    tangent integrator; ``TypeError`` or ``ValueError`` naming ``precision`` otherwise."""
    precision = check_group("precision", precision, Precision)
    if not is_double(precision.fp_type):
        raise ValueError(f"Lyapunov exponents are computed in float64, got precision=Precision(fp_type="
                         f"{precision.fp_type!r})")
    return precision


@takes_option_groups
def lyapunov_spectrum(
    system: ConstrainedSystem,
    x0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    k: int = 1,
    interval: float = 1.0,
    deviations: str = "perpendicular",
    precision: Precision = DEFAULT_PRECISION,
    rate: float = 1.0,
    compact_mode: bool | None = None,
    seed: int = 0,
    throw: bool = True,
    budget: Budget = LYAPUNOV_BUDGET,
) -> LyapunovResult:
    """Finite-time estimates of the ``k`` largest Lyapunov exponents of the geodesic of ``system`` from ``(x0, v0)``.

    Parameters
    ----------
    system
        The :class:`~manifold.constrained.ConstrainedSystem`.
    x0, v0
        Start (float64, shape ``(N,)``; ``x0`` within ``1e-9`` of ``c = 0``,
        ``v0`` tangent, nonzero), completed as in :func:`~manifold.constrained.solve_constrained`.
    t_final
        Length of the estimate, ``> 0``.
    k
        How many exponents: 1 (the maximal one) up to the dimension of the
        deviation space, ``2 (N - m) - 2`` (perpendicular) or ``2 (N - m)`` (tangent).
    interval
        Time between renormalisations, ``> 0`` (``exp(lambda interval)`` must
        stay far from overflow; 1 is safe for exponents below 100).
    deviations
        ``"perpendicular"`` (default) or ``"tangent"`` (module docstring).
    precision
        :class:`~manifold.options.Precision` ``(tol=...)``: heyoka's tolerance (``None``: machine epsilon), as
        in :func:`~manifold.constrained.solve_constrained`; float64 only (the tangent integrator's type): another
        ``fp_type`` raises ``ValueError``.
    rate
        The Baumgarte rate, as in :func:`~manifold.constrained.solve_constrained`.
    compact_mode
        heyoka's compact mode for the variational system; ``None`` (default, as every solver's compile option
        reads it: the measured default) is compact (``k`` times more equations: compact mode compiles it in
        seconds, once per ``k`` and system; heyoka caches it on disk).
    seed
        Seed of the random initial deviations.
    throw
        Raise :class:`LyapunovError` if the trajectory fails its energy or
        constraint check (default), or return the result with ``status`` set.
        The checks run at every renormalisation: a failed one ends the run there.
    budget
        The :class:`~manifold.budget.Budget` of Taylor steps (default :data:`LYAPUNOV_BUDGET`, 1e6); spent, the
        estimate stops with status ``BUDGET_EXCEEDED`` and a message naming the budget and the steps needed.

    Returns
    -------
    LyapunovResult
        The exponents (in Gram-Schmidt order, not sorted: see the module docstring), their convergence history
        and the checks of the trajectory.

    Raises
    ------
    SolveInterrupted
        On Ctrl-C (within about 0.1 s), carrying the result so far (status ``INTERRUPTED``).
    """
    t_final = check_real("t_final", t_final, positive=True)
    interval = check_real("interval", interval, positive=True)
    tol = float64_precision(precision).tol
    rate = check_real("rate", rate, positive=True)
    compact_mode = check_bool("compact_mode", True if compact_mode is None else compact_mode)
    throw = check_bool("throw", throw)
    if deviations not in DEVIATIONS:
        raise ValueError(f"deviations must be one of {DEVIATIONS}, got {deviations!r}")
    N, m = system.ambient_dim, system.n_constraints
    dim = 2 * (N - m) - (2 if deviations == "perpendicular" else 0)
    k = check_positive_int("k", k)
    if k > dim:
        raise ValueError(f"k must be an integer in [1, {dim}] (the {deviations} deviations of this system), got {k}")
    x0, v0 = real_array("x0", x0), real_array("v0", v0)
    for name, arr in (("x0", x0), ("v0", v0)):
        if arr.shape != (N,):
            raise ValueError(f"{name} must have shape ({N},), got {arr.shape}")

    comp = compiled_constrained(system)
    geo = ConstrainedGeometry(system, float)
    X, V, E, alpha = geo.start(x0[None, :], v0[None, :], t_final, rate)
    x, v, E0 = X[0], V[0], float(E[0])
    if not E0 > 0:
        raise ValueError("v0 must be nonzero: a chain at rest has no Lyapunov exponents")
    K = np.asarray(system.metric_matrix, dtype=float)
    speed = math.sqrt(2 * E0)
    # whitening: |S d|^2 = dx^T K dx + dv^T K dv / s^2, so Gram-Schmidt in the plain norm of S d
    R = np.linalg.cholesky(K).T
    S = np.block([[R, np.zeros_like(R)], [np.zeros_like(R), R / speed]])
    S_inv = np.linalg.inv(S)
    jac = comp.phase_jacobian(float)
    jac_pars = comp.layout.pack(system, 0.0, float)[: jac.nparams]

    def project(x: NDArray, v: NDArray, Y: NDArray) -> NDArray:
        """Orthogonal projection (whitened coordinates) onto the deviations allowed at ``(x, v)``."""
        C = jac(np.concatenate([x, v]), pars=jac_pars).reshape(2 * m, 2 * N)
        if deviations == "perpendicular":
            vK = v @ K
            C = np.vstack([C, np.concatenate([vK, np.zeros(N)]), np.concatenate([np.zeros(N), vK])])
        Q, _ = np.linalg.qr((C @ S_inv).T)  # the rows of C are independent on P (G has full rank)
        return Y - Q @ (Q.T @ Y)

    rng = np.random.default_rng(seed)
    Y, _ = np.linalg.qr(project(x, v, rng.standard_normal((2 * N, k))))
    n_intervals = max(1, math.ceil(t_final / interval - 1e-9))
    # no sliver at the end; a generator, not an array: T = 1e7 at interval 0.01 would be 8 GB of end times
    ends = (t_final * j / n_intervals for j in range(1, n_intervals + 1))
    logs, history, times, energies, energy_times = np.zeros(k), [], [], [], []
    t, n_steps, drift, failure = 0.0, 0, 0.0, None
    eps = taylor_relative_tolerance(tol, float)
    with comp.tangent_integrator(k, tol, compact_mode) as ta, interruptible() as pressed, \
            spending(budget) as account:
        ta.pars[:] = comp.layout.pack(system, float(alpha[0]), float)[: len(ta.pars)]
        for end in ends:
            ta.time = t
            ta.state[:] = np.concatenate([x, v, (S_inv @ Y).T.ravel()])
            outcome, steps, stop = propagate_until(ta, float(end), max_steps=allowance(0))
            spend(steps, 0)
            interrupted = stop == INTERRUPTED or pressed()  # or between intervals
            n_steps += steps
            y = np.array(ta.state)
            x, v, t = y[:N], y[N : 2 * N], float(ta.time)
            c, _, _, Ek = geo(x[None, :], v[None, :])  # checked where it stopped, as a single solve checks
            energies.append(float(Ek[0]))
            energy_times.append(t)
            drift = max(drift, float(geo.drift(c)[0]))
            if interrupted or stop == BUDGET or outcome != hy.taylor_outcome.time_limit:
                failure = INTERRUPTED if interrupted else BUDGET if stop == BUDGET else str(outcome)
                break
            checked = verdict(energy_violation(np.array([abs(energies[-1] - E0) / E0]), [t], n_steps, eps,
                                               "ambient coordinates"), drift, n_steps, eps, t, None)[0]
            if checked is not SolveStatus.SUCCESS:  # no use running on: the final verdict says why
                break
            Y, Rk = np.linalg.qr(project(x, v, S @ y[2 * N :].reshape(k, 2 * N).T))
            logs += np.log(np.abs(np.diag(Rk)))
            history.append(logs / t)
            times.append(t)
        pressed_at_all = pressed()  # also where another failure ended the run: a Ctrl-C is never swallowed
    dev = np.abs(np.array(energies) - E0) / E0
    status, message = verdict(energy_violation(dev, energy_times, n_steps, eps, "ambient coordinates"), drift,
                              n_steps, eps, t, failure,
                              lambda tol: system.rounding_hint(float, tol, remedy=False))  # float64 only
    if failure == BUDGET:  # named even where a failed check comes first
        spent = spent_message(account, t, t_final)
        message = spent if status is SolveStatus.BUDGET_EXCEEDED else f"{message}; stopped there: {spent}"
    status, message = settled(pressed_at_all, status, message, t)
    result = LyapunovResult(history[-1] if history else np.full(k, np.nan), np.array(times),
                            np.array(history).reshape(-1, k), deviations, interval, speed, n_steps,
                            float(np.max(dev, initial=0.0)), status, message)
    if status is SolveStatus.INTERRUPTED:
        raise SolveInterrupted(message, result)
    if throw and status is not SolveStatus.SUCCESS:
        raise LyapunovError(message, result)
    return result
