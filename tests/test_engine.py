"""The geodesic engine: a new chart family plugs in by its formula alone; one loop, one solution type.

The round sphere S^2 with two stereographic charts (``tests/sphere_family.py``)
has great circles as exact geodesics; the same solver, with both steppers,
must follow them through chart switches.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from charts import SuspensionChart
from linkage import Chain
from linkage.motion import free_motion
from manifold import (
    Atlas,
    GeodesicIntegrationError,
    Precision,
    SaveAt,
    ScipyStepper,
    SolveStatus,
    TaylorStepper,
    compiled,
    solve_chart_exp_ode,
)

from .conftest import unit_speed_start
from .sphere_family import StereographicChart, StereographicFamily, great_circle, sphere_metric, sphere_start


def _chain_start(chain, a, c):
    """Interleaved real point and velocity of ``unit_speed_start``."""
    h0, v0 = unit_speed_start(chain, a, c)
    return chain.to_point(h0), chain.to_point(v0)



@pytest.mark.parametrize("stepper, tol", [(TaylorStepper(), 1e-12), (ScipyStepper("DOP853", 1e-12, 1e-12), 1e-9)])
def test_sphere_geodesics_are_great_circles_through_switches(stepper, tol):
    p0, v0 = sphere_start()
    T = 20.0
    sol = solve_chart_exp_ode(sphere_metric(), p0, v0, T, stepper=stepper)
    assert sol.success and sol.n_switches >= 4  # every half turn passes near a projection pole
    ts = np.linspace(0, T, 401)
    p, v = sol(ts)
    assert np.abs(p - great_circle(p0, v0, ts)).max() <= tol
    assert sol.relative_energy_error <= 10 * tol
    assert all(s.quality_to >= 0.5 for s in sol.switches)  # the other chart is at least as good as the equator


def test_sphere_backward_run_returns_to_the_start():
    p0, v0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.5, 1.2])  # a great circle through both caps
    fwd = solve_chart_exp_ode(sphere_metric(), p0, v0, 7.0)
    p1, v1 = fwd.end_state()
    back = solve_chart_exp_ode(sphere_metric(), p1, v1, -7.0)
    assert back.n_switches >= 1 and fwd.n_switches >= 1  # counts may differ: hysteresis depends on direction
    assert np.abs(back.end_state()[0] - p0).max() <= 1e-12


def test_an_atlas_of_two_families_is_refused():
    with pytest.raises(ValueError, match="one chart family"):
        Atlas([StereographicChart(False), StereographicChart(True, StereographicFamily("other"))])


def test_families_are_compiled_once_per_key():
    assert compiled(StereographicFamily("x")) is compiled(StereographicFamily("x"))
    assert compiled(StereographicFamily("x")) is not compiled(StereographicFamily("y"))
    assert SuspensionChart(4, 2.5).family == SuspensionChart(4, 3.5).family


def test_chart_quality_is_the_compiled_quality_expression():
    """The numpy quality of a chart is the minimum of the family's quality expressions (one formula):
    here against the same formula run on numpy (cosines of the latitudes and the two fold terms)."""
    from charts import suspension_formula
    from manifold.backends import NUMPY

    chart = SuspensionChart(5, 3.4)
    rng = np.random.default_rng(2)
    a = np.column_stack([rng.uniform(-1.5, 1.5, (50, 2)), rng.uniform(-3, 3, 50)])
    fold = suspension_formula.fold_qualities([a[:, k] for k in range(3)], 3.4, NUMPY)
    expected = np.min(np.column_stack([np.cos(a[:, :2])] + fold), axis=-1)
    assert np.abs(chart.quality(a) - expected).max() <= 1e-15


# -- one solution type ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def chain_run():
    """Chart 0 at latitude 1.2 heading for its pole: a switch at t = 0.11 (chart parameters, chart=0)."""
    chain = Chain(4, 2.9)
    a, c = np.array([1.2, 0.3]), np.array([1.0, 0.2])
    return chain, a, c, solve_chart_exp_ode(chain.metric(), a, c, 12.0, chart=0)


def test_vectorised_evaluation_equals_pointwise(chain_run):
    _, _, _, sol = chain_run
    ts = np.linspace(0, 12, 301)
    p, v = sol(ts)
    for k in (0, 77, 150, 300):
        pk, vk = sol(ts[k])
        assert np.abs(pk - p[k]).max() <= 1e-15 and np.abs(vk - v[k]).max() <= 1e-15
    charts, a, c = sol.parameters(ts)
    assert charts.shape == ts.shape and a.shape == c.shape == (301, 2)
    for i in np.unique(charts):
        sel = charts == i
        assert np.abs(sol.metric.atlas.get_point(int(i), a[sel]) - p[sel]).max() <= 1e-13


def test_compact_dense_output_holds_only_the_taylor_coefficients(chain_run):
    _, _, _, sol = chain_run
    k2 = 2 * sol.metric.atlas.dim
    with compiled(sol.metric.atlas.charts[0].family).integrator() as ta:
        order = ta.order
    assert sol.dense_nbytes == sum((s.n_steps * (order + 1) * k2 + s.n_steps + 1) * 8 for s in sol.segments)


def test_grid_output_without_dense_storage(chain_run):
    chain, a, c, dense = chain_run
    ts = np.linspace(0, 12, 25)
    grid = solve_chart_exp_ode(chain.metric(), a, c, 12.0, save=SaveAt(dense=False, t_eval=ts), chart=0)
    assert grid.dense_nbytes == 0
    p, v = dense(ts)
    assert np.abs(grid.points - p).max() <= 1e-15 and np.abs(grid.velocities - v).max() <= 1e-15
    with pytest.raises(ValueError, match="dense=False"):
        grid(1.0)


def test_backward_grid_and_bad_grids():
    chain = Chain(4, 2.9)
    p0, v0 = _chain_start(chain, [1.2, 0.3], [1.0, 0.2])
    ts = np.linspace(0, -6, 13)
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, -6.0, save=SaveAt(t_eval=ts))
    assert np.abs(sol.points - sol(ts)[0]).max() <= 1e-15
    for bad in (np.linspace(0, 6, 5), ts[::-1], np.array([[0.0]])):
        with pytest.raises(ValueError, match="t_eval"):
            solve_chart_exp_ode(chain.metric(), p0, v0, -6.0, save=SaveAt(t_eval=bad))


def test_failure_is_one_exception_or_one_status(chain_run):
    chain, a, c, _ = chain_run
    with pytest.raises(GeodesicIntegrationError, match="max_switches") as err:
        solve_chart_exp_ode(chain.metric(), a, c, 40.0, max_switches=1, chart=0)
    partial = err.value.solution
    assert partial.status is SolveStatus.MAX_SWITCHES and partial.n_switches == 1
    quiet = solve_chart_exp_ode(chain.metric(), a, c, 40.0, max_switches=1, throw=False, chart=0)
    assert quiet.status is SolveStatus.MAX_SWITCHES and not quiet.success
    assert float(quiet.t_reached) == float(partial.t_reached) < 40.0
    assert np.abs(quiet(quiet.t_reached)[0] - partial.end_state()[0]).max() <= 1e-14  # polynomial vs state
    assert "max_switches" in repr(quiet) or "switches" in repr(quiet)


def test_stats_and_short_repr(chain_run):
    _, _, _, sol = chain_run
    s = sol.stats
    assert s.n_steps == sol.n_steps > 0 and s.n_switches == sol.n_switches >= 1
    assert 0 <= s.switch_seconds <= s.wall_seconds and 0 <= s.compile_seconds <= s.wall_seconds
    assert len(repr(sol)) < 200 and "\n" not in repr(sol)
    assert isinstance(sol.relative_energy_error, float)


# -- thread safety -------------------------------------------------------------------------------
def test_concurrent_solves_equal_serial_ones():
    """Solves share compiled code but never an integrator: threads give the serial answers exactly."""
    chain = Chain(5, 3.3)
    starts = [unit_speed_start(chain, [0.2 * k, -0.3, 0.1 * k], [1.0, 0.5 - 0.2 * k, 0.3]) for k in range(6)]

    def run(start):
        motion = free_motion(chain, start[0], start[1], 6.0)
        return motion.solution.end_state()[0], motion.n_switches

    serial = [run(s) for s in starts]
    with ThreadPoolExecutor(4) as pool:
        threaded = list(pool.map(run, starts))
    for (ps, ns), (pt, nt) in zip(serial, threaded):
        assert ns == nt and np.array_equal(ps, pt)


def test_the_ambient_reference_returns_the_same_solution_type():
    """Hinge-coordinate segments (chart None): points directly, chart parameters on demand from the atlas."""
    from linkage.ambient import integrate_ambient

    chain = Chain(5, 3.4)
    h0, v0 = unit_speed_start(chain, [0.4, -0.2, 0.7], [1.0, 0.3, -0.5])
    motion = integrate_ambient(chain, h0, v0, 3.0, project=True, projection_interval=0.5)
    sol = motion.solution
    assert isinstance(sol.relative_energy_error, float) and sol.success and sol.method == "ambient-DOP853"
    assert all(s.chart is None for s in sol.segments) and len(sol.segments) == 6
    ts = np.linspace(0, 3, 13)
    p, v = sol(ts)
    charts, a, c = sol.parameters(ts)
    for k in range(len(ts)):
        chart = sol.metric.atlas.charts[charts[k]]
        # DOP853's interpolant leaves the manifold by ~1e-11 between steps: the chart reads its nearest point
        assert np.abs(chart.get_point(a[k]) - p[k]).max() <= 1e-10
        assert np.abs(chart.tangent_vector(a[k], c[k]) - v[k]).max() <= 1e-10
        assert charts[k] == sol.metric.atlas.get_chart_index(p[k])
    ref = free_motion(chain, h0, v0, 3.0)
    assert np.abs(motion(ts)[0] - ref(ts)[0]).max() <= 1e-9


def test_energy_error_is_measured_in_the_working_precision():
    """Rounding each energy to float64 before subtracting hid every deviation below 1e-16 (it reported 0)."""
    chain = Chain(4, 2.7)
    h0, v0 = unit_speed_start(chain, [0.3, 0.4], [1.0, 0.2])
    sol = free_motion(chain, h0, v0, 3.0, precision=Precision(fp_type=np.longdouble)).solution
    E = np.array(sol.energies, dtype=np.longdouble)
    expected = float(np.max(np.abs(E - E[0]) / E[0]))
    assert 0 < sol.relative_energy_error == pytest.approx(expected, rel=1e-6)
    assert sol.relative_energy_error < 1e-17
