"""The traps of issue 11: 0/0 base points, bonds at branch points, bonds at infinity.

The linkages are the paper's; the traps are planted by writing their printed
configuration curves in other (birationally equivalent) forms, so the expected
bonds and local distances are still the paper's eqs. (9), (14) and Example 3.
"""

from __future__ import annotations

import cmath
import functools

import numpy as np
import pytest
import sympy

from linkage.spatial import ConfigurationCurve, RevoluteChain

from .test_spatial_fourbar import (
    BENNETT,
    BENNETT_BONDS,
    D_BENNETT_1,
    D_BENNETT_2,
    PLANAR,
    PLANAR_BONDS,
    assert_same_bond_set,
    same_point,
)

I = 1j
t, w = sympy.symbols("t w")

# eq. (13), typed in from the paper
G13 = t**4 - 8 * t**3 + 2 * t**2 + 56 * t - 47
EQ13 = [(-(t**2) + 2 * t + 5 - w) / (2 * (t + 3)), (t**2 + 1 + w) / (4 * (2 - t)), (t**2 - 4 * t + 1 + w) / (4 * (t - 1)), t]


def bennett_eq7(s):
    """eq. (7) with the parameter ``t`` replaced by the expression ``s``."""
    return [s - 1, s, s - 1, -s]


@functools.lru_cache(maxsize=None)
def bennett_form(form: str) -> RevoluteChain:
    """Example 1 with eq. (7) written on a conic (``t = tau + w``, ``w^2 = tau^2 + 1``), on a
    circle (``t = w / (1 + tau)``, ``w^2 = 1 - tau^2``) or as printed (``"rational"``)."""
    tau = sympy.Symbol("tau")
    curves = {
        "rational": ConfigurationCurve.rational(bennett_eq7(t)),
        "conic": ConfigurationCurve.hyperelliptic(bennett_eq7(tau + w), tau**2 + 1, t=tau),
        "circle": ConfigurationCurve.hyperelliptic(bennett_eq7(w / (1 + tau)), 1 - tau**2, t=tau),
    }
    return RevoluteChain(BENNETT, curve=curves[form])


def check_bennett(chain):
    bonds = chain.bonds()
    assert_same_bond_set([b.joints for b in bonds], BENNETT_BONDS)
    for b in bonds:
        expected = D_BENNETT_1 if abs(b.joints[0] ** 2 + 1) < 1e-12 else D_BENNETT_2
        assert np.array_equal(2 * b.local_distances, expected), b
    return bonds


def test_base_point_of_eq_13_is_resolved_not_a_bond():
    """At ``t = 2``, ``w = -5``, eq. (13) reads ``t_2 = 0/0``; the homogeneous pair ``(0, 0)``
    would pass ``a^2 + c^2 = 0`` as a false bond.  The place gives the limit along the curve."""
    curve = ConfigurationCurve.hyperelliptic(EQ13, G13)
    assert np.isnan(curve(2.0, branch=-1)[1])  # naive evaluation: 0/0
    assert any(abs(complex(c) - 2) < 1e-30 for c in curve.bond_candidates() if c != complex("inf"))
    (place,) = [p for p in curve.places(2) if p.branch == -1]
    limit = place.joint_values()[1]
    # approach t = 2 along the branch w = -sqrt(g): eq. (13) evaluated by hand
    for eps in (1e-6, -1e-6):
        tt = 2 + eps
        ww = -cmath.sqrt(tt**4 - 8 * tt**3 + 2 * tt**2 + 56 * tt - 47)
        assert abs((tt**2 + 1 + ww) / (4 * (2 - tt)) - limit) < 1e-5
    assert abs(limit**2 + 1) > 0.1  # the true t_2 is no bond coordinate
    chain = RevoluteChain(PLANAR, curve=curve)
    assert_same_bond_set([b.joints for b in chain.bonds()], PLANAR_BONDS)
    assert all(abs(b.parameter - 2) > 1e-9 for b in chain.bonds())


def test_bonds_at_branch_points():
    """The Bennett curve on the conic ``w^2 = tau^2 + 1`` via ``t = tau + w`` (birational,
    inverse ``tau = (t - 1/t)/2``): the bonds ``t = +-I`` sit at the branch points
    ``tau = +-I``, where ``tau - tau0`` is not a local parameter (it would double every order)."""
    bonds = check_bennett(bennett_form("conic"))
    at_branch = [b for b in bonds if b.branch == 0]
    assert sorted(round(b.parameter.imag) for b in at_branch) == [-1, 1]
    assert all(abs(b.parameter.real) < 1e-30 for b in at_branch)


def test_bonds_at_parameter_infinity_and_a_base_point_at_a_branch_point():
    """The Bennett curve on the circle ``w^2 = 1 - tau^2`` via stereographic projection
    ``t = w / (1 + tau)``: as ``tau -> inf``, ``w/tau -> +-I``, so the bonds ``t = +-I`` lie
    over ``tau = inf``.  At ``tau = -1`` the formula is 0/0 and a branch point at once; the
    limit there is the home configuration ``t_k = inf``, not a bond."""
    chain = bennett_form("circle")
    bonds = check_bennett(chain)
    assert sum(b.parameter == complex("inf") for b in bonds) == 2
    (home,) = chain.configuration_curve().places(-1)
    assert all(z == complex("inf") for z in home.joint_values())


@pytest.mark.parametrize("form", ["rational", "conic", "circle"])
def test_the_50_digit_series_agree_with_the_exact_orders(form):
    """The Bennett linkage in the three forms above: exact orders (multiplicities over Q,
    or series over Q(I, t0, sqrt)) and the forced 50-digit series give the same bonds."""
    chain = bennett_form(form)
    exact, series = chain.bonds(), chain.bonds(numeric=True)
    assert {b.method for b in exact} == {"exact"}
    assert {b.method for b in series} == {"mpmath-50"}
    assert len(exact) == len(series) == 4
    for b in exact:
        (twin,) = [c for c in series if same_point(c.joints, b.joints)]
        assert np.array_equal(twin.local_distances, b.local_distances)
        assert twin.typical == b.typical


def test_zero_threshold_is_documented_and_used():
    from linkage.spatial import series

    assert series.WORKING_DIGITS == 50 and series.ZERO_THRESHOLD == pytest.approx(1e-30)
    s = series.Series.exact([series.ZERO_THRESHOLD / 10, 0, 1])
    assert s.order() == 2  # below the threshold counts as zero
    assert series.Series.exact([series.ZERO_THRESHOLD * 10, 0, 1]).order() == 0


def shared_axis_chain(curve):
    """Axes 1 and 3 on one line (``h3 = -h1``): with joints 2 and 4 at the identity the chain
    still moves, ``(t - h1)(t - h3) = t^2 + 1`` is real.  On that component the bonds have
    joint coordinates ``inf`` (Remark 13)."""
    from .test_spatial_fourbar import line

    h1 = line([0, 0, 1], [0, 0, 0])
    return RevoluteChain([h1, line([1, 0, 0], [0, 0, 1]), -h1, line([0, 1, 0], [1, 0, 0])], curve=curve)


# by hand from Definition 14 on the component (t, inf, t, inf): F_12 = F_34 = 1 and
# F_13 = F_14 = F_23 = F_24 = t + h1 up to factors 1, with Q(t + h1) = t^2 + 1
D_SHARED_AXIS = [[0, 0, 1, 1], [0, 0, 1, 1], [1, 1, 0, 0], [1, 1, 0, 0]]


def test_bonds_with_joint_coordinates_at_infinity_exact_and_series():
    inf = complex("inf")
    # t_k = (a_k + b_k w) / c_k with c_2 = c_4 = 0: joints 2 and 4 at t = inf
    rational = ConfigurationCurve([t, 1, t, 1], [0, 0, 0, 0], [1, 0, 1, 0])
    tau = sympy.Symbol("t")  # the same curve on the conic w^2 = t^2 + 1, joint 1 = t + w
    conic = ConfigurationCurve([tau, 1, tau, 1], [1, 0, 1, 0], [1, 0, 1, 0], g=tau**2 + 1)
    for curve, numeric in ((rational, False), (rational, True), (conic, False), (conic, True)):
        bonds = shared_axis_chain(curve).bonds(numeric=numeric)
        method = "mpmath-50" if numeric else "exact"
        assert_same_bond_set([b.joints for b in bonds], [(I, inf, I, inf), (-I, inf, -I, inf)])
        for b in bonds:
            assert b.method == method
            assert np.array_equal(2 * b.local_distances, D_SHARED_AXIS)
            assert b.connection_numbers == {(1, 3): 1}
