"""Configuration curves of closed 5R chains by exact elimination over the rationals.

The closure condition ``(t_1 - h_1) ... (t_5 - h_5)`` real and nonzero ([HSS] eq. 1) is
the coupling equality for the links ``o_5`` and ``o_2``:

    (t_1 - h_1)(t_2 - h_2)  ~  Z = (t_5 + h_5)(t_4 + h_4)(t_3 + h_3),

so ``Z`` lies in the coupling space ``L_12 = span(1, h_1, h_2, h_1 h_2)`` and its coordinates
``alpha`` there satisfy ``alpha_0 alpha_3 = alpha_1 alpha_2`` (then ``t_1 = -alpha_2/alpha_3``,
``t_2 = -alpha_1/alpha_3``).  ``Z = A t_3 + A h_3`` with ``A = (t_5 + h_5)(t_4 + h_4)`` is
linear in ``t_3``: with ``P`` the projection onto the complement of ``L_12``, a ``t_3``
exists where the vectors ``P A`` and ``P A h_3`` are parallel, i.e. where all their 2 x 2
minors vanish.  These are polynomials of bidegree at most ``(2, 2)`` in ``(t_4, t_5)``;
their gcd over Q holds every curve component of the configuration set, projected to the
``(t_4, t_5)`` plane.  Each irreducible factor is parametrised (rationally when it is
linear in one variable, else by ``w = sqrt(discriminant)``) and kept only if the closure
condition holds on it identically (exact check by the chain's constructor), which discards
the spurious factors (``t_k^2 + 1``, the locus where ``P A = P A h_3 = 0``).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy

from .curve import T, W, ConfigurationCurve
from .dualquat import DualQuaternion

__all__ = ["RigidLinkageError", "candidate_curves_5r"]


class RigidLinkageError(ValueError):
    """The chain is rigid: its closure equations have no curve of solutions."""


def candidate_curves_5r(axes: Sequence[DualQuaternion]) -> list[ConfigurationCurve]:
    """Curves in the normal form of :class:`ConfigurationCurve`, one per component candidate.

    ``axes`` are five rational unit lines.  The candidates still have to pass the exact
    closure check (``RevoluteChain(axes, curve=...)``).  A component on which joint 4 or
    joint 5 stays fixed (a factor free of one variable, not ``t^2 + 1``) cannot be
    parametrised by the other one; it raises ``ValueError``.
    """
    h1, h2, h3, h4, h5 = axes
    y = sympy.Symbol("y")  # t_4; t_5 is the curve parameter T
    one = sympy.Integer(1)
    basis = sympy.Matrix([list(v) for v in (DualQuaternion.scalar(one), h1, h2, h1 * h2)]).T
    if basis.rank() != 4:
        raise ValueError("axes 1 and 2 span less than a 4-dimensional coupling space (equal lines?)")
    coords = (basis.T * basis).inv() * basis.T
    a = sympy.Matrix(list(((T + h5) * (y + h4)).map(sympy.expand)))
    b = sympy.Matrix(list(((T + h5) * (y + h4) * h3).map(sympy.expand)))
    pa = (a - basis * (coords * a)).applyfunc(sympy.expand)
    pb = (b - basis * (coords * b)).applyfunc(sympy.expand)
    minors = [sympy.expand(pa[k] * pb[m] - pa[m] * pb[k]) for k in range(8) for m in range(k + 1, 8)]
    minors = [e for e in minors if e != 0]
    if not minors:
        raise ValueError("P A and P A h_3 are parallel for all t_4, t_5: a degenerate chain (two-dimensional motion?)")
    g = minors[0]
    for e in minors[1:]:
        g = sympy.gcd(g, e)
        if g.is_number:
            return []
    curves = []
    for f, _ in sympy.factor_list(g, y, T)[1]:
        dy, dt = sympy.degree(f, y), sympy.degree(f, T)
        v = T if dy == 0 else (y if dt == 0 else None)
        if v is not None:
            if sympy.rem(v**2 + 1, f, v) == 0:
                continue  # t_k = +-I: the product has zero norm there, no configuration
            raise ValueError(
                f"the configuration set has a component with joint {5 if v == T else 4} fixed ({f} = 0); "
                "it cannot be parametrised by the other joint: pass curve= for that component"
            )
        if dy == 1:
            c1, c0 = sympy.Poly(f, y).all_coeffs()
            t4 = -c0 / c1
            g_w = None
        else:  # the minors have degree <= 2 in t_4
            ca, cb, cc = sympy.Poly(f, y).all_coeffs()
            g_w = sympy.expand(cb**2 - 4 * ca * cc)
            t4 = (-cb + W) / (2 * ca)
        pa_s, pb_s = pa.subs(y, t4), pb.subs(y, t4)
        k = next((k for k in range(8) if sympy.simplify(pa_s[k]) != 0), None)
        if k is None:
            continue
        t3 = sympy.together(-pb_s[k] / pa_s[k])
        z = a.subs(y, t4) * t3 + b.subs(y, t4)
        alpha = coords * z
        t1 = sympy.together(-alpha[2] / alpha[3])
        t2 = sympy.together(-alpha[1] / alpha[3])
        joints = [t1, t2, t3, t4, T]
        try:
            if g_w is None:
                curves.append(ConfigurationCurve.rational([sympy.cancel(e) for e in joints]))
            else:
                curves.append(ConfigurationCurve.hyperelliptic(joints, g_w))
        except (ValueError, ZeroDivisionError):
            continue  # a degenerate formula on a spurious factor
    return curves
