"""Events declared once (``manifold.events``), located by heyoka in the Taylor steppers and, for a stepper that only
steps, on its dense output by the shared locator.

The locator is checked on functions whose crossings are known in closed form; the two ways of locating events are
checked against each other (the same chart switches at the same times, forward and backward) and against the
geometry: on the round sphere a switch happens where a great circle reaches the height ``1 - 2 q_out`` in the
chart's frame, a closed form independent of both steppers.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage import Chain
from manifold import ScipyStepper, SolveStatus, TaylorStepper, compiled, solve_chart_exp_ode
from manifold.events import EITHER, FALLING, RISING, SWITCH, WRAP, first_crossing
from manifold.steppers import DenseStepper, Step, StepperFailure, locate_events

from .sphere_family import great_circle, sphere_metric, sphere_start

EPS = np.finfo(float).eps


def _crossing(directions, g, dg, t0, t1):
    """:func:`first_crossing` for the events ``g(t)`` (values at a time) with rates ``dg(t)``."""
    return first_crossing(np.array(directions), g, t0, t1, (g(t0), dg(t0)), (g(t1), dg(t1)))


# --- the locator on known functions -------------------------------------------------------------------------------


@settings(max_examples=200, deadline=None)
@given(t0=st.floats(-50, 50), width=st.floats(1e-3, 2.0), backward=st.booleans(), where=st.floats(0.02, 0.98),
       rate=st.floats(1e-3, 1e3))
def test_a_crossing_is_found_in_its_direction_along_the_motion(t0, width, backward, where, rate):
    sense = -1.0 if backward else 1.0
    t1 = t0 + sense * width
    root = t0 + sense * width * where
    # g falls along the motion in either time order: dg/dt has the sign opposite to the motion's
    g = lambda t: np.array([-sense * rate * (t - root)])  # noqa: E731
    dg = lambda t: np.array([-sense * rate])  # noqa: E731
    for direction in (FALLING, EITHER):
        index, t = _crossing([direction], g, dg, t0, t1)
        assert index == 0
        assert abs(t - root) <= 8 * EPS * max(abs(t0), abs(t1))
    assert _crossing([RISING], g, dg, t0, t1) is None


def test_an_event_exactly_at_a_step_end_fires_there():
    g = lambda t: np.array([0.75 - t])  # noqa: E731  (0.75 exact)
    dg = lambda t: np.array([-1.0])  # noqa: E731
    assert _crossing([FALLING], g, dg, 0.5, 0.75) == (0, 0.75)
    assert _crossing([FALLING], g, dg, 0.25, 0.5) is None  # before it: nothing
    # backward, landing on it from the other side: g rises along that motion
    assert _crossing([RISING], g, dg, 1.0, 0.75) == (0, 0.75)


def test_a_segment_starting_on_the_event_and_crossing_it_fires_at_once():
    """A start exactly on the surface, heading across (a periodic angle at exactly -pi moving down), fires at the
    start: the loop acts on it (a wrap) rather than run on past it; heading away, nothing fires."""
    g = lambda t: np.array([-t])  # noqa: E731
    dg = lambda t: np.array([-1.0])  # noqa: E731
    assert _crossing([FALLING], g, dg, 0.0, 0.1) == (0, 0.0)
    assert _crossing([RISING], g, dg, 0.0, 0.1) is None


def test_a_dip_through_zero_and_back_inside_one_step_is_found():
    """Grazing: ``g`` is positive at both ends of the step; a sign test alone would miss the two crossings."""
    depth = 1e-6
    g = lambda t: np.array([(t - 0.5) ** 2 - depth])  # noqa: E731
    dg = lambda t: np.array([2 * (t - 0.5)])  # noqa: E731
    index, t = _crossing([FALLING], g, dg, 0.0, 1.0)
    assert index == 0 and abs(t - (0.5 - np.sqrt(depth))) <= 1e-12
    index, t = _crossing([FALLING], g, dg, 1.0, 0.0)  # backward: the other crossing comes first
    assert index == 0 and abs(t - (0.5 + np.sqrt(depth))) <= 1e-12
    assert _crossing([RISING], g, dg, 0.0, 1.0) is None  # it rises back across zero only after falling


def test_a_near_miss_does_not_fire():
    g = lambda t: np.array([(t - 0.5) ** 2 + 1e-9])  # noqa: E731
    dg = lambda t: np.array([2 * (t - 0.5)])  # noqa: E731
    assert _crossing([FALLING], g, dg, 0.0, 1.0) is None


def test_the_earliest_event_along_the_motion_wins():
    g = lambda t: np.array([0.7 - t, t - 0.3, 0.3 - t])  # noqa: E731  (0.3 is crossed rising and falling)
    dg = lambda t: np.array([-1.0, 1.0, -1.0])  # noqa: E731
    assert _crossing([FALLING, RISING, FALLING], g, dg, 0.0, 1.0) == (1, pytest.approx(0.3, abs=1e-15))
    assert _crossing([RISING, FALLING, RISING], g, dg, 1.0, 0.0) == (0, pytest.approx(0.7, abs=1e-15))  # backward
    assert _crossing([RISING, FALLING, RISING], g, dg, 0.0, 1.0) is None  # forward, none of them in its direction


# --- the family's declared events ---------------------------------------------------------------------------------


def test_the_declared_events_are_the_switches_then_two_wraps_per_periodic_parameter():
    """The locator's events; heyoka's integrators declare the switches alone (they wrap between steps)."""
    chain = Chain(4, 2.9)
    family = compiled(chain.atlas().charts[0].family)
    events = family.events()
    n_q, periodic = family.n_quality, family.family.periodic
    assert n_q >= 1 and len(periodic) == 1 and len(events) == n_q + 2
    assert all(e.kind == SWITCH and e.direction == FALLING for e in events[:n_q])
    up, down = events[n_q:]
    assert (up.kind, up.direction, up.parameter, up.shift) == (WRAP, RISING, periodic[0], -1)
    assert (down.kind, down.direction, down.parameter, down.shift) == (WRAP, FALLING, periodic[0], 1)
    assert family.events(wraps=False) == events[:n_q]
    with family.integrator(float) as ta:
        assert len(ta.t_events) == n_q


# --- both ways of locating events on real geodesics ----------------------------------------------------------------


def _switch_log(sol):
    return [(s.from_chart, s.to_chart) for s in sol.switches], np.array([s.time for s in sol.switches])



@pytest.mark.parametrize("T", [20.0, -20.0])
def test_sphere_switches_agree_between_the_taylor_and_the_scipy_stepper(T):
    metric = sphere_metric()
    p0, v0 = sphere_start()
    taylor = solve_chart_exp_ode(metric, p0, v0, T)
    scipy_run = solve_chart_exp_ode(metric, p0, v0, T, stepper=ScipyStepper("DOP853", 1e-12, 1e-12))
    charts, times = _switch_log(taylor)
    assert len(charts) >= 8 and _switch_log(scipy_run)[0] == charts
    assert np.abs(_switch_log(scipy_run)[1] - times).max() <= 1e-10
    # and both where the geometry puts them: the great circle at height 1 - 2 q_out in the left chart's frame
    q_out = metric.atlas.switch_threshold
    for sol in (taylor, scipy_run):
        for s in sol.switches:
            height = (metric.atlas.charts[s.from_chart].linear_map @ great_circle(p0, v0, s.time))[2]
            assert abs(height - (1 - 2 * q_out)) <= 1e-10


@pytest.mark.parametrize("T, c", [(8.0, [1.0, 0.2]), (-8.0, [-1.0, -0.2])])
def test_chain_switches_and_wraps_agree_between_the_taylor_and_the_scipy_stepper(T, c):
    chain = Chain(4, 2.9)
    a = [1.2, 0.3]  # chart 0 heading for its pole (a switch at |t| = 0.11), then wraps of the circle angle
    taylor = solve_chart_exp_ode(chain.metric(), a, c, T, chart=0)
    scipy_run = solve_chart_exp_ode(chain.metric(), a, c, T, chart=0, stepper=ScipyStepper("DOP853", 1e-12, 1e-12))
    assert taylor.n_switches >= 1 and taylor.stats.n_wraps >= 2
    assert _switch_log(scipy_run)[0] == _switch_log(taylor)[0]
    assert np.abs(_switch_log(scipy_run)[1] - _switch_log(taylor)[1]).max() <= 1e-10
    # the locator ends a segment at each wrap; heyoka's stepper wraps between steps, in the same chart
    assert scipy_run.stats.n_wraps == taylor.stats.n_wraps
    assert len(scipy_run.segments) == len(taylor.segments) + scipy_run.stats.n_wraps
    switch_times = {s.time for s in scipy_run.switches}
    wraps = [float(s.t_end) for s in scipy_run.segments[:-1] if float(s.t_end) not in switch_times]
    assert len(wraps) == scipy_run.stats.n_wraps
    periodic = compiled(chain.atlas().charts[0].family).family.periodic[0]
    for t in wraps:  # there the Taylor run's circle angle is at +-pi
        _, a, _ = taylor.parameters(t)
        assert abs(abs(a[periodic]) - np.pi) <= 1e-9


def _grazing_start(delta):
    """North chart at ``p0 = (1, 0, 0)``, unit velocity ``(0, cos b, sin b)`` with ``sin b = 1/2 + delta``: the great
    circle's height ``sin b sin t`` peaks at ``t = pi/2``, just above (``delta > 0``) or below the switch height 1/2."""
    s = 0.5 + delta
    return np.array([1.0, 0.0]), np.array([s, np.sqrt(1 - s * s)]), s  # chart coefficients: J(1, 0) = [e_z, e_y]


@pytest.mark.parametrize("stepper", [TaylorStepper(), ScipyStepper("DOP853", 1e-12, 1e-12)], ids=["taylor", "scipy"])
def test_a_grazing_switch_is_taken_at_its_first_crossing(stepper):
    metric = sphere_metric()
    a, c, s = _grazing_start(1e-6)
    assert metric.atlas.switch_threshold == 0.25  # the switch height 1 - 2 q_out = 1/2
    first, second = np.arcsin(0.5 / s), np.pi - np.arcsin(0.5 / s)  # 4e-3 apart
    sol = solve_chart_exp_ode(metric, a, c, 3.0, chart=0, stepper=stepper)
    assert sol.switches and (sol.switches[0].from_chart, sol.switches[0].to_chart) == (0, 1)
    assert abs(sol.switches[0].time - first) <= 1e-9
    if isinstance(stepper, ScipyStepper):  # the test tests a dip: one step holds both crossings
        ends = np.array(solve_chart_exp_ode(metric, a, c, 3.0, chart=0, stepper=stepper, switching=False).energy_times,
                        dtype=float)
        k = int(np.searchsorted(ends, first))
        assert ends[k] > second, "a step end falls between the crossings: the dip is not inside one step"


@pytest.mark.parametrize("stepper", [TaylorStepper(), ScipyStepper("DOP853", 1e-12, 1e-12)], ids=["taylor", "scipy"])
def test_a_near_miss_takes_no_switch(stepper):
    a, c, _ = _grazing_start(-1e-6)
    sol = solve_chart_exp_ode(sphere_metric(), a, c, 3.0, chart=0, stepper=stepper)
    assert sol.success and sol.n_switches == 0


def test_an_event_exactly_at_a_step_end_of_the_scipy_stepper():
    """``q_out`` set to the quality at the end of a step: the switch event is ``0`` there to the last bit, and fires
    at that step's end, not one step later, with the state of the step itself."""
    metric = sphere_metric()
    family = compiled(metric.atlas.charts[0].family)
    a, c, _ = _grazing_start(0.2)
    y0 = np.concatenate([a, c])
    values, directions = family.event_values(float), np.array([e.direction for e in family.events()])
    stepper = ScipyStepper("DOP853", 1e-12, 1e-12)
    with stepper.stepping(family, form="embedded", backward=False) as steps:
        pars = metric.atlas.charts[0].numerics(metric.K, 0.0).pars  # q_out = 0: the event's value is the quality
        taken = list(steps(0.0, y0, 1.5, pars))
        quality = np.array([values(s.y, pars=pars[: values.nparams])[0] for s in taken])
        j = int(np.argmax(quality < 0.3))  # the quality falls along this start
        assert j >= 2 and np.all(np.diff(quality[: j + 1]) < 0)
        pars = metric.atlas.charts[0].numerics(metric.K, float(quality[j])).pars

        def at(y):
            return values(np.ascontiguousarray(y), pars=pars[: values.nparams])

        assert at(taken[j].y)[0] == 0.0
        adv = locate_events(steps(0.0, y0, 1.5, pars), 0.0, y0, at, directions, True)
    assert adv.event == 0 and adv.t == taken[j].t and adv.n_steps == j + 1
    assert np.array_equal(adv.y, taken[j].y)
    assert np.array_equal(adv.step_times, [s.t for s in taken[: j + 1]])


# --- a new stepper only steps -------------------------------------------------------------------------------------


class RungeKutta4(DenseStepper):
    """Classical Runge-Kutta with a fixed step and cubic Hermite dense output: all a stepper has to write."""

    name = "rk4"

    def __init__(self, h: float) -> None:
        self.h = h

    def relative_tolerance(self, fp_type: Any) -> float:
        return self.h**4

    @contextmanager
    def stepping(self, family, *, form, backward) -> Iterator[Any]:
        k = family.family.dim
        acc = family.acceleration(float, form)

        def steps(t, y, t_final, pars):
            def f(y):
                return np.concatenate([y[k:], acc(np.ascontiguousarray(y), pars=pars[: acc.nparams])])

            while t != t_final:
                h = float(np.sign(t_final - t)) * min(self.h, abs(t_final - t))
                k1 = f(y)
                k2 = f(y + h / 2 * k1)
                k3 = f(y + h / 2 * k2)
                k4 = f(y + h * k3)
                y1 = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
                t1 = t_final if abs(t_final - t) <= self.h else t + h
                yield Step(t, t1, y1, _hermite(t, y, k1, h, y1, f(y1)))
                t, y = t1, y1

        yield steps


def _hermite(t0, y0, f0, h, y1, f1):
    """The cubic Hermite interpolant of a step, called like scipy's ``DenseOutput``."""
    def interpolant(t):
        s = (np.asarray(t, dtype=float) - t0) / h
        s = s[None, :] if s.ndim else s
        y0_, y1_, f0_, f1_ = (x[:, None] if np.ndim(s) else x for x in (y0, y1, f0, f1))
        return ((2 * s**3 - 3 * s**2 + 1) * y0_ + (s**3 - 2 * s**2 + s) * h * f0_ + (-2 * s**3 + 3 * s**2) * y1_
                + (s**3 - s**2) * h * f1_)
    return interpolant


@pytest.mark.parametrize("T", [10.0, -10.0])
def test_a_stepper_that_only_steps_takes_the_same_switches(T):
    metric = sphere_metric()
    p0, v0 = sphere_start()
    taylor = solve_chart_exp_ode(metric, p0, v0, T)
    rk4 = solve_chart_exp_ode(metric, p0, v0, T, stepper=RungeKutta4(2e-3))
    assert rk4.n_switches >= 4 and _switch_log(rk4)[0] == _switch_log(taylor)[0]
    assert np.abs(_switch_log(rk4)[1] - _switch_log(taylor)[1]).max() <= 1e-8
    ts = np.linspace(0, T, 101)
    assert np.abs(rk4(ts)[0] - great_circle(p0, v0, ts)).max() <= 1e-8  # dense output across the switches


class BreaksDown(RungeKutta4):
    """Fails after a few steps, as a stepper may (a step size underflow, a Newton failure)."""

    @contextmanager
    def stepping(self, family, *, form, backward) -> Iterator[Any]:
        with super().stepping(family, form=form, backward=backward) as steps:
            def failing(t, y, t_final, pars):
                for n, step in enumerate(steps(t, y, t_final, pars)):
                    if n == 3:
                        raise StepperFailure(f"no step from t = {step.t_old}")
                    yield step

            yield failing


def test_a_stepper_that_breaks_down_ends_the_solve_with_its_reason():
    metric = sphere_metric()
    p0, v0 = sphere_start()
    sol = solve_chart_exp_ode(metric, p0, v0, 1.0, stepper=BreaksDown(1e-2), throw=False)
    assert sol.status is SolveStatus.STEPPER_FAILED and "no step from t = 0.03" in sol.message
    assert float(sol.t_reached) == pytest.approx(0.03, abs=1e-15)  # the three steps taken are kept
