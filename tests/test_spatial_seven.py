"""Why a 7R chain needs ``curve=``: each joint value is taken at 16 configurations.

With ``t_7 = c`` fixed, the closure of a 7R is the inverse kinematics of a 6R: the same
coupling equality as for 6R chains (``Z (t_3 + h_3)`` in ``L_12``, now with
``Z = (c + h_7)(t_6 + h_6)(t_5 + h_5)(t_4 + h_4)``) gives ``det M(t_5, t_6) = 0``, and the null
vector ``(t_3 t_4, t_3, t_4, 1)`` of ``M`` lies on the quadric ``v_0 v_3 = v_1 v_2``.  The
resultant of the two in ``t_6`` is a polynomial in ``t_5``; its roots where the closure holds are
the configurations over ``t_7 = c``.  For random rational axes they are 16 (an irreducible factor
of degree 16 over Q), the classical count for the 6R inverse kinematics: the configuration curve
covers the line of every joint 16 times, so it has no normal form ``t_k = (a_k + b_k w)/c_k``,
``w^2 = g(t)`` in a joint, which :class:`ConfigurationCurve` stores.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy

from linkage.spatial import DualQuaternion, RevoluteChain

R = sympy.Rational
DIRECTIONS = [
    (R(2, 3), R(1, 3), R(2, 3)),
    (R(3, 5), 0, R(4, 5)),
    (R(2, 7), R(3, 7), R(6, 7)),
    (R(1, 3), R(2, 3), R(-2, 3)),
    (0, R(3, 5), R(4, 5)),
    (R(6, 7), R(-2, 7), R(3, 7)),
    (R(4, 9), R(-7, 9), R(4, 9)),
]


def random_7r(seed: int) -> RevoluteChain:
    rng = np.random.default_rng(seed)
    points = [[sympy.Integer(int(v)) for v in rng.integers(-3, 4, 3)] for _ in DIRECTIONS]
    return RevoluteChain([DualQuaternion.from_line(p, d) for p, d in zip(points, DIRECTIONS)])


def configurations_over_t7(chain: RevoluteChain, c) -> tuple[list, dict]:
    """The configurations with ``t_7 = c`` (floats) and the degrees of the eliminant's factors
    in ``t_5`` that carry them (``{degree: number of closing roots}``)."""
    x, y = sympy.symbols("x y")  # t_5, t_6
    h1, h2, h3, h4, h5, h6, h7 = chain.axes
    one = sympy.Integer(1)
    basis = sympy.Matrix([list(v) for v in (DualQuaternion.scalar(one), h1, h2, h1 * h2)]).T
    normals = sympy.Matrix.hstack(*basis.T.nullspace()).T  # N v = 0 iff v in L_12
    coords = np.array(((basis.T * basis).inv() * basis.T).evalf(), dtype=complex)
    u = ((c + h7) * (y + h6) * (x + h5)).map(sympy.expand)
    m = (normals * sympy.Matrix([list(e.map(sympy.expand)) for e in (u, u * h4, u * h3, u * h4 * h3)]).T).applyfunc(
        sympy.expand
    )
    det = sympy.expand(m.det(method="berkowitz"))
    v = m.adjugate(method="berkowitz").col(0)
    segre = sympy.expand(v[0] * v[3] - v[1] * v[2])
    eliminant = sympy.resultant(sympy.Poly(det, y), sympy.Poly(segre, y)).as_expr()
    hf = [a.map(complex) for a in chain.axes]
    det_in_y = [sympy.lambdify(x, e) for e in sympy.Poly(det, y).all_coeffs()]
    segre_f = sympy.lambdify((x, y), segre)
    m_f = sympy.lambdify((x, y), m)
    found, degrees = [], {}
    for factor, _ in sympy.factor_list(eliminant, x)[1]:
        for t5 in sympy.Poly(factor, x).nroots(n=30):
            t5 = complex(t5)
            # the t_6 of the configuration: the root of det M(t_5, .) where the null vector is on the quadric
            t6 = min(np.roots([f(t5) for f in det_in_y]), key=lambda r: abs(segre_f(t5, r)) / (1 + abs(r)) ** 12)
            w = np.linalg.svd(np.array(m_f(t5, t6), dtype=complex))[2][-1].conj()
            t3, t4 = w[1] / w[3], w[2] / w[3]
            z = (complex(c) + hf[6]) * (t6 + hf[5]) * (t5 + hf[4]) * (t4 + hf[3]) * (t3 + hf[2])
            alpha = coords @ np.array(list(z), dtype=complex)
            joints = [-alpha[2] / alpha[3], -alpha[1] / alpha[3], t3, t4, t5, t6, complex(c)]
            prod = DualQuaternion.scalar(1.0 + 0j)
            for t, h in zip(joints, hf):
                prod = prod * (t - h)
            if max(abs(e) for e in prod.coefficients[1:]) <= 1e-8 * abs(prod[0]):
                found.append(joints)
                degree = sympy.degree(factor, x)
                degrees[degree] = degrees.get(degree, 0) + 1
    return found, degrees


def test_a_random_7r_takes_a_joint_value_at_sixteen_configurations():
    chain = random_7r(7)
    assert chain.is_mobile()  # six independent joint screws at the home pose
    found, degrees = configurations_over_t7(chain, R(3, 2))
    assert degrees == {16: 16}  # one irreducible factor of degree 16, every root a configuration
    assert len({complex(np.round(p[4], 6)) for p in found}) == 16  # 16 distinct values of t_5
    with pytest.raises(NotImplementedError, match="16 configurations"):
        chain.configuration_curve()
