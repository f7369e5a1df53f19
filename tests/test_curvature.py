"""Curvature of induced metrics: the Gauss equation (production) against independent routes.

* round spheres and ellipsoids (closed forms, via the stereographic test family);
* the intrinsic route for the chain: Christoffel symbols and the Riemann tensor
  from ``g``, ``dg`` and ``d^2 g``, differentiated symbolically by heyoka here
  in the test (third derivatives of the chart, where the Gauss equation needs
  second ones);
* chart independence (two charts at one point), Gauss-Bonnet (``int K dA = 4 pi``
  on ``M^4_L = S^2``), and the algebra tying sectional to scalar curvature.
"""

from __future__ import annotations

import heyoka as hy
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from charts import SuspensionChart
from linkage import Chain
from linkage.sampling import sample_configurations
from manifold import Atlas, InducedMetric, compiled

from .conftest import base_lengths, chart_parameters, folded_conditioning
from .sphere_family import StereographicChart, sphere_metric


# -- an ellipsoid: the stereographic charts composed with a diagonal map ---------------------------
class EllipsoidChart(StereographicChart):
    """``p = diag(axes) z``, ``z`` on the unit sphere: the ellipsoid ``sum (p_r / axes_r)^2 = 1``."""

    def __init__(self, mirror: bool, axes: np.ndarray) -> None:
        super().__init__(mirror)
        self.axes = np.asarray(axes, dtype=float)
        self.sphere_chart = StereographicChart(mirror)
        self.linear_map = self.sphere_chart.linear_map * self.axes[:, None]

    def get_parameters(self, p):
        return self.sphere_chart.get_parameters(np.asarray(p, dtype=float) / self.axes)


def ellipsoid_metric(axes) -> InducedMetric:
    return InducedMetric(Atlas([EllipsoidChart(False, axes), EllipsoidChart(True, axes)]), np.eye(3))


def ellipsoid_gaussian_curvature(axes, p):
    """``K = 1 / (a^2 b^2 c^2 (x^2/a^4 + y^2/b^4 + z^2/c^4)^2)`` (classical closed form)."""
    axes = np.asarray(axes, dtype=float)
    return 1.0 / (np.prod(axes**2) * np.sum(p**2 / axes**4, axis=-1) ** 2)


def random_sphere_points(rng, size):
    x = rng.standard_normal((size, 3))
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


# -- the intrinsic route, built here ----------------------------------------------------------------
_INTRINSIC = {}


def intrinsic_riemann(chart, K, a):
    """``R_abcd`` (convention ``R(u, v, v, u) > 0`` on spheres) from ``g``, ``dg``, ``d^2 g`` of ``chart`` at ``a``.

    ``R^std_abcd = 1/2 (g_ad,bc + g_bc,ad - g_bd,ac - g_ac,bd) + g_ef (G^e_bc G^f_ad - G^e_bd G^f_ac)``
    is the tensor with ``R^std(u, v, u, v) > 0``; the library's is ``R^std_abdc``.
    """
    family = chart.family
    cf, k = _INTRINSIC.get(family.key), family.dim
    pairs = [(i, j) for i in range(k) for j in range(i, k)]
    if cf is None:
        P = compiled(family).pieces(float)
        g = [P.g[i][j] for i, j in pairs]
        dt = hy.diff_tensors(g, P.a, diff_order=2)
        outs = g + [dt.jacobian[m, l] for m in range(len(g)) for l in range(k)]
        outs += [dt.hessian(m)[l, n] for m in range(len(g)) for l in range(k) for n in range(k)]
        cf = _INTRINSIC[family.key] = hy.cfunc(outs, P.a, compact_mode=True)
    pars = compiled(family).layout.pack(chart.family_parameters, chart.core_metric(K), 0.0, float)[: cf.nparams]
    out = cf(np.asarray(a, dtype=float), pars=pars)
    m = len(pairs)
    g, dg, ddg = np.zeros((k, k)), np.zeros((k, k, k)), np.zeros((k, k, k, k))  # dg[i, j, l] = d_l g_ij
    for s, (i, j) in enumerate(pairs):
        for target in ((i, j), (j, i)):
            g[target] = out[s]
            dg[target] = out[m + s * k : m + (s + 1) * k]
            ddg[target] = out[m + m * k + s * k * k : m + m * k + (s + 1) * k * k].reshape(k, k)
    first = 0.5 * (dg.transpose(0, 2, 1) + dg - dg.transpose(2, 0, 1))  # Gamma_{e,bc} = 1/2 (g_ec,b + g_eb,c - g_bc,e)
    second = np.linalg.solve(g, first.reshape(k, k * k)).reshape(k, k, k)  # Gamma^e_bc
    R = 0.5 * (np.einsum("adbc->abcd", ddg) + np.einsum("bcad->abcd", ddg)
               - np.einsum("bdac->abcd", ddg) - np.einsum("acbd->abcd", ddg))
    R += np.einsum("ef,ebc,fad->abcd", g, second, second) - np.einsum("ef,ebd,fac->abcd", g, second, second)
    return R.transpose(0, 1, 3, 2)


# -- closed forms --------------------------------------------------------------------------------------
@given(seed=st.integers(0, 2**32 - 1), radius=st.floats(0.1, 10.0))
def test_round_sphere_has_curvature_one_over_r_squared(seed, radius):
    """K = 1 on the unit sphere (K = I) and 1/r^2 with K = r^2 I, at points over all of S^2 (both charts)."""
    rng = np.random.default_rng(seed)
    p = random_sphere_points(rng, 16)
    unit, scaled = sphere_metric(), InducedMetric(sphere_metric().atlas, radius**2 * np.eye(3))
    assert np.allclose(unit.gaussian_curvature(p), 1.0, rtol=0, atol=1e-13)
    assert np.allclose(unit.scalar_curvature(p), 2.0, rtol=0, atol=3e-13)
    assert np.allclose(scaled.gaussian_curvature(p), radius**-2, rtol=1e-13, atol=0)
    u = np.cross(p, rng.standard_normal((16, 3)))  # tangent: orthogonal to p
    v = np.cross(p, rng.standard_normal((16, 3)))
    assert np.allclose(unit.sectional_curvature(p, u, v), 1.0, rtol=0, atol=1e-12)


def test_sphere_riemann_tensor_is_that_of_constant_curvature():
    """``R_abcd = g_ad g_bc - g_ac g_bd`` in a stereographic chart (K = 1), far from and near its pole
    (at ``|a| = 32`` the normal part of ``H`` is ``1/|a|`` of it: 4e-13 observed, where 3e-16 at ``|a| < 3``)."""
    metric = sphere_metric()
    a = np.array([[0.1, -0.3], [2.0, 1.5], [-30.0, 12.0]])
    g = metric.local_metric(0, a)
    expected = np.einsum("...ad,...bc->...abcd", g, g) - np.einsum("...ac,...bd->...abcd", g, g)
    R = metric.riemann_tensor(0, a)
    assert np.allclose(R, expected, rtol=0, atol=1e-12 * np.abs(expected).max(axis=(1, 2, 3, 4))[:, None, None, None, None])


@given(seed=st.integers(0, 2**32 - 1), axes=st.lists(st.floats(0.2, 5.0), min_size=3, max_size=3))
def test_ellipsoid_gaussian_curvature_matches_the_closed_form(seed, axes):
    """Non-constant curvature: the Gauss equation against ``1 / (a^2 b^2 c^2 (sum p_r^2 / a_r^4)^2)``."""
    rng = np.random.default_rng(seed)
    p = random_sphere_points(rng, 16) * np.asarray(axes)
    K = ellipsoid_metric(axes).gaussian_curvature(p)
    assert np.allclose(K, ellipsoid_gaussian_curvature(axes, p), rtol=1e-12, atol=0)


# -- the chain: two routes, two charts -----------------------------------------------------------------
@settings(max_examples=40)
@given(L=base_lengths(4), a=chart_parameters(4), masses=st.sampled_from(["unit", "heavy"]))
def test_four_rod_gaussian_curvature_by_two_routes(L, a, masses):
    """n = 4: the Gauss equation (best chart at the point) against the intrinsic route (in chart 0 and in
    the best chart), to 1e-9 relative, with unit masses and with unequal hinge masses and heavy rods."""
    chain = Chain(4, L) if masses == "unit" else Chain(4, L, hinge_masses=[1.0, 3.0, 0.5], rod_densities=[0.2, 2.0, 0.0, 1.0])
    metric = chain.metric()
    p = SuspensionChart(4, L).get_point(a)
    K = metric.gaussian_curvature(p)
    i, b = metric.atlas.best_chart(p)
    chart = metric.atlas.charts[i]
    R = intrinsic_riemann(chart, metric.K, b)
    g = metric.local_metric(i, b)
    K_intrinsic = R[0, 1, 1, 0] / np.linalg.det(g)
    tol = 1e-9 * folded_conditioning(4, L)
    assert abs(K - K_intrinsic) <= tol * max(1.0, abs(K))
    # the whole tensor in the best chart, and chart 0 where it is good enough to be a second witness
    assert np.allclose(metric.riemann_tensor(i, b), R, rtol=0, atol=tol * max(1.0, np.abs(R).max()))
    if metric.atlas.charts[0].quality(a) > 0.3:
        g0 = metric.local_metric(0, a)
        K0 = intrinsic_riemann(metric.atlas.charts[0], metric.K, a)[0, 1, 1, 0] / np.linalg.det(g0)
        assert abs(K - K0) <= tol * max(1.0, abs(K))


@settings(max_examples=15)
@given(L=base_lengths(5), a=chart_parameters(5), seed=st.integers(0, 2**32 - 1))
def test_five_rods_riemann_tensor_two_routes_and_two_charts(L, a, seed):
    """n = 5 (dimension 3): the full tensor by both routes in the best chart; the tensor carried to a
    second chart of good quality agrees (curvature does not depend on the chart)."""
    chain = Chain(5, L, hinge_masses=[1.0, 2.0, 1.5, 0.7])
    metric = chain.metric()
    p = SuspensionChart(5, L).get_point(a)
    q = metric.atlas.qualities(p)
    i, j = np.argsort(q)[::-1][:2]
    tol = 1e-9 * folded_conditioning(5, L)
    ai, aj = metric.atlas.get_parameters(i, p), metric.atlas.get_parameters(j, p)
    Ri = metric.riemann_tensor(i, ai)
    scale = max(1.0, np.abs(Ri).max())
    assert np.allclose(Ri, intrinsic_riemann(metric.atlas.charts[i], metric.K, ai), rtol=0, atol=tol * scale)
    if q[j] > 0.3:
        # the Jacobian of the transition: d a_i / d a_j = J_i^+ J_j
        T = np.linalg.pinv(metric.atlas.charts[i].jacobian(ai)) @ metric.atlas.charts[j].jacobian(aj)
        carried = np.einsum("ia,jb,kc,ld,ijkl->abcd", T, T, T, T, Ri)
        assert np.allclose(metric.riemann_tensor(j, aj), carried, rtol=0, atol=1e-8 * folded_conditioning(5, L) * scale)
    # sectional and scalar curvature agree: S = sum_{i != j} K(e_i, e_j) over any orthonormal frame
    rng = np.random.default_rng(seed)
    J = metric.atlas.charts[i].jacobian(ai)
    g = metric.local_metric(i, ai)
    frame = J @ np.linalg.inv(np.linalg.cholesky(g)).T @ np.linalg.qr(rng.standard_normal((3, 3)))[0]
    pairs = [(r, s) for r in range(3) for s in range(3) if r != s]
    S = sum(metric.sectional_curvature(p, frame[:, r], frame[:, s]) for r, s in pairs)
    assert abs(S - metric.scalar_curvature(p)) <= 1e-9 * folded_conditioning(5, L) * max(1.0, abs(S))


def test_curvature_is_invariant_under_the_reflection_of_the_plane():
    """``p -> conj(p)`` is an isometry of every chain (``K = A (x) I_2`` commutes with it) and maps charts to
    other parameters: curvature at mirror configurations agrees, for n = 4 (Gaussian) and n = 5 (scalar)."""
    rng = np.random.default_rng(10)
    for chain, curvature in ((Chain(4, 2.3, hinge_masses=[1.0, 2.0, 3.0]), "gaussian_curvature"),
                             (Chain(5, 3.4, rod_densities=[0.5, 0.0, 2.0, 1.0, 0.3]), "scalar_curvature")):
        h = sample_configurations(chain, 40, rng)
        f = getattr(chain.metric(), curvature)
        K, K_mirror = f(chain.to_point(h)), f(chain.to_point(np.conj(h)))
        assert np.allclose(K, K_mirror, rtol=1e-12, atol=1e-12)


# -- Gauss-Bonnet -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("L, masses", [(2.3, None), (3.0, None), (3.8, None), (2.7, ([1.0, 4.0, 0.5], [0.0, 1.0, 3.0, 0.2]))])
def test_gauss_bonnet_on_four_rods(L, masses):
    """``int K dA = 2 pi chi(S^2) = 4 pi`` to 1e-6: chart 0's box, 128 Gauss-Legendre nodes in phi, 192
    trapezoid nodes in t, K through the best chart at every node.  (The rule converges spectrally: at L = 2.3,
    where chart 0's fold sharpens the integrand, 96 x 144 nodes are off by 1.2e-6 and 128 x 192 by 1.3e-8.)"""
    chain = Chain(4, L) if masses is None else Chain(4, L, hinge_masses=masses[0], rod_densities=masses[1])
    metric = chain.metric()
    total = metric.integrate(metric.gaussian_curvature, 0, metric.atlas.parameter_box, (128, 192), periodic=(1,))
    assert abs(total - 4 * np.pi) < 1e-6


# -- refusals ----------------------------------------------------------------------------------------------
def test_curvature_refuses_bad_input():
    metric = sphere_metric()
    p = np.array([0.0, 0.6, 0.8])
    u, v = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.8, -0.6])
    with pytest.raises(ValueError, match="u is not tangent at p"):
        metric.sectional_curvature(p, p, v)
    with pytest.raises(ValueError, match="v must be a nonzero tangent vector"):
        metric.sectional_curvature(p, u, 0 * v)
    with pytest.raises(ValueError, match="u and v must span a plane: sin of their angle is"):
        metric.sectional_curvature(p, u, 2 * u + 1e-10 * v)
    assert metric.sectional_curvature(p, u, 2 * u + 1e-6 * v) == pytest.approx(1.0, abs=1e-9)
    with pytest.raises(TypeError, match="u must be a real array"):
        metric.sectional_curvature(p, u.astype(complex), v)
    five = Chain(5, 3.5).metric()
    with pytest.raises(ValueError, match="gaussian_curvature needs a manifold of dimension 2, got dimension 3"):
        five.gaussian_curvature(five.atlas.get_point(0, np.array([0.1, 0.2, 0.3])))
    with pytest.raises(ValueError, match=r"nodes\[1\] must be a positive integer, got 0"):
        five.integrate(lambda p: np.ones(len(p)), 0, five.atlas.parameter_box, (4, 0, 4))
    with pytest.raises(ValueError, match="box and nodes need dim = 3 entries, got 3, 3 and 2"):
        five.integrate(lambda p: np.ones(len(p)), 0, five.atlas.parameter_box, (4, 4))


# -- the second fundamental form, bending and stiffness ---------------------------------------------------------
@given(seed=st.integers(0, 2**32 - 1), radius=st.floats(0.1, 10.0))
def test_second_fundamental_form_of_the_round_sphere(seed, radius):
    """On the sphere of radius r (K = r^2 I on the unit sphere's points): II(u, v) = -<u, v> p (the inward normal
    times <u, v>_K / r^2 in ambient units), |II|^2 = 2 / r^2, and the stiffness |II(v, v)|_K = |v|_K^2 / r."""
    rng = np.random.default_rng(seed)
    p = random_sphere_points(rng, 16)
    metric = InducedMetric(sphere_metric().atlas, radius**2 * np.eye(3))
    u, v = np.cross(p, rng.standard_normal((16, 3))), np.cross(p, rng.standard_normal((16, 3)))
    II = metric.second_fundamental_form(p, u, v)
    assert np.allclose(II, -np.sum(u * v, axis=1)[:, None] * p, rtol=0, atol=1e-12 * np.abs(II).max())
    assert np.allclose(metric.bending(p), 2 / radius**2, rtol=1e-12, atol=0)
    speed2 = radius**2 * np.sum(v * v, axis=1)
    assert np.allclose(metric.stiffness(p, v), speed2 / radius, rtol=1e-12, atol=0)


@given(L=base_lengths(5), seed=st.integers(0, 2**32 - 1), density=st.sampled_from([0.0, 0.6]))
@example(L=4.999999611612582, seed=15303, density=0.0)  # CI's draw: |II|^2 off by 10.5 eps / gap, II by about half
@settings(max_examples=25)
def test_second_fundamental_form_of_a_chain_is_the_constraints_normal_acceleration(L, seed, density):
    """The charts' route (second derivatives of the suspension chart, best chart) against the constraints' route
    (no chart): II(u, w) = -K^-1 G^T (G K^-1 G^T)^-1 (u^T nabla^2 c w), and so II(v, v) is the geodesic's
    acceleration, |II|^2 the sum over a K-orthonormal basis (linkage.geometry.tangent_basis).  Both routes lose
    about eps / gap, the gap of L to the nearer end of its range (measured 1.3e-9 relative at a gap of 1e-7);
    |II|^2, a sum of squares, twice that relative to itself."""
    from linkage.constraints import HingeConstraints
    from linkage.geometry import tangent_basis

    rng = np.random.default_rng(seed)
    chain = Chain(5, L, hinge_masses=rng.choice([0.2, 1.0, 5.0], size=4), rod_densities=density)
    metric, hc = chain.metric(), HingeConstraints(chain)
    h = sample_configurations(chain, 1, rng)[0]
    x = chain.to_point(h)
    E = chain.to_point(tangent_basis(chain, h))  # (3, 8)
    G0 = hc.jacobian(np.zeros_like(x))

    def constraint_form(a, b):
        return hc.min_norm_correction(hc.jacobian(x), -(hc.jacobian(a) - G0) @ b)  # dG[a] b; G is affine in x

    u, w = rng.standard_normal(3) @ E, rng.standard_normal(3) @ E
    rtol = 1e-10 + 10 * np.finfo(float).eps / min(L - 3, 5 - L)
    II = metric.second_fundamental_form(x, u, w)
    scale = np.linalg.norm(constraint_form(u, u)) + np.linalg.norm(constraint_form(w, w))
    assert np.abs(II - constraint_form(u, w)).max() <= rtol * scale
    assert np.abs(metric.second_fundamental_form(x, w, w) - hc.acceleration(x, w)).max() <= rtol * scale
    K = chain.ambient_metric
    bending = sum(constraint_form(a, b) @ K @ constraint_form(a, b) for a in E for b in E)
    assert abs(metric.bending(x) - bending) <= 2 * rtol * bending  # a square doubles the relative error
    assert abs(metric.stiffness(x, w) - np.sqrt(constraint_form(w, w) @ K @ constraint_form(w, w))) <= rtol * scale


def test_velocities_projected_in_hinge_space_are_tangent_for_the_charts_near_the_stretched_chain():
    """L within 1e-9 of n: HingeConstraints.project_velocity's vectors are accepted by the curvature code (a single
    projection left a normal part of 2e-8 of |v|, which sectional_curvature refused: one tolerance for both)."""
    from linkage.constraints import HingeConstraints

    chain = Chain(5, 5 - 1e-9)
    rng = np.random.default_rng(0)
    metric, hc = chain.metric(), HingeConstraints(chain)
    for h in sample_configurations(chain, 5, rng):
        x = chain.to_point(h)
        u, v = (hc.project_velocity(x, rng.normal(size=x.shape)) for _ in range(2))
        assert np.isfinite(metric.sectional_curvature(x, u, v))
