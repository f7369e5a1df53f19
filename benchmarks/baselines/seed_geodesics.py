"""The dynamics seed's own geodesic method for the 4-rod chain (its section "Geodesics").

A faithful transcription, kept as a baseline to compare the library against:

* the closed-form metric ``metric4(phi, t, L)`` of :mod:`benchmarks.baselines.seed_metric4`
  (unit hinge masses, massless rods, identity rod order, coordinates
  ``a = (phi, t) = (phi_4, t)`` of ``SuspensionChart(4, L)``), with
  ``E = h_phiphi``, ``F = h_phit``, ``G = h_tt``;
* its six partials by central differences with ``eps = 1e-5``,
  ``dE/dphi ~ (E(phi + eps, t) - E(phi - eps, t)) / (2 eps)`` and so on;
* the inverse metric by the 2x2 formula, ``D = EG - F^2``,
  ``E^ = G/D``, ``F^ = -F/D``, ``G^ = E/D``;
* the Christoffel symbols

  .. math::

      \\Gamma^\\phi_{\\phi\\phi} &= \\tfrac12 [E^ E_\\phi + F^ (2 F_\\phi - E_t)], &
      \\Gamma^t_{\\phi\\phi} &= \\tfrac12 [F^ E_\\phi + G^ (2 F_\\phi - E_t)], \\\\
      \\Gamma^\\phi_{tt} &= \\tfrac12 [E^ (2 F_t - G_\\phi) + F^ G_t], &
      \\Gamma^t_{tt} &= \\tfrac12 [F^ (2 F_t - G_\\phi) + G^ G_t], \\\\
      \\Gamma^\\phi_{\\phi t} &= \\tfrac12 [E^ E_t + F^ G_\\phi], &
      \\Gamma^t_{\\phi t} &= \\tfrac12 [F^ E_t + G^ G_\\phi];

* the geodesic equations
  ``phi'' = -(phi'^2 Gam^phi_phiphi + 2 phi' t' Gam^phi_phit + t'^2 Gam^phi_tt)`` and
  ``t''   = -(phi'^2 Gam^t_phiphi   + 2 phi' t' Gam^t_phit   + t'^2 Gam^t_tt)``;
* integrated by fixed-step classical RK4 in the single chart: the seed does no
  chart switching, and says that a trajectory through a pole ``phi = +-pi/2``
  "just breaks".  :func:`integrate_seed_rk4` stops there and reports where
  (``failed_at``) instead of raising, because that failure is the point of the
  comparison with the library's atlas.

Accuracy: the central differences have truncation error ``~eps^2 |g'''|`` and
rounding error ``~1e-16 |g| / eps``, so the vector field is good to roughly
``1e-10 .. 1e-7`` relative away from the poles.  Two weak spots:

* near a pole the metric degenerates (``D -> 0``), the Christoffel symbols blow
  up and the differences lose digits (relative error ``5e-5`` at
  ``cos phi = 0.006``, ``4e-3`` at ``8e-4``); ``metric4`` is NaN within about
  ``1e-8`` of the pole;
* near ``t = +-pi/2`` the seed's ``nu_in = cos t sqrt((4 - |p_2|^2) / cos^2 t)``
  cancels and switches branch at ``|cos t| < 1e-6``; the ``t``-differences
  straddle that region, so within ``~1e-4`` of ``t = +-pi/2`` the acceleration
  is off by ``1e-4 .. 1e-2`` relative, and exactly at ``t = pi/2`` by orders of
  magnitude (``(p_2 . dp_2/dphi) / nu_in`` is rounding over rounding).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from charts import SuspensionChart, validate_chain
from manifold.validation import check_real

from .seed_metric4 import metric4

__all__ = ["SEED_EPS", "SeedSolution", "integrate_seed_rk4", "seed_vector_field"]

#: The seed's central-difference step for the metric partials.
SEED_EPS = 1e-5
HALF_PI = math.pi / 2


def _validate_L(L: object) -> float:
    return validate_chain(4, L)[1]


def _vector_field(state: NDArray, L: float) -> NDArray:
    """The seed's ``geodesicVectorField`` without input checks."""
    phi, t, phidot, tdot = state
    eps = SEED_EPS
    m = metric4(phi, t, L)
    mPh = metric4(phi + eps, t, L)
    mPl = metric4(phi - eps, t, L)
    mTh = metric4(phi, t + eps, L)
    mTl = metric4(phi, t - eps, L)

    E, F, G = m[0, 0], m[0, 1], m[1, 1]
    Ep = (mPh[0, 0] - mPl[0, 0]) / (2 * eps)
    Fp = (mPh[0, 1] - mPl[0, 1]) / (2 * eps)
    Gp = (mPh[1, 1] - mPl[1, 1]) / (2 * eps)
    Et = (mTh[0, 0] - mTl[0, 0]) / (2 * eps)
    Ft = (mTh[0, 1] - mTl[0, 1]) / (2 * eps)
    Gt = (mTh[1, 1] - mTl[1, 1]) / (2 * eps)

    # inverse metric (script E, F, G of the seed)
    D = E * G - F * F
    Ei, Fi, Gi = G / D, -F / D, E / D

    # Christoffel symbols Gam_<upper>_<lower lower>
    Gam_p_pp = 0.5 * (Ei * Ep + Fi * (2 * Fp - Et))
    Gam_t_pp = 0.5 * (Fi * Ep + Gi * (2 * Fp - Et))
    Gam_p_tt = 0.5 * (Ei * (2 * Ft - Gp) + Fi * Gt)
    Gam_t_tt = 0.5 * (Fi * (2 * Ft - Gp) + Gi * Gt)
    Gam_p_pt = 0.5 * (Ei * Et + Fi * Gp)
    Gam_t_pt = 0.5 * (Fi * Et + Gi * Gp)

    phiddot = -(phidot * phidot * Gam_p_pp + 2 * phidot * tdot * Gam_p_pt + tdot * tdot * Gam_p_tt)
    tddot = -(phidot * phidot * Gam_t_pp + 2 * phidot * tdot * Gam_t_pt + tdot * tdot * Gam_t_tt)
    return np.array([phidot, tdot, phiddot, tddot], dtype=float)


def seed_vector_field(state: ArrayLike, L: float) -> NDArray:
    """The seed's geodesic vector field ``(phi, t, phi', t') -> (phi', t', phi'', t'')``.

    Parameters
    ----------
    state
        ``(phi, t, phidot, tdot)``: chart parameters ``a = (phi_4, t)`` of
        ``SuspensionChart(4, L)`` and their velocities; finite.
    L
        Base length, ``2 < L < 4``.

    Returns
    -------
    numpy.ndarray
        ``(phidot, tdot, phiddot, tddot)`` with the accelerations from the
        Christoffel symbols of ``metric4`` (central differences, ``eps = 1e-5``;
        see the module docstring).  Non-finite at a pole ``|phi| = pi/2``.
    """
    L = _validate_L(L)
    y = np.asarray(state, dtype=float)
    if y.shape != (4,):
        raise ValueError(f"state must be (phi, t, phidot, tdot), got shape {y.shape}")
    if not np.all(np.isfinite(y)):
        raise ValueError(f"state must be finite, got {y}")
    with np.errstate(all="ignore"):
        return _vector_field(y, L)


@dataclass
class SeedSolution:
    """Result of :func:`integrate_seed_rk4`.

    Attributes
    ----------
    t
        Times of the recorded (good) states: ``0, h, 2h, ...`` (signed), the
        last one ``t_final`` unless the run failed.
    a, c
        Parameters ``(phi, t)`` and velocities ``(phi', t')``, shape ``(len(t), 2)``.
    hinges
        Complex hinges ``(len(t), 3)`` from ``SuspensionChart(4, L).hinges(a)``.
    energy
        ``1/2 c^T metric4(a) c`` at each recorded time.  NaN for a state within
        about ``1e-8`` of a pole, where ``metric4`` itself is NaN (rounding puts
        the inner chain's length ``d`` above 3); the step after it then fails.
    failed_at
        Time of the first step whose result was non-finite or had ``|phi| > pi/2``
        (that state is not recorded); ``None`` if the run reached ``t_final``.
    L, h
        Base length and (positive) step size.
    """

    t: NDArray
    a: NDArray
    c: NDArray
    hinges: NDArray
    energy: NDArray
    failed_at: float | None
    L: float
    h: float

    @property
    def n_steps(self) -> int:
        """Steps whose result was recorded."""
        return len(self.t) - 1

    @property
    def relative_energy_error(self) -> NDArray:
        """``|E(t) - E(0)| / E(0)`` at every recorded time."""
        return np.abs(self.energy - self.energy[0]) / self.energy[0]


def _energy(a: NDArray, c: NDArray, L: float) -> float:
    return float(0.5 * c @ metric4(a[0], a[1], L) @ c)


def integrate_seed_rk4(L: float, a0: ArrayLike, c0: ArrayLike, t_final: float, h: float) -> SeedSolution:
    """Integrate the seed's geodesic equations by fixed-step classical RK4 in one chart.

    With ``y = (phi, t, phi', t')`` and ``f`` = :func:`seed_vector_field`, each step is

    .. math::

        k_1 = f(y),\\; k_2 = f(y + \\tfrac h2 k_1),\\; k_3 = f(y + \\tfrac h2 k_2),\\;
        k_4 = f(y + h k_3),\\qquad y \\leftarrow y + \\tfrac h6 (k_1 + 2k_2 + 2k_3 + k_4).

    Parameters
    ----------
    L
        Base length, ``2 < L < 4``.
    a0
        Start parameters ``(phi, t)`` with ``|phi| < pi/2`` (the chart's
        interior: at a pole the seed's metric is degenerate).
    c0
        Start velocities ``(phi', t')``, finite.
    t_final
        Finite, nonzero end time; negative integrates backward.  Need not be a
        multiple of ``h`` (the last step is shortened).
    h
        Step size, finite and ``> 0``.

    Returns
    -------
    SeedSolution
        The recorded states up to ``t_final`` or up to the failure; the run
        stops at the first step that is non-finite or leaves ``|phi| <= pi/2``
        and records its time in ``failed_at`` (no exception).
    """
    L = _validate_L(L)
    a0 = np.asarray(a0, dtype=float)
    c0 = np.asarray(c0, dtype=float)
    if a0.shape != (2,) or c0.shape != (2,):
        raise ValueError(f"a0 = (phi, t) and c0 = (phi', t') must have shape (2,), got {a0.shape} and {c0.shape}")
    if not (np.all(np.isfinite(a0)) and np.all(np.isfinite(c0))):
        raise ValueError(f"a0 and c0 must be finite, got {a0} and {c0}")
    if not abs(a0[0]) < HALF_PI:
        raise ValueError(
            f"phi must lie strictly inside (-pi/2, pi/2) (the seed's chart is singular at its poles), got {a0[0]!r}"
        )
    t_final = check_real("t_final", t_final, nonzero=True)
    h = check_real("h", h, positive=True)

    T = abs(t_final)
    n = max(1, math.ceil(T / h - 1e-9))
    sign = math.copysign(1.0, t_final)

    y = np.concatenate([a0, c0])
    ts, ys = [0.0], [y]
    failed_at = None
    with np.errstate(all="ignore"):
        for k in range(n):
            hk = sign * (h if k < n - 1 else T - (n - 1) * h)
            try:
                k1 = _vector_field(y, L)
                k2 = _vector_field(y + 0.5 * hk * k1, L)
                k3 = _vector_field(y + 0.5 * hk * k2, L)
                k4 = _vector_field(y + hk * k3, L)
                y_new = y + (hk / 6) * (k1 + 2 * k2 + 2 * k3 + k4)
            except (ZeroDivisionError, FloatingPointError, ValueError):
                y_new = np.full(4, np.nan)
            t_new = t_final if k == n - 1 else sign * (k + 1) * h
            if not np.all(np.isfinite(y_new)) or abs(y_new[0]) > HALF_PI:
                failed_at = float(t_new)
                break
            y = y_new
            ts.append(t_new)
            ys.append(y)
        Y = np.array(ys)
        a, c = Y[:, :2], Y[:, 2:]
        energy = np.array([_energy(ai, ci, L) for ai, ci in zip(a, c)])
    return SeedSolution(
        t=np.array(ts),
        a=a,
        c=c,
        hinges=SuspensionChart(4, L).hinges(a),
        energy=energy,
        failed_at=failed_at,
        L=L,
        h=h,
    )
