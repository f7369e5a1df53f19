"""Dual quaternions: algebra laws, the action on points, lines, exact and complex coefficients."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
import sympy
from hypothesis import given
from hypothesis import strategies as st

from linkage.spatial import DualQuaternion

coef = st.floats(-3, 3, allow_nan=False)
dq = st.lists(coef, min_size=8, max_size=8).map(DualQuaternion)
vec3 = st.lists(coef, min_size=3, max_size=3)


@st.composite
def unit_lines(draw) -> DualQuaternion:
    d = np.array(draw(vec3))
    if np.linalg.norm(d) < 1e-2:
        d = np.array([0.0, 0.0, 1.0])
    d /= np.linalg.norm(d)
    return DualQuaternion.from_line(draw(vec3), list(d))


@st.composite
def motions(draw) -> DualQuaternion:
    """Products of rotations ``t - h`` about random lines: points of the Study quadric."""
    h = DualQuaternion.scalar(1.0)
    for _ in range(draw(st.integers(1, 3))):
        h = h * (draw(st.floats(-4, 4)) - draw(unit_lines()))
    return h


def close(a: DualQuaternion, b: DualQuaternion, tol: float = 1e-9) -> bool:
    scale = 1 + max(abs(x) for x in a) + max(abs(x) for x in b)
    return max(abs(x - y) for x, y in zip(a, b)) <= tol * scale


@given(dq, dq, dq)
def test_product_is_associative(a, b, c):
    assert close((a * b) * c, a * (b * c), 1e-12)


@given(dq, dq)
def test_norm_is_multiplicative_as_a_dual_number(a, b):
    (a0, a1), (b0, b1) = a.norm(), b.norm()
    n0, n1 = (a * b).norm()
    scale = 1 + abs(a0 * b0) + abs(a0 * b1) + abs(a1 * b0)
    assert abs(n0 - a0 * b0) <= 1e-10 * scale
    assert abs(n1 - (a0 * b1 + a1 * b0)) <= 1e-10 * scale


@given(dq)
def test_norm_is_h_times_its_conjugate(a):
    n = a * a.conjugate()
    p, d = a.norm()
    assert close(n, DualQuaternion((p, 0, 0, 0, d, 0, 0, 0)), 1e-12)


@given(unit_lines())
def test_unit_line_squares_to_minus_one(h):
    assert close(h * h, DualQuaternion.scalar(-1.0), 1e-12)


@given(motions(), vec3, vec3, vec3)
def test_action_is_a_rigid_motion(h, x, y, z):
    assert abs(h.study_condition()) <= 1e-9 * (1 + h.norm().primal)
    x, y, z = (np.array(v) for v in (x, y, z))
    hx, hy, hz = (np.array(h.act(list(v))) for v in (x, y, z))
    assert np.linalg.norm(hx - hy) == pytest.approx(np.linalg.norm(x - y), abs=1e-8)
    assert np.linalg.norm(hz - hx) == pytest.approx(np.linalg.norm(z - x), abs=1e-8)
    # the linear part is orthogonal with determinant +1 (a rotation, no reflection)
    origin = np.array(h.act([0.0, 0.0, 0.0]))
    rot = np.array([np.array(h.act(list(e))) - origin for e in np.eye(3)])
    assert np.allclose(rot @ rot.T, np.eye(3), atol=1e-8)
    assert np.linalg.det(rot) == pytest.approx(1.0, abs=1e-8)


@given(vec3, unit_lines(), st.floats(-5, 5))
def test_rotation_t_minus_h_fixes_its_axis(s, h, t):
    """``t - h`` fixes every point of the line ``h`` (point = d x m for the foot of the moment)."""
    d = np.array(h.primal[1:], dtype=float)
    m = -np.array(h.dual[1:], dtype=float)
    foot = np.cross(d, m)  # the point of the line closest to the origin
    p = foot + s[0] * d
    assert np.allclose((t - h).act(list(p)), p, atol=1e-9)


def test_rotation_angle_is_twice_arccot_t():
    """``t = cot(phi/2)``: ``t - k`` turns by ``phi`` clockwise about the z axis.

    ``t - h`` is proportional to ``cos(phi/2) - sin(phi/2) h``, the rotation by
    ``-phi`` about the oriented line ``h`` (by ``+phi`` about ``-h``).
    """
    phi = 0.7
    h = DualQuaternion.from_line([0, 0, 0], [0, 0, 1])
    image = (1 / math.tan(phi / 2) - h).act([1.0, 0.0, 0.0])
    assert np.allclose(image, [math.cos(phi), -math.sin(phi), 0.0])


def test_planar_axis_of_the_paper_passes_through_its_point():
    """Paper, Example 3: ``h1 = eps i + k`` is the vertical line through (0, -1, 0)."""
    h1 = DualQuaternion((0, 0, 0, 1, 0, 1, 0, 0))
    assert DualQuaternion.from_line([0, -1, 0], [0, 0, 1]) == h1


def test_hamilton_rules_exact():
    one, i, j, k = (DualQuaternion([int(m == n) for m in range(8)]) for n in range(4))
    eps = DualQuaternion([int(m == 4) for m in range(8)])
    assert i * j == k and j * k == i and k * i == j and j * i == -k
    assert i * i == j * j == k * k == i * j * k == -one
    assert eps * eps == DualQuaternion([0] * 8)
    assert eps * i == DualQuaternion([0, 0, 0, 0, 0, 1, 0, 0])


def test_complex_unit_is_not_the_quaternion_i():
    """``I - i`` is a nonzero zero divisor: ``(I - i)(I + i) = I^2 + 1 = 0`` and ``N(I - i) = 0``."""
    i = DualQuaternion([0, 1, 0, 0, 0, 0, 0, 0])
    a = DualQuaternion.scalar(1j) - i
    assert a != DualQuaternion([0] * 8)
    assert a * (DualQuaternion.scalar(1j) + i) == DualQuaternion([0j] * 8)
    assert a.norm() == (0, 0)


def test_sympy_and_mpmath_coefficients():
    r = sympy.Rational
    h3 = DualQuaternion([0, -r(1, 3), -r(2, 3), r(2, 3), 0, -4, 4, 2])  # Example 1, h3
    assert h3 * h3 == DualQuaternion.scalar(sympy.Integer(-1))
    with mpmath.workdps(50):
        g = h3.map(mpmath.mpf)
        sq = g * g
        assert abs(sq[0] + 1) < mpmath.mpf("1e-45")
        assert all(abs(x) < mpmath.mpf("1e-45") for x in sq.coefficients[1:])


def test_inverse():
    h = (sympy.Rational(1, 2) - DualQuaternion([0, 0, 1, 0, 0, 9, 0, -9])) * (3 - DualQuaternion([0, 1, 0, 0, 0, 0, 0, 0]))
    assert h * h.inverse() == DualQuaternion.scalar(sympy.Integer(1))


@pytest.mark.parametrize("bad", [[1, 2, 3], list(range(9))])
def test_wrong_length_is_refused(bad):
    with pytest.raises(ValueError, match="8 entries"):
        DualQuaternion(bad)


def test_lines_need_a_unit_direction_and_an_orthogonal_moment():
    """A zero or non-unit direction is not a line (h^2 != -1): refused where the line is built."""
    with pytest.raises(ValueError, match="must be a unit vector"):
        DualQuaternion.from_line((0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match="must be a unit vector"):
        DualQuaternion.from_line((1, 2, 3), (0, 0, 2.0))
    with pytest.raises(ValueError, match="orthogonal"):
        DualQuaternion.from_plucker((1, 0, 0), (1, 0, 0))
