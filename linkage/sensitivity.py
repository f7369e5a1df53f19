r"""How sensitive a chain's free motion is to its start: the growth of the linearised flow, and what it does to errors.

Two solves that each keep the energy to 1e-13 can still differ by order one: over 25 radii a chaotic
motion amplifies a difference of ``1e-14`` a hundred billion times, and no check on the energy sees it.
:func:`sensitivity` measures that amplification with the linearised geodesic flow. Its columns are
the Jacobi fields (:func:`linkage.geometry.jacobi_field`) from a kinetic-orthonormal basis
``e_1 .. e_k`` of the start's tangent space:

.. math::

    \Phi(t)\colon (\delta x_0, \tau\, \delta v_0) \mapsto (J(t), \tau\, D_t J(t)),
    \qquad A(t) = \|\Phi(t)\|_2 ,

on the ``2k`` fields ``J(0) = e_i, D_t J(0) = 0`` and ``J(0) = 0, D_t J(0) = e_i / \tau``. Both sides
are measured in the kinetic norm. ``\tau = 1 / (\sqrt{2E}\, s)`` is the time in which the fastest
motion of that energy crosses the chain's length (``s`` is
:func:`manifold.constrained.speed_scale`), so ``A`` is scale-free and ``A(0) = 1``. A perturbation
of the start of relative size ``delta`` moves the state at ``t`` by at most about ``A(t) delta``. The
integrator's own local errors, of the size of its tolerance, grow no faster, so
``A(t) max(tol, energy error)`` estimates the relative error of the computed state (an estimate, not
a bound: errors made later grow less, and the energy error is a lower bound on the state's).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.compiled import default_tolerance
from manifold.constrained import speed_scale
from manifold.options import (DEFAULT_PRECISION, DEFAULT_SAVE, DEFAULT_START, Precision, SaveAt, StartCheck,
                              check_group, takes_option_groups)
from manifold.precision import unit_roundoff

from .chain import Chain
from .constraints import ChainSystem
from .geometry import checked_start, jacobi_field_from, tangent_basis_at
from .motion import AUTO

__all__ = ["DEFAULT_THRESHOLD", "Sensitivity", "SensitivityWarning", "sensitivity"]

#: Estimated relative error of the state above which :func:`sensitivity` warns.
DEFAULT_THRESHOLD = 1e-6


class SensitivityWarning(UserWarning):
    """A motion so sensitive to its start that its own rounding and truncation may have changed it visibly."""


@dataclass(frozen=True)
class Sensitivity:
    """:func:`sensitivity`'s answer.

    Attributes
    ----------
    times
        Sample times (1-d).
    amplification
        ``A(t) = ||Phi(t)||_2`` at :attr:`times` (1 at ``t = 0``).
    level
        The relative error made along the way, ``max(tol, relative energy error)`` of the solve.
    time_scale
        ``tau``, the time unit that makes positions and velocities comparable.
    """

    times: NDArray
    amplification: NDArray
    level: float
    time_scale: float

    @property
    def estimated_error(self) -> NDArray:
        """``A(t) level``: the estimated relative error of the computed state at :attr:`times`."""
        return self.amplification * self.level

    @property
    def rate(self) -> float:
        """``log A(T) / T``: the mean exponential growth rate over the run (a finite-time Lyapunov exponent)."""
        return float(np.log(self.amplification[-1]) / abs(self.times[-1]))

    def __repr__(self) -> str:
        return (f"Sensitivity(A(T) = {self.amplification[-1]:.3g} at T = {self.times[-1]:g}, estimated relative "
                f"error {self.estimated_error[-1]:.1e})")


@takes_option_groups
def sensitivity(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, T: float, *, save: SaveAt = DEFAULT_SAVE,
                precision: Precision = DEFAULT_PRECISION, method: str = AUTO, start: StartCheck = DEFAULT_START,
                threshold: float = DEFAULT_THRESHOLD, **options: Any) -> Sensitivity:
    """The amplification ``A(t)`` of the linearised flow from ``(hinges0, velocity0)`` over ``T``.

    It warns with :class:`SensitivityWarning` when the estimated relative error of the state at ``T``
    exceeds ``threshold``.

    Parameters
    ----------
    chain, hinges0, velocity0, T, save, precision, method, start
        As in :func:`linkage.geometry.jacobi_field` (``save=SaveAt(t_eval=...)``; default: every step;
        ``start=StartCheck(tangent_tol, project_velocity)``, the one check of the start).
    threshold
        Warn above this estimated relative error (``> 0``; default :data:`DEFAULT_THRESHOLD`).
    **options
        Passed to :func:`linkage.geometry.jacobi_field` (``throw``, ``rate``, ``compact_mode``, ...).
        The fields' invariants are not checked (they lose digits with the growth they measure); the geodesic's
        energy and rods are.

    Returns
    -------
    Sensitivity
        ``times``, ``amplification``, ``level``, ``estimated_error``, ``rate``.

    Notes
    -----
    The ``2k`` Jacobi fields cost about as much as ``2k`` extra geodesics in one integrator.
    """
    threshold = float(threshold)
    if not threshold > 0 or not np.isfinite(threshold):
        raise ValueError(f"threshold must be a finite number > 0, got {threshold!r}")
    precision = check_group("precision", precision, Precision)
    hinge_start, grid = checked_start(chain, hinges0, velocity0, T, save, start, method)
    v0 = hinge_start.v0
    basis = tangent_basis_at(hinge_start.constraints, hinge_start.x0)
    energy = float(0.5 * v0 @ chain.ambient_metric @ v0)
    # at rest there is no speed to set a time unit; the run's own length serves (A then measures J(T) = T U0)
    tau = 1.0 / (np.sqrt(2 * energy) * speed_scale(ChainSystem(chain))) if energy > 0 else abs(float(T))
    zeros = np.zeros_like(basis)
    fields = jacobi_field_from(hinge_start, np.concatenate([basis, zeros]), np.concatenate([zeros, basis / tau]),
                               grid, precision, method, start, False, options, "sensitivity")
    solution = fields.carried.solution
    R = np.linalg.cholesky(chain.ambient_metric).T  # |x|_K = |R x|
    J = chain.to_point(fields.field) @ R.T  # (times, 2k, N), Euclidean after R
    U = chain.to_point(fields.field_derivative) @ R.T * tau
    columns = np.concatenate([J, U], axis=2)  # Phi's columns, (times, 2k, 2N)
    amplification = np.linalg.svd(columns, compute_uv=False)[:, 0]
    fp_type = precision.fp_type
    tol = precision.tol or default_tolerance(fp_type) or unit_roundoff(fp_type)
    level = max(float(tol), float(solution.relative_energy_error))
    result = Sensitivity(fields.times, amplification, level, float(tau))
    if result.estimated_error[-1] > threshold:
        warnings.warn(f"the motion amplifies errors of its start {amplification[-1]:.3g}-fold by t = "
                      f"{fields.times[-1]:g} (rate {result.rate:.3g} per unit time): its estimated relative error "
                      f"{result.estimated_error[-1]:.1e} exceeds {threshold:g}; a higher precision "
                      f"(precision=Precision(fp_type=...)) or a shorter time keeps it meaningful", SensitivityWarning, stacklevel=2)
    return result
