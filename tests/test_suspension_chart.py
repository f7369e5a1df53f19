"""Suspension charts: closure, inverse, derivatives, angle form, symbolic form, errors."""

import heyoka as hy
import numpy as np
import pytest
from hypothesis import assume, example, given
from hypothesis import strategies as st

from charts import SuspensionChart
from charts.chain_geometry import closure_residual, to_complex
from charts import suspension_formula as formula
from manifold import ChartDomainError
from manifold.backends import NUMPY

from .conftest import (
    HALF_PI,
    base_lengths,
    chart_parameters,
    folded_conditioning,
    parameter_rounding_floor,
    rod_orders,
)

chains = st.integers(3, 8).flatmap(lambda n: st.tuples(st.just(n), base_lengths(n)))


def _wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))))
def test_every_rod_has_unit_length(case):
    (n, L), a, order = case
    chart = SuspensionChart(n, L, order)
    assert closure_residual(chart.hinges(a), L) <= 1e-13


@pytest.mark.parametrize("L", [1e-3, 0.7, 1.0, 1.999])
@pytest.mark.parametrize("sheet", [1, -1])
def test_two_rods_are_the_two_elbows(L, sheet):
    chart = SuspensionChart(2, L, sheet=sheet)
    (p1,) = chart.hinges(np.zeros(0))
    assert abs(abs(p1) - 1) < 1e-15 and abs(abs(L - p1) - 1) < 1e-15
    assert np.sign(p1.imag) == sheet
    assert chart.get_parameters(chart.get_point(np.zeros(0))).shape == (0,)
    with pytest.raises(ChartDomainError, match="other sheet"):
        SuspensionChart(2, L, sheet=-sheet).get_parameters(chart.get_point(np.zeros(0)))


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))))
def test_inverse_round_trip_where_the_chart_is_good(case):
    """1e-12 where ``q >= 0.05``, or the chart's own rounding floor where that is larger
    (several nested latitudes near their poles: one ulp of ``p`` moves ``t`` by 1e-11)."""
    (n, L), a, order = case
    chart = SuspensionChart(n, L, order)
    assume(chart.quality(a) >= 0.05)
    back = chart.get_parameters(chart.get_point(a))
    err = np.abs(_wrap(back - a))
    assert err.max() <= max(1e-12, parameter_rounding_floor(chart, a)), (err, a)


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))))
def test_point_round_trip_everywhere_including_poles(case):
    """``get_point(get_parameters(p)) = p`` even on the singular set (backward stability)."""
    (n, L), a, order = case
    chart = SuspensionChart(n, L, order)
    p = chart.get_point(a)
    assert np.abs(chart.get_point(chart.get_parameters(p)) - p).max() <= 1e-12 * folded_conditioning(n, L)


def _quad_point(chart, a):
    """The chart formula evaluated by numpy in real128 (not the compiled float64 code ``get_point`` runs)."""
    z = formula.hinges(list(a), hy.real128(chart.L), NUMPY, rods=chart.rods)
    return np.array([part for w in z for part in (w.re, w.im)], dtype=object)


def _central_difference(chart, a, h=1e-6):
    """Fourth-order central differences of the chart formula in real128, one column per parameter.

    Numerical trap: in float64 the rounding of ``a`` itself (ulp(pi) = 4.4e-16 near ``t = pi``) moves the point by
    ``|J|`` times that, and next to a fold (``|J| = 3e7`` at ``n = 3``, ``L = 1 + 1e-7``) no step is both below the
    scale on which ``J`` changes and above that noise; 113 bits lower the noise 2**60-fold."""
    a = [hy.real128(float(x)) for x in a]
    cols = []
    for k in range(chart.dim):
        step = hy.real128(float(h))
        f = [_quad_point(chart, [x + (j * step if i == k else 0) for i, x in enumerate(a)]) for j in (-2, -1, 1, 2)]
        cols.append([float(v) for v in (f[0] - 8 * f[1] + 8 * f[2] - f[3]) / (12 * step)])
    return np.array(cols).T


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]))))
@example(case=((3, 1.0000001), np.array([np.pi])))  # a fold at t = pi: |J| = 3e7, beyond float64 differences
def test_jacobian_matches_finite_differences(case):
    (n, L), a = case
    chart = SuspensionChart(n, L)
    a = np.clip(a, -1.45, 1.45)  # keep the stencil inside the chart
    a[-1] = case[1][-1]
    J = chart.jacobian(a)
    # The scale on which p bends shrinks near L = n-2 (folding rods) and no single
    # step suits every case: a correct J agrees with the differences at some step
    # in the sweep, a wrong one at none.
    scale = max(1.0, np.abs(J).max())
    err = min(np.abs(J - _central_difference(chart, a, h / scale)).max() for h in 10.0 ** -np.arange(2, 8))
    assert err <= 1e-7 * scale


@pytest.mark.parametrize("n", [3, 4, 6])
@pytest.mark.parametrize("t0", [HALF_PI, -HALF_PI])
@pytest.mark.parametrize("L_rel", [1e-3, 0.5, 1 - 1e-3])
def test_smooth_across_circle_poles(n, t0, L_rel):
    """At ``t = +-pi/2`` the map is smooth: one-sided and central differences agree with J."""
    L = n - 2 + 2 * L_rel
    chart = SuspensionChart(n, L)
    a = np.append(np.full(n - 3, 0.3), t0)
    J = chart.jacobian(a)
    h = 1e-6
    e = np.zeros(n - 2)
    e[-1] = h
    p0 = chart.get_point(a)
    right = (chart.get_point(a + e) - p0) / h
    left = (p0 - chart.get_point(a - e)) / h
    scale = max(1.0, np.abs(J).max())
    assert np.abs(right - J[:, -1]).max() <= 1e-5 * scale
    assert np.abs(left - J[:, -1]).max() <= 1e-5 * scale
    # the elbow height nu changes sign linearly: it passes through the base, it does not bounce
    z = to_complex(chart.get_point(a[None, :] + np.outer([-1e-3, 1e-3], e / h)))
    rel = np.array([z_[0] / z_[1] for z_ in z])  # p_1 / p_2 in the chain's own order
    assert np.sign(rel[0].imag) != np.sign(rel[1].imag)


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))))
def test_angle_form_equals_position_form(case):
    (n, L), a, order = case
    chart = SuspensionChart(n, L, order)
    rods = np.diff(np.concatenate([[0], chart.hinges(a), [L]]))
    angles = chart.rod_angles(a)
    assert np.abs(_wrap(angles - np.angle(rods))).max() <= 1e-12


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]))))
def test_heyoka_expressions_equal_numpy_values(case):
    """The compiled chart (heyoka, polynomial sinc) reproduces the formula on numpy (exact sinc)."""
    (n, L), a = case
    chart = SuspensionChart(n, L)
    z = formula.hinges([np.asarray(x) for x in a], L, NUMPY)
    numpy_point = np.array([part for h in z for part in (h.re, h.im)], dtype=float)
    assert np.abs(chart.get_point(a) - numpy_point).max() <= 1e-14


@pytest.mark.parametrize(
    "a, match",
    [
        ([0.1, 0.2], r"shape \(\.\.\., 3\) = \(phi_5, phi_4, t\)"),
        ([0.1, np.nan, 0.2], r"finite, got a\[1\] = nan"),
        ([1.6, 0.0, 0.2], r"\[-pi/2, pi/2\]"),
        ([0.0, -2.0, 0.2], r"\[-pi/2, pi/2\]"),
    ],
)
def test_bad_parameters_raise(a, match):
    with pytest.raises(ChartDomainError, match=match):
        SuspensionChart(5, 3.5).get_point(a)


def test_the_shape_message_lists_the_parameters():
    with pytest.raises(ChartDomainError, match=r"shape \(\.\.\., 2\) = \(phi_4, t\), got shape \(3,\)"):
        SuspensionChart(4, 3.0).get_point([0.1, 0.2, 0.3])
    with pytest.raises(ChartDomainError, match=r"shape \(\.\.\., 1\) = \(t\), got shape \(2,\)"):
        SuspensionChart(3, 2.0).get_point([0.1, 0.2])


def test_bad_points_raise():
    chart = SuspensionChart(4, 3.0)
    p = chart.get_point([0.2, 0.3])
    with pytest.raises(ChartDomainError, match="does not close"):
        chart.get_parameters(p * 1.001)
    with pytest.raises(ChartDomainError, match="finite"):
        chart.get_parameters(np.full(6, np.nan))
    with pytest.raises(ChartDomainError, match="shape"):
        chart.get_parameters(p[:4])


def test_jacobian_at_a_pole_raises():
    chart = SuspensionChart(5, 4.5)
    with pytest.raises(ChartDomainError, match="singular"):
        chart.jacobian([HALF_PI, 0.2, 0.1])


@pytest.mark.parametrize("order, match", [([0, 1, 1, 3], "permutation"), ([0, 1, 2], "permutation")])
def test_bad_rod_order_raises(order, match):
    with pytest.raises(ValueError, match=match):
        SuspensionChart(4, 3.0, order)


def test_pole_is_three_rods_aligned():
    """``phi_m = +-pi/2`` puts the chart's first three rods in one direction."""
    order = np.array([2, 0, 3, 1, 4])
    chart = SuspensionChart(5, 3.7, order)
    for a in ([HALF_PI, 0.3, 1.0], [0.2, -HALF_PI, -2.0]):
        rods = np.diff(np.concatenate([[0], chart.hinges(a), [3.7]]))
        first = rods[order[:3]]
        assert np.abs(first - first[0]).max() < 1e-7
