"""The dynamics seed's closed-form kinetic metric of the 4-rod chain (its section 3).

An independent transcription of the seed's ``metric4(phi, t, L)``: named scalar
partials, the angular-velocity functional ``Omega_a`` and the boxed components
``h_tt, h_phi t, h_phi phi``.  It shares no code with the pulled-back metric
``J^T J`` of :class:`charts.SuspensionChart` and serves as a cross-check and as
the seed's own baseline method.  Unit hinge masses, massless rods, identity
rod order, coordinates ``(phi, t) = (phi_4, t)``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def metric4(phi: float, t: float, L: float) -> NDArray:
    """``[[h_pp, h_pt], [h_pt, h_tt]]`` at ``(phi, t)`` for base length ``L`` (``2 < L < 4``).

    The seed switches ``nu_in`` to its limit ``cos(t) sqrt(d alpha_in sin alpha_in)``
    where ``|cos t| < 1e-6`` (its ratio is 0/0 at ``t = +-pi/2``); that branch is
    kept, so near there the result is only as accurate as the seed's.
    """
    alpha = np.arccos((L * L - 8) / (2 * L))
    cphi, sphi = np.cos(phi), np.sin(phi)
    theta = alpha * sphi
    ctheta, stheta = np.cos(theta), np.sin(theta)
    d = np.sqrt(L * L - 2 * L * ctheta + 1)
    R = np.arctan2(-stheta, L - ctheta)
    dtheta_p = alpha * cphi
    dd_p = (L * stheta / d) * dtheta_p
    dR_p = ((1 - L * ctheta) / (d * d)) * dtheta_p

    alpha_in = np.arccos((d * d - 3) / (2 * d))
    sin_ai = np.sqrt((d * d - 1) * (9 - d * d)) / (2 * d)
    ct, st = np.cos(t), np.sin(t)
    theta_in = alpha_in * st
    dtheta_in_t = alpha_in * ct
    dalpha_in_p = -((d * d + 3) / (2 * d * d * sin_ai)) * dd_p
    dtheta_in_p = dalpha_in_p * st

    p3 = np.array([L - ctheta, -stheta])
    u4 = np.array([ctheta, stheta])
    u3 = np.array([np.cos(R + theta_in), np.sin(R + theta_in)])
    p2 = p3 - u3
    p2_abs = np.hypot(*p2)
    if abs(ct) < 1e-6:
        nu_in = ct * np.sqrt(d * alpha_in * sin_ai)
    else:
        nu_in = ct * np.sqrt((4 - p2_abs * p2_abs) / (ct * ct))

    # -i u s = (u_im s, -u_re s)
    dt_p2 = np.array([u3[1] * dtheta_in_t, -u3[0] * dtheta_in_t])
    c1, c2 = dtheta_p, dR_p + dtheta_in_p
    dphi_p2 = np.array([u4[1] * c1 + u3[1] * c2, -(u4[0] * c1 + u3[0] * c2)])

    def omega(v: NDArray) -> float:
        im = (p2[0] * v[1] - p2[1] * v[0]) / (p2_abs * p2_abs)
        re = (p2[0] * v[0] + p2[1] * v[1]) / (p2_abs * nu_in)
        return im - re

    om_t, om_p = omega(dt_p2), omega(dphi_p2)
    u34 = u3 @ u4
    h_tt = om_t * om_t + dtheta_in_t * dtheta_in_t
    h_pp = om_p * om_p + 2 * dtheta_p * dtheta_p + c2 * c2 + 2 * dtheta_p * c2 * u34
    h_pt = om_t * om_p + dtheta_in_t * (dtheta_p * u34 + c2)
    return np.array([[h_pp, h_pt], [h_pt, h_tt]])
