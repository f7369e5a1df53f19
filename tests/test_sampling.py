"""Random starts: configurations uniform in the Riemannian volume, velocities uniform on the energy sphere.

Every statistical test has a fixed seed and a bound that a wrong measure
breaks: Kolmogorov-Smirnov against closed forms (Archimedes' uniform height on
the sphere, the height law on a spheroid), sample means against the
volume-weighted quadrature of :meth:`InducedMetric.integrate` within five
standard errors, and the diagonal parameterization's independent sampler.
The first test shows the KS bound rejecting the chart's Lebesgue measure.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy import stats

from charts import RoundSphereProposal, SuspensionChart, sphere_parameters
from linkage import Chain
from linkage.constraints import HingeConstraints, start_state
from linkage.diagonals import DiagonalSpace
from linkage.sampling import sample_configurations, sample_starts, sample_velocities
from manifold import InducedMetric, StartCheck
from manifold.sampling import BoxProposal, sample_volume

from .sphere_family import sphere_metric

SQUARE = BoxProposal(np.array([-1.0, -1.0]), np.array([1.0, 1.0]))  # holds each stereographic chart's best region |a| <= 1
P_MIN = 1e-3  # a KS p-value below this fails (fixed seeds: the tests are deterministic)


def z_score(sample: np.ndarray, expected: float, extra_variance: float = 0.0) -> float:
    return abs(sample.mean() - expected) / np.sqrt(sample.var() / sample.size + extra_variance)


# -- closed forms on S^2 -------------------------------------------------------------------------------------
def test_sphere_heights_are_uniform_and_the_chart_measure_is_not():
    """Archimedes: on the unit sphere the height ``z`` of a uniform point is uniform on [-1, 1], and so is
    the azimuth on the circle.  The same KS test rejects points uniform in the chart's own parameters."""
    rng = np.random.default_rng(1)
    sample = sample_volume(sphere_metric(), 4000, rng, SQUARE)
    p = sample.points
    assert np.allclose(np.linalg.norm(p, axis=-1), 1.0, rtol=0, atol=1e-15)
    assert stats.kstest(p[:, 2], stats.uniform(-1, 2).cdf).pvalue > P_MIN
    assert stats.kstest(np.arctan2(p[:, 1], p[:, 0]), stats.uniform(-np.pi, 2 * np.pi).cdf).pvalue > P_MIN
    assert 0.3 < sample.acceptance < 1 and sample.restarts == 0
    naive = sphere_metric().atlas.get_point(0, rng.uniform(-1, 1, size=(4000, 2)))  # Lebesgue in chart 0
    assert stats.kstest(naive[:, 2], stats.uniform(-1, 2).cdf).pvalue < 1e-6


@pytest.mark.parametrize("c", [0.4, 2.5])
def test_spheroid_height_law(c):
    """``K = diag(1, 1, c^2)`` makes the unit sphere the spheroid ``(x, y, c z)``; its area has height density
    ``~ sqrt(1 - e^2 s^2)`` in ``s = z``, ``e^2 = 1 - 1/c^2`` (``r(Z) sqrt(1 + r'^2)`` of the surface of revolution)."""
    metric = InducedMetric(sphere_metric().atlas, np.diag([1.0, 1.0, c * c]))
    s = sample_volume(metric, 4000, np.random.default_rng(2), SQUARE).points[:, 2]
    e2 = 1 - 1 / c**2

    def cdf(x):
        if e2 > 0:
            e = np.sqrt(e2)
            F = lambda y: (y * np.sqrt(1 - e2 * y * y) + np.arcsin(e * y) / e) / 2  # noqa: E731
        else:
            e = np.sqrt(-e2)
            F = lambda y: (y * np.sqrt(1 - e2 * y * y) + np.arcsinh(e * y) / e) / 2  # noqa: E731
        return (F(x) - F(-1.0)) / (F(1.0) - F(-1.0))

    assert stats.kstest(s, cdf).pvalue > P_MIN
    assert stats.kstest(s, stats.uniform(-1, 2).cdf).pvalue < 1e-4  # the law differs from the round sphere's


# -- chains: sample means against quadrature ------------------------------------------------------------------
def chain_observables(chain: Chain, points: np.ndarray) -> np.ndarray:
    """Smooth test functions of a configuration: hinge coordinates, squared diagonals, a product."""
    h = chain.from_point(points)
    cols = [h.real, h.imag, np.abs(h[:, 1:]) ** 2, (h[:, :1].imag * h[:, -1:].imag)]  # |p_1| = 1: not a test
    return np.concatenate(cols, axis=1)


CHAINS = {
    "n4": lambda: Chain(4, 2.6),
    "n4-masses": lambda: Chain(4, 3.3, hinge_masses=[1.0, 5.0, 0.5], rod_densities=[2.0, 0.0, 0.0, 1.0]),
    "n4-low": lambda: Chain(4, 2.02),
    "n5": lambda: Chain(5, 3.4, hinge_masses=[1.0, 2.0, 1.0, 0.3]),
}
# Quadrature nodes of chart 0.  At L = 2.02 its fold (the first two rods folded back, |p_2| >= 0.02) makes
# sqrt(det g) a sharp peak: the mean of Re p_2 moves by 6e-2 from 40 x 64 to 320 x 512 nodes, then by 8e-4.
NODES = {"n4": (40, 64), "n4-masses": (40, 64), "n4-low": (320, 512), "n5": (24, 24, 40)}


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_chain_sample_means_match_volume_quadrature(name):
    """Means of the observables over 3000 samples against ``int f dvol / vol`` (chart 0, tensor rule),
    each within 5 standard errors; the volume ``n F acceptance`` within 5 binomial errors."""
    chain = CHAINS[name]()
    metric = chain.metric()
    box = metric.atlas.parameter_box
    sample = sample_volume(metric, 3000, np.random.default_rng(3), RoundSphereProposal(chain.dim))
    assert np.all(chain.closure_residual(chain.from_point(sample.points)) < 1e-12)
    nodes, periodic = NODES[name], (chain.dim - 1,)
    volume = metric.integrate(lambda p: np.ones(p.shape[0]), 0, box, nodes, periodic)
    f = chain_observables(chain, sample.points)
    exact = metric.integrate(lambda p: chain_observables(chain, p), 0, box, nodes, periodic) / volume
    for col in range(f.shape[1]):
        assert z_score(f[:, col], exact[col]) < 5, (col, f[:, col].mean(), exact[col])
    # E[acceptance] = vol / (n F): the rejection step's own volume estimate
    rate, m = sample.acceptance, sample.proposals
    assert abs(rate - volume / (len(metric.atlas) * sample.density_bound)) < 5 * np.sqrt(rate * (1 - rate) / m)


def test_agrees_with_the_diagonal_sampler():
    """Unit rods and masses: the diagonal parameterization's Riemannian sampler (importance resampling in
    another coordinate system) gives the same means of the diagonals ``x = (|p_2|, |p_3|, |p_4|)`` and of
    ``sqrt(min slack(x))``, which tells the Riemannian measure (crowding the walls of the diagonal polytope)
    from the polytope's Lebesgue measure by some 30 standard errors."""
    chain, rng = Chain(5, 3.6), np.random.default_rng(4)
    space = DiagonalSpace(np.ones(5), 3.6)

    def stats_of(x):
        return np.column_stack([x, np.sqrt(space.slacks(x).min(axis=-1))])

    ours = stats_of(np.abs(sample_configurations(chain, 3000, rng)[:, 1:]))
    theirs = space.sample(2000, rng, measure="riemannian", pool=20)
    ref = stats_of(theirs.x)
    for j in range(ref.shape[1]):
        extra = ref[:, j].var() * (1 / len(theirs) + 1 / theirs.ess)  # resampling, then the weighted pool
        assert z_score(ours[:, j], ref[:, j].mean(), extra) < 5
    lebesgue = stats_of(space.sample(2000, rng).x)[:, -1]
    assert z_score(ours[:, -1], lebesgue.mean(), lebesgue.var() / lebesgue.size) > 10


def test_circle_and_two_points():
    """n = 3: uniform in arclength on the closed curve M^3_L (quadrature over t); n = 2: each elbow half the time."""
    chain = Chain(3, 1.7, hinge_masses=[1.0, 2.5])
    metric = chain.metric()
    sample = sample_volume(metric, 3000, np.random.default_rng(5), BoxProposal(*metric.atlas.parameter_box))
    f = chain_observables(chain, sample.points)
    box = metric.atlas.parameter_box
    volume = metric.integrate(lambda p: np.ones(p.shape[0]), 0, box, (256,), (0,))
    exact = metric.integrate(lambda p: chain_observables(chain, p), 0, box, (256,), (0,)) / volume
    for col in range(f.shape[1]):
        assert z_score(f[:, col], exact[col]) < 5
    elbows = sample_configurations(Chain(2, 1.2), 2000, np.random.default_rng(6))[:, 0].imag > 0
    assert abs(elbows.mean() - 0.5) < 5 * np.sqrt(0.25 / 2000)


# -- velocities ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("n, L", [(4, 2.9), (5, 3.2), (6, 4.5)])
def test_velocities_are_tangent_with_the_energy_and_uniform_directions(n, L):
    """At one configuration: every velocity is tangent (``G v = 0``) with ``T = E``; in the orthonormal frame
    of another chart than the sampler's the direction is uniform on ``S^(k-1)``: its last coordinate has the law of the height of a uniform
    point (uniform angle for k = 2, uniform height for k = 3, ``~ (1 - s^2)^((k-3)/2)`` in general)."""
    chain = Chain(n, L, hinge_masses=np.linspace(0.5, 2.0, n - 1), rod_densities=0.3)
    rng = np.random.default_rng(7)
    h = sample_configurations(chain, 1, rng)[0]
    E = 0.7
    v = sample_velocities(chain, np.repeat(h[None], 4000, axis=0), E, rng)
    x, w = chain.to_point(h), chain.to_point(v)
    G = HingeConstraints(chain).jacobian(x)
    assert np.abs(w @ G.T).max() < 1e-12 * np.abs(w).max()
    assert np.allclose(chain.kinetic_energy(v), E, rtol=1e-13, atol=0)
    metric = chain.metric()
    j = int(np.argsort(metric.atlas.qualities(x))[-2])  # not the sampler's (best) chart
    a = metric.atlas.get_parameters(j, x)
    assert metric.atlas.charts[j].quality(a) > 0.1
    J, g = metric.atlas.charts[j].jacobian(a), metric.local_metric(j, a)
    c = np.linalg.solve(g, J.T @ metric.K @ w.T).T  # coefficients in chart j
    frame = c @ np.linalg.cholesky(g)  # orthonormal coordinates: |frame|^2 = c^T g c = 2E
    unit = frame / np.sqrt(2 * E)
    assert np.allclose(np.linalg.norm(unit, axis=-1), 1.0, rtol=0, atol=1e-12)
    k = n - 2
    height = stats.beta((k - 1) / 2, (k - 1) / 2, loc=-1, scale=2)  # law of one coordinate of a uniform unit vector
    assert stats.kstest(unit[:, -1], height.cdf).pvalue > P_MIN
    # covariance: E[v v^T] = (2E / k) J g^{-1} J^T
    cov = 2 * E / k * J @ np.linalg.solve(g, J.T)
    prods = np.einsum("si,sj->sij", w, w)
    err = np.abs(prods.mean(axis=0) - cov) / np.sqrt(prods.var(axis=0) / len(w) + 1e-30)
    assert err.max() < 5


@settings(max_examples=10, deadline=None)
@given(st.integers(4, 6), st.floats(0.05, 0.95), st.floats(-8.0, 8.0), st.integers(0, 2**32 - 1))
@example(4, 0.3, 8.0, 0)  # Chain(4, 2.6, hinge_masses=[1e-8, 1, 1e8]): refused before
def test_starts_with_spread_masses_are_accepted_by_the_solvers(n, where, spread, seed):
    """What the sampler returns the solvers take as it is: with hinge masses spread over up to 16 decades the
    velocities stay tangent to the start check's tolerance, and of the energy to rounding.  Before, a velocity
    made as ``C^{-1} Q w`` carried ``cond C`` times the rounding of ``Q w`` into its normal part: masses
    1e-8, 1, 1e8 at n = 4 gave 24 refusals in 40 starts (up to 1.5e-8 of ``|v|``)."""
    masses = np.logspace(-abs(spread), abs(spread), n - 1)
    masses = masses if seed == 0 else masses[np.random.default_rng(seed).permutation(n - 1)]
    chain = Chain(n, n - 2 + 2 * where, hinge_masses=masses)
    h, v = sample_starts(chain, 3, 0.5, np.random.default_rng(seed))
    assert np.allclose(chain.kinetic_energy(v), 0.5, rtol=4e-16 * n, atol=0)
    for k in range(3):
        start_state(chain, h[k], v[k], 1.0, StartCheck())  # the solvers' start check: closure, tangency, energy


def test_starts_and_refusals():
    chain, rng = Chain(4, 3.1), np.random.default_rng(8)
    h, v = sample_starts(chain, 5, 2.0, rng)
    assert h.shape == v.shape == (5, 3) and h.dtype.kind == v.dtype.kind == "c"
    assert np.allclose(chain.kinetic_energy(v), 2.0, rtol=1e-13)
    with pytest.raises(ValueError, match="size must be a positive integer, got 0"):
        sample_configurations(chain, 0, rng)
    with pytest.raises(ValueError, match="size must be a positive integer, got 2.5"):
        sample_configurations(chain, 2.5, rng)
    with pytest.raises(TypeError, match="rng must be a numpy.random.Generator"):
        sample_configurations(chain, 3, 42)
    with pytest.raises(ValueError, match=r"energy must be a real number in \(0, inf\), got -1"):
        sample_velocities(chain, h, -1, rng)
    with pytest.raises(ValueError, match="configuration does not close"):
        sample_velocities(chain, h * 1.01, 1.0, rng)
    with pytest.raises(ValueError, match="dimension 0 has no tangent vectors"):
        sample_starts(Chain(2, 1.5), 2, 1.0, rng)
    for other in (Chain((1.0, 2.0, 1.5, 2.5, 1.2), 3.0), Chain(4, 1.0)):  # no atlas: the alternative is named
        with pytest.raises(ValueError, match=r"sample_configurations .* has none .*measure='riemannian'"):
            sample_configurations(other, 3, rng)
    # the function called is named, and what the space is instead: L = 1 is a critical value of three unit rods
    with pytest.raises(ValueError, match=r"^sample_starts .* Chain\(n=3, L=1.0\) has none \(.*singular \(not a manifold\)"):
        sample_starts(Chain(3, 1.0), 2, 1.0, rng)
    with pytest.raises(ValueError, match=r"^sample_starts .* has none \(.*two tori T\^1"):
        sample_starts(Chain(3, 0.5), 2, 1.0, rng)
    with pytest.raises(ValueError, match="a box needs lower < upper"):
        BoxProposal(np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match=r"proposal.draw\(8192, rng\) must return shape \(8192, 2\), got \(8192, 3\)"):
        sample_volume(sphere_metric(), 3, rng, BoxProposal(np.zeros(3), np.ones(3)))


@pytest.mark.parametrize("k", [1, 2, 3, 5])
def test_round_sphere_proposal(k):
    """Its draws are uniform on the round sphere (``sphere_point`` of them: one coordinate has the law of a
    uniform unit vector's), ``sphere_parameters`` inverts ``sphere_point``, and its density integrates to 1."""
    proposal, rng = RoundSphereProposal(k), np.random.default_rng(9)
    a = proposal.draw(4000, rng)
    chart = SuspensionChart(k + 2, k + 1.5)
    x = chart.sphere_point(a)
    height = stats.beta(k / 2, k / 2, loc=-1, scale=2)  # one coordinate of a uniform point of S^k
    assert stats.kstest(x[:, 0], height.cdf).pvalue > P_MIN
    assert np.allclose(sphere_parameters(x), a, rtol=0, atol=1e-14)
    lower, upper = np.array([-np.pi / 2] * (k - 1) + [-np.pi]), np.array([np.pi / 2] * (k - 1) + [np.pi])
    grid = [np.polynomial.legendre.leggauss(24 if k <= 3 else 12) for _ in range(k)]  # 12^5 nodes for k = 5
    nodes = np.stack(np.meshgrid(*[lo + (hi - lo) * (x + 1) / 2 for (x, _), lo, hi in zip(grid, lower, upper)],
                                 indexing="ij"), axis=-1).reshape(-1, k)
    weights = np.prod(np.stack(np.meshgrid(*[w * (hi - lo) / 2 for (_, w), lo, hi in zip(grid, lower, upper)],
                                           indexing="ij"), axis=-1).reshape(-1, k), axis=-1)
    assert abs(np.sum(weights * proposal.density(nodes)) - 1) < 1e-12
