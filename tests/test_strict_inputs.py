"""Strict inputs: every bad argument gets a clear error that names it (issue 8, section 3)."""

from __future__ import annotations

import numpy as np
import pytest

from charts import SuspensionAtlas
from linkage import Chain, ConfigurationError
from linkage.ambient import integrate_ambient
from linkage.motion import free_motion
from manifold import Precision, ScipyStepper, StartCheck, TaylorStepper, solve_chart_exp_ode
from manifold.validation import ArgumentError

from .conftest import unit_speed_start


@pytest.fixture(scope="module")
def start():
    chain = Chain(4, 2.9)
    h0, v0 = unit_speed_start(chain, [1.2, 0.3], [1.0, 0.2])
    return chain, h0, v0


@pytest.mark.parametrize("tol", [1.0, 0.0, -1e-9, np.nan, np.inf, "1e-10", True])
def test_tolerances_outside_their_range_are_refused(start, tol):
    chain, h0, v0 = start
    with pytest.raises(ValueError, match=r"tol must be a real number in \(0, 0.01\]"):
        free_motion(chain, h0, v0, 1.0, precision=Precision(tol=tol))
    with pytest.raises(ValueError, match=r"tol must be a real number in \(0, 0.01\]"):
        TaylorStepper(tol)
    with pytest.raises(ValueError, match=r"rtol must be a real number"):
        ScipyStepper("DOP853", rtol=tol)


@pytest.mark.parametrize("kw, error, match", [
    ({"compact_mode": "yes"}, TypeError, "compact_mode must be True or False"),
    ({"compact_mode": 1}, TypeError, "compact_mode must be True or False"),
    ({"opt_level": 4}, ValueError, r"opt_level must be an integer in \[0, 3\], got 4"),
    ({"opt_level": -1}, ValueError, r"opt_level must be an integer in \[0, 3\]"),
    ({"opt_level": 2.0}, TypeError, r"opt_level must be an integer in \[0, 3\]"),
    ({"opt_level": True}, TypeError, r"opt_level must be an integer in \[0, 3\]"),
])
def test_compile_options_of_the_taylor_stepper_are_checked(kw, error, match):
    with pytest.raises(error, match=match):
        TaylorStepper(**kw)


@pytest.mark.parametrize("kw, match", [
    ({"max_switches": 0}, "max_switches"), ({"max_switches": 1.5}, "max_switches"),
    ({"max_switches": True}, "max_switches"), ({"q_out": 0.9}, r"q_out must lie in \(0, 0.6\)"),
    ({"q_out": "0.2"}, "q_out"),
])
def test_solver_options_are_checked_before_the_run(start, kw, match):
    chain, h0, v0 = start
    with pytest.raises(ValueError, match=match):
        free_motion(chain, h0, v0, 1.0, **kw)


@pytest.mark.parametrize("kw, error", [({"switching": "no"}, TypeError), ({"save": [0.0, 1.0]}, TypeError),
                                       ({"chart": True}, TypeError), ({"chart": 4}, ValueError),
                                       ({"throw": None}, TypeError)])
def test_flags_and_chart_indices_must_have_their_type(start, kw, error):
    chain, h0, v0 = start
    with pytest.raises(error, match=list(kw)[0]):
        solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), 1.0, **kw)


def test_strings_are_not_numbers(start):
    chain, h0, v0 = start
    with pytest.raises(ValueError, match=r"L \(base length\) must be a finite number > 0, got L = '2.5'"):
        Chain(4, L="2.5")
    with pytest.raises(ValueError, match="t_final"):
        free_motion(chain, h0, v0, "1")
    with pytest.raises(ValueError, match="t_final"):
        solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), "1")


def test_a_zero_dimensional_array_is_a_time(start):
    chain, h0, v0 = start
    assert free_motion(chain, h0, v0, np.array(0.5)).success


@pytest.mark.parametrize("rtol", [np.nan, -1e-9, np.inf, 0.0])
def test_ambient_tolerances_are_checked(start, rtol):
    chain, h0, v0 = start
    with pytest.raises(ValueError, match="rtol"):
        integrate_ambient(chain, h0, v0, 1.0, rtol=rtol)
    with pytest.raises(ValueError, match="atol"):
        integrate_ambient(chain, h0, v0, 1.0, atol=rtol)


def test_complex_points_and_parameters_are_refused():
    atlas = SuspensionAtlas(4, 2.9)
    a = np.array([0.3, 0.4])
    p = atlas.get_point(0, a)
    with pytest.raises(TypeError, match="p must be a real array"):
        atlas.get_chart_index(p + 0.3j)
    with pytest.raises(TypeError, match="chart parameters must be a real array"):
        atlas.get_point(0, a + 1j)
    with pytest.raises(TypeError, match="p0 must be a real array"):
        solve_chart_exp_ode(Chain(4, 2.9).metric(), p + 0j, np.zeros(6), 1.0)


def test_hinges_and_points_are_not_confused(start):
    chain, h0, _ = start
    with pytest.raises(ConfigurationError, match="to_point takes complex hinges"):
        chain.to_point(chain.to_point(h0))
    with pytest.raises(ConfigurationError, match="from_point takes real points"):
        chain.from_point(h0)
    with pytest.raises(ConfigurationError, match="complex"):
        free_motion(chain, chain.to_point(h0), np.zeros(6), 1.0)


def test_a_batch_of_points_gets_one_chart_per_point():
    atlas = SuspensionAtlas(5, 3.3)
    rng = np.random.default_rng(4)
    a = np.column_stack([rng.uniform(-1.5, 1.5, (7, 2)), rng.uniform(-3, 3, 7)])
    pts = atlas.get_point(2, a)
    idx, params = atlas.best_chart(pts)
    assert idx.shape == (7,) and params.shape == (7, 3)
    for k in range(7):
        assert idx[k] == atlas.get_chart_index(pts[k])
        assert np.abs(atlas.get_point(int(idx[k]), params[k]) - pts[k]).max() <= 1e-12
    assert np.array_equal(atlas.get_chart_index(pts.reshape(7, 1, 8)), idx.reshape(7, 1))


def test_errors_name_the_public_arguments(start):
    chain, h0, v0 = start
    with pytest.raises(ValueError, match="velocity0 is not tangent"):
        free_motion(chain, h0, v0 + 0.1, 1.0)
    with pytest.raises(ConfigurationError, match="does not close"):
        free_motion(chain, h0 * 1.01, v0, 1.0)
    with pytest.raises(ValueError, match="velocity0 gives a non-finite kinetic energy"):
        free_motion(chain, h0, v0 * 1e200, 1.0)
    with pytest.raises(ValueError, match="v0 gives a non-finite kinetic energy"):
        solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0) * 1e200, 1.0)


# -- options and inputs an adversarial fuzz found unchecked ------------------------------------------------------
def test_options_found_unchecked_are_refused_by_name(start):
    from linkage.topology import topology

    chain, h0, v0 = start
    for rtol in (np.nan, -1.0, 10.0):
        with pytest.raises(ValueError, match="rtol must be"):
            topology((1, 1, 1, 1), 2.6, rtol=rtol)
    space, rng = chain.diagonal_space(), np.random.default_rng(0)
    with pytest.raises(ValueError, match="steps must be an integer >= 1, got 0"):
        space.sample(3, rng, method="hit-and-run", steps=0)
    with pytest.raises(ValueError, match="max_draws must be an integer >= 1, got 0"):
        space.sample(3, rng, max_draws=0)
    with pytest.raises(TypeError, match="project_velocity must be True or False"):
        StartCheck(project_velocity="yes")
    x, flips = chain.diagonals(h0)
    with pytest.raises(TypeError, match="x must be an array of real diagonals, got complex"):
        chain.from_diagonals(x + 1j, flips)
    with pytest.raises(ValueError, match=r"hinge_masses must be in \[1e-100, 1e\+100\] \(beyond the range, .*overflows or underflows"):
        Chain(4, 2.6, hinge_masses=1e-300)
    for bad in (0.0, -1.0, np.nan):  # not a scale: no word of overflow
        with pytest.raises(ValueError, match=r"hinge_masses must be in \[1e-100, 1e\+100\] \(a mass is a number > 0\)"):
            Chain(4, 2.6, hinge_masses=bad)
    with pytest.raises(ValueError, match=r"rod_densities must be in \[0, 1e\+100\] \(a density is a number >= 0\)"):
        Chain(4, 2.6, rod_densities=-0.5)
    with pytest.raises(ValueError, match=r"\(a mass is a number > 0; beyond the range, .*\), got \[0.e\+000 1.e\+200\]"):
        Chain(4, 2.6, hinge_masses=[0.0, 1e200, 1.0])  # both reasons, each for its value
    with pytest.raises(ValueError, match=r"rod_densities must be in \[0, 1e\+100\]"):
        Chain(4, 2.6, rod_densities=1e200)
    with pytest.raises(TypeError, match="metric must be a manifold.InducedMetric"):
        solve_chart_exp_ode(None, np.zeros(6), np.zeros(6), 1.0)
    with pytest.raises(ValueError, match=r"hinges0 must be one configuration.*free_motions"):
        free_motion(chain, np.stack([h0, h0]), np.stack([v0, v0]), 1.0, method="hinges")
    bad = h0.copy()
    bad[1] = np.nan  # named by the argument the user wrote, with the entry
    with pytest.raises(ValueError, match=r"^hinges0 must be finite, got hinges0\[1\] = \(?nan"):
        free_motion(chain, bad, v0, 1.0, method="hinges")
    for method in ("hinges", "charts"):
        with pytest.raises(TypeError, match=f"free_motion.method='{method}'. does not take rtol=1e-10; the tolerance is "
                                            r"precision=Precision\(tol=\.\.\.\)"):
            free_motion(chain, h0, v0, 1.0, method=method, rtol=1e-10)
    chart = chain.atlas().charts[0]
    with pytest.raises(ValueError, match="c must hold the 2 coefficients"):
        chart.tangent_vector(np.array([0.1, 0.2]), np.array([1.0, 2.0, 3.0]))


def test_a_motion_takes_real_times_only_and_no_times_at_all(start):
    chain, h0, v0 = start
    motion = free_motion(chain, h0, v0, 1.0, method="hinges")
    hinges, velocities = motion(np.array([]))
    assert hinges.shape == velocities.shape == (0, 3)
    for bad in ("1", True, 1j):
        with pytest.raises(TypeError, match="t must be a real time or an array of times"):
            motion(bad)


@pytest.mark.parametrize("args, kwargs, argument", [
    ((4, 4.5), {}, "L"),  # an empty space: L is the side too long
    (((1.0, 5.0, 1.0), 2.0), {}, "lengths"),  # an empty space: a rod is
    ((1, 0.5), {}, "lengths"),
    (((1.0, -1.0), 1.0), {}, "lengths"),
    ((4, np.nan), {}, "L"),
    ((4, 2.6), {"hinge_masses": 0.0}, "hinge_masses"),
    ((4, 2.6), {"hinge_masses": [1.0, 2.0]}, "hinge_masses"),
    ((4, 2.6), {"rod_densities": -1.0}, "rod_densities"),
])
def test_a_refused_chain_says_which_argument(args, kwargs, argument):
    # a caller that maps the arguments to its own fields (the explorer's requests) reads the argument, not the message
    with pytest.raises(ArgumentError) as refused:
        Chain(*args, **kwargs)
    assert refused.value.argument == argument
    assert isinstance(refused.value, ValueError) and argument in str(refused.value)
