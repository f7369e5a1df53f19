"""HingeConstraints: G is dc/dx, the correction is the K-smallest solution, projections land on c = 0, G v = 0."""

import numpy as np
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.linalg import null_space

from charts import SuspensionChart
from linkage import Chain, rods
from linkage.constraints import ChainSystem, HingeConstraints
from manifold.constrained import ConstrainedGeometry


@st.composite
def systems(draw):
    """``(constraints, x, rng)``: a chain with a random mass model and a closed configuration ``x``.

    Unit rods in the sphere regime (``x`` from a suspension chart), or any
    generic lengths, any topology (``x`` from the diagonal parameterization).
    """
    n = draw(st.integers(3, 7))
    masses = dict(
        hinge_masses=draw(st.lists(st.floats(0.2, 5.0), min_size=n - 1, max_size=n - 1)),
        rod_densities=draw(st.lists(st.floats(0.0, 3.0), min_size=n, max_size=n)),
    )
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    if draw(st.booleans()):
        L = draw(st.floats(n - 2 + 0.05, n - 0.05))
        chain = Chain(n, L, **masses)
        a = [draw(st.floats(-1.4, 1.4)) for _ in range(n - 3)] + [draw(st.floats(-np.pi, np.pi))]
        x = SuspensionChart(n, L).get_point(np.array(a))
    else:
        ls = [draw(st.floats(0.3, 3.0)) for _ in range(n)]
        L = draw(st.floats(0.05, sum(ls) - 0.05))
        assume(2 * max(*ls, L) < sum(ls) + L)
        chain = Chain(ls, L, **masses)
        assume(chain.topology().generic)
        sample = chain.diagonal_space().sample(1, rng, method="hit-and-run")
        x = chain.to_point(sample.hinges[0])
    return HingeConstraints(chain), x, rng


def k_orthogonal_to_tangent_space(sys: HingeConstraints, G: np.ndarray, d: np.ndarray) -> float:
    """``max |w^T K d|`` over an orthonormal basis ``w`` of ``ker G``, relative to ``|K d|``."""
    W = null_space(G)
    return float(np.max(np.abs(W.T @ sys.K @ d), initial=0.0) / max(np.linalg.norm(sys.K @ d), 1e-300))


@given(systems())
def test_configurations_satisfy_the_constraints(case):
    sys, x, _ = case
    assert np.max(np.abs(sys.constraints(x))) < 1e-13


@given(systems(), st.floats(0.0, 0.3))
def test_jacobian_is_the_derivative_of_the_constraints(case, spread):
    """Central differences are exact for the quadratic ``c`` up to rounding, at any ``x``."""
    sys, x, rng = case
    x = x + spread * rng.normal(size=x.size)  # off the configuration space too
    eps = 1e-6
    fd = np.column_stack([(sys.constraints(x + eps * e) - sys.constraints(x - eps * e)) / (2 * eps)
                          for e in np.eye(x.size)])
    G = sys.jacobian(x)
    assert G.shape == (sys.n, 2 * (sys.n - 1)) == (sys.n, sys.ambient_dim)
    assert np.max(np.abs(G - fd)) < 1e-8 * max(1.0, np.max(np.abs(G)))


@given(systems())
def test_min_norm_correction_solves_and_is_k_orthogonal_to_the_tangent_space(case):
    sys, x, rng = case
    G = sys.jacobian(x)
    r = rng.normal(size=sys.n)
    d = sys.min_norm_correction(G, r)
    np.testing.assert_allclose(G @ d, r, rtol=0, atol=1e-10 * np.max(np.abs(r)))
    assert k_orthogonal_to_tangent_space(sys, G, d) < 1e-10
    # the K-smallest: adding any tangent vector w increases d^T K d
    w = null_space(G) @ rng.normal(size=sys.ambient_dim - sys.n)
    assert (d + w) @ sys.K @ (d + w) >= d @ sys.K @ d


@given(systems())
def test_acceleration_keeps_the_constraints_to_second_order(case):
    """Along ``x(t) = x + t v + t^2/2 a`` with tangent ``v``: ``c'' = G a + 2 |e'|^2 = 0``."""
    sys, x, rng = case
    v = sys.project_velocity(x, rng.normal(size=sys.ambient_dim))
    a = sys.acceleration(x, v)
    tau = 1e-2
    c = [sys.constraints(x + t * v + 0.5 * t * t * a) for t in tau * np.arange(-2, 3)]
    # c(x(t)) is a quartic in t, for which this five-point stencil is exact (up to rounding)
    c_second = (-c[0] + 16 * c[1] - 30 * c[2] + 16 * c[3] - c[4]) / (12 * tau**2)
    scale = np.linalg.norm(v) ** 2 + 1.0
    assert np.max(np.abs(c_second)) < 1e-9 * scale
    assert k_orthogonal_to_tangent_space(sys, sys.jacobian(x), a) < 1e-10  # a constraint force: K a = G^T lambda


@given(systems(), st.floats(1e-6, 1e-2))
def test_projections_land_on_the_constraints_and_the_tangent_space(case, spread):
    sys, x, rng = case
    x_off = x + spread * rng.normal(size=x.size)
    v_off = rng.normal(size=x.size)
    y = sys.project(np.concatenate([x_off, v_off]))
    xp, vp = y[: sys.ambient_dim], y[sys.ambient_dim :]
    assert np.max(np.abs(sys.constraints(xp))) < 1e-14
    G = sys.jacobian(xp)
    assert np.max(np.abs(G @ vp)) < 1e-12 * max(1.0, np.linalg.norm(v_off))
    # the velocity projection is K-orthogonal (the removed part is a constraint force) and idempotent
    assert k_orthogonal_to_tangent_space(sys, G, v_off - vp) < 1e-10
    # to the rounding floor of the multiplier system S = G K^-1 G^T (ill-conditioned near a fold, L -> n-2)
    floor = 10 * np.finfo(float).eps * np.linalg.cond(G @ sys.K_inv @ G.T)
    np.testing.assert_allclose(sys.project_velocity(xp, vp), vp, rtol=0, atol=max(1e-14, floor) * np.linalg.norm(v_off))
    # a point on the constraints stays there (to rounding)
    np.testing.assert_allclose(sys.project_position(xp), xp, rtol=0, atol=1e-14)


@settings(max_examples=25, deadline=None)
@given(systems(), st.floats(0.0, 0.3))
def test_the_compiled_rods_agree_with_numpys(case, spread):
    """The heyoka code of ``ChainSystem`` and the numpy code of ``HingeConstraints`` evaluate one formula
    (``linkage.rods``): ``c``, ``G v`` and the K-smallest correction agree to rounding, on and off the
    configuration space, and ``G v`` agrees with the product of numpy's ``G`` by ``v``."""
    sys, x, rng = case
    x = x + spread * rng.normal(size=x.size)
    v, r = rng.normal(size=x.size), rng.normal(size=sys.n)
    c, Gv, correction, energy = ConstrainedGeometry(ChainSystem(sys.chain), float)(x[None], v[None], r[None])
    G = sys.jacobian(x)
    scale = max(1.0, float(np.max(np.abs(G))))
    assert np.max(np.abs(c[0] - sys.constraints(x))) < 1e-14 * max(1.0, float(np.max(np.abs(c))))
    assert np.max(np.abs(Gv[0] - G @ v)) < 1e-14 * scale * np.linalg.norm(v)
    assert np.isclose(sys.tangency_residual(x, v), np.max(sys.lengths * np.abs(G @ v)), rtol=1e-13, atol=1e-15)
    expected = sys.min_norm_correction(G, r)
    assert np.max(np.abs(correction[0] - expected)) < 1e-9 * max(1.0, float(np.max(np.abs(expected))))
    assert np.isclose(float(energy[0]), 0.5 * v @ sys.K @ v, rtol=1e-14)


@given(systems(), st.floats(0.0, 0.3))
def test_the_rod_formulas_are_the_rods_and_the_derivatives_of_the_constraints(case, spread):
    """``linkage.rods`` against independent computations: the rods are the complex differences of the hinges
    (``Chain.rods``), and since ``c(x + s v)`` is quadratic in ``s``, its first and second differences with step
    1 are exactly ``G v`` and ``(dG/dt) v`` up to rounding."""
    sys, x, rng = case
    x = x + spread * rng.normal(size=x.size)
    v = rng.normal(size=x.size)
    e = rods.rod_vectors(list(x), sys.L)
    assert np.allclose([complex(z.re, z.im) for z in e], sys.chain.rods(sys.chain.from_point(x)), rtol=0, atol=1e-15)
    q = 1.0 / sys.lengths**2

    def c(s: float) -> np.ndarray:
        return np.array(rods.relative_residuals(rods.rod_vectors(list(x + s * v), sys.L), q, 1.0))

    scale = max(1.0, float(np.max(np.abs(c(1.0)))), float(np.max(np.abs(c(-1.0)))))
    rates = rods.rod_vectors(list(v), 0.0)
    assert np.max(np.abs(rods.constraint_rates(e, rates, q) - (c(1.0) - c(-1.0)) / 2)) < 1e-14 * scale
    assert np.max(np.abs(rods.velocity_terms(rates, q) - (c(1.0) - 2 * c(0.0) + c(-1.0)))) < 1e-14 * scale
