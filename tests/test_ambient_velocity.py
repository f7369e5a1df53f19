"""The chart path with the ambient velocity as state (:mod:`manifold.ambient_velocity`).

Changing the state from ``(a, c)`` to ``(a, J c)``, with the acceleration from the
rod constraints instead of the chart's second derivatives, must not change the
motion: the same geodesic, switches and energy as the embedded form, in ``t`` and
in Sundman's time, for every mass model, chains of any lengths (charts whose base
is a link), backward, and in real128.
"""

from __future__ import annotations

import pickle

import heyoka as hy
import numpy as np
import pytest

from charts.suspension_symbolic import SuspensionFamily
from linkage import Chain
from linkage.constraints import ChainSystem, HingeConstraints
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import Precision, solve_chart_exp_ode
from manifold.ambient_velocity import DEFAULT_RATE, ConstrainedVelocity
from manifold.compiled import Transfer, compiled
from manifold.constrained import damping_rate, speed_scale
from manifold.steppers import TaylorStepper
from manifold.sundman import SundmanStepper
from manifold.terms import SegmentStart
from manifold.weighted_velocity import WeightedVelocity

from .conftest import assert_same_motion, atlas_start, unit_speed_start



@pytest.mark.parametrize("sundman", [False, True])
@pytest.mark.parametrize("lengths, L, masses, densities, T", [
    (3, 1.6, 1.0, 0.0, 12.0), (4, 2.7, 1.0, 0.0, 15.0), (4, 3.5, [0.1, 1.0, 10.0], 0.0, -12.0),
    (5, 3.2, [0.3, 2.0, 1.0, 0.5], 0.0, 10.0), (5, 3.4, 1.0, 0.2, 10.0), (6, 4.9, 1.0, 0.0, 8.0),
    ((1.0, 2.0, 1.5, 2.5, 1.2), 7.0, 1.0, 0.0, 10.0),  # L dominant, chains of any lengths
    ((3.0, 1.0, 1.2, 0.9), 0.3, [1.0, 0.5, 2.0], 0.0, 10.0),  # the link l_1 dominant: charts on a link base
])
def test_the_ambient_velocity_gives_the_same_motion_switches_and_energy(lengths, L, masses, densities, T, sundman):
    chain = Chain(lengths, L, hinge_masses=masses, rod_densities=densities)
    p0, v0 = atlas_start(chain, chain.n)
    factor = [ChainTimeFactor(chain)] if sundman else []
    kind = SundmanStepper if sundman else TaylorStepper
    plain = solve_chart_exp_ode(chain.metric(), p0, v0, T, stepper=kind(*factor))
    ambient = solve_chart_exp_ode(chain.metric(), p0, v0, T,
                                  stepper=kind(*factor, velocity=ConstrainedVelocity(ChainSystem(chain))))
    assert_same_motion(ambient, plain, T)
    ts = np.linspace(0.0, T, 51)
    assert np.max(np.abs(ambient(ts)[1] - plain(ts)[1])) <= 1e-10
    assert np.max(np.abs(ambient.end_state()[1] - plain.end_state()[1])) <= 1e-10
    i, a, c = ambient.parameters(T / 3)  # chart coordinates on demand, as (a, c)
    assert (i, *np.round([a, c], 9).ravel()) == (plain.parameters(T / 3)[0], *np.round(plain.parameters(T / 3)[1:], 9).ravel())


def test_free_motion_closes_and_agrees_with_the_hinge_method():
    """Through the chain API, backward and forward: closure along the run, and the hinge method's motion."""
    chain = Chain(5, 3.3, hinge_masses=[1.0, 0.4, 2.0, 1.0])
    h0, v0 = unit_speed_start(chain, [0.3, -0.5, 1.1], [0.4, 1.0, -0.7])
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=ConstrainedVelocity(ChainSystem(chain)))
    for T in (10.0, -10.0):
        charts = free_motion(chain, h0, v0, T, stepper=stepper)
        hinges = free_motion(chain, h0, v0, T, method="hinges")
        ts = np.linspace(0.0, T, 21)
        assert np.max(np.abs(charts(ts)[0] - hinges(ts)[0])) <= 1e-10
        assert charts.closure_residuals.max() <= 1e-13
        assert charts.relative_energy_error <= 1e-13


def test_real128_agrees_with_the_embedded_form_to_its_precision():
    chain = Chain(4, 2.6)
    h0, v0 = unit_speed_start(chain, [0.4, -0.3], [0.7, 0.5])
    p0, w0 = chain.to_point(h0), chain.to_point(v0)
    factor = ChainTimeFactor(chain)
    plain = solve_chart_exp_ode(chain.metric(), p0, w0, 1.5, precision=Precision(fp_type=hy.real128),
                                stepper=SundmanStepper(factor))
    ambient = solve_chart_exp_ode(chain.metric(), p0, w0, 1.5, precision=Precision(fp_type=hy.real128),
                                  stepper=SundmanStepper(factor, velocity=ConstrainedVelocity(ChainSystem(chain))))
    ts = np.linspace(0.0, 1.5, 7)
    assert float(np.max(np.abs(ambient(ts)[0] - plain(ts)[0]))) <= 1e-31
    assert float(np.max(np.abs(ambient(ts)[1] - plain(ts)[1]))) <= 1e-31
    E = ambient.energies
    assert max(abs(float(e / E[0] - 1)) for e in E) <= 1e-31


def test_a_bad_velocity_is_refused_by_name():
    for bad in ("hinges", ConstrainedVelocity):
        with pytest.raises(TypeError, match="velocity must be None or a manifold.ambient_velocity.ConstrainedVelocity"):
            TaylorStepper(velocity=bad)
    with pytest.raises(TypeError, match="system must be a manifold.constrained.ConstrainedSystem"):
        ConstrainedVelocity(Chain(4, 2.5))  # type: ignore[arg-type]
    chain = Chain(4, 2.5)
    p0, v0 = atlas_start(chain, 1)
    other = ConstrainedVelocity(ChainSystem(Chain(5, 3.5)))
    with pytest.raises(ValueError, match=r"velocity: the constraint system lives in R\^8, the charts .* in R\^6"):
        solve_chart_exp_ode(chain.metric(), p0, v0, 1.0, stepper=TaylorStepper(velocity=other))
    own = TaylorStepper(velocity=ConstrainedVelocity(ChainSystem(chain)))
    with pytest.raises(ValueError, match="form='christoffel' is a form of the state \\(a, c\\)"):
        solve_chart_exp_ode(chain.metric(), p0, v0, 1.0, stepper=own, form="christoffel")


def test_the_stepper_pickles_and_the_solution_names_its_state():
    """Ensembles send steppers to other processes; the solution's ``method`` says which state was integrated."""
    chain = Chain(4, 2.5)
    p0, v0 = atlas_start(chain, 3)
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=ConstrainedVelocity(ChainSystem(chain), rate=3.0,
                                                                                   solve="jets", conserving=True))
    copy = pickle.loads(pickle.dumps(stepper))
    assert copy.velocity.rate == 3.0 and copy.velocity.solve == "jets" and copy.velocity.conserving
    first = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, stepper=stepper)
    again = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, stepper=copy)
    assert np.array_equal(first.end_state()[1], again.end_state()[1])
    assert first.method == "taylor-sundman (a, J c)"
    assert solve_chart_exp_ode(chain.metric(), p0, v0, 2.0).method == "taylor"


@pytest.mark.parametrize("densities, ambient", [(0.0, True), (0.2, False)])
def test_free_motion_uses_the_ambient_velocity_by_default_except_with_rod_densities(densities, ambient):
    """The default chart stepper is Sundman's time with the state ``(a, J c)``; with rod densities (generic multiplier
    pivots: digits lost near the top of the range) and with a ``form`` asked for, the state ``(a, c)``."""
    chain = Chain(4, 2.7, hinge_masses=[1.0, 0.5, 2.0], rod_densities=densities)
    h0, v0 = unit_speed_start(chain, [0.2, 0.3], [0.5, -0.9])
    velocity = ConstrainedVelocity(ChainSystem(chain))
    default = free_motion(chain, h0, v0, 3.0, method="charts")
    explicit = {state: free_motion(chain, h0, v0, 3.0, stepper=SundmanStepper(ChainTimeFactor(chain), velocity=vel))
                for state, vel in (("(a, J c)", velocity), ("(a, c)", None))}
    chosen = "(a, J c)" if ambient else "(a, c)"
    other = "(a, c)" if ambient else "(a, J c)"
    assert np.array_equal(default(3.0)[1], explicit[chosen](3.0)[1])
    assert not np.array_equal(default(3.0)[1], explicit[other](3.0)[1])
    embedded = free_motion(chain, h0, v0, 3.0, form="embedded")
    assert np.array_equal(embedded(3.0)[1], explicit["(a, c)"](3.0)[1])


def test_unrolled_chart_code_integrates_the_same_motion_as_the_compact_default():
    """``compact_mode=False`` (straight-line code, for long runs) and the default compact code of the chart path
    solve the same motion through a chart switch; ``free_motion``'s option builds the stepper a user would write."""
    chain = Chain(4, 2.7)
    h0, v0 = unit_speed_start(chain, [1.45, 0.3], [1.0, 0.2])
    default = free_motion(chain, h0, v0, 8.0, method="charts")
    unrolled = free_motion(chain, h0, v0, 8.0, method="charts", compact_mode=False)
    written = free_motion(chain, h0, v0, 8.0, method="charts", stepper=SundmanStepper(
        ChainTimeFactor(chain), compact_mode=False, velocity=ConstrainedVelocity(ChainSystem(chain))))
    assert default.solution.n_switches >= 1
    assert_same_motion(unrolled.solution, default.solution, 8.0)
    assert np.array_equal(unrolled(8.0)[1], written(8.0)[1])


def test_a_compile_option_beside_a_stepper_is_refused():
    """A stepper given holds its own compile options: ``compact_mode`` beside it would be silently ignored."""
    chain = Chain(4, 2.7)
    h0, v0 = unit_speed_start(chain, [1.45, 0.3], [1.0, 0.2])
    with pytest.raises(TypeError, match=r"compact_mode=False for its default stepper only: the stepper given holds "
                                        r"its own compile options \(TaylorStepper\(\.\.\., compact_mode=\.\.\.\)\)"):
        free_motion(chain, h0, v0, 1.0, method="charts", compact_mode=False, stepper=TaylorStepper())


@pytest.mark.parametrize("chain, options", [(Chain(4, 2.7, rod_densities=0.5), {}),
                                            (Chain(4, 2.7), {"form": "embedded"})])
def test_unrolled_code_is_refused_for_the_state_a_c(chain, options):
    """With rod densities, or a ``form`` asked for, the charts' default state is ``(a, c)``, whose unrolled code
    compiles for minutes: ``compact_mode=False`` is refused before anything is compiled, naming the way to it."""
    h0, v0 = unit_speed_start(chain, [1.45, 0.3], [1.0, 0.2])
    with pytest.raises(ValueError, match=r"compact_mode=False would compile the chart state \(a, c\).*185 s at "
                                         r"n = 3.*stepper=SundmanStepper\(ChainTimeFactor\(chain\), compact_mode=False\)"):
        free_motion(chain, h0, v0, 1.0, method="charts", compact_mode=False, **options)


def test_the_constraints_see_the_tangent_velocity_so_rounding_does_not_feed_back():
    """``f`` is evaluated at ``J a'``, the tangent part of ``V``: with ``V`` itself, rounding's drift off the tangent
    space fed back into the acceleration (this start, T = 20: energy error 3.4e-14 against 3.7e-15; the bound is
    4x the latter).  The states read back as ``(a, c)`` are refined by their residual: unrefined, 1.7e-14."""
    chain = Chain(4, 2.7)
    atlas = chain.atlas()
    rng = np.random.default_rng(0)
    a0 = np.append(rng.uniform(-1, 1, 1), 0.3)
    v0 = atlas.charts[0].tangent_vector(a0, rng.normal(size=2))
    v0 = v0 / np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=ConstrainedVelocity(ChainSystem(chain)))
    sol = solve_chart_exp_ode(chain.metric(), atlas.get_point(0, a0), v0, 20.0, stepper=stepper)
    E = np.asarray(sol.energies, dtype=float)
    assert np.max(np.abs(E / E[0] - 1)) <= 1.5e-14


class _LongTangentPart(SuspensionFamily):
    """The suspension family with its velocity recursion's ``a'`` and ``J a'`` made ``1 + bias`` times too long: a
    planted version of the rounding bias of the tangent part (a few hundredths of an eps in the level recursion)."""

    def __init__(self, n: int, bias: float) -> None:
        super().__init__(n)
        self.bias = bias

    @property
    def key(self) -> tuple:
        return (*super().key, "long tangent part", self.bias)

    def velocity_solve(self, a, V, fp_type):
        a_dot, W = super().velocity_solve(a, V, fp_type)
        return [(1 + self.bias) * x for x in a_dot], [(1 + self.bias) * w for w in W]


def _planted_drift_run(rate: float, dt: float, drift: float, chain: Chain | None = None,
                       a0: np.ndarray | None = None, gamma: float | None = None,
                       bias: float = 0.0, conserving: bool = False) -> tuple[float, float, float]:
    """Integrate ``(a, V)`` in ``t`` from ``V = J c + n`` with ``n`` K-normal to the chart (``|n| = drift``) for
    ``dt``; return ``|V - J a'|`` at the end, ``exp(-|gamma dt|)`` and the relative change of the tangent energy.

    ``chain`` (default ``Chain(4, 2.7)``, unit rods), the chart point ``a0`` (default ``(0.2, 0.3)``) and ``gamma``
    (default the speed rate :func:`~manifold.constrained.damping_rate` at ``rate``) set the run; ``bias`` plants a
    tangent part ``J a'`` that long (:class:`_LongTangentPart`); ``conserving`` is :class:`ConstrainedVelocity`'s."""
    chain = Chain(4, 2.7) if chain is None else chain
    atlas = chain.atlas()
    chart = atlas.charts[0]
    numerics = chart.numerics(chain.ambient_metric, atlas.switch_threshold, float)
    family = compiled(_LongTangentPart(chain.n, bias) if bias else chart.family)
    system = ChainSystem(chain)
    transfer = Transfer(family, float, numerics.pars)
    k, N = chain.n - 2, 2 * (chain.n - 1)
    rng = np.random.default_rng(0)
    a0, c0 = (np.array([0.2, 0.3]) if a0 is None else a0), rng.normal(size=k)

    def tangent(a: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, float]:
        """``J c`` and ``E`` of ``c = g^-1 J^T W u``."""
        c = transfer.coefficients(a[:, None], u[:, None])
        out = transfer(a[:, None], c, np.zeros((N, 1)))
        return out[N : 2 * N, 0], float(out[-1, 0])

    V0, E0 = tangent(a0, transfer(a0[:, None], c0[:, None], np.zeros((N, 1)))[N : 2 * N, 0])
    V0, E0 = V0 / np.sqrt(E0), 1.0  # unit energy
    r = rng.normal(size=N)
    n = r - tangent(a0, r)[0]
    velocity = ConstrainedVelocity(system, rate=rate, conserving=conserving)
    gamma = damping_rate(speed_scale(system), rate, E0, dt) if gamma is None else gamma
    with family.integrator(float, terms=(velocity,)) as ta:
        ta.state[:] = np.concatenate([a0, V0 + drift * n / np.linalg.norm(n)])
        ta.time = 0.0
        ta.pars[:] = np.concatenate([numerics.pars, velocity.parameters(float), [gamma, 1 / (2 * E0)]])
        ta.reset_cooldowns()
        assert ta.propagate_until(dt)[0] == hy.taylor_outcome.time_limit  # no switch event on the way
        y = np.array(ta.state)
    Jc, E = tangent(y[:k], y[k:])
    return float(np.linalg.norm(y[k:] - Jc)), float(np.exp(-abs(gamma * dt))), E / E0 - 1


@pytest.mark.parametrize("dt", [0.5, -0.5])
@pytest.mark.parametrize("rate", [0.0, 1.0, 10.0])
def test_the_normal_drift_of_the_velocity_decays_at_the_damping_rate_both_ways(rate, dt):
    """``V' = ... - gamma (V - J a')``: a drift ``n`` off the tangent space decays like ``exp(-|gamma t|)`` forward and
    backward (the rate's sign follows the direction).  ``a'`` reads ``V`` by forward substitution, an oblique
    projection, which lets a little of the drift into ``a'`` and so into ``V'``: undamped the drift changes by 2-3 %
    over ``|t| = 0.5`` (measured; the K-orthogonal ``g^-1 J^T W V`` kept it to 4e-10), a rate far below the damping's."""
    drift, expected, _ = _planted_drift_run(rate, dt, 1e-6)
    assert drift / 1e-6 == pytest.approx(expected, rel=0.05)
    if rate > 0:
        assert expected < 0.8


def test_the_damping_keeps_the_normal_drift_out_of_the_energy():
    """A normal drift ``delta`` turns into tangent velocity as the tangent space turns, and the constraint force does
    work on it, ``<delta, g>_W``: planted at 1e-6, undamped it changed the energy by 6.6e-7 over t = 3, damped at
    the default rate by 6.6e-8.  Left to rounding, that drift made the energy error of long runs grow like
    ``t^0.6..0.9`` (n = 4, T = 1e4: 4.7e-13..7.7e-13 over four starts; damped at the default rate 0.98e-13..2.2e-13,
    ``docs/methods.md``).  The conserving equations take ``g``'s part along ``V`` out of ``V'``, and the energy's
    rate is then of second order in the drift: 1e-13 undamped, 4e-14 damped (measured)."""
    undamped = _planted_drift_run(0.0, 3.0, 1e-6)[2]
    damped = _planted_drift_run(DEFAULT_RATE, 3.0, 1e-6)[2]
    assert abs(undamped) > 1e-7
    assert abs(damped) < 0.25 * abs(undamped)
    assert abs(_planted_drift_run(DEFAULT_RATE, 3.0, 0.0)[2]) < 1e-14  # nothing planted: the motion's own energy
    for rate in (0.0, DEFAULT_RATE):
        assert abs(_planted_drift_run(rate, 3.0, 1e-6, conserving=True)[2]) < 1e-12  # a square of 1e-6


def test_the_damping_does_not_pump_a_biased_tangent_part_into_the_energy():
    """Rounding makes ``a'`` and ``J a'`` longer or shorter than ``V``'s tangent part by a few hundredths of an eps
    on average (the level recursion's and the jets' alike, each its own way).  The damping pulls ``V`` towards
    ``J a'``: damping the whole drift ``V - J a'`` would pump that bias into the energy at ``2 gamma beta``, the
    faster the harder it damps, and over long runs the energy drifted by one sign.  So the drift's part along
    ``J a'`` is not damped.  Planted at ``beta = 1e-9`` over t = 3, what the energy still takes comes from the
    normal acceleration of the motion at the long ``J a'`` turning ``V`` a little too fast, which the damping
    removes ever faster: measured 8.3e-9 at the default rate and 1.4e-9 at ten times it (1.8e-8 undamped; with the
    whole drift damped 1.9e-8 and 1.1e-7).  The conserving equations take that acceleration's part along ``V``
    out: 1e-15 or less at every rate (measured)."""
    fed = [_planted_drift_run(rate, 3.0, 0.0, bias=1e-9)[2] for rate in (DEFAULT_RATE, 10 * DEFAULT_RATE)]
    assert 0 < fed[1] < 0.3 * fed[0], fed
    for rate in (0.0, DEFAULT_RATE, 10 * DEFAULT_RATE):
        assert abs(_planted_drift_run(rate, 3.0, 0.0, bias=1e-9, conserving=True)[2]) < 1e-14, rate


def _nearly_stretched_segment(dt: float, masses: list | float = 1.0) -> tuple[Chain, np.ndarray, float, float]:
    """A chain 5e-8 from the top of its range (its configuration space a sphere of radius about 2e-4) at a chart
    point: ``(chain, a0, gamma, omega)`` with the default damping rate ``gamma`` of a segment of length ``dt``
    started there at unit energy, and the turning rate ``omega = |f| / |v|`` there (``f`` the normal acceleration,
    from the hinge reference)."""
    chain = Chain(5, 5 - 5e-8, hinge_masses=masses)
    atlas = chain.atlas()
    chart = atlas.charts[0]
    numerics = chart.numerics(chain.ambient_metric, atlas.switch_threshold, float)
    a0 = np.array([0.3, -0.2, 0.4])
    c0 = np.random.default_rng(0).normal(size=3)  # the planted-drift helper's own draw: the same velocity
    family = compiled(chart.family)
    E = float(family.transfer_at(float, numerics.pars)(a0[:, None], c0[:, None], np.zeros((8, 1)))[-1, 0])
    segment = SegmentStart(family, float, 0.0, np.concatenate([a0, c0 / np.sqrt(E)]), dt, numerics.pars)
    x, v = segment.ambient
    f = HingeConstraints(chain).acceleration(x, v)
    return chain, a0, ConstrainedVelocity(ChainSystem(chain)).damping(segment), float(np.linalg.norm(f) / np.linalg.norm(v))


@pytest.mark.parametrize("masses", [1.0, [0.9, 30.6, 0.013, 0.047]])
def test_the_damping_follows_the_turning_of_a_small_configuration_space(masses):
    """Near the top of its range of ``L`` a chain's configuration space is a small sphere, whose tangent space turns
    at the speed over its radius: far faster than the speed over the rod length.  The damping rate follows it,
    ``gamma >= rate |f| / |v|`` (``f`` the normal acceleration, from the hinge reference), thousands of times the
    speed rate; a planted drift then decays as ``exp(-gamma t)`` within a fraction of a turn and feeds the energy
    less than at the speed rate (a drift left at the speed rate fed the energy 3.8e-11 in ``t = 0.9`` of a fuzz case
    on this chain, 1.9e-12 damped at the turning rate).  Spread masses: Euclidean norms, so that the light hinges'
    fast turning sets the rate."""
    dt = 2e-4
    chain, a0, gamma, omega = _nearly_stretched_segment(dt, masses)
    speed_rate = damping_rate(speed_scale(ChainSystem(chain)), DEFAULT_RATE, 1.0, dt)
    assert gamma >= DEFAULT_RATE * omega * (1 - 1e-6)  # the two normal accelerations agree to 4e-9 (spread masses)
    assert gamma > 300 * speed_rate  # unit masses 5,500x, these spread ones 750x
    if masses != 1.0:
        return
    left, expected, fed = _planted_drift_run(DEFAULT_RATE, dt, 1e-9, chain, a0, gamma)
    assert left / 1e-9 == pytest.approx(expected, rel=0.1) and expected < 0.3
    left_slow, _, fed_slow = _planted_drift_run(DEFAULT_RATE, dt, 1e-9, chain, a0)
    assert left_slow / 1e-9 > 0.9
    assert abs(fed) < 0.6 * abs(fed_slow)


def test_a_bad_rate_or_solve_is_refused_by_name():
    system = ChainSystem(Chain(4, 2.5))
    for bad in (-1.0, float("nan"), "1"):
        with pytest.raises(ValueError, match="rate must be a finite real number"):
            ConstrainedVelocity(system, rate=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"solve must be one of \('recursion', 'jets'\), got 'newton'"):
        ConstrainedVelocity(system, solve="newton")


@pytest.mark.parametrize("chain, seed", [(Chain(5, 3.6), 1),
                                         (Chain([1.0, 0.7, 1.3, 0.9], 3.1, hinge_masses=[0.3, 2.0, 1.0]), 0)])
def test_both_velocity_solves_give_the_same_motion(chain, seed):
    """``solve="recursion"`` (the suspension's levels) and ``"jets"`` (forward substitution on the chart's jets)
    read the same ``a'`` from ``V``: the same motion, switches and energy, through pole crossings."""
    p0, v0 = atlas_start(chain, seed)
    got = {solve: solve_chart_exp_ode(chain.metric(), p0, v0, 20.0, stepper=SundmanStepper(
        ChainTimeFactor(chain), velocity=ConstrainedVelocity(ChainSystem(chain), solve=solve)))
        for solve in ("recursion", "jets")}
    assert len(got["jets"].switches) >= 1
    assert_same_motion(got["recursion"], got["jets"], 20.0)
    # two computations, not one: they round differently
    assert not np.array_equal(got["recursion"].end_state()[1], got["jets"].end_state()[1])


def _rod_rates(z: np.ndarray, V: np.ndarray, L: float) -> np.ndarray:
    """``e_k . (v_k - v_{k-1})`` of the rods of a chain pinned at 0 and ``L`` (hinges ``z``, velocities ``V`` in the
    chart's frame, interleaved): 0 for a velocity tangent to its configuration space."""
    p = np.concatenate([[0.0, 0.0], z, [L, 0.0]]).reshape(-1, 2)
    v = np.concatenate([[0.0, 0.0], V, [0.0, 0.0]]).reshape(-1, 2)
    return np.sum(np.diff(p, axis=0) * np.diff(v, axis=0), axis=1)


@pytest.mark.parametrize("weighted", [False, True])
def test_a_wrap_between_steps_puts_the_ambient_velocity_back_on_the_tangent_space(weighted, monkeypatch):
    """A wrap rounds ``2 pi`` and so moves the point along ``t`` (by 2.4e-16; here by 1e-7, to see it): the state term
    projects ``V`` (or ``w = R V``) onto the tangent space at the moved point, where the old one leaves it by about
    the move, keeping the energy to second order; a solve calls it once per wrap (``manifold.steppers.angle_wrap``:
    left off, the energy drifted one way, -1.2e-12 over T = 1.2e5)."""
    chain = Chain(4, 2.7, hinge_masses=[1.0, 0.4, 2.0])
    atlas = chain.atlas()
    chart = atlas.charts[0]
    numerics = chart.numerics(chain.ambient_metric, atlas.switch_threshold, float)
    family = compiled(chart.family)
    segment = SegmentStart(family, float, 0.0, np.array([0.4, 2.9, 0.3, 1.2]), 1.0, numerics.pars)
    system = ChainSystem(chain)
    term = WeightedVelocity(system, block=2) if weighted else ConstrainedVelocity(system)
    R, R_inv = term.factors(segment) if weighted else (np.eye(3), np.eye(3))
    state = term.enter(segment).copy()
    state[1] += 1e-7  # the circle angle, moved as a wrap's rounding moves it

    def velocity(s: np.ndarray) -> np.ndarray:
        return (R_inv @ s[2:].reshape(3, 2)).reshape(6)

    z = family.evaluate_point(numerics.pars[: family.family.n_params], state[:2])
    before = velocity(state)
    term.rewrapped(segment)(state)
    after = velocity(state)
    assert np.abs(_rod_rates(z, before, 2.7)).max() >= 1e-8
    assert np.abs(_rod_rates(z, after, 2.7)).max() <= 1e-15
    K = np.kron(np.diag([1.0, 0.4, 2.0]), np.eye(2))
    assert abs(after @ K @ after / (before @ K @ before) - 1) <= 1e-13
    calls = []
    plain = ConstrainedVelocity.rewrapped

    def counted(self, segment):
        project = plain(self, segment)
        return lambda live: (calls.append(1), project(live))

    monkeypatch.setattr(ConstrainedVelocity, "rewrapped", counted)
    sol = free_motion(chain, *unit_speed_start(chain, [0.4, 2.9], [0.3, 1.2]), 20.0, method="charts").solution
    assert sol.stats.n_wraps >= 2 and len(calls) == sol.stats.n_wraps


@pytest.mark.parametrize("T", [20.0, -20.0])
def test_the_conserving_equations_integrate_the_same_motion(T):
    """The term they add, ``g``'s part along ``V``, is 0 on the exact solution: the motion agrees with the hinge
    method's as the default equations' does, through switches and both ways; and ``conserving`` is checked."""
    chain = Chain(4, 2.7, hinge_masses=[0.7, 1.6, 0.4])
    h0, v0 = unit_speed_start(chain, [1.45, 0.3], [1.0, 0.2])  # near chart 0's pole: a switch soon
    velocity = ConstrainedVelocity(ChainSystem(chain), conserving=True)
    charts = free_motion(chain, h0, v0, T, stepper=SundmanStepper(ChainTimeFactor(chain), velocity=velocity))
    hinges = free_motion(chain, h0, v0, T, method="hinges")
    ts = np.linspace(0.0, T, 41)
    assert charts.relative_energy_error <= 1e-13 and (charts.n_switches > 0 or T < 0)  # forward: into the pole
    assert np.max(np.abs(charts(ts)[0] - hinges(ts)[0])) <= 1e-10
    with pytest.raises(TypeError, match="conserving"):
        ConstrainedVelocity(ChainSystem(chain), conserving=1)
