"""Geodesic motion through the atlas: energy, switching, independent forms, periodicity."""

import heyoka as hy
import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

from charts import SuspensionChart
from linkage import Chain
from linkage.ambient import integrate_ambient
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import Precision, SaveAt, ScipyStepper, StartCheck, TaylorStepper, solve_chart_exp_ode
from manifold.sundman import SundmanStepper

HALF_PI = np.pi / 2


def start(chain: Chain, a, c, chart=0):
    """Point and tangent velocity from chart parameters and coefficients."""
    atlas = chain.atlas()
    return atlas.get_point(chart, np.asarray(a, float)), atlas.charts[chart].tangent_vector(np.asarray(a, float), np.asarray(c, float))


@pytest.mark.parametrize("n, L, T", [(4, 2.6, 800.0), (5, 3.3, 650.0), (6, 5.5, 150.0)])
def test_energy_is_conserved_across_a_hundred_switches(n, L, T):
    chain = Chain(n, L, rod_densities=0.2)
    rng = np.random.default_rng(n)
    a0 = np.append(rng.uniform(-1, 1, n - 3), 0.4)
    p0, v0 = start(chain, a0, rng.normal(size=n - 2))
    speed = np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))
    # q_out = 0.45 (still below the atlas's worst best quality 0.6) switches often
    sol = solve_chart_exp_ode(chain.metric(), p0, v0 * (3.0 / speed), T, save=SaveAt(dense=False), q_out=0.45)
    assert sol.n_switches >= 100
    assert sol.relative_energy_error <= 1e-12
    assert max(s.point_gap for s in sol.switches) <= 1e-14  # each transfer keeps the point (observed ~1e-15)
    # bounded switching: at speed 3 a switch needs the path to move a finite distance
    assert sol.n_switches / T <= 3.0
    times = np.array([s.time for s in sol.switches])
    assert np.all(np.diff(times) > 1e-3), "chattering: two switches in a row"


def test_circle_chain_never_switches_and_conserves_energy():
    chain = Chain(3, 1.4)
    p0, v0 = start(chain, [0.3], [2.0])
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, 300.0, save=SaveAt(dense=False))
    assert sol.n_switches == 0
    assert sol.relative_energy_error <= 1e-12


@pytest.mark.parametrize("L", [1.001, 1.5, 2.5, 2.999])
def test_three_rods_period_is_the_length_of_the_curve(L):
    """At unit speed the motion of n = 3 is periodic with period = length of M^3_L in hinge space."""
    chart = SuspensionChart(3, L)
    speed = lambda t: np.linalg.norm(chart.jacobian(np.array([t]))[:, 0])  # noqa: E731
    length = sum(quad(speed, lo, lo + HALF_PI, epsabs=1e-13, epsrel=1e-13, limit=200)[0]
                 for lo in (-np.pi, -HALF_PI, 0.0, HALF_PI))
    chain = Chain(3, L)
    a0 = np.array([HALF_PI])
    p0, v0 = chart.get_point(a0), chart.jacobian(a0)[:, 0] / speed(HALF_PI)
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, 1.05 * length)
    # the first return: <p(t) - p0, v0> changes sign from - to + as the chain passes its start
    period = brentq(lambda t: (sol(t)[0] - p0) @ v0, 0.99 * length, 1.01 * length, xtol=1e-14)
    assert period == pytest.approx(length, rel=1e-10)
    p_end, v_end = sol(period)
    assert np.abs(p_end - p0).max() < 1e-9 and np.abs(v_end - v0).max() < 1e-9


def test_embedded_and_christoffel_forms_agree():
    chain = Chain(4, 3.1)
    p0, v0 = start(chain, [1.2, 0.3], [1.0, 0.2])
    emb = solve_chart_exp_ode(chain.metric(), p0, v0, 10.0)
    chr_ = solve_chart_exp_ode(chain.metric(), p0, v0, 10.0, form="christoffel")
    assert emb.n_switches >= 1
    ts = np.linspace(0, 10, 41)
    assert np.abs(emb(ts)[0] - chr_(ts)[0]).max() <= 1e-9


def test_compile_options_change_the_cost_not_the_geodesic():
    """LLVM's optimisation level reaches heyoka (opt_level 0 is measurably slower, benchmarks/taylor_options.py)
    and leaves the motion alone: the same geodesic through the same switches."""
    chain = Chain(4, 3.1)
    p0, v0 = start(chain, [1.2, 0.3], [1.0, 0.2])
    ref = solve_chart_exp_ode(chain.metric(), p0, v0, 10.0, stepper=TaylorStepper(opt_level=3))
    low = solve_chart_exp_ode(chain.metric(), p0, v0, 10.0, stepper=TaylorStepper(opt_level=0))
    assert low.n_switches == ref.n_switches >= 1
    ts = np.linspace(0, 10, 41)
    assert np.abs(low(ts)[0] - ref(ts)[0]).max() <= 1e-12


@pytest.mark.parametrize("n, L", [(4, 2.05), (5, 4.6), (6, 4.4)])
def test_reversibility(n, L):
    chain = Chain(n, L)
    rng = np.random.default_rng(10 + n)
    p0, v0 = start(chain, np.append(rng.uniform(-1.2, 1.2, n - 3), -1.0), np.append(1.0, rng.normal(size=n - 3)))
    fwd = solve_chart_exp_ode(chain.metric(), p0, v0, 10.0, save=SaveAt(dense=False))
    back = solve_chart_exp_ode(chain.metric(), *fwd.end_state(), -10.0, save=SaveAt(dense=False))
    p_back, v_back = back.end_state()
    assert fwd.n_switches >= 1
    assert np.abs(p_back - p0).max() <= 1e-10
    assert np.abs(v_back - v0).max() <= 1e-10 * max(1, np.abs(v0).max())


def test_start_exactly_at_a_pole():
    """Rods 0, 1, 2 aligned: chart 0's pole. The solver starts in another chart and passes through."""
    chain = Chain(5, 3.4)
    atlas = chain.atlas()
    a_pole = np.array([0.3, HALF_PI, 1.0])
    p0 = atlas.get_point(0, a_pole)
    assert atlas.charts[0].quality(atlas.get_parameters(0, p0)) < 1e-7
    j = atlas.get_chart_index(p0)
    aj = atlas.get_parameters(j, p0)
    v0 = atlas.charts[j].tangent_vector(aj, np.array([0.5, -1.0, 0.7]))
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, 20.0)
    assert sol.segments[0].chart == j != 0
    assert sol.relative_energy_error <= 1e-12


def test_real128_energy_error():
    chain = Chain(4, 2.7)
    p0, v0 = start(chain, [1.2, 0.3], [1.0, 0.2])
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, precision=Precision(fp_type=hy.real128))
    assert sol.relative_energy_error <= 1e-28


def test_long_double_runs_end_to_end():
    chain = Chain(4, 2.7)
    sol = solve_chart_exp_ode(chain.metric(), [1.2, 0.3], [1.0, 0.2], 10.0,
                              precision=Precision(fp_type=np.longdouble), chart=0)
    assert sol.n_switches >= 1
    assert sol.relative_energy_error <= 1e-17
    p, _ = sol(5.0)
    assert p.dtype == np.longdouble


def test_chain_motion_returns_closed_configurations():
    chain = Chain(5, 4.1, hinge_masses=[1, 2, 1, 3])
    p0, v0 = start(chain, [0.2, 1.0, 0.5], [1.0, -0.5, 0.3])
    motion = free_motion(chain, chain.from_point(p0), chain.from_point(v0), 5.0)
    h, v = motion(np.linspace(0, 5, 11))
    assert h.shape == (11, 4) and chain.closure_residual(h).max() < 1e-12
    E = chain.kinetic_energy(v)
    assert np.abs(E - E[0]).max() <= 1e-12 * E[0]


class TestBadInput:
    chain = Chain(4, 3.0)

    def _pv(self):
        return start(self.chain, [0.2, 0.3], [1.0, 0.0])

    def test_non_closing_start(self):
        p0, v0 = self._pv()
        with pytest.raises(ValueError, match="does not close"):
            solve_chart_exp_ode(self.chain.metric(), p0 * 1.01, v0, 1.0)

    def test_nan(self):
        p0, v0 = self._pv()
        with pytest.raises(ValueError, match="finite"):
            solve_chart_exp_ode(self.chain.metric(), p0, v0 * np.nan, 1.0)
        with pytest.raises(ValueError, match="finite"):
            solve_chart_exp_ode(self.chain.metric(), p0 * np.nan, v0, 1.0)

    @pytest.mark.parametrize("T", [np.inf, np.nan, -np.inf])
    def test_t_final_not_finite(self, T):
        p0, v0 = self._pv()
        with pytest.raises(ValueError, match="t_final must be a finite real number"):
            solve_chart_exp_ode(self.chain.metric(), p0, v0, T)

    def test_non_tangent_velocity(self):
        p0, v0 = self._pv()
        normal = np.zeros(6)
        normal[:2] = p0[:2]  # radial on the first hinge: changes |e_1|
        with pytest.raises(ValueError, match="not tangent"):
            solve_chart_exp_ode(self.chain.metric(), p0, v0 + normal, 1.0)
        sol = solve_chart_exp_ode(self.chain.metric(), p0, v0 + normal, 1.0, start=StartCheck(project_velocity=True))
        assert sol.relative_energy_error < 1e-12

    def test_outside_span(self):
        p0, v0 = self._pv()
        sol = solve_chart_exp_ode(self.chain.metric(), p0, v0, 1.0)
        with pytest.raises(ValueError, match="outside"):
            sol(1.5)
        with pytest.raises(ValueError, match="outside"):
            sol(-0.1)

    def test_L_out_of_range(self):
        with pytest.raises(ValueError, match="2 < L < 4"):
            Chain(4, 4.5)


@pytest.mark.parametrize("n, L", [(4, 3.5), (5, 3.6), (6, 5.2)])
@pytest.mark.parametrize("where", ["generic", "pole"])
def test_chart_solution_matches_ambient_reference(n, L, where):
    """Atlas geodesic vs hinge-space integration with Lagrange multipliers (no charts)."""
    chain = Chain(n, L)
    atlas = chain.atlas()
    rng = np.random.default_rng(n)
    a0 = np.append(rng.uniform(-1, 1, n - 3), 0.7)
    c0 = np.append(1.0, 0.3 * rng.normal(size=n - 3))
    if where == "pole":
        a0[0] = HALF_PI  # chart 0's pole: its first n-1 rods stretched in one line
    else:
        a0[0] = 1.2  # heading for chart 0's pole
    p0 = atlas.get_point(0, a0)
    if where == "pole":
        j = atlas.get_chart_index(p0)
        assert j != 0
        v0 = atlas.charts[j].tangent_vector(atlas.get_parameters(j, p0), c0)
    else:
        v0 = atlas.charts[0].tangent_vector(a0, c0)
    v0 /= np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))  # unit speed
    T = 10.0
    ts = np.linspace(0, T, 21)
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, T, q_out=0.55)  # switches often (the floor is 0.6)
    ref = integrate_ambient(chain, chain.from_point(p0), chain.from_point(v0), T, save=SaveAt(t_eval=ts), rtol=1e-13,
                            atol=1e-13)
    assert sol.n_switches >= (1 if where == "generic" else 0)
    h_chart = chain.from_point(sol(ts)[0])
    assert np.abs(h_chart - ref.hinges).max() <= 1e-9


def test_backward_integration_switches_before_the_pole():
    """Event directions follow time: a backward run must still leave a chart before its pole."""
    chain = Chain(4, 2.9)
    atlas = chain.atlas()
    a0 = np.array([1.2, 0.3])
    c0 = np.array([-1.0, 0.1])  # forward in time phi decreases, so backward it climbs to the pole
    sol = solve_chart_exp_ode(chain.metric(), a0, c0, -3.0, chart=0)
    assert sol.n_switches >= 1 and sol.switches[0].from_chart == 0
    assert sol.switches[0].quality_from == pytest.approx(atlas.switch_threshold, abs=1e-9)
    assert sol.relative_energy_error < 1e-12
    ref = integrate_ambient(chain, chain.from_point(atlas.get_point(0, a0)),
                            chain.from_point(atlas.charts[0].tangent_vector(a0, c0)), -3.0, rtol=1e-13, atol=1e-13)
    assert np.abs(chain.from_point(sol.end_state()[0]) - ref.hinges[-1]).max() < 1e-9


@pytest.mark.parametrize("stepper", [TaylorStepper(), SundmanStepper(ChainTimeFactor(Chain(3, 1.7)))])
def test_backward_run_wraps_the_circle_angle(stepper):
    """The circle angle, wrapped between steps: within one step's turn of ``[-pi, pi]`` at every step (the dense
    output ends each step on its own polynomial), as many wraps as the angle turns through ``+-pi`` (the three-rod
    chain's one chart: it turns one way for ever), and the hinge method's motion."""
    chain = Chain(3, 1.7)
    T = -30.0
    sol = solve_chart_exp_ode(chain.metric(), [0.0], [-2.0], T, chart=0, stepper=stepper)
    assert len(sol.segments) == 1 and sol.relative_energy_error < 1e-13
    steps = np.array([float(t) for t in sol.energy_times])
    angle = sol.parameters(steps)[1][:, 0]
    reach = np.abs(np.diff(np.unwrap(angle))).max()  # the largest turn in a step
    assert reach < 0.2 and np.all(np.abs(angle) <= np.pi + reach)
    turned = np.unwrap(sol.parameters(np.linspace(0, T, 20001))[1][:, 0])  # steps of at most 0.02 in the angle
    assert np.all(np.diff(turned) > 0)
    assert sol.stats.n_wraps == int(np.floor((turned[-1] + np.pi) / (2 * np.pi))) >= 5
    p0, v0 = sol(0.0)
    ref = free_motion(chain, chain.from_point(p0), chain.from_point(v0), T, method="hinges")
    assert np.abs(chain.from_point(sol(T)[0]) - ref(T)[0]).max() < 1e-11


def test_forced_start_chart_below_threshold_switches_at_once():
    chain = Chain(4, 2.9)
    sol = solve_chart_exp_ode(chain.metric(), [1.5, 0.3], [0.2, 1.0], 1.0, chart=0)
    assert sol.switches and sol.switches[0].time == 0.0 and sol.segments[0].chart != 0


@pytest.mark.parametrize("method, rtol, tol", [("DOP853", 1e-12, 1e-9), ("RK45", 1e-10, 1e-6), ("Radau", 1e-8, 1e-5)])
def test_scipy_driver_follows_the_same_geodesic(method, rtol, tol):
    chain = Chain(4, 2.9)
    a, c = [1.2, 0.3], [1.0, 0.2]  # chart 0 heading for its pole: a switch at t = 0.11
    ours = solve_chart_exp_ode(chain.metric(), a, c, 8.0, chart=0)
    theirs = solve_chart_exp_ode(chain.metric(), a, c, 8.0, chart=0, stepper=ScipyStepper(method, rtol=rtol, atol=rtol))
    assert theirs.n_switches == ours.n_switches >= 1
    ts = np.linspace(0, 8, 17)
    assert np.abs(theirs(ts)[0] - ours(ts)[0]).max() <= tol


def test_scipy_single_chart_wraps_instead_of_switching():
    """With switching off the first scipy event is a wrap of t, not a quality crossing."""
    chain = Chain(4, 2.9)
    sol = solve_chart_exp_ode(chain.metric(), [0.2, 3.0], [0.1, 1.0], 2.0, chart=0, switching=False, stepper=ScipyStepper())
    assert sol.n_switches == 0 and len(sol.segments) >= 2  # t passed pi and was wrapped
    assert all(s.chart == 0 for s in sol.segments)
    assert -np.pi <= sol.final_state[1][-1] <= np.pi
