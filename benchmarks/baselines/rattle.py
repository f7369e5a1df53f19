"""RATTLE: the symplectic, time-reversible constrained integrator for the free chain.

The chain moves in hinge space ``R^(2(n-1))`` (interleaved real hinge vector
``x``) with the constant kinetic-energy metric ``K = A (x) I_2`` of
:attr:`Chain.ambient_metric`, under the ``n`` rod constraints

.. math::

    c_k(x) = |e_k|^2 / l_k^2 - 1 = 0, \\qquad e_1 = p_1,\\; e_k = p_k - p_{k-1},\\; e_n = L - p_{n-1},

with Jacobian ``G = dc/dx`` (``n x 2(n-1)``); see :mod:`linkage.constraints`.
With no potential, one RATTLE step of size ``h`` (Andersen 1983; Leimkuhler &
Skeel 1994) from ``(x, v)`` is

.. math::

    v_{1/2} &= v - \\tfrac{h}{2} K^{-1} G(x)^T \\lambda, \\\\
    x_1 &= x + h\\, v_{1/2}, \\qquad c(x_1) = 0 \\quad (\\text{n equations for } \\lambda), \\\\
    v_1 &= v_{1/2} - \\tfrac{h}{2} K^{-1} G(x_1)^T \\mu, \\qquad G(x_1) v_1 = 0 \\quad (\\text{linear in } \\mu).

The position equations are solved by Newton's method in the scaled unknown
``s = h^2 lambda / 2`` (so ``x_1 = x + h v - K^{-1} G(x)^T s``):

.. math::

    s \\leftarrow s + \\big(G(x_1) K^{-1} G(x)^T\\big)^{-1} c(x_1),

started from the previous step's ``s``.  The velocity equations have the closed
form ``v_1 = v_{1/2} - K^{-1} G_1^T (G_1 K^{-1} G_1^T)^{-1} G_1 v_{1/2}``
(``G_1 = G(x_1)``): the K-orthogonal projection onto the tangent space.  Both
use :class:`linkage.constraints.HingeConstraints`, the second through its
:meth:`~linkage.constraints.HingeConstraints.min_norm_correction`.

Properties (of the exact map, up to the Newton tolerance and rounding): every
step lands on the constraints ``c = 0`` with a tangent velocity; the map is
symplectic and symmetric (a step of ``-h`` from ``(x_1, v_1)`` returns to
``(x, v)``), so it is second order and its energy error ``O(h^2)`` stays
bounded over exponentially long times instead of drifting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from charts.chain_geometry import to_complex

from linkage import Chain
from linkage.constraints import start_state
from linkage.constraints import HingeConstraints
from manifold.options import DEFAULT_START, StartCheck
from manifold.validation import check_real

__all__ = ["RattleSolution", "integrate_rattle"]

#: Default Newton tolerance on ``max_k |c_k(x_1)|``.
NEWTON_TOL = 1e-14
#: Default maximal Newton iterations per step.
NEWTON_MAX_ITER = 20


@dataclass
class RattleSolution:
    """Result of :func:`integrate_rattle`.

    Attributes
    ----------
    t
        Recorded times: ``0``, every ``record_every``-th step, and always ``t_final``.
    hinges, velocities
        Complex hinges ``p_j`` and velocities ``p_j'`` at ``t``, shape ``(len(t), n-1)``.
    energy
        Kinetic energy ``1/2 v^T K v`` at ``t`` (bounded oscillation ``O(h^2)``, no drift).
    constraint_residual
        ``max_k | |e_k| - l_k | / l_k`` at ``t`` (Newton tolerance level after the first step).
    n_steps
        Number of RATTLE steps taken (the last one possibly shortened).
    newton_iterations
        Total Newton iterations over all steps.
    h
        The (positive) nominal step size.
    """

    t: NDArray
    hinges: NDArray
    velocities: NDArray
    energy: NDArray
    constraint_residual: NDArray
    n_steps: int
    newton_iterations: int
    h: float

    @property
    def relative_energy_error(self) -> NDArray:
        """``|E(t) - E(0)| / E(0)`` at every recorded time (absolute error if ``E(0) = 0``)."""
        dE = np.abs(self.energy - self.energy[0])
        return dE / self.energy[0] if self.energy[0] != 0 else dE


def _step_sizes(t_final: float, h: float) -> NDArray:
    """Signed step sizes ``h, ..., h, r`` summing to ``t_final`` (``0 < |r| <= h (1 + 1e-9)``)."""
    T = abs(t_final)
    n = max(1, math.ceil(T / h - 1e-9))  # no sliver of a last step
    steps = np.full(n, h)
    steps[-1] = T - (n - 1) * h
    return math.copysign(1.0, t_final) * steps


class _Rattle:
    """One chain's RATTLE map (all real, interleaved)."""

    def __init__(self, system: HingeConstraints, tol: float, max_iter: int) -> None:
        self.sys, self.tol, self.max_iter = system, tol, max_iter

    def step(self, x: NDArray, v: NDArray, G0: NDArray, s: NDArray, h: float, where: str):
        """``(x, v)`` to ``(x_1, v_1)``; returns ``x_1, v_1, G(x_1), s, iterations``.

        ``G0 = G(x)``; ``s`` is the starting guess for ``h^2 lambda / 2``.
        """
        sys = self.sys
        x_pred = x + h * v
        KiG0t = sys.K_inv @ G0.T  # (m, n)
        d = KiG0t @ s
        x1 = x_pred - d
        c = sys.constraints(x1)
        res = np.max(np.abs(c))
        it = 0
        while not res <= self.tol:
            if not np.isfinite(res):
                raise RuntimeError(f"RATTLE Newton iteration diverged (non-finite state) {where} (h = {h:g})")
            if it == self.max_iter:
                raise RuntimeError(
                    f"RATTLE position solve did not converge {where}: after {it} Newton iterations "
                    f"max_k |c_k| = {res:.3g} > tol = {self.tol:g} (step h = {h:g}); "
                    "try a smaller h"
                )
            G1 = sys.jacobian(x1)
            try:
                s = s + np.linalg.solve(G1 @ KiG0t, c)
            except np.linalg.LinAlgError as err:
                raise RuntimeError(f"RATTLE Newton matrix G(x_1) K^-1 G(x)^T is singular {where} (h = {h:g})") from err
            d = KiG0t @ s
            x1 = x_pred - d
            c = sys.constraints(x1)
            res = np.max(np.abs(c))
            it += 1
        v_half = v - d / h  # = (x1 - x) / h, without its cancellation
        G1 = sys.jacobian(x1)
        v1 = v_half - sys.min_norm_correction(G1, G1 @ v_half)
        return x1, v1, G1, s, it


def integrate_rattle(
    chain: Chain,
    hinges0: ArrayLike,
    velocity0: ArrayLike,
    t_final: float,
    h: float,
    *,
    record_every: int = 1,
    newton_tol: float = NEWTON_TOL,
    max_newton_iterations: int = NEWTON_MAX_ITER,
    start: StartCheck = DEFAULT_START,
) -> RattleSolution:
    """Integrate the free motion of ``chain`` by RATTLE with fixed step ``h``.

    Each step solves (module docstring)

    .. math::

        x_1 = x + h v - \\tfrac{h^2}{2} K^{-1} G(x)^T \\lambda, \\quad c(x_1) = 0, \\qquad
        v_1 = \\tfrac{x_1 - x}{h} - \\tfrac{h}{2} K^{-1} G(x_1)^T \\mu, \\quad G(x_1) v_1 = 0,

    a second-order, symplectic and time-symmetric approximation of the
    geodesic flow of the kinetic-energy metric on the configuration sphere.

    Parameters
    ----------
    chain
        The :class:`~linkage.Chain` (``n``, ``L`` and mass model ``K``).
    hinges0
        Complex initial hinges ``p_1 .. p_{n-1}``; must close to ``1e-9``
        (:meth:`Chain.check_configuration`, raises ``ConfigurationError``).
    velocity0
        Complex initial hinge velocities, finite and tangent:
        ``max_k l_k |(G v)_k| <= start.tangent_tol * max(1, |v|)``, else ``ValueError``
        -- unless ``start.project_velocity``.
    t_final
        Finite, nonzero end time; negative integrates backward (steps ``-h``).
        Need not be a multiple of ``h``: the last step is shortened.
    h
        Step size, finite and ``> 0``.
    record_every
        Record every ``record_every``-th step (and always the first and last state).
    newton_tol
        Newton stops when ``max_k |c_k(x_1)| <= newton_tol``.
    max_newton_iterations
        Newton iterations allowed per step; more raises ``RuntimeError``.
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the relative tolerance of the
        tangency check of ``velocity0``, and whether a non-tangent one is projected K-orthogonally onto the
        tangent space instead of refused.

    Returns
    -------
    RattleSolution

    Raises
    ------
    ConfigurationError
        ``hinges0`` has the wrong shape, is not finite or does not close.
    ValueError
        Bad ``velocity0``, ``t_final``, ``h``, ``record_every`` or tolerances.
    RuntimeError
        Newton's method failed to put a step on the constraints.
    """
    h = check_real("h", h, positive=True)
    if isinstance(record_every, bool) or not isinstance(record_every, (int, np.integer)) or record_every < 1:
        raise ValueError(f"record_every must be an integer >= 1, got {record_every!r}")
    newton_tol = check_real("newton_tol", newton_tol, positive=True)
    if isinstance(max_newton_iterations, bool) or not isinstance(max_newton_iterations, (int, np.integer)) \
            or max_newton_iterations < 1:
        raise ValueError(f"max_newton_iterations must be an integer >= 1, got {max_newton_iterations!r}")
    system, x, v, t_final = start_state(chain, hinges0, velocity0, t_final, start)

    steps = _step_sizes(t_final, h)
    n_steps = len(steps)
    rec = [0] + list(range(record_every, n_steps, record_every)) + [n_steps]
    rec = sorted(set(rec))
    ts = np.empty(len(rec))
    xs = np.empty((len(rec), system.ambient_dim))
    vs = np.empty((len(rec), system.ambient_dim))
    ts[0], xs[0], vs[0] = 0.0, x, v

    rattle = _Rattle(system, newton_tol, int(max_newton_iterations))
    G = system.jacobian(x)
    s = np.zeros(chain.n)
    total_it, r, h_prev = 0, 1, steps[0]
    t = 0.0
    for k, hk in enumerate(steps):
        s = s * (hk / h_prev) ** 2  # s = h^2 lambda / 2: rescale the guess for a shortened step
        x, v, G, s, it = rattle.step(x, v, G, s, hk, where=f"at step {k + 1} of {n_steps} (t = {t:g} -> {t + hk:g})")
        total_it += it
        h_prev = hk
        t = t_final if k == n_steps - 1 else (k + 1) * steps[0]
        if r < len(rec) and rec[r] == k + 1:
            ts[r], xs[r], vs[r] = t, x, v
            r += 1

    hinges, velocities = to_complex(xs), to_complex(vs)
    return RattleSolution(
        t=ts,
        hinges=hinges,
        velocities=velocities,
        energy=0.5 * np.einsum("ti,ij,tj->t", vs, system.K, vs),
        constraint_residual=chain.closure_residual(hinges),
        n_steps=n_steps,
        newton_iterations=total_it,
        h=h,
    )
