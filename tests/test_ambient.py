"""The chart-free reference integrator: conservation, constraints, reversibility, periodicity, errors."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from charts import SuspensionChart
from linkage import Chain, ConfigurationError
from linkage.ambient import integrate_ambient
from manifold import SaveAt, StartCheck

from .conftest import unit_speed_start


start = unit_speed_start


@st.composite
def starts(draw, n: int, masses: bool = False):
    """``(chain, h0, v0)`` with ``L`` away from the ends (see the test near the ends), latitudes away from the poles."""
    L = draw(st.floats(n - 2 + 0.1, n - 0.1))
    kw = {}
    if masses:
        kw = {
            "hinge_masses": draw(st.lists(st.floats(0.2, 5.0), min_size=n - 1, max_size=n - 1)),
            "rod_densities": draw(st.lists(st.floats(0.0, 3.0), min_size=n, max_size=n)),
        }
    chain = Chain(n, L, **kw)
    a = [draw(st.floats(-1.3, 1.3)) for _ in range(n - 3)] + [draw(st.floats(-np.pi, np.pi))]
    c = draw(st.lists(st.floats(-1, 1), min_size=n - 2, max_size=n - 2).filter(lambda c: np.linalg.norm(c) > 0.1))
    return (chain, *start(chain, a, c))


def relative_energy_error(sol) -> float:
    return float(np.max(np.abs(sol.energies - sol.energies[0])) / sol.energies[0])


RTOL = 1e-12  # the reference runs' tolerance, given explicitly


def energy_bound(sol) -> float:
    """DOP853 is not symplectic: each step may leave an error of ``rtol`` relative to the state in the energy, and
    these add up, so the bound is ``steps * rtol``.  Over 30 draws (n = 3..6, T = 10) the largest error was 0.19 of
    it; a fixed 1e-10 failed near the top of the range (L = 3.89 at n = 4: 1.3e-10 over 353 steps, 0.37 of it)."""
    return sol.solution.n_steps * RTOL


# -- conservation ----------------------------------------------------------------------
@pytest.mark.parametrize("n", [3, 4, 5, 6])
@settings(max_examples=3)
@given(data=st.data())
def test_energy_is_conserved_and_constraints_hold_over_T10(n, data):
    chain, h0, v0 = data.draw(starts(n))
    sol = integrate_ambient(chain, h0, v0, 10.0, rtol=RTOL, atol=RTOL)
    assert sol.success
    assert sol.times[0] == 0 and sol.times[-1] == 10.0 and np.all(np.diff(sol.times) > 0)
    assert sol.energies[0] == pytest.approx(0.5, rel=1e-12)
    assert relative_energy_error(sol) < energy_bound(sol)
    assert np.max(sol.closure_residuals) < 1e-9


@settings(max_examples=4)
@given(st.integers(3, 6).flatmap(lambda n: starts(n, masses=True)))
def test_other_mass_models_conserve_energy(start_):
    chain, h0, v0 = start_
    sol = integrate_ambient(chain, h0, v0, 10.0, rtol=RTOL, atol=RTOL)
    assert relative_energy_error(sol) < energy_bound(sol)
    assert np.max(sol.closure_residuals) < 1e-9


@pytest.mark.parametrize("method, rtol", [("RK45", 1e-11), ("Radau", 1e-9), ("LSODA", 1e-11)])
def test_any_solve_ivp_method_works(method, rtol):
    chain = Chain(5, 4.3)
    h0, v0 = start(chain, [0.3, -0.4, 1.0], [1.0, 0.5, -0.2])
    ref = integrate_ambient(chain, h0, v0, 0.5)
    sol = integrate_ambient(chain, h0, v0, 0.5, method=method, rtol=rtol, atol=rtol)
    assert sol.success
    assert np.max(np.abs(sol(0.5)[0] - ref(0.5)[0])) < 1e3 * rtol
    assert relative_energy_error(sol) < 1e3 * rtol


@pytest.mark.parametrize("n, L", [(4, 2.001), (4, 3.999), (5, 3.0 + 1e-6)])
def test_near_the_ends_of_the_L_range_accuracy_degrades_gracefully(n, L):
    """Near ``L = n`` the sphere is tiny (radius ~ sqrt(n - L)), the motion at unit speed circles it
    fast and ``G K^-1 G^T`` is ill-conditioned: the energy error grows roughly like ``1 / (n - L)``
    (1e-10 at ``n - L = 0.05``, 1e-8 at 1e-3 over T = 10); near ``L = n - 2`` it stays ~1e-11."""
    chain = Chain(n, L)
    rng = np.random.default_rng(7)
    h0, v0 = start(chain, [*rng.uniform(-1.2, 1.2, n - 3), rng.uniform(-3, 3)], rng.normal(size=n - 2))
    sol = integrate_ambient(chain, h0, v0, 1.0)
    assert relative_energy_error(sol) < 1e-9
    assert np.max(sol.closure_residuals) < 1e-10


def test_a_chain_of_two_rods_stays_put():
    chain = Chain(2, 1.5)
    h0 = np.array([0.75 + 1j * np.sqrt(1 - 0.75**2)])
    sol = integrate_ambient(chain, h0, [0j], 1.0)
    assert np.array_equal(sol.hinges[-1], h0) and np.all(sol.energies == 0)


# -- projection -------------------------------------------------------------------------
def test_projection_puts_the_state_back_on_the_constraints():
    chain = Chain(6, 4.7, hinge_masses=[1, 2, 0.5, 1.5, 3], rod_densities=[0.3, 1, 2, 0, 1, 0.5])
    h0, v0 = start(chain, [0.2, -0.7, 0.9, 2.0], [1.0, -0.3, 0.4, 0.8])
    T, dt = 10.0, 0.25
    marks = np.linspace(0, T, 41)  # the projection points
    sol = integrate_ambient(chain, h0, v0, T, project=True, projection_interval=dt, save=SaveAt(t_eval=marks))
    assert sol.success and np.array_equal(sol.times, marks)
    assert np.max(sol.closure_residuals) < 1e-12
    assert relative_energy_error(sol) < 1e-10
    # tangent after projection: d/dt |e_k|^2 = 2 Re(conj(e_k) e_k') = 0
    e, ed = chain.rods(sol.hinges), np.diff(np.pad(sol.velocities, ((0, 0), (1, 1))), axis=-1)
    assert np.max(np.abs((np.conj(e) * ed).real)) < 1e-12
    # dense output works across the segments and between the projection points
    fine = np.linspace(0, T, 1001)
    h, v = sol(fine)
    assert np.max(chain.closure_residual(h)) < 1e-10  # DOP853's interpolant: ~2e-11 between steps
    steps = integrate_ambient(chain, h0, v0, T, project=True, projection_interval=dt)
    assert np.all(np.diff(steps.times) > 0) and steps.times[-1] == T
    assert np.max(steps.closure_residuals) < 1e-11
    # and agrees with the plain flow
    plain = integrate_ambient(chain, h0, v0, T)
    hp, vp = plain(fine)
    assert np.max(np.abs(h - hp)) < 1e-9 and np.max(np.abs(v - vp)) < 1e-9


def test_projection_works_backward_with_a_ragged_last_segment():
    chain = Chain(4, 3.2)
    h0, v0 = start(chain, [0.5, 0.1], [1.0, 1.0])
    sol = integrate_ambient(chain, h0, v0, -2.05, project=True, projection_interval=0.3)
    assert sol.solution.t_span == (0.0, -2.05) and sol.times[0] == 0 and np.all(np.diff(sol.times) < 0)
    assert sol.closure_residuals[-1] < 1e-12
    plain = integrate_ambient(chain, h0, v0, -2.05)
    t = np.linspace(0, -2.05, 77)
    assert np.max(np.abs(sol(t)[0] - plain(t)[0])) < 1e-10


# -- reversibility ----------------------------------------------------------------------
@pytest.mark.parametrize("n", [3, 4, 5, 6])
def test_backward_then_forward_returns_to_the_start(n):
    rng = np.random.default_rng(n)
    chain = Chain(n, n - 1 + rng.uniform(-0.8, 0.8))
    h0, v0 = start(chain, [*rng.uniform(-1.2, 1.2, n - 3), rng.uniform(-3, 3)], rng.normal(size=n - 2))
    back = integrate_ambient(chain, h0, v0, -5.0)
    assert back.success and back.solution.t_span == (0.0, -5.0)
    forth = integrate_ambient(chain, back.hinges[-1], back.velocities[-1], 5.0)
    assert np.max(np.abs(forth.hinges[-1] - h0)) < 1e-9
    assert np.max(np.abs(forth.velocities[-1] - v0)) < 1e-9
    # time reversal: the flow from (h0, -v0) forward is the flow from (h0, v0) backward
    rev = integrate_ambient(chain, h0, -v0, 5.0)
    t = np.linspace(0, 5, 11)
    hb, vb = back(-t)
    hr, vr = rev(t)
    assert np.max(np.abs(hb - hr)) < 1e-9 and np.max(np.abs(vb + vr)) < 1e-9


# -- periodicity of n = 3 -----------------------------------------------------------------
def circumference(chain: Chain, points: int = 20000) -> float:
    """Length of the configuration circle of ``n = 3`` in the kinetic metric (the global chart, trapezoid)."""
    t = np.linspace(-np.pi, np.pi, points, endpoint=False)[:, None]
    J = SuspensionChart(3, chain.L).jacobian(t)[..., 0]
    return float(np.mean(np.sqrt(np.einsum("ti,ij,tj->t", J, chain.ambient_metric, J))) * 2 * np.pi)


@pytest.mark.parametrize(
    "L, kw, t0, c",
    [(1.5, {}, 0.3, 1.0), (1.2, {"hinge_masses": [1.0, 2.0], "rod_densities": [0.5, 0.0, 1.0]}, -2.0, -1.0),
     (1.9, {"rod_densities": 1.0}, 1.0, 1.0)],
)
def test_motion_of_three_rods_is_periodic_with_the_circumference_as_period(L, kw, t0, c):
    """The configuration space is a circle; at unit speed the motion returns after its length."""
    chain = Chain(3, L, **kw)
    h0, v0 = start(chain, [t0], [c])
    length = circumference(chain)
    sol = integrate_ambient(chain, h0, v0, 1.5 * length)
    x0, w0, K = chain.to_point(h0), chain.to_point(v0), chain.ambient_metric

    def along(t):  # K-component of the displacement along the initial velocity
        return (chain.to_point(sol(t)[0]) - x0) @ K @ w0

    # first return: the first upward zero of `along` close to the start
    grid = np.linspace(0, 1.5 * length, 3001)[1:]
    x = chain.to_point(sol(grid)[0])
    near = np.linalg.norm(x - x0, axis=1) < 0.1 * np.max(np.linalg.norm(x - x0, axis=1))
    g = (x - x0) @ K @ w0
    i = np.flatnonzero((g[:-1] <= 0) & (g[1:] > 0) & near[:-1])[0]
    period = brentq(along, grid[i], grid[i + 1], xtol=1e-14)
    assert period == pytest.approx(length, rel=1e-9)
    h, v = sol(period)
    assert np.max(np.abs(h - h0)) < 1e-9 and np.max(np.abs(v - v0)) < 1e-9
    # and not before: the chain stays away from its start in between
    mid = np.linspace(0.05, 0.95, 200) * period
    assert np.min(np.max(np.abs(sol(mid)[0] - h0), axis=-1)) > 1e-3


# -- output and bad inputs --------------------------------------------------------------------
def test_t_eval_and_calls_agree_with_shapes():
    chain = Chain(4, 3.5)
    h0, v0 = start(chain, [0.2, 0.4], [0.3, 1.0])
    t = np.array([0.0, 0.3, 1.1, 2.0])
    sol = integrate_ambient(chain, h0, v0, 2.0, save=SaveAt(t_eval=t))
    assert np.array_equal(sol.times, t) and sol.hinges.shape == sol.velocities.shape == (4, 3)
    assert sol.energies.shape == sol.closure_residuals.shape == (4,)
    h, v = sol(t)
    assert np.allclose(h, sol.hinges, rtol=0, atol=1e-15) and np.allclose(v, sol.velocities, rtol=0, atol=1e-15)
    assert sol(1.0)[0].shape == (3,) and sol(np.zeros((2, 5)))[1].shape == (2, 5, 3)
    assert np.array_equal(sol(0.0)[0], h0) and sol.n_steps > 0


@pytest.fixture
def good():
    chain = Chain(5, 3.6)
    return (chain, *start(chain, [0.1, 0.2, 0.3], [1.0, 0.0, 0.5]))


def test_start_must_close(good):
    chain, h0, v0 = good
    with pytest.raises(ConfigurationError, match="does not close"):
        integrate_ambient(chain, h0 * 1.001, v0, 1.0)
    with pytest.raises(ConfigurationError, match="finite"):
        integrate_ambient(chain, np.where(np.arange(4) == 1, np.nan, h0), v0, 1.0)
    with pytest.raises(ConfigurationError, match="n - 1 = 4"):
        integrate_ambient(chain, h0[:3], v0, 1.0)


def test_velocity_must_be_finite_and_tangent(good):
    chain, h0, v0 = good
    with pytest.raises(ValueError, match="velocity0 must be finite"):
        integrate_ambient(chain, h0, np.where(np.arange(4) == 2, np.nan, v0), 1.0)
    with pytest.raises(ValueError, match="n - 1 = 4"):
        integrate_ambient(chain, h0, v0[:3], 1.0)
    bad = v0 + 1e-6 * chain.rods(h0)[:4]  # stretches rods
    with pytest.raises(ValueError, match=r"not tangent.*\|\(G v\)_k\| = [0-9.e-]+"):
        integrate_ambient(chain, h0, bad, 1.0)
    # projected instead: K-orthogonally, back onto (nearly) v0
    sol = integrate_ambient(chain, h0, bad, 1.0, start=StartCheck(project_velocity=True))
    w = sol.velocities[0]
    assert np.max(np.abs(w - v0)) < 2e-6
    K = chain.ambient_metric
    d, t = chain.to_point(bad - w), chain.to_point(v0)
    assert abs(d @ K @ t) < 1e-12  # the removed part is K-orthogonal to the tangent space
    assert relative_energy_error(sol) < 1e-10


@pytest.mark.parametrize("t_final", [np.nan, np.inf, -np.inf, "soon", 0.0])
def test_t_final_must_be_finite_and_nonzero(good, t_final):
    chain, h0, v0 = good
    with pytest.raises(ValueError, match="t_final"):
        integrate_ambient(chain, h0, v0, t_final)


def test_other_bad_options(good):
    chain, h0, v0 = good
    with pytest.raises(ValueError, match="projection_interval"):
        integrate_ambient(chain, h0, v0, 1.0, project=True, projection_interval=0.0)
    with pytest.raises(ValueError, match="t_eval"):
        integrate_ambient(chain, h0, v0, 1.0, save=SaveAt(t_eval=[0.5, 1.5]))
    with pytest.raises(ValueError, match="t_eval"):
        integrate_ambient(chain, h0, v0, -1.0, save=SaveAt(t_eval=[0.5]))
    with pytest.raises(ValueError, match="in integration order"):
        integrate_ambient(chain, h0, v0, 1.0, save=SaveAt(t_eval=[0.5, 0.25]))
    with pytest.raises(TypeError, match=r"reads its grid from dense output: save=SaveAt\(dense=False\) is not taken"):
        integrate_ambient(chain, h0, v0, 1.0, save=SaveAt(t_eval=[0.5], dense=False))
    with pytest.raises(TypeError, match=r"integrate_ambient\(\) does not take t_eval=: t_eval= is given as save="):
        integrate_ambient(chain, h0, v0, 1.0, t_eval=[0.5])


def test_calls_outside_the_span_are_refused(good):
    chain, h0, v0 = good
    sol = integrate_ambient(chain, h0, v0, -1.0)
    for t in [0.1, -1.01, np.nan, [-0.5, 2.0]]:
        with pytest.raises(ValueError, match=r"outside the solution.s time span \[-1.0, 0.0\]"):
            sol(t)
