"""Equation terms (``manifold.terms``): a compiled integrator is the composition of its terms, keyed by them.

A term written here, outside the library (a constant rescaling of time, ``dt = lambda dtau``), composes with the
chart geodesic without touching ``manifold``: the rescaled run reaches at ``tau = T / lambda`` the state that the
plain run reaches at ``T``, and its parameter sits where the composition puts it.
"""

from __future__ import annotations

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import compiled, solve_chart_exp_ode
from manifold.ambient_velocity import ChartCarried, ConstrainedVelocity
from manifold.carried import CarriedSolution, CarriedTerm, solve_carried
from manifold.constrained import ConstrainedGeometry
from manifold.jacobi import JacobiField
from manifold.events import EITHER, RISING, STOP, Event
from manifold.solution import SolveStatus
from manifold.steppers import TaylorStepper
from manifold.sundman import SundmanStepper, SundmanTime
from manifold.precision import as_fp
from manifold.terms import ChartGeodesic, Term
from manifold.transport import ParallelTransport

from .conftest import unit_speed_start
from .sphere_family import great_circle, sphere_metric, sphere_start


class ScaledTime(Term):
    """``dy/dtau = lambda dy/dt`` with ``lambda = par[offset]``, and an event where ``tau``'s clock ``w`` reaches 1."""

    key = "scaled-time"
    n_params = 1

    def equations(self, pieces, equations, offset):
        w = hy.expression("clock")
        return [(lhs, hy.par[offset] * rhs) for lhs, rhs in equations] + [(w, hy.expression(1.0))]

    def events(self, equations, offset):
        return [Event(equations[-1][0] - 1.0, RISING, "stop")]



def _sphere_state():
    metric = sphere_metric()
    numerics = metric.atlas.charts[0].numerics(metric.K, metric.atlas.switch_threshold)
    return compiled(metric.atlas.charts[0].family), numerics.pars, np.array([0.3, -0.2, 0.4, 0.1])  # (a, c)


def test_a_term_written_outside_the_library_composes_with_the_geodesic():
    family, pars, y0 = _sphere_state()
    T, lam = 0.6, 2.5  # short of the chart's switch event and of the clock's
    with family.integrator(float) as plain:
        plain.state[:], plain.time, plain.pars[:] = y0, 0.0, pars[: len(plain.pars)]
        assert plain.propagate_until(T)[0] == hy.taylor_outcome.time_limit
        end = np.array(plain.state)
    with family.integrator(float, terms=(ChartGeodesic(), ScaledTime())) as scaled:
        assert len(scaled.pars) == family.layout.terms_index + 1  # its parameter right after the chart's
        assert len(scaled.t_events) == len(family.events(wraps=False)) + 1  # its event after the family's
        scaled.state[:], scaled.time = np.append(y0, 0.0), 0.0
        scaled.pars[:] = np.append(pars, lam)
        assert scaled.propagate_until(T / lam)[0] == hy.taylor_outcome.time_limit
        assert np.abs(scaled.state[:-1] - end).max() <= 1e-13
        assert abs(scaled.state[-1] - T / lam) <= 1e-15
        scaled.state[:], scaled.time = np.append(y0, 0.0), 0.0
        scaled.pars[-1] = 0.5  # tau = 1 is t = 0.5, before the switch
        outcome = scaled.propagate_until(10.0)[0]  # its stop event: the clock reaches 1 at tau = 1
        assert outcome == hy.taylor_outcome(-len(family.events(wraps=False)) - 1) and abs(scaled.time - 1.0) <= 1e-14


def test_integrators_are_keyed_by_the_composition():
    family, _, _ = _sphere_state()
    with family.integrator(float, terms=(ChartGeodesic(),)) as a:
        first = id(a)
    with family.integrator(float) as b:  # the default composition is the same
        assert id(b) == first
    with family.integrator(float, terms=(ChartGeodesic("christoffel"),)) as c:
        assert id(c) != first


def test_the_parameters_follow_the_terms_in_order():
    chain = Chain(4, 2.9)
    family = compiled(chain.atlas().charts[0].family)
    velocity, factor = ConstrainedVelocity(ChainSystem(chain)), ChainTimeFactor(chain)
    with family.integrator(float, terms=(velocity, SundmanTime(factor))) as ta:
        assert len(ta.pars) == family.layout.terms_index + velocity.n_params + 1 + factor.n_params


@pytest.mark.parametrize("terms", [(SundmanTime(ChainTimeFactor(Chain(4, 2.9))),), (ChartGeodesic(), ChartGeodesic()),
                                   ("embedded",), ()])
def test_a_composition_without_one_state_term_first_is_refused(terms):
    family, _, _ = _sphere_state()
    with pytest.raises(TypeError, match="terms must be a manifold.terms.StateTerm followed by other Terms"):
        with family.integrator(float, terms=terms):
            pass


def test_a_bad_form_is_refused_by_name():
    with pytest.raises(ValueError, match="form must be one of"):
        ChartGeodesic("hamiltonian")


class Deadline(Term):
    """Ends the motion at the time ``at``: one parameter, whose value the term gives itself at every segment's start,
    and a stop event ``t - par[offset]`` (either direction: forward and backward runs)."""

    n_params = 1

    def __init__(self, at):
        self.at = at
        self.asked = 0

    @property
    def key(self):
        return "deadline"

    def equations(self, pieces, equations, offset):
        return equations

    def events(self, equations, offset):
        return [Event(hy.time - hy.par[offset], EITHER, STOP)]

    def parameter_values(self, segment):
        self.asked += 1
        return np.array([self.at], dtype=segment.y.dtype)


@pytest.mark.parametrize("T, at", [(20.0, 7.3), (-20.0, -7.3)])
def test_a_term_gives_its_parameter_values_and_the_loop_acts_on_its_stop_event(T, at):
    """No stepper of its own: the Taylor stepper asks the term for its parameter at every segment (chart switches
    before the deadline), and the loop ends the solve at its stop event, where the great circle is."""
    metric = sphere_metric()
    p0, v0 = sphere_start()
    deadline = Deadline(at)
    sol = solve_chart_exp_ode(metric, p0, v0, T, stepper=TaylorStepper(terms=(deadline,)))
    assert sol.status is SolveStatus.SUCCESS and sol.message.startswith("stopped at t = ")
    assert sol.n_switches >= 2 and deadline.asked == len(sol.segments) == sol.n_switches + 1
    assert float(sol.segments[-1].t_end) == pytest.approx(at, abs=1e-14)
    p_end, _ = sol.end_state()
    assert np.abs(p_end - great_circle(p0, v0, at)).max() <= 1e-11
    plain = solve_chart_exp_ode(metric, p0, v0, T)  # the same motion up to there
    assert [s.to_chart for s in sol.switches] == [s.to_chart for s in plain.switches[: sol.n_switches]]
    assert np.allclose([s.time for s in sol.switches], [s.time for s in plain.switches[: sol.n_switches]],
                       rtol=0, atol=1e-12)


def test_a_term_whose_values_miss_its_declared_parameters_is_refused_by_name():
    class Short(Deadline):
        def parameter_values(self, segment):
            return np.zeros(0)

    metric = sphere_metric()
    p0, v0 = sphere_start()
    with pytest.raises(ValueError, match=r"declares n_params = 1 but its parameter_values gave 0"):
        solve_chart_exp_ode(metric, p0, v0, 1.0, stepper=TaylorStepper(terms=(Short(0.5),)))


def test_sundman_time_is_a_term_of_the_taylor_stepper_and_its_stop_an_event_of_the_composition():
    """SundmanStepper is the Taylor stepper with SundmanTime composed: the same solve bitwise; the loop ends it at
    Sundman's stop event, the composition's last, exactly at t_final."""
    chain = Chain(4, 2.9)
    factor = ChainTimeFactor(chain)
    family = compiled(chain.atlas().charts[0].family)
    stepper = SundmanStepper(factor)
    events = stepper.events(family, float, "embedded")
    assert events[:-1] == family.events(wraps=False) and events[-1].kind == STOP  # wrapped between steps
    a, c = [1.2, 0.3], [1.0, 0.2]  # a switch at t = 0.11, then wraps
    composed = solve_chart_exp_ode(chain.metric(), a, c, 6.0, chart=0, stepper=TaylorStepper(terms=(SundmanTime(factor),)))
    sundman = solve_chart_exp_ode(chain.metric(), a, c, 6.0, chart=0, stepper=stepper)
    assert sundman.n_switches >= 1 and sundman.message == composed.message == "reached t_final"
    assert float(sundman.segments[-1].t_end) == 6.0
    assert [s.n_steps for s in composed.segments] == [s.n_steps for s in sundman.segments]
    for x, y in zip(composed.final_state[1:], sundman.final_state[1:]):
        assert np.array_equal(x, y)


def test_more_than_one_clock_and_a_state_term_among_the_terms_are_refused():
    factor = ChainTimeFactor(Chain(4, 2.9))
    with pytest.raises(ValueError, match="at most one Clock"):
        TaylorStepper(terms=(SundmanTime(factor), SundmanTime(factor)))
    with pytest.raises(TypeError, match="terms must hold manifold.terms.Term objects that are not state terms"):
        TaylorStepper(terms=(ChartGeodesic(),))


class ParallelVector(CarriedTerm):
    """One tangent vector transported along the geodesic, written here as a new kind of carried quantity: its
    equations ``W' = -K^-1 G^T M^-1 ((dG/dt) W + alpha G W)`` on the system's pieces, its K-norm the invariant."""

    name = "a parallel vector"

    def __init__(self, vector):
        self.vector = np.asarray(vector, dtype=float)

    key = "parallel vector"

    def size(self, N):
        return N

    def equations(self, pieces, y, stabilised):
        turn = pieces.bilinear(y)
        if stabilised:
            turn = [h + hy.par[0] * gw for h, gw in zip(turn, pieces.rates(y))]
        return pieces.correction([-r for r in turn])

    def start(self, geometry, x, v):
        return geometry.tangent(x[None, :], as_fp(self.vector[None, :], geometry.fp))[0]

    def invariants(self, geometry, x, v, y):
        norm2 = np.einsum("bi,ij,bj->b", y, geometry.K, y)[:, None]
        return norm2, np.abs(norm2.astype(float))

    def read(self, geometry, x, v, y):
        return {"vector": y}


def test_a_carried_quantity_written_outside_the_library_is_a_term_of_the_chart_path():
    """Composed after the state (a, J c) and before Sundman's time, through chart switches, with no file of manifold/
    touched: transporting the geodesic's own velocity gives the velocity, and another vector agrees with the
    transport in hinge coordinates (the constraint equations, no charts) and keeps its length."""
    chain, T = Chain(4, 2.9), 6.0
    system, chart = ChainSystem(chain), chain.metric().atlas.charts[0]
    a, c = np.array([1.2, 0.3]), np.array([1.0, 0.2])  # chart 0 heading for its pole: a switch at t = 0.11, wraps
    x0, v0, wx = chart.get_point(a), chart.tangent_vector(a, c), chart.tangent_vector(a, np.array([-0.4, 0.9]))
    velocity = ConstrainedVelocity(system)
    terms = (ChartCarried(ParallelVector(v0), velocity), ChartCarried(ParallelVector(wx), velocity))
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=velocity, terms=terms)
    sol = solve_chart_exp_ode(chain.metric(), a, c, T, chart=0, stepper=stepper)
    assert sol.n_switches >= 1 and sol.stats.n_wraps >= 1
    carried = CarriedSolution(sol, tuple(t.term for t in terms), ConstrainedGeometry(system, float))
    assert carried.violation(stepper.relative_tolerance(float)) is None
    ts = np.linspace(0.0, T, 25)
    x, v, (own, other) = carried(ts)
    assert np.abs(own["vector"] - v).max() <= 1e-11
    hinges = solve_carried(system, x0, v0, T, [ParallelTransport(wx)])
    _, _, (reference,) = hinges(ts)
    assert np.abs(other["vector"] - reference["vectors"][:, 0]).max() <= 1e-10
    norms = np.einsum("bi,ij,bj->b", other["vector"], system.metric_matrix, other["vector"])
    assert np.abs(norms - norms[0]).max() <= 1e-13 * norms[0]


def test_a_carried_term_refuses_a_state_of_another_system():
    velocity = ConstrainedVelocity(ChainSystem(Chain(4, 2.9)))
    other = ConstrainedVelocity(ChainSystem(Chain(4, 2.8)))
    stepper = TaylorStepper(velocity=other, terms=(ChartCarried(ParallelVector(np.zeros(6)), velocity),))
    h0, u0 = unit_speed_start(Chain(4, 2.8), [0.2, 0.3], [1.0, 0.2])
    with pytest.raises(ValueError, match=r"rides on the state \(a, V\) of ConstrainedVelocity"):
        free_motion(Chain(4, 2.8), h0, u0, 1.0, method="charts", stepper=stepper)


def test_a_start_at_rest_is_integrated_when_a_term_moves_at_rest():
    """At rest the geodesic is its start and a Jacobi field is ``J(0) + t D_t J(0)`` (no curvature term: ``v = 0``).
    The loop asks the stepper's terms whether anything moves at rest: the carried field does, so the solve integrates
    it; without it the start is the solution, with no step."""
    chain, T = Chain(4, 2.9), 2.5
    system, chart = ChainSystem(chain), chain.metric().atlas.charts[0]
    a = np.array([0.4, -0.3])
    x0, j0, w0 = chart.get_point(a), chart.tangent_vector(a, np.array([0.3, 0.1])), chart.tangent_vector(a, [-0.2, 0.5])
    velocity = ConstrainedVelocity(system)
    field = ChartCarried(JacobiField(j0, w0), velocity)
    still = solve_chart_exp_ode(chain.metric(), x0, np.zeros_like(x0), T, stepper=TaylorStepper(velocity=velocity))
    assert still.n_steps == 0
    moving = solve_chart_exp_ode(chain.metric(), x0, np.zeros_like(x0), T,
                                 stepper=TaylorStepper(velocity=velocity, terms=(field,)))
    assert moving.n_steps > 0
    carried = CarriedSolution(moving, (field.term,), ConstrainedGeometry(system, float))
    x, _, (values,) = carried(np.array([0.0, 1.0, T]))
    assert np.abs(x - x0).max() <= 1e-15  # the chart map's rounding of the start only
    expected = j0 + np.array([0.0, 1.0, T])[:, None] * w0
    assert np.abs(values["field"][:, 0] - expected).max() <= 1e-13
