"""The dynamics seed's own geodesic method (n = 4): agreement, 4th order, and how it fails at a pole."""

import numpy as np
import pytest

from benchmarks.baselines.seed_geodesics import SEED_EPS, integrate_seed_rk4, seed_vector_field
from charts import SuspensionChart
from linkage import Chain
from manifold import compiled, solve_chart_exp_ode

HALF_PI = np.pi / 2


def library_acceleration(L: float, a, c) -> np.ndarray:
    """``c'`` of the library's embedded geodesic equations in ``SuspensionChart(4, L)`` (unit masses)."""
    chart = SuspensionChart(4, L)
    cf = compiled(chart.family).acceleration(float)
    pars = chart.numerics(np.eye(6), -2.0).pars[: cf.nparams]
    return cf(np.concatenate([a, c]).astype(float), pars=pars)


def relative_difference(L: float, a, c) -> float:
    lib = library_acceleration(L, a, c)
    seed = seed_vector_field(np.concatenate([a, c]), L)
    return float(np.max(np.abs(seed[2:] - lib)) / np.max(np.abs(lib)))


# -- the vector field ----------------------------------------------------------------------
@pytest.mark.parametrize("L", [2.05, 2.6, 3.3, 3.9])
def test_vector_field_agrees_with_the_library_away_from_poles(L):
    rng = np.random.default_rng(int(100 * L))
    worst = 0.0
    for _ in range(60):
        t = rng.uniform(-np.pi, np.pi)
        if abs(np.cos(t)) < 0.1:  # see the next test
            continue
        a, c = np.array([rng.uniform(-1.2, 1.2), t]), rng.normal(size=2)
        y = seed_vector_field(np.concatenate([a, c]), L)
        assert np.array_equal(y[:2], c)
        worst = max(worst, relative_difference(L, a, c))
    assert worst < 1e-6  # finite differences: measured max 1.1e-7 (L = 2.05), median ~3e-10
    assert SEED_EPS == 1e-5


def test_vector_field_is_wrong_at_the_elbow_switch_t_half_pi():
    """The seed's ``nu_in = ct sqrt((4 - |p2|^2) / ct^2)`` cancels as ``cos t -> 0`` and switches to its limit
    branch at ``|cos t| < 1e-6``; central differences (eps = 1e-5) amplify both.  Measured relative error of
    the acceleration at ``phi = 0.3``: 4e-10 at ``|t - pi/2| = 0.1``, 4e-7 at 1e-3, 2e-4 at 1e-4, ~1e-2 at
    1e-5 .. 1e-7, and ``2e4`` exactly at ``t = pi/2`` (the library: exact there)."""
    c = np.array([1.0, 0.7])
    assert relative_difference(2.6, np.array([0.3, 0.5]), c) < 1e-8
    assert relative_difference(2.6, np.array([0.3, HALF_PI + 1e-3]), c) < 1e-5
    assert relative_difference(2.6, np.array([0.3, HALF_PI + 1e-4]), c) > 1e-5
    assert relative_difference(2.6, np.array([0.3, HALF_PI]), c) > 1.0


def test_vector_field_degrades_toward_a_pole():
    """Near ``phi = pi/2`` the metric degenerates (``D = EG - F^2 -> 0``); the differences lose digits.

    Measured at ``t = 0.4``: 1e-9 at phi = 1.3, 9e-9 at 1.5, 5e-5 at 1.565, 4e-3 at 1.57."""
    c = np.array([1.0, 0.5])
    errs = [relative_difference(2.6, np.array([phi, 0.4]), c) for phi in (1.3, 1.5, 1.565, 1.57)]
    assert errs[0] < 1e-8 and errs[1] < 1e-7
    assert errs[2] > 1e-6 and errs[3] > 1e-4


# -- RK4 -------------------------------------------------------------------------------------
@pytest.mark.parametrize("L", [2.6, 3.3])
def test_rk4_converges_at_fourth_order_away_from_poles(L):
    """From a = (0.3, 0.5), c = (0.5, -0.3) the path keeps |phi| <= 1.16 and |t| <= 1.04 (no pole, no t = pi/2)."""
    chain = Chain(4, L)
    a0, c0, T = np.array([0.3, 0.5]), np.array([0.5, -0.3]), 2.0
    ref = solve_chart_exp_ode(chain.metric(), a0, c0, T, chart=0, switching=False)
    p_ref = ref.end_state()[0]
    hs = [0.1, 0.05, 0.025, 0.0125]
    err = []
    for h in hs:
        sol = integrate_seed_rk4(L, a0, c0, T, h)
        assert sol.failed_at is None and sol.t[-1] == T and len(sol.t) == round(T / h) + 1
        err.append(np.max(np.abs(chain.to_point(sol.hinges[-1]) - p_ref)))
    ratios = np.array(err[:-1]) / np.array(err[1:])
    assert np.all((ratios > 13) & (ratios < 19.5)), ratios  # measured 11.8 (h = 0.1) then 16.3 .. 17.0; 14.7 .. 15.9
    assert err[-1] < 1e-8  # measured 2.6e-9 and 2.2e-9
    assert sol.relative_energy_error.max() < 1e-8


def test_solution_fields_are_consistent_with_the_chart():
    L = 3.3
    sol = integrate_seed_rk4(L, [0.3, 0.5], [0.5, -0.3], -1.03, 0.1)
    assert sol.failed_at is None and sol.n_steps == 11
    np.testing.assert_allclose(sol.t, np.append(-0.1 * np.arange(11), -1.03), rtol=0, atol=1e-15)
    assert sol.t[-1] == -1.03
    chart = SuspensionChart(4, L)
    np.testing.assert_array_equal(sol.hinges, chart.hinges(sol.a))
    J = chart.jacobian(sol.a[5])
    assert sol.energy[5] == pytest.approx(0.5 * sol.c[5] @ J.T @ J @ sol.c[5], rel=1e-12)
    # back to the start (RK4 is not symmetric, but accurate)
    back = integrate_seed_rk4(L, sol.a[-1], sol.c[-1], 1.03, 0.1)
    assert np.max(np.abs(back.a[-1] - [0.3, 0.5])) < 1e-5


# -- at and near a pole -------------------------------------------------------------------------
def aimed_at_pole(L: float, tau: float, c_pole) -> tuple[np.ndarray, np.ndarray]:
    """Chart-0 state ``(a, c)`` whose geodesic hits the chart-0 pole ``phi = pi/2`` exactly at time ``tau``.

    Built with the library's atlas: start at the pole, integrate for ``tau``, reverse the velocity.
    """
    chain = Chain(4, L)
    atlas = chain.atlas()
    pole = atlas.charts[0].get_point(np.array([HALF_PI, 0.0]))
    i = atlas.get_chart_index(pole)
    v = atlas.charts[i].tangent_vector(atlas.get_parameters(i, pole), np.asarray(c_pole, float))
    v /= np.sqrt(2 * chain.metric().ambient_kinetic_energy(v))
    p1, v1 = solve_chart_exp_ode(chain.metric(), pole, v, tau).end_state()
    a1 = atlas.charts[0].get_parameters(p1)
    return a1, atlas.charts[0].coefficients(a1, -v1)


@pytest.mark.parametrize("c_pole", [[1.0, 0.0], [0.3, 1.0]])
def test_a_run_through_a_pole_fails_there(c_pole):
    """Aimed exactly at the pole (reached at tau = 0.3 from phi ~ 1.2 .. 1.3), the seed's run breaks at the pole:
    ``t'`` explodes (to 1e2 .. 1e10) and the next step is non-finite or overshoots ``pi/2``.  Measured
    ``failed_at`` = 0.35, 0.31, 0.30 for h = 0.05, 0.01, 0.002.  The library's atlas goes straight through."""
    L, tau = 2.6, 0.3
    a0, c0 = aimed_at_pole(L, tau, c_pole)
    assert 1.2 < a0[0] < 1.35 and c0[0] > 0
    lib = solve_chart_exp_ode(Chain(4, L).metric(), SuspensionChart(4, L).get_point(a0),
                              SuspensionChart(4, L).tangent_vector(a0, c0), 1.0)
    assert lib.relative_energy_error < 1e-12
    for h in (0.05, 0.01, 0.002):
        sol = integrate_seed_rk4(L, a0, c0, 1.0, h)
        assert sol.failed_at is not None, h
        assert tau - h <= sol.failed_at <= tau + 2 * h + 1e-12, (h, sol.failed_at)
        assert sol.t[-1] < sol.failed_at and np.all(np.abs(sol.a[:, 0]) <= HALF_PI)
    # up to shortly before the pole the small-step run is accurate
    k = np.searchsorted(sol.t, tau - 0.1)
    assert np.max(sol.relative_energy_error[: k + 1]) < 1e-8
    p_lib, _ = lib(sol.t[k])
    assert np.max(np.abs(Chain(4, L).to_point(sol.hinges[k]) - p_lib)) < 1e-7


def test_a_near_miss_of_a_pole_fails_or_loses_energy():
    """Start at phi = 1.4 heading north (phi' = 1, t' = 0).  The true geodesic does *not* reach the pole (the
    meridian t = const is not a geodesic): it passes at cos(phi) ~ 0.008 near t = 0.15.  The seed's RK4 there:
    h = 0.05 and 0.01 fail at t = 0.2 and 0.19 (energy error first 0.12 and 1e7); h = 0.005 .. 0.0005 get
    through with energy errors 2e-3 .. 2e-2 and position errors at T = 3 of 5e-4 .. 7e-2, *not* decreasing
    with h (the finite-difference vector field is off by 5e-5 .. 4e-3 near the pole)."""
    L, T = 2.6, 3.0
    chain = Chain(4, L)
    chart = SuspensionChart(4, L)
    a0, c0 = np.array([1.4, 0.5]), np.array([1.0, 0.0])
    p0, v0 = chart.get_point(a0), chart.tangent_vector(a0, c0)
    lib = solve_chart_exp_ode(chain.metric(), p0, v0, T)  # best chart at p0
    assert lib.relative_energy_error < 1e-12
    P, _ = lib(np.linspace(0, T, 301))
    closest = min(chart.quality(chart.get_parameters(p)) for p in P)
    assert 0.005 < closest < 0.012  # a near miss, not a hit

    for h in (0.05, 0.01):
        sol = integrate_seed_rk4(L, a0, c0, T, h)
        assert sol.failed_at is not None and 0.1 < sol.failed_at < 0.25, (h, sol.failed_at)
    sol = integrate_seed_rk4(L, a0, c0, T, 0.002)
    assert sol.failed_at is None
    assert sol.relative_energy_error.max() > 1e-3  # measured 3.5e-3 (1e-10 away from the pole at this h)
    assert np.max(np.abs(chain.to_point(sol.hinges[-1]) - lib.end_state()[0])) > 1e-3  # measured 4.2e-3


# -- errors -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("L", [2.0, 4.0, 1.5, np.nan, np.inf, "x"])
def test_bad_base_length(L):
    with pytest.raises(ValueError, match="L must be"):
        integrate_seed_rk4(L, [0.3, 0.5], [1.0, 0.0], 1.0, 0.1)
    with pytest.raises(ValueError, match="L must be"):
        seed_vector_field([0.3, 0.5, 1.0, 0.0], L)


@pytest.mark.parametrize(
    "a0, c0, match",
    [
        ([0.3], [1.0, 0.0], "shape"),
        ([0.3, 0.5], [1.0, 0.0, 0.0], "shape"),
        ([np.nan, 0.5], [1.0, 0.0], "finite"),
        ([0.3, 0.5], [np.inf, 0.0], "finite"),
        ([HALF_PI, 0.5], [1.0, 0.0], "strictly inside"),
        ([-2.0, 0.5], [1.0, 0.0], "strictly inside"),
    ],
)
def test_bad_start(a0, c0, match):
    with pytest.raises(ValueError, match=match):
        integrate_seed_rk4(2.6, a0, c0, 1.0, 0.1)


@pytest.mark.parametrize("T, h, match", [(0.0, 0.1, "t_final"), (np.nan, 0.1, "t_final"), (1.0, 0.0, "h must"),
                                         (1.0, -0.1, "h must"), (1.0, np.inf, "h must"), (1.0, None, "h must")])
def test_bad_times(T, h, match):
    with pytest.raises(ValueError, match=match):
        integrate_seed_rk4(2.6, [0.3, 0.5], [1.0, 0.0], T, h)


def test_bad_state():
    with pytest.raises(ValueError, match="shape"):
        seed_vector_field([0.3, 0.5, 1.0], 2.6)
    with pytest.raises(ValueError, match="finite"):
        seed_vector_field([0.3, np.nan, 1.0, 0.0], 2.6)
