"""Finite-time Lyapunov exponents: zero where geodesics do not separate, positive and converged for n = 4,
and equal to the separation rate of two nearby trajectories integrated on their own."""

from __future__ import annotations

import re

import heyoka as hy
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion, lyapunov_exponent, lyapunov_exponents
from linkage.sampling import sample_starts
from manifold import SolveStatus
from manifold import SaveAt
from manifold.budget import Budget
from manifold.constrained import ConstrainedSystem, compiled_constrained
from manifold.lyapunov import LyapunovError, lyapunov_spectrum

from .conftest import unit_speed_start


class RoundSphere(ConstrainedSystem):
    """The unit sphere ``|x|^2 = 1`` in Euclidean ``R^3``: geodesics are great circles."""

    ambient_dim, n_constraints = 3, 1
    key = ("test round sphere",)
    metric_matrix = np.eye(3)

    def constraint_expressions(self, x, p, fp_type):
        return [x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - hy.expression(fp_type(1.0))]


def _sphere_start(speed: float):
    x0 = np.array([0.6, 0.0, 0.8])
    v0 = speed * np.array([0.0, 1.0, 0.0])
    return x0, v0


@pytest.mark.parametrize("speed", [1.0, 2.5])
def test_round_sphere_perpendicular_deviations_keep_their_size(speed):
    """A perpendicular Jacobi field on the unit sphere is ``J = a cos(s t) + b sin(s t)`` along a parallel normal
    ``e``: ``|J|^2 + |J'|^2 / s^2`` is constant, so every finite-time estimate is 0 (to rounding), not only the limit."""
    x0, v0 = _sphere_start(speed)
    r = lyapunov_spectrum(RoundSphere(), x0, v0, 200.0, k=2, interval=0.7)
    assert r.success
    assert np.abs(r.history).max() * r.times.max() <= 1e-9  # log growth, not the mean: exactly 0
    assert r.exponents.shape == (2,)


def test_round_sphere_tangent_deviations_grow_linearly():
    """With the flow and energy directions kept, a faster geodesic drifts ahead linearly: ``lambda_1 ~ log(t) / t``
    (positive, above the perpendicular value 0, below ``2 log(t) / t``), ``lambda_1 + ... = 0``."""
    x0, v0 = _sphere_start(1.0)
    r = lyapunov_spectrum(RoundSphere(), x0, v0, 400.0, k=4, deviations="tangent")
    t, lam1 = r.times, r.history[:, 0]
    late = t >= 50
    assert np.all(lam1[late] > 0.2 * np.log(t[late]) / t[late])
    assert np.all(lam1[late] < 2.0 * np.log(t[late]) / t[late])
    assert abs(r.exponents.sum()) <= 1e-9 * t[-1]


def test_circle_n3_exponent_decays_like_log_t_over_t():
    """n = 3: the configuration space is a closed curve, every motion periodic; the only deviations are along the
    flow and the energy, and the estimate decays like ``log(t) / t``."""
    chain = Chain(3, 1.7)
    h, v = unit_speed_start(chain, [0.3], [1.0])
    with pytest.raises(ValueError, match=r"k must be an integer in \[1, 0\]"):
        lyapunov_exponent(chain, h, v, 10.0)  # no perpendicular deviations on a curve
    r = lyapunov_exponent(chain, h, v, 500.0, k=2, deviations="tangent")
    t, lam1 = r.times, r.history[:, 0]
    late = t >= 50
    assert np.all(np.abs(lam1[late]) < 2.0 * np.log(t[late]) / t[late])
    assert lam1[-1] < 0.02 and lam1[-1] < lam1[np.searchsorted(t, 100)]
    # the sum is the growth rate of areas: bounded areas, so it decays like 1/t (not like log(t) / t)
    assert abs(r.exponents.sum()) * t[-1] <= 0.01


def test_n4_exponent_is_positive_converged_and_paired():
    """L = 2.6, a start in the chaotic sea: lambda_1 > 0, steady between T/2 and T, and lambda_2 = -lambda_1
    (the perpendicular flow preserves area: the exponents pair up)."""
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    r = lyapunov_exponent(chain, h, v, 600.0, k=2, interval=2.0)
    assert r.success and r.relative_energy_error <= 1e-13
    lam = r.exponent
    assert 0.08 < lam < 0.2
    half = r.history[np.searchsorted(r.times, 300.0), 0]
    # finite-time exponents scatter: over six starts 1e-12 apart, lambda(600) was 0.107-0.143 and
    # |lambda(600) - lambda(300)| / lambda(600) 0.002-0.15 (this start: 0.15 since the any-lengths chart formula)
    assert abs(lam - half) <= 0.25 * lam
    assert abs(r.exponents[0] + r.exponents[1]) <= 0.01 * lam
    assert r.exponents[0] > r.exponents[1]


@settings(max_examples=8)
@given(seed=st.integers(0, 2**32 - 2), interval=st.floats(0.2, 2.5))
def test_finite_time_exponents_are_the_growth_rates_of_volumes(seed, interval):
    """At t = 5 the estimates are those of the QR factors of ``Phi(t) Y_0``: the same with one renormalisation as
    with many; and for ``k`` the whole perpendicular space (n = 4: 2), their sum, the growth rate of its volume, is
    the same from every seed's initial deviations."""
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    once = lyapunov_exponent(chain, h, v, 5.0, k=2, interval=5.0, seed=seed)
    often = lyapunov_exponent(chain, h, v, 5.0, k=2, interval=interval, seed=seed)
    other = lyapunov_exponent(chain, h, v, 5.0, k=2, interval=5.0, seed=seed + 1)
    assert np.abs(often.exponents - once.exponents).max() <= 1e-9
    assert abs(once.exponents.sum() - other.exponents.sum()) <= 1e-9


def test_finite_time_exponents_come_in_gram_schmidt_order_not_sorted():
    """The module docstring's example: a first deviation that starts near the contracting direction grows less,
    over t = 5, than the second one's share of the area, and the estimates are returned as they are."""
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    r = lyapunov_exponent(chain, h, v, 5.0, k=2, seed=25)
    assert r.exponents == pytest.approx([-0.288, 0.299], abs=1e-3)
    assert r.exponent == r.exponents[0]


def test_n4_exponent_matches_the_separation_of_two_trajectories():
    """Independent estimate: two single solves from starts 1e-9 apart; the slope of log |separation| fitted in the
    linear regime equals that of the variational deviation's log growth on the same window."""
    chain = Chain(4, 2.6)
    a, c = np.array([0.3, 0.5]), np.array([1.0, -0.4])
    h1, v1 = unit_speed_start(chain, a, c)
    h2, v2 = unit_speed_start(chain, a + 1e-9 * np.array([1.0, -0.6]), c)
    ts = np.arange(0.0, 111.0)
    m1, m2 = (free_motion(chain, h, v, 110.0, method="hinges", save=SaveAt(t_eval=ts, dense=False))
              for h, v in ((h1, v1), (h2, v2)))
    K = chain.ambient_metric
    dx = chain.to_point(m2.hinges) - chain.to_point(m1.hinges)
    dv = chain.to_point(m2.velocities) - chain.to_point(m1.velocities)
    separation = np.sqrt(np.einsum("ti,ij,tj->t", dx, K, dx) + np.einsum("ti,ij,tj->t", dv, K, dv))
    r = lyapunov_exponent(chain, h1, v1, 110.0, interval=1.0)
    growth = np.concatenate([[0.0], r.history[:, 0] * r.times])  # log |d(t)| / |d(0)|
    window = (ts >= 40) & (ts <= 110)  # after alignment (exp(-2 lambda 40) ~ 1e-5), separation below 1e-2
    assert separation[window].max() < 1e-2
    rate_separation = np.polyfit(ts[window], np.log(separation[window]), 1)[0]
    rate_variational = np.polyfit(ts[window], growth[window], 1)[0]
    assert rate_separation > 0.05
    assert abs(rate_separation - rate_variational) <= 0.01 * rate_variational


def test_tangent_equations_agree_with_heyokas_variational_system():
    """The deviation equations (forward-mode directional derivatives) against heyoka's ``var_ode_sys`` matrix."""
    chain = Chain(5, 3.3, hinge_masses=[1.0, 2.0, 0.5, 1.5], rod_densities=0.4)
    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    h, v = unit_speed_start(chain, [0.2, -0.4, 1.0], [0.5, 1.0, -0.3])
    y0 = np.concatenate([chain.to_point(h), chain.to_point(v)])
    d0 = np.random.default_rng(0).normal(size=(2, y0.size))
    pars = comp.layout.pack(system, 0.8, float)
    full = hy.taylor_adaptive(hy.var_ode_sys(comp.pieces(float).equations(True), hy.var_args.vars, order=1), y0,
                              compact_mode=True)
    full.pars[:] = pars[: len(full.pars)]
    full.propagate_until(5.0)
    Phi = np.array(full.state[y0.size :]).reshape(y0.size, y0.size)
    with comp.tangent_integrator(2, compact_mode=True) as ta:
        ta.time = 0.0
        ta.state[:] = np.concatenate([y0, d0.ravel()])
        ta.pars[:] = pars[: len(ta.pars)]
        ta.propagate_until(5.0)
        d = np.array(ta.state[y0.size :]).reshape(2, y0.size)
        assert np.abs(np.array(ta.state[: y0.size]) - np.array(full.state[: y0.size])).max() <= 1e-13
    expected = d0 @ Phi.T
    assert np.abs(d - expected).max() <= 1e-10 * np.abs(expected).max()


def test_ensemble_of_exponents_equals_single_calls():
    chain = Chain(4, 3.2)
    starts = [unit_speed_start(chain, a, c) for a, c in [([0.1, 0.2], [1.0, 0.0]), ([-0.5, 1.5], [0.3, 1.0]),
                                                          ([1.2, -2.0], [1.0, 1.0])]]
    H, V = np.array([h for h, _ in starts]), np.array([v for _, v in starts])
    many = lyapunov_exponents(chain, H, V, 40.0, backend="threads", chunk_size=2, k=2)
    for (h, v), r in zip(starts, many):
        one = lyapunov_exponent(chain, h, v, 40.0, k=2)
        assert np.array_equal(one.history, r.history)


def test_the_compile_option_reads_none_as_its_default_as_every_solver_does():
    """``compact_mode=None`` is the default everywhere (the free motions' and the carried solves' too); ``False``
    and a non-boolean are still told apart from it."""
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    default = lyapunov_exponent(chain, h, v, 10.0, k=2)
    assert np.array_equal(lyapunov_exponent(chain, h, v, 10.0, k=2, compact_mode=None).history, default.history)
    with pytest.raises(TypeError, match="compact_mode must be True or False"):
        lyapunov_exponent(chain, h, v, 10.0, k=2, compact_mode=0)


def test_convergence_plot_draws_the_history():
    import matplotlib

    matplotlib.use("Agg")
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    r = lyapunov_exponent(chain, h, v, 20.0, k=2)
    ax = r.plot()
    curves = [line for line in ax.lines if len(line.get_xdata()) == len(r.times)]
    assert len(curves) == 2
    for i, line in enumerate(curves):
        assert np.array_equal(line.get_ydata(), r.history[:, i])


def test_bad_arguments_are_refused_by_name():
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    with pytest.raises(ValueError, match=r"k must be an integer in \[1, 2\]"):
        lyapunov_exponent(chain, h, v, 10.0, k=3)
    with pytest.raises(ValueError, match="k must be an integer >= 1"):
        lyapunov_exponent(chain, h, v, 10.0, k=0)
    with pytest.raises(ValueError, match="deviations must be one of"):
        lyapunov_exponent(chain, h, v, 10.0, deviations="normal")
    with pytest.raises(ValueError, match=r"t_final must be a real number in \(0, inf\)"):
        lyapunov_spectrum(ChainSystem(chain), chain.to_point(h), chain.to_point(v), -10.0)
    with pytest.raises(ValueError, match="interval must be"):
        lyapunov_exponent(chain, h, v, 10.0, interval=0.0)
    with pytest.raises(ValueError, match="v0 must be nonzero"):
        lyapunov_exponent(chain, h, 0 * v, 10.0)


def test_a_failed_check_raises_unless_asked_not_to():
    """A start at 1e150 times unit speed overflows in the first step: the estimate is refused, not returned as one."""
    chain = Chain(4, 2.6)
    h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    with pytest.raises(LyapunovError, match="energy check failed") as info:
        lyapunov_exponent(chain, h, 1e150 * v, 10.0)
    assert not info.value.result.success
    r = lyapunov_exponent(chain, h, 1e150 * v, 10.0, throw=False)
    assert not r.success and np.isnan(r.exponent)


def test_an_estimate_stops_at_its_budget_and_says_so():
    """Spent, the estimate stops with what it computed and a message naming the budget and the need."""
    chain = Chain(4, 2.6)
    h, v = sample_starts(chain, 1, 0.5, np.random.default_rng(3))
    r = lyapunov_exponent(chain, h[0], v[0], 1e6, budget=Budget(steps=300), throw=False)
    assert r.status is SolveStatus.BUDGET_EXCEEDED and r.n_steps == 300
    assert re.search(r"the budget of 300 steps, .* reaching t_final = 1e\+06 would take about", r.message)
    assert "dense=False" not in r.message  # an estimate keeps no dense output: no such hint
    assert 0 < r.times[-1] < 1e6 and np.all(np.isfinite(r.exponents))
    with pytest.raises(LyapunovError, match="the budget of 300 steps"):
        lyapunov_exponent(chain, h[0], v[0], 1e6, budget=Budget(steps=300))


def test_a_failed_check_ends_the_estimate_at_that_renormalisation(monkeypatch):
    """A check that fails stops the run at the renormalisation where it failed, not at t_final (a run near the
    stretched chain failed its energy check at t = 1 and went on for minutes)."""
    from manifold import lyapunov as module

    calls = []

    def failing(deviations, times, n_steps, tol, where):
        calls.append(times[-1])
        return "energy check failed (planted)"

    chain = Chain(4, 2.6)
    h, v = sample_starts(chain, 1, 0.5, np.random.default_rng(3))
    monkeypatch.setattr(module, "energy_violation", failing)
    r = lyapunov_exponent(chain, h[0], v[0], 1e6, throw=False)
    assert r.status is SolveStatus.ENERGY_CHECK_FAILED and "planted" in r.message
    assert calls[0] == pytest.approx(1.0) and len(r.times) == 0  # one interval, then the verdict
