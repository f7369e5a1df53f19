"""The fast chart choice equals the full definition: the argmax over all charts of ``quality(get_parameters(p))``.

``Atlas.chart_choice`` ranks the charts by their quality at the closed-form
(unpolished) parameters, all charts and points in one compiled call
(``manifold.symbolic.ChartRanking``), and polishes only the charts within
``QUALITY_MARGIN`` of the best.  These tests hold it to the
full definition, computed chart by chart through the public per-chart inverse,
where it is hardest: latitudes at and near the poles, ``t`` near ``+-pi/2``,
``L`` within 1e-7 of either end of its range (folds) and at 1e-12 above ``n - 2``.
"""

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from charts import SuspensionAtlas, SuspensionChart, suspension_formula
from charts.chain_geometry import to_complex, unlabel_hinges
from manifold.atlas import QUALITY_MARGIN
from manifold.backends import NUMPY, Cx
from manifold.symbolic import chart_ranking

from .conftest import HALF_PI, base_lengths, chart_parameters, folded_conditioning, rod_orders
from .sphere_family import sphere_metric

chains = st.integers(3, 8).flatmap(lambda n: st.tuples(st.just(n), base_lengths(n)))
at_a_fold = st.integers(3, 8).flatmap(lambda n: st.tuples(st.just(n), st.sampled_from([n - 2 + 1e-12, n - 2 + 1e-9])))
cases = st.one_of(chains, at_a_fold).flatmap(
    lambda nL: st.tuples(st.just(nL), chart_parameters(nL[0]), rod_orders(nL[0])))


def _full_qualities(atlas, p):
    """The definition: every chart inverted in full (closed form and polish), its quality there."""
    return np.array([c.quality(c.get_parameters(p)) for c in atlas.charts])


@given(cases)
def test_chart_choice_is_the_argmax_of_the_full_qualities(case):
    (n, L), a, order = case
    atlas = SuspensionAtlas(n, L)
    p = SuspensionChart(n, L, order).get_point(a)
    full = _full_qualities(atlas, p)
    i, ai, qi = atlas.chart_choice(p)
    best = int(np.argmax(full))
    tie = np.sort(full)[-2] >= full[best] - QUALITY_MARGIN
    assert i == best or (tie and full[i] >= full[best] - QUALITY_MARGIN), (i, full)
    # the same parameters up to the polish: the batched evaluation may round a last bit differently (SIMD),
    # and two Gauss-Newton steps from slightly different starts agree to what they converge to
    a_full = atlas.charts[i].get_parameters(p)
    tol = 1e-12 * folded_conditioning(n, L)
    assert np.abs(atlas.get_point(i, ai) - p).max() <= tol and np.abs(atlas.get_point(i, a_full) - p).max() <= tol
    assert qi == atlas.charts[i].quality(ai)


@given(cases)
def test_the_polish_moves_a_competitive_quality_by_less_than_half_the_margin(case):
    """Why polishing only the charts within QUALITY_MARGIN of the best cannot change the choice: wherever
    a chart's quality is above 0.25 (the best is above the atlas's floor, 0.6) before or after its polish,
    the polish moves it by less than QUALITY_MARGIN / 2."""
    (n, L), a, order = case
    atlas = SuspensionAtlas(n, L)
    p = SuspensionChart(n, L, order).get_point(a)
    for chart in atlas.charts:
        rough = chart.approximate_parameters(p)
        q_rough, q_full = chart.quality(rough), chart.quality(chart.polish_parameters(rough, p))
        if max(q_rough, q_full) >= 0.25:
            assert abs(q_rough - q_full) <= QUALITY_MARGIN / 2, (chart, q_rough, q_full)


@given(base_lengths(5), st.integers(1, 12), st.integers(0, 2**32 - 1))
def test_the_compiled_inverse_ranks_as_the_formula_on_numpy(L, count, seed):
    """ChartRanking inverts every chart in one compiled call; the same formula on numpy (exact sinc, libm)
    is the independent route.  Where a chart is well conditioned (quality >= 0.25) both give its parameters
    and quality to rounding; at its own poles both give quality ~0."""
    atlas = SuspensionAtlas(5, L)
    rng = np.random.default_rng(seed)
    a = np.column_stack([rng.uniform(-HALF_PI, HALF_PI, (count, 2)), rng.uniform(-np.pi, np.pi, count)])
    a[: count // 2, 0] = HALF_PI  # exact poles of chart 0
    pts = atlas.get_point(0, a)
    A, Q = chart_ranking(atlas.charts)(pts)
    tol = 1e-12 * folded_conditioning(5, L)
    for c, chart in enumerate(atlas.charts):
        z = unlabel_hinges(to_complex(pts), chart.order, L)
        with np.errstate(divide="ignore", invalid="ignore"):  # np.where evaluates both branches
            cols = suspension_formula.parameters([Cx(z[:, k].real, z[:, k].imag) for k in range(4)], L, NUMPY)
        a_np = np.stack(np.broadcast_arrays(*cols), -1)
        q_np = chart.quality(a_np)
        good = q_np >= 0.25
        assert np.abs(A[good, c] - a_np[good]).max(initial=0) <= tol
        assert np.abs(Q[:, c] - q_np).max() <= max(tol, 1e-9)
    assert np.all(Q[: count // 2, 0] <= 1e-7)


def test_a_batch_of_points_is_chosen_point_by_point():
    atlas = SuspensionAtlas(6, 4.0 + 1e-9)
    rng = np.random.default_rng(7)
    a = np.column_stack([rng.uniform(-1.6, 1.6, (40, 3)), rng.choice([HALF_PI, 0.0, rng.uniform(-3, 3)], 40)])
    a[::3, 1] = -HALF_PI
    pts = atlas.get_point(1, np.clip(a, -HALF_PI, HALF_PI))
    idx, params, q = atlas.chart_choice(pts)
    for k in range(len(pts)):
        i, ai, qi = atlas.chart_choice(pts[k])
        assert idx[k] == i and abs(q[k] - qi) <= 1e-12  # batched and single evaluations round alike, to a bit
        assert np.abs(params[k] - ai).max() <= 1e-12


def test_a_batch_across_both_points_of_s0():
    """Each S^0 chart holds one point: the batch falls back to the charts point by point."""
    atlas = SuspensionAtlas(2, 1.5)
    pts = np.stack([atlas.get_point(1, np.zeros(0)), atlas.get_point(0, np.zeros(0)), atlas.get_point(1, np.zeros(0))])
    idx, params, q = atlas.chart_choice(pts)
    assert idx.tolist() == [1, 0, 1] and params.shape == (3, 0) and q.tolist() == [1.0, 1.0, 1.0]


def test_a_generic_atlas_chooses_by_the_same_rule():
    """The stereographic atlas (no overridden batch inverse): the chart whose projection pole is farther."""
    atlas = sphere_metric().atlas
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(30, 3))
    pts /= np.linalg.norm(pts, axis=1, keepdims=True)
    idx, _, q = atlas.chart_choice(pts)
    assert np.array_equal(idx, (pts[:, 2] > 0).astype(int))  # the south chart (1) projects from the south pole
    assert np.allclose(q, (1 + np.abs(pts[:, 2])) / 2, rtol=0, atol=1e-15)  # 1 / (1 + |a|^2) = (1 + |h|) / 2


def test_an_atlas_that_has_chosen_charts_still_pickles():
    """Dask ships chains and their atlases to worker processes: the ranking an atlas keeps holds no compiled code."""
    import pickle

    atlas = SuspensionAtlas(5, 3.5)
    a = np.array([0.4, -0.3, 0.7])
    p = atlas.charts[1].get_point(a)
    i, b = atlas.best_chart(p)
    copy = pickle.loads(pickle.dumps(atlas))
    j, c = copy.best_chart(p)
    assert i == j and np.array_equal(b, c)
