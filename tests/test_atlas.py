"""The cyclic suspension atlas: chart choice, transition maps, induced metric."""

import numpy as np
import pytest
from hypothesis import assume, example, given
from hypothesis import strategies as st

from benchmarks.baselines.seed_metric4 import metric4
from charts import SuspensionAtlas, SuspensionChart
from linkage import Chain
from manifold import Atlas, InducedMetric

from .conftest import HALF_PI, base_lengths, chart_parameters, folded_conditioning, rod_orders

chains = st.integers(3, 8).flatmap(lambda n: st.tuples(st.just(n), base_lengths(n)))


def _random_point(n, L, a, order):
    """A point of the chain given by parameters of a chart with an arbitrary rod order."""
    return SuspensionChart(n, L, order).get_point(a)


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))))
def test_best_chart_is_good_everywhere_including_exact_poles(case):
    """Points from charts with random rod orders: latitudes at or near the poles are
    exact or near alignments of three or more rods."""
    (n, L), a, order = case
    atlas = SuspensionAtlas(n, L)
    p = _random_point(n, L, a, order)
    i = atlas.get_chart_index(p)
    assert atlas.charts[i].quality(atlas.get_parameters(i, p)) >= 0.5


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))),
       st.integers(0, 7), st.integers(0, 7))
def test_transition_maps_round_trip_points(case, i, j):
    (n, L), a, order = case
    atlas = SuspensionAtlas(n, L)
    i, j = i % n, j % n
    ai = atlas.get_parameters(i, _random_point(n, L, a, order))
    p = atlas.get_point(i, ai)
    tol = 1e-12 * folded_conditioning(n, L)
    assert np.abs(atlas.get_point(j, atlas.transition_map(i, j, ai)) - p).max() <= tol


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))),
       st.integers(0, 7), st.integers(0, 7), st.integers(0, 2**32 - 1))
def test_transition_map_diff_maps_the_embedded_velocity(case, i, j, seed):
    (n, L), a, order = case
    chain = Chain(n, L, hinge_masses=1.0 + np.arange(n - 1) / n, rod_densities=0.5)
    atlas, i, j = chain.atlas(), i % n, j % n
    metric = chain.metric(atlas)
    p = _random_point(n, L, a, order)
    ai, aj = atlas.get_parameters(i, p), atlas.get_parameters(j, p)
    assume(min(atlas.charts[i].quality(ai), atlas.charts[j].quality(aj)) >= 0.05)
    c = np.random.default_rng(seed).normal(size=n - 2)
    cj = atlas.transition_map_diff(i, ai, c, j)
    vi = atlas.charts[i].tangent_vector(ai, c)
    vj = atlas.charts[j].tangent_vector(aj, cj)
    tol = 1e-12 * folded_conditioning(n, L)
    assert np.abs(vj - vi).max() <= tol * max(1.0, np.abs(vi).max())
    Ei, Ej = metric.kinetic_energy(i, ai, c), metric.kinetic_energy(j, aj, cj)
    assert abs(Ej - Ei) <= tol * Ei


def _seed_rounding_bound(phi: float, t: float, L: float) -> float:
    """Relative error the seed's ``metric4`` can carry from rounding alone.

    Its inner elbow factor ``nu = cos t sqrt((4 - |p_2|^2) / cos^2 t)`` subtracts
    two numbers near 4 whose difference is ``~ cos^2 t d alpha_in sin alpha_in``
    (the seed's own limit), so it loses ``eps / (cos^2 t d alpha_in sin alpha_in)``;
    100 eps is the constant observed over 2e4 samples (at most 40 eps).
    """
    alpha = np.arccos((L * L - 8) / (2 * L))
    d = np.sqrt(L * L - 2 * L * np.cos(alpha * np.sin(phi)) + 1)
    alpha_in = np.arccos((d * d - 3) / (2 * d))
    return 100 * np.finfo(float).eps / (np.cos(t) ** 2 * d * alpha_in * np.sin(alpha_in))


near_the_crossing = st.tuples(st.sampled_from([-1.0, 1.0]), st.floats(-4, -0.5)).map(
    lambda s: s[0] * HALF_PI + 10.0 ** s[1])


@given(st.floats(2.001, 3.999), st.floats(-1.5, 1.5),
       st.one_of(st.floats(-np.pi, np.pi), near_the_crossing))
def test_seed_closed_form_metric_agrees_with_pullback(L, phi, t):
    """Agreement to 1e-10 wherever the seed's own formula is accurate to 1e-4.

    Near ``t = +-pi/2`` the seed's formula cancels (see ``_seed_rounding_bound``);
    within ~1e-5 of the crossing it returns NaN.  Ours does not cancel there.
    """
    seed_error = _seed_rounding_bound(phi, t, L)
    assume(seed_error <= 1e-4)
    g = Chain(4, L).metric().local_metric(0, np.array([phi, t]))
    assert np.abs(g - metric4(phi, t, L)).max() <= max(1e-10, seed_error) * np.abs(g).max()


def test_check_chart_switch_uses_the_threshold():
    atlas = SuspensionAtlas(5, 4.0, switch_threshold=0.3)
    assert atlas.check_chart_switch(0, np.array([np.arccos(0.29), 0.0, 0.0]))
    assert not atlas.check_chart_switch(0, np.array([np.arccos(0.31), 0.0, 0.0]))
    assert not atlas.check_chart_switch(0, np.array([0.0, np.arccos(0.31), 0.0]))
    assert atlas.check_chart_switch(0, np.array([0.0, -np.arccos(0.29), 0.0]))


def test_atlas_of_two_rods_is_two_points():
    atlas = SuspensionAtlas(2, 1.5)
    for i in range(2):
        p = atlas.get_point(i, np.zeros(0))
        assert atlas.get_chart_index(p) == i


def test_atlas_errors():
    atlas = SuspensionAtlas(4, 3.0)
    with pytest.raises(ValueError, match=r"chart index must be an integer in \[0, 3\], got 4"):
        atlas.get_point(4, [0.0, 0.0])
    for bad in (1.0, True, "0"):
        with pytest.raises(TypeError, match=r"chart index must be an integer in \[0, 3\]"):
            atlas.get_parameters(bad, atlas.get_point(0, [0.1, 0.2]))
    with pytest.raises(ValueError, match="switch_threshold"):
        SuspensionAtlas(4, 3.0, switch_threshold=1.5)
    with pytest.raises(ValueError, match="at least one chart"):
        Atlas([])
    with pytest.raises(ValueError, match="disagree"):
        Atlas([SuspensionChart(4, 3.0), SuspensionChart(5, 4.0)])
    with pytest.raises(ValueError, match="positive definite"):
        InducedMetric(atlas, -np.eye(6))
    with pytest.raises(ValueError, match="shape"):
        InducedMetric(atlas, np.eye(5))


def test_metric_norm_and_inner_are_consistent():
    chain = Chain(5, 4.1, rod_densities=0.3)
    metric = chain.metric()
    a, X, Y = np.array([0.3, -0.2, 1.0]), np.array([1.0, 2.0, -1.0]), np.array([0.5, 0.0, 0.3])
    g = metric.local_metric(2, a)
    assert np.allclose(g, g.T) and np.all(np.linalg.eigvalsh(g) > 0)
    assert metric.inner(2, a, X, Y) == pytest.approx(X @ g @ Y, rel=1e-14)
    assert metric.norm(2, a, X) ** 2 == pytest.approx(2 * metric.kinetic_energy(2, a, X), rel=1e-14)
    v = atlas_v = metric.atlas.charts[2].tangent_vector(a, X)
    assert metric.ambient_kinetic_energy(atlas_v) == pytest.approx(chain.kinetic_energy(chain.from_point(v)), rel=1e-14)


@given(chains.flatmap(lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0]))))
@example(((8, 6.5), np.array([-np.pi / 2, 0, -np.pi / 2, 0, -np.pi / 2, 0]), np.arange(8)))  # a tie, 1 ulp apart
def test_best_chart_returns_the_best_index_and_its_parameters(case):
    """The best chart's quality is the largest, to rounding: symmetric points tie (charts 6 and 7 of this
    example agree to 1.1e-16, and the separately computed qualities may order them either way)."""
    (n, L), a, order = case
    atlas = SuspensionAtlas(n, L)
    p = _random_point(n, L, a, order)
    i, ai = atlas.best_chart(p)
    qualities = [c.quality(c.get_parameters(p)) for c in atlas.charts]
    assert qualities[i] >= max(qualities) - 1e-12
    a_full = atlas.charts[i].get_parameters(p)  # equal up to the polish (best_chart inverts all charts in one batch)
    tol = 1e-12 * folded_conditioning(n, L)
    assert np.abs(atlas.get_point(i, ai) - p).max() <= tol and np.abs(atlas.get_point(i, a_full) - p).max() <= tol


def test_a_chart_that_does_not_contain_the_point_has_no_quality():
    """S^0: each chart holds one of the two points; the other gets quality -inf."""
    atlas = SuspensionAtlas(2, 1.5)
    p = atlas.get_point(1, np.zeros(0))
    assert atlas.qualities(p).tolist() == [-np.inf, 1.0]
    assert atlas.best_chart(p)[0] == 1


def test_a_point_outside_every_chart_is_an_error():
    atlas = Atlas([SuspensionChart(2, 1.5, sheet=1)])
    p = SuspensionChart(2, 1.5, sheet=-1).get_point(np.zeros(0))
    with pytest.raises(ValueError, match="lies in no chart"):
        atlas.best_chart(p)


@pytest.mark.parametrize("n", [3, 4, 5, 6])
@pytest.mark.parametrize("gap", [1e-12, 1e-9, 1e-6, 1e-3])
def test_best_chart_is_well_conditioned_at_folds(n, gap):
    """Near L = n - 2 the best chart stays well conditioned: the fold terms of the quality see the fold
    of the first two rods (cond(J) ~ 1/|p_2|) and the folded triple (sigma_min ~ gap^(1/4)), which
    min cos(phi_m) alone scored 1.0 (issue 8: cond(J) of the chosen chart reached 1/gap)."""
    L = n - 2 + gap
    atlas = SuspensionAtlas(n, L)
    rng = np.random.default_rng(n)
    params = [np.append(np.zeros(n - 3), t) for t in (0.0, np.pi, HALF_PI, -HALF_PI)]  # folds, folded triples
    params += [np.append(rng.uniform(-1.5, 1.5, n - 3), rng.uniform(-np.pi, np.pi)) for _ in range(12)]
    for order in rod_orders_sample(n, rng):
        chart = SuspensionChart(n, L, order)
        for a in params:
            p = chart.get_point(a)
            i, a_best = atlas.best_chart(p)
            s = np.linalg.svd(atlas.charts[i].jacobian(a_best), compute_uv=False)
            # the folded triples attain the floor: their qualities meet it to rounding (2.8e-12 short at gap 1e-12)
            assert atlas.qualities(p).max() >= atlas.quality_floor - 1e-9
            assert s[-1] / s[0] >= 0.05, (order, a, i, s)  # measured >= 0.064 over n <= 8


def rod_orders_sample(n: int, rng: np.random.Generator) -> list:
    return [np.arange(n), rng.permutation(n), rng.permutation(n)]
