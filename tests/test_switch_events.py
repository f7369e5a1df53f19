"""Switch events that can never fire are not compiled: the suspension family's quality floors.

A quality whose lower bound over every configuration (:meth:`SuspensionFamily.quality_floors`) lies above the
switch threshold never reaches it; its event would still cost Taylor coefficients and a root search at every step.
The floors are checked against the qualities themselves (any ``a``, every chart, unit rods and any lengths, down
to ``1e-9`` above the fold), the floor of ``q_A`` is reached at the chart's origin, and a solve without the events
that cannot fire is the same motion, bit for bit, as one with all of them.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

import manifold.geodesic_solver as geodesic_solver
from charts.chain_geometry import sphere_range
from charts.suspension import SuspensionAtlas
from linkage import Chain
from manifold import SaveAt, solve_chart_exp_ode
from manifold.compiled import compiled
from manifold.geodesic_solver import needed_switches
from manifold.steppers import TaylorStepper


def _qualities(chart, a: np.ndarray) -> np.ndarray:
    """Every quality of ``chart`` at the parameter rows ``a`` (float64, compiled): shape ``(m, n_quality)``."""
    cf = compiled(chart.family).quality(float)
    theta = np.asarray(chart.family_parameters, dtype=float)
    return np.array([cf(row, pars=theta[: cf.nparams]) for row in a])


@st.composite
def atlases(draw) -> SuspensionAtlas:
    """Unit rods, links of any lengths with the base dominant, or a dominant link as the charts' base; the base a
    log-uniform share of its range above the lower end (the fold), from 1e-9 to all of it."""
    n = draw(st.integers(3, 7))
    share = 10.0 ** draw(st.floats(-9, 0)) * (1 - 1e-12)
    kind = draw(st.sampled_from(["unit", "lengths", "link base"]))
    if kind == "unit":
        return SuspensionAtlas(n, n - 2 + 2 * share)
    sides = np.array(draw(st.lists(st.floats(0.2, 3.0), min_size=n, max_size=n)))  # n sides besides the base
    lower, upper = sphere_range(sides)
    base = lower + (upper - lower) * share
    if kind == "lengths":
        return SuspensionAtlas(sides, base)
    j = draw(st.integers(0, n - 1))  # the dominant link's slot; the last side drawn is the pinned base L
    return SuspensionAtlas(np.insert(sides[:-1], j, base), float(sides[-1]))


@settings(max_examples=40)
@given(atlas=atlases(), seed=st.integers(0, 2**32 - 1))
def test_no_quality_falls_below_its_floor(atlas, seed):
    rng = np.random.default_rng(seed)
    for chart in atlas.charts:
        floors = chart.family.quality_floors(chart.family_parameters)
        # any real parameters, past the poles and the circle's period too: a floor holds for every a
        a = rng.uniform(-4.0, 4.0, size=(64, atlas.dim))
        a[:8] = 0.0  # the equator of every level, where the fold terms are smallest
        a[8:16, -1] = np.pi / 2
        q = _qualities(chart, a)
        assert np.all(q >= floors - 1e-12), (chart, np.min(q - floors, axis=0))


@pytest.mark.parametrize("n", [3, 4, 6])
@pytest.mark.parametrize("lo", [1e-6, 1e-2, 0.5])
def test_the_fold_floor_is_reached_at_the_origin(n, lo):
    """Unit rods: at ``a = 0`` every level sits at its equator, the circle level's slack is the chain's ``lo`` and
    ``|p_2| = D - 1``, so ``q_A = lo / (lo + 1/4)``, the floor itself."""
    chain = Chain(n, n - 2 + lo)
    chart = chain.atlas().charts[0]
    q_A = _qualities(chart, np.zeros((1, n - 2)))[0, -2]
    floor = chart.family.quality_floors(chart.family_parameters)[-2]
    assert floor == pytest.approx(lo / (lo + 0.25), rel=1e-12)
    assert q_A == pytest.approx(floor, rel=1e-9)


def test_the_switch_events_a_solve_needs():
    far, near = Chain(4, 3.0).atlas(), Chain(4, 2 + 1e-3).atlas()
    assert needed_switches(far, 0.25) == (0,)  # the latitude's; q_A >= 0.8 and q_B >= 0.84 there
    assert needed_switches(near, 0.25) is None  # all of them: the default integrator
    assert needed_switches(far, 0.9) is None  # a threshold above the floors keeps them
    assert needed_switches(far, -2.0) == ()  # switching off: below every quality
    family = compiled(far.charts[0].family)
    stepper = TaylorStepper()
    assert len(stepper.events(family, float, "embedded", (0,))) == len(stepper.events(family, float, "embedded")) - 2


def test_any_lengths_need_the_fold_events_near_the_fold_only():
    lengths = np.array([1.0, 0.5, 2.0, 1.5])
    lower, upper = sphere_range(lengths)
    assert needed_switches(Chain(lengths, lower + 1e-4).atlas(), 0.25) is None
    assert needed_switches(Chain(lengths, (lower + upper) / 2).atlas(), 0.25) == (0,)
    link_based = SuspensionAtlas([3.3, 1.0, 1.0, 1.2], 0.3)  # the link of 3.3 dominant (lo = 0.4): the base
    assert all(chart.family.link_base for chart in link_based.charts)
    assert needed_switches(link_based, 0.25) == (0,)


@pytest.mark.parametrize("T", [4.0, -4.0])
def test_a_solve_without_the_events_that_cannot_fire_is_the_same_motion(T, monkeypatch):
    metric = Chain(4, 3.0).metric()
    a0, c0 = np.array([1.2, 0.4]), np.array([np.sign(T), 0.3])  # chart 0 near its pole, heading for it
    stepper = TaylorStepper()
    pruned = solve_chart_exp_ode(metric, a0, c0, T, chart=0, stepper=stepper, save=SaveAt(dense=False))
    monkeypatch.setattr(geodesic_solver, "needed_switches", lambda atlas, q_out: None)
    every = solve_chart_exp_ode(metric, a0, c0, T, chart=0, stepper=stepper, save=SaveAt(dense=False))
    assert pruned.n_switches >= 1  # the latitude's events still fire
    assert [s.time for s in pruned.switches] == [s.time for s in every.switches]
    assert pruned.n_steps == every.n_steps
    for x, y in zip(pruned.final_state, every.final_state):
        assert np.array_equal(np.asarray(x), np.asarray(y))
