"""Geometry beyond exp: parallel transport, Jacobi fields, log and distance (``linkage.geometry``, ``manifold.carried``).

Each is checked against something computed another way: transport against a
numpy/scipy integration of its own equations from ``HingeConstraints`` (numpy
code, not the heyoka expressions) and by its invariants; Jacobi fields against
finite differences of geodesics and, on the n = 4 sphere, against the scalar
Jacobi equation ``y'' + K |v|^2 y = 0`` with the Gaussian curvature of the
curvature code (the Gauss equation in the charts); log against exp; holonomy
against the angle excess of the geodesic triangle.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from linkage import Chain
from linkage import geometry
from linkage.constraints import ChainSystem, HingeConstraints
from linkage.diagonal_path import DifferentComponentsError
from linkage.motion import choose_method, free_motion
from linkage.sampling import sample_starts
from linkage.sensitivity import sensitivity
from manifold import GeodesicIntegrationError, Precision, SaveAt
from manifold.carried import solve_carried
from manifold.jacobi import JacobiField
from manifold.transport import ParallelTransport


def _random_tangent(chain: Chain, hinges: np.ndarray, rng: np.random.Generator, k: int | None = None) -> np.ndarray:
    """Complex tangent vectors at ``hinges`` (``k`` of them, or one), K-projected from Gaussian draws."""
    hc = HingeConstraints(chain)
    x = chain.to_point(hinges)
    rows = [hc.project_velocity(x, rng.normal(size=x.shape)) for _ in range(1 if k is None else k)]
    w = chain.from_point(np.array(rows))
    return w[0] if k is None else w


def _gram(chain: Chain, vectors: np.ndarray) -> np.ndarray:
    """Kinetic inner products ``Re(u^H A w)`` of the rows of ``vectors`` (last axis the hinges)."""
    return np.real(np.einsum("...ai,ij,...bj->...ab", vectors.conj(), chain.mass_matrix, vectors))


def _pole_start(n: int, L: float) -> np.ndarray:
    """Hinges at an exact pole of chart 0 (its first rods in one line)."""
    chain = Chain(n, L)
    a = np.zeros(n - 2)
    a[0] = np.pi / 2
    return chain.from_point(chain.atlas().get_point(0, a))


chains = st.builds(
    lambda n, gap, side, masses, density: Chain(n, (n - 2 + gap) if side else (n - gap),
                                                hinge_masses=masses[: n - 1], rod_densities=density),
    st.integers(3, 6), st.sampled_from([0.5, 0.1, 1e-2, 1e-3]), st.booleans(),
    st.lists(st.sampled_from([1e-2, 0.3, 1.0, 5.0, 50.0]), min_size=7, max_size=7), st.sampled_from([0.0, 0.4]))


def _transport_drift(chain: Chain, seed: int, T: float) -> tuple[float, geometry.TransportedVectors]:
    """Over ``T``, the largest change of the Gram matrix of two transported vectors and the velocity (relative to
    the norms), from a start of speed ~1 (kinetic energy half the mean hinge mass)."""
    rng = np.random.default_rng(seed)
    H, V = sample_starts(chain, 1, 0.5 * float(np.mean(chain.hinge_masses)), rng)
    W0 = _random_tangent(chain, H[0], rng, 2)
    pt = geometry.parallel_transport(chain, H[0], V[0], W0, T, save=SaveAt(t_eval=np.linspace(0, T, 41)))
    gram = _gram(chain, np.concatenate([pt.vectors, pt.velocities[:, None, :]], axis=1))
    norms = np.sqrt(np.diagonal(gram[0]))
    return float((np.abs(gram - gram[0]) / np.outer(norms, norms)).max()), pt


@pytest.mark.parametrize("n", [3, 4, 6, 8])
def test_transport_is_an_isometry_to_1e_13_over_t_20(n):
    """Unit rods and masses, L in mid-range: the Gram matrix of (W_1, W_2, v) moves by at most 1e-13."""
    drift, _ = _transport_drift(Chain(n, n - 0.6), 1, 20.0)
    assert drift <= 1e-13


@given(chain=chains, seed=st.integers(0, 2**16), backward=st.booleans())
@example(chain=Chain(3, 1.001, hinge_masses=[0.01, 1.0]), seed=41801, backward=True)
@settings(max_examples=10)
def test_transport_is_an_isometry_and_keeps_its_angle_with_the_velocity(chain, seed, backward):
    """Over T = 20, short links, spread masses and L near both ends included: the Gram matrix of two transported
    vectors and the velocity moves by at most 20 times the geodesic's own energy error plus the random walk of
    rounding, ``sqrt(steps) u`` (the transport is as isometric as the geodesic keeps its energy: both are
    integrated with one tolerance; near the top of L both lose digits), and the vectors stay as tangent as the
    geodesic's own velocity: their tangency residual, per kinetic norm, is at most 20 times the sum of that yardstick
    and the velocity's largest residual per kinetic norm.  A solve may refuse (raise) only where the geodesic alone fails its
    energy check too.

    The example: L = 1.001, just above the singular length 1 of three unit rods, and a hinge of mass 0.01 that
    whips round near the folded chain at seven times the mean speed for 0.002 of time.  The velocity leaves its
    tangent space by 24 yardsticks there, the transported vectors by 47, and both decay under the stabilisation."""
    T = -20.0 if backward else 20.0
    try:
        drift, pt = _transport_drift(chain, seed, T)
    except GeodesicIntegrationError as refusal:
        rng = np.random.default_rng(seed)
        H, V = sample_starts(chain, 1, 0.5 * float(np.mean(chain.hinge_masses)), rng)
        alone = free_motion(chain, H[0], V[0], T, method="hinges", compact_mode=True, throw=False)
        assert not alone.success, f"the transport refused where the geodesic alone succeeds: {refusal}"
        return
    sol = pt.carried.solution
    # measured over 80 draws: the Gram matrix at most 5.5 times this yardstick; over 120 more and the 25 mass pairs
    # of the example's chain, the tangency at most 3.3 times its own
    yardstick = sol.relative_energy_error + np.sqrt(sol.n_steps) * 2.0**-53
    assert drift <= 20 * yardstick
    gram0 = _gram(chain, np.concatenate([pt.vectors[0], pt.velocities[:1]]))
    norms = np.sqrt(np.diagonal(gram0))
    hc = HingeConstraints(chain)
    x = chain.to_point(pt.hinges)
    velocity_residual = (hc.tangency_residual(x, chain.to_point(pt.velocities)) / norms[2]).max()
    for a in range(2):
        w = chain.to_point(pt.vectors[:, a])
        assert hc.tangency_residual(x, w).max() <= 20 * (yardstick + velocity_residual) * norms[a]


def _numpy_transport(chain: Chain, h0, v0, w0, ts) -> np.ndarray:
    """The geodesic and a transported vector by scipy's DOP853 on numpy code: ``x'' = HingeConstraints.acceleration``,
    ``W' = K^-1 G^T M^-1 (-(dG[v]) W)`` with ``dG[v] = G(v) - G(0)`` (``G`` is affine in ``x``)."""
    hc = HingeConstraints(chain)
    N = 2 * (chain.n - 1)
    G0 = hc.jacobian(np.zeros(N))

    def rhs(_, y):
        x, v, W = y[:N], y[N : 2 * N], y[2 * N :]
        return np.concatenate([v, hc.acceleration(x, v),
                               hc.min_norm_correction(hc.jacobian(x), -(hc.jacobian(v) - G0) @ W)])

    y0 = np.concatenate([chain.to_point(h0), chain.to_point(v0), chain.to_point(w0)])
    sol = solve_ivp(rhs, (0, ts[-1]), y0, method="DOP853", rtol=1e-13, atol=1e-13, t_eval=ts)
    assert sol.success
    return chain.from_point(sol.y[2 * N :].T)


@pytest.mark.parametrize("where", ["generic", "pole"])
@pytest.mark.parametrize("masses", ["unit", "hinge masses", "rod densities"])
def test_transport_agrees_with_an_independent_numpy_integration(where, masses):
    """Over T = 10, from a generic start and from an exact pole of chart 0: the heyoka transport and a scipy
    DOP853 integration of numpy code agree to 1e-10."""
    kw = {"unit": {}, "hinge masses": {"hinge_masses": [0.5, 2.0, 1.0, 3.0]},
          "rod densities": {"hinge_masses": [0.5, 2.0, 1.0, 3.0], "rod_densities": 0.7}}[masses]
    chain = Chain(5, 3.4, **kw)
    rng = np.random.default_rng(7)
    if where == "pole":
        h0 = _pole_start(5, 3.4)
        v0 = _random_tangent(chain, h0, rng)
    else:
        H, V = sample_starts(chain, 1, 0.5, rng)
        h0, v0 = H[0], V[0]
    w0 = _random_tangent(chain, h0, rng)
    ts = np.linspace(0, 10, 21)
    pt = geometry.parallel_transport(chain, h0, v0, w0, 10.0, save=SaveAt(t_eval=ts))
    reference = _numpy_transport(chain, h0, v0, w0, ts)
    assert np.abs(pt.vectors - reference).max() <= 1e-10 * max(1.0, np.abs(w0).max())


def test_transport_runs_in_every_precision():
    """long double, real128 and 150-bit MultiPrecision keep the isometry to their own precision (1e-16, 1e-28 and
    1e-40 relative, over T = 5); a Jacobi field runs in MultiPrecision too, its invariants checked by the solve."""
    chain = Chain(4, 2.6, hinge_masses=[1.0, 2.0, 0.5])
    rng = np.random.default_rng(2)
    H, V = sample_starts(chain, 1, 0.5, rng)
    w0 = _random_tangent(chain, H[0], rng)
    for fp_type, bound in (("longdouble", 1e-16), ("real128", 1e-28), ("mp150", 1e-40)):
        pt = geometry.parallel_transport(chain, H[0], V[0], w0, 5.0, precision=Precision(fp_type=fp_type))
        _, v, values = pt.carried(np.array([0.0, 5.0]))
        W = values[0]["vectors"][:, 0]
        K = pt.carried.geometry.K
        norm = [W[i] @ K @ W[i] for i in range(2)]
        angle = [W[i] @ K @ v[i] for i in range(2)]
        assert float(abs(norm[1] - norm[0]) / norm[0]) <= bound
        assert float(abs(angle[1] - angle[0]) / norm[0]) <= 10 * bound
    jf = geometry.jacobi_field(chain, H[0], V[0], 0 * w0, w0, 2.0, precision=Precision(fp_type="mp150"))
    assert jf.carried.solution.success and jf.carried.solution.relative_energy_error <= 1e-40


def _geodesic_end(hc: HingeConstraints, chain: Chain, x0, v0, ts):
    from manifold.constrained import solve_constrained

    sol = solve_constrained(ChainSystem(chain), x0, v0, ts[-1], save=SaveAt(t_eval=ts, dense=False))
    return sol.points.astype(float)


@pytest.mark.parametrize("n, L, masses", [(5, 3.3, [1.0, 0.3, 2.0, 1.0]), (6, 4.5, [1.0, 1.0, 4.0, 0.5, 1.0])])
def test_jacobi_fields_agree_with_finite_differences_of_geodesics(n, L, masses):
    """J(t) for J(0) = j0, D_t J(0) = w0 against the central difference of the geodesics from the start curve
    (proj(x0 + s j0), P(v0 + s w0)), s = +-1e-5 (difference error ~ s^2): to 1e-7 relative over T = 5."""
    chain = Chain(n, L, hinge_masses=masses)
    rng = np.random.default_rng(11)
    H, V = sample_starts(chain, 1, 0.5, rng)
    j0, w0 = _random_tangent(chain, H[0], rng), _random_tangent(chain, H[0], rng)
    ts = np.linspace(0, 5, 11)
    jf = geometry.jacobi_field(chain, H[0], V[0], j0, w0, 5.0, save=SaveAt(t_eval=ts))
    hc = HingeConstraints(chain)
    x0, v0 = chain.to_point(H[0]), chain.to_point(V[0])
    s = 1e-5
    ends = []
    for sign in (1, -1):
        x = hc.project_position(x0 + sign * s * chain.to_point(j0))
        v = hc.project_velocity(x, v0 + sign * s * chain.to_point(w0))
        ends.append(_geodesic_end(hc, chain, x, v, ts))
    difference = chain.from_point((ends[0] - ends[1]) / (2 * s))
    assert np.abs(jf.field - difference).max() <= 1e-7 * np.abs(jf.field).max()


def test_jacobi_field_solves_the_jacobi_equation_of_the_curvature_code_and_vanishes_at_the_conjugate_point():
    """n = 4 (a 2-sphere): with J(0) = 0 and D_t J(0) = n0 perpendicular to v, J = y(t) n(t) with n the
    transported unit normal and y'' + K(x(t)) |v|^2 y = 0, K the Gaussian curvature of the metric (Gauss equation
    in the charts).  The transport and the field ride on one geodesic (two terms in one integrator); y from scipy
    agrees to 1e-8, and J vanishes at y's first zero, the first conjugate point, to 1e-8 of its size."""
    chain = Chain(4, 2.2, hinge_masses=[1.0, 3.0, 0.5])
    metric = chain.metric()
    rng = np.random.default_rng(5)
    H, V = sample_starts(chain, 1, 0.5, rng)
    x0, v0 = chain.to_point(H[0]), chain.to_point(V[0])
    K = chain.ambient_metric
    w = HingeConstraints(chain).project_velocity(x0, rng.normal(size=x0.shape))
    n0 = w - (w @ K @ v0) / (v0 @ K @ v0) * v0
    n0 /= np.sqrt(n0 @ K @ n0)
    T = 12.0
    carried = solve_carried(ChainSystem(chain), x0, v0, T, [ParallelTransport(n0), JacobiField(0 * n0, n0)])
    speed2 = float(v0 @ K @ v0)

    def rhs(t, y):
        p, _ = carried.solution(np.array([t]))
        return [y[1], -float(metric.gaussian_curvature(p.astype(float))[0]) * speed2 * y[0]]

    def zero(t, y):
        return y[0]
    zero.direction = -1

    ts = np.linspace(0, T, 25)
    ref = solve_ivp(rhs, (0, T), [0.0, 1.0], method="DOP853", rtol=1e-12, atol=1e-13, t_eval=ts, events=zero)
    assert ref.success and len(ref.t_events[0]) >= 1, "the geodesic must reach a conjugate point within T"
    _, _, values = carried(ts)
    normal, J = values[0]["vectors"][:, 0].astype(float), values[1]["field"][:, 0].astype(float)
    y = np.einsum("ti,ij,tj->t", J, K, normal)
    assert np.abs(y - ref.y[0]).max() <= 1e-8 * np.abs(ref.y[0]).max()
    # J is normal: its tangential part (D_t J(0) is perpendicular to v) stays zero
    residual = J - y[:, None] * normal
    assert np.abs(residual).max() <= 1e-10 * np.abs(J).max()
    t_conjugate = ref.t_events[0][0]
    _, _, at = carried(np.array([t_conjugate]))
    Jc = at[1]["field"][0, 0].astype(float)
    assert np.sqrt(Jc @ K @ Jc) <= 1e-8 * np.abs(ref.y[0]).max()


@given(n=st.integers(4, 6), seed=st.integers(0, 2**16), radius=st.sampled_from([0.05, 0.2, 0.4]),
       pole=st.booleans())
@settings(max_examples=10)
def test_log_inverts_exp_and_distance_is_symmetric(n, seed, radius, pole):
    """log(h0, exp(h0, v0)) = v0 to 1e-10 for |v0| below the injectivity radius, from a generic start or an exact
    pole of chart 0, with spread masses; distance is symmetric to 1e-12.  The kinetic length scales with the square
    root of the masses, so |v0| is ``radius`` times the square root of the lightest (at L = n - 0.6, unit masses,
    |v0| = 0.8 was already beyond it: a geodesic of length 0.795 joined the ends)."""
    rng = np.random.default_rng(seed)
    L = n - 0.6
    chain = Chain(n, L, hinge_masses=rng.choice([0.2, 1.0, 5.0], size=n - 1))
    h0 = _pole_start(n, L) if pole else sample_starts(chain, 1, 0.5, rng)[0][0]
    v0 = _random_tangent(chain, h0, rng)
    size = radius * np.sqrt(chain.hinge_masses.min())
    v0 *= size / np.sqrt(2 * float(chain.kinetic_energy(v0)))
    h1 = geometry.exp(chain, h0, v0)
    result = geometry.log(chain, h0, h1)
    assert np.abs(result.velocity - v0).max() <= 1e-10
    assert abs(result.distance - size) <= 1e-12
    assert abs(geometry.distance(chain, h1, h0) - result.distance) <= 1e-12


def _angle(chain: Chain, u: np.ndarray, w: np.ndarray) -> float:
    g = _gram(chain, np.array([u, w]))
    return float(np.arccos(np.clip(g[0, 1] / np.sqrt(g[0, 0] * g[1, 1]), -1, 1)))


def _curvature_integral(chain: Chain, A, B, C, nodes: int = 12) -> float:
    """``int K dA`` over the geodesic triangle ABC, on the fan of geodesics ``F(u, s) = exp_A(s V(u))`` from ``A``
    to the side BC (``V(u) = log_A(BC(u))``): Gauss-Legendre in ``u`` and ``s``, the area element
    ``|F_s ^ F_u|`` from the Jacobi field ``F_u`` (zero at ``A``, matched to the side's velocity at ``s = 1``) and
    ``K`` from the curvature code."""
    x, wx = np.polynomial.legendre.leggauss(nodes)
    u, wu = (x + 1) / 2, wx / 2
    side = geometry.parallel_transport(chain, B, geometry.log(chain, B, C).velocity, np.zeros(chain.n - 1, complex),
                                       1.0, save=SaveAt(t_eval=u))
    basis = geometry.tangent_basis(chain, A)
    metric, total = chain.metric(), 0.0
    for k in range(nodes):
        V = geometry.log(chain, A, side.hinges[k]).velocity
        fan = geometry.jacobi_field(chain, A, V, np.zeros_like(basis), basis, 1.0,
                                    save=SaveAt(t_eval=np.append(u, 1.0)))
        c, *_ = np.linalg.lstsq(chain.to_point(fan.field[-1]).T, chain.to_point(side.velocities[k]), rcond=None)
        g = _gram(chain, np.stack([fan.velocities[:-1], np.einsum("i,tin->tn", c, fan.field[:-1])], axis=1))
        area = np.sqrt(g[:, 0, 0] * g[:, 1, 1] - g[:, 0, 1] ** 2)
        total += wu[k] * np.sum(wu * metric.gaussian_curvature(chain.to_point(fan.hinges[:-1])) * area)
    return float(total)


def test_holonomy_of_a_geodesic_triangle_is_its_angle_excess_and_its_curvature_integral():
    """n = 4: a vector transported around a geodesic triangle (sides from log) turns by the triangle's angle
    excess, which equals the enclosed integral of the Gaussian curvature (Gauss-Bonnet), to 1e-8.  Three routes:
    transport; the angles between logs; Jacobi fields and the curvature code (the Gauss equation in the charts)."""
    chain = Chain(4, 2.5, hinge_masses=[1.0, 2.0, 0.7])
    rng = np.random.default_rng(9)
    A = sample_starts(chain, 1, 0.5, rng)[0][0]
    B = geometry.exp(chain, A, 0.8 * _unit(chain, _random_tangent(chain, A, rng)))
    C = geometry.exp(chain, A, 0.8 * _unit(chain, _random_tangent(chain, A, rng)))
    vertices = [A, B, C]
    logs = {(i, j): geometry.log(chain, vertices[i], vertices[j]).velocity for i in range(3) for j in range(3) if i != j}
    excess = sum(_angle(chain, logs[(i, (i + 1) % 3)], logs[(i, (i + 2) % 3)]) for i in range(3)) - np.pi
    w0 = w = _random_tangent(chain, A, rng)
    for i in range(3):
        side = geometry.parallel_transport(chain, vertices[i], logs[(i, (i + 1) % 3)], w, 1.0,
                                           save=SaveAt(t_eval=[0.0, 1.0]))
        assert np.abs(side.hinges[-1] - vertices[(i + 1) % 3]).max() <= 1e-12
        w = side.vectors[-1]
    assert abs(excess) >= 1e-3, "the triangle must enclose curvature for the test to say something"
    assert abs(_angle(chain, w0, w) - abs(excess)) <= 1e-8
    assert abs(_curvature_integral(chain, A, B, C) - excess) <= 1e-8


def _unit(chain: Chain, v: np.ndarray) -> np.ndarray:
    return v / np.sqrt(2 * float(chain.kinetic_energy(v)))


def test_bad_inputs_are_refused_by_name():
    chain = Chain(4, 2.6)
    rng = np.random.default_rng(0)
    H, V = sample_starts(chain, 1, 0.5, rng)
    with pytest.raises(ValueError, match="vectors0 is not tangent"):
        geometry.parallel_transport(chain, H[0], V[0], H[0], 1.0)
    with pytest.raises(ValueError, match="vectors0: expected n - 1 = 3 complex hinges"):
        geometry.parallel_transport(chain, H[0], V[0], np.zeros((2, 5), complex), 1.0)
    with pytest.raises(ValueError, match="field0 and derivative0 must have one shape"):
        geometry.jacobi_field(chain, H[0], V[0], np.zeros(3, complex), np.zeros((2, 3), complex), 1.0)
    with pytest.raises(ValueError, match="T must be"):
        geometry.parallel_transport(chain, H[0], V[0], V[0], 0.0)
    with pytest.raises(ValueError, match="t must be"):
        geometry.exp(chain, H[0], V[0], float("nan"))
    with pytest.raises(TypeError, match="exp does not take save="):
        geometry.exp(chain, H[0], V[0], 1.0, save=SaveAt(dense=True))
    # an option the method does not take is named with the function and the method, before anything is solved
    with pytest.raises(TypeError, match=r"exp\(method='hinges'\) does not take method='charts' \(its options: "):
        geometry.exp(chain, H[0], V[0], 1.0, method="charts")
    with pytest.raises(TypeError, match=r"parallel_transport\(method='charts'\) does not take rate=2.0 \(its options: "
                                        r"budget, chart, compact_mode, .*q_out"):
        geometry.parallel_transport(chain, H[0], V[0], V[0], 1.0, method="charts", rate=2.0)
    with pytest.raises(TypeError, match=r"jacobi_field\(method='hinges'\) does not take q_out=0.5 \(its options: "
                                        r"budget, compact_mode, progress, projection_interval, rate"):
        geometry.jacobi_field(chain, H[0], V[0], 0 * V[0], V[0], 1.0, method="hinges", q_out=0.5)
    with pytest.raises(TypeError, match=r"sensitivity\(method='hinges'\) does not take rtol=1e-08; the tolerance is "
                                        r"precision=Precision\(tol=...\)"):
        sensitivity(chain, H[0], V[0], 1.0, rtol=1e-8)
    with pytest.raises(ValueError, match="max_iterations"):
        geometry.log(chain, H[0], H[0], max_iterations=0)
    with pytest.raises(ValueError, match="velocity_guess must have shape"):
        geometry.log(chain, H[0], H[1] if len(H) > 1 else H[0] * 1, velocity_guess=[V[0], V[0]])
    with pytest.raises(ValueError, match=r"log shoots in float64 .*, got precision=Precision\(fp_type="):
        geometry.log(chain, H[0], H[0], precision=Precision(fp_type="real128"))
    with pytest.raises(TypeError, match="CarriedTerm"):
        solve_carried(ChainSystem(chain), chain.to_point(H[0]), chain.to_point(V[0]), 1.0, ["transport"])
    with pytest.raises(ValueError, match="projection"):
        solve_carried(ChainSystem(chain), chain.to_point(H[0]), chain.to_point(V[0]), 1.0,
                      [ParallelTransport(chain.to_point(V[0]))], stabilisation="projection")


def test_the_carried_check_sees_a_drift():
    """The invariant check of a carried term flags a transported vector whose norm moved (and passes it unmoved)."""
    from manifold.carried import carried_violation
    from manifold.constrained import ConstrainedGeometry

    chain = Chain(4, 2.6)
    rng = np.random.default_rng(0)
    H, V = sample_starts(chain, 1, 0.5, rng)
    x, v = chain.to_point(H[0]), chain.to_point(V[0])
    w = chain.to_point(_random_tangent(chain, H[0], rng))
    term, geo = ParallelTransport(w), ConstrainedGeometry(ChainSystem(chain), float)
    first = np.concatenate([x, v, w])
    slots = slice(12, 18)
    assert carried_violation(term, geo, first[None, :], first, slots, [1.0], 10, 1e-16) is None
    moved = np.concatenate([x, v, (1 + 1e-9) * w])[None, :]
    message = carried_violation(term, geo, moved, first, slots, [1.0], 10, 1e-16)
    assert message is not None and "parallel transport check failed at t = 1" in message


@given(n=st.integers(3, 7), seed=st.integers(0, 2**16), density=st.sampled_from([0.0, 0.5]))
@settings(max_examples=10)
def test_tangent_basis_is_orthonormal_in_the_kinetic_metric_and_tangent(n, seed, density):
    rng = np.random.default_rng(seed)
    chain = Chain(n, n - 0.5, hinge_masses=rng.choice([0.1, 1.0, 10.0], size=n - 1), rod_densities=density)
    h = sample_starts(chain, 1, 0.5, rng)[0][0]
    E = geometry.tangent_basis(chain, h)
    assert E.shape == (n - 2, n - 1)
    assert np.abs(_gram(chain, E) - np.eye(n - 2)).max() <= 1e-13
    x = chain.to_point(h)
    assert HingeConstraints(chain).tangency_residual(np.broadcast_to(x, (n - 2, len(x))), chain.to_point(E)).max() <= 1e-13


def test_log_guards_its_guesses_and_refuses_what_it_cannot_reach():
    """A zero first guess still finds the geodesic (the chord's guess runs too); an end point that closes only to
    1e-10 is projected first; a point of the other component of a two-circle space is refused, naming the
    component (before any Newton step); a step that overshoots is halved (from a poor guess, Newton still
    converges)."""
    chain = Chain(4, 2.6, hinge_masses=[1.0, 2.0, 0.5])
    rng = np.random.default_rng(4)
    h0 = sample_starts(chain, 1, 0.5, rng)[0][0]
    v = _unit(chain, _random_tangent(chain, h0, rng))
    h1 = geometry.exp(chain, h0, v)
    assert np.abs(geometry.log(chain, h0, h1, velocity_guess=np.zeros(3, complex)).velocity - v).max() <= 1e-10
    off = h1 * (1 + 3e-10)
    assert np.abs(geometry.log(chain, h0, off).velocity - v).max() <= 1e-8
    poor = geometry.log(chain, h0, h1, velocity_guess=-2.5 * v)
    assert poor.distance <= 1.0 + 1e-10 and min(poor.candidates) == poor.distance
    two_circles = Chain(3, 0.5)  # two circles: the elbow configurations and their mirror images
    h = _three_rod_configuration(two_circles)
    with pytest.raises(DifferentComponentsError, match="different connected components"):
        geometry.log(two_circles, h, np.conj(h))


def _three_rod_configuration(chain: Chain) -> np.ndarray:
    """A configuration of three unit rods from 0 to L: the first rod up at 80 degrees, the rest by the circle
    of the last hinge."""
    p1 = np.exp(1j * np.deg2rad(80.0))
    L = chain.L
    d = abs(L - p1)
    # p2 on the circles |p2 - p1| = 1, |p2 - L| = 1: the midpoint plus the perpendicular offset
    mid = (p1 + L) / 2
    p2 = mid + 1j * (L - p1) / d * np.sqrt(1 - (d / 2) ** 2)
    return np.array([p1, p2])


def test_results_pickle_and_evaluate_the_same_after():
    """A transport and a Jacobi field result, shipped to another process as pickles, give the same numbers."""
    import pickle

    chain = Chain(4, 2.6)
    rng = np.random.default_rng(8)
    H, V = sample_starts(chain, 1, 0.5, rng)
    w = _random_tangent(chain, H[0], rng)
    for result in (geometry.parallel_transport(chain, H[0], V[0], w, 3.0),
                   geometry.jacobi_field(chain, H[0], V[0], 0 * w, w, 3.0)):
        copy = pickle.loads(pickle.dumps(result))
        a, b = result(np.array([0.5, 2.5])), copy(np.array([0.5, 2.5]))
        names = ["vectors"] if isinstance(a, geometry.TransportedVectors) else ["field", "field_derivative"]
        for name in ["hinges", "velocities"] + names:
            assert np.array_equal(getattr(a, name), getattr(b, name))


def test_log_follows_the_diagonal_path_where_its_guesses_fail():
    """Far apart (distance about 3 at n = 5), from a velocity guess that points away: the guesses fail or find a
    geodesic, and the continuation along the diagonal path finds one whose exp lands on hinges1."""
    chain = Chain(5, 3.3)
    rng = np.random.default_rng(12)
    H = chain.from_diagonals(chain.diagonal_space().sample(2, rng).x, [[1, 1, -1, 1], [-1, 1, 1, -1]])
    result = geometry.log(chain, H[0], H[1], max_iterations=6)
    assert np.abs(geometry.exp(chain, H[0], result.velocity) - H[1]).max() <= 1e-10


@pytest.mark.parametrize("where", ["generic", "pole"])
@pytest.mark.parametrize("masses", ["unit", "hinge masses", "rod densities"])
def test_transport_and_jacobi_fields_in_charts_agree_with_hinge_coordinates(where, masses):
    """Over T = 10, across chart switches (at a threshold of 0.55, so that they happen; the atlas guarantees 0.6), in Sundman's time with the
    state (a, J c): transported vectors and a Jacobi field carried beside the chart geodesic equal those of the
    hinge-coordinate integration (the constraint equations, no chart) to 1e-10."""
    kw = {"unit": {}, "hinge masses": {"hinge_masses": [0.5, 2.0, 1.0, 3.0]},
          "rod densities": {"hinge_masses": [0.5, 2.0, 1.0, 3.0], "rod_densities": 0.7}}[masses]
    chain = Chain(5, 3.4, **kw)
    rng = np.random.default_rng(21)
    h0 = _pole_start(5, 3.4) if where == "pole" else sample_starts(chain, 1, 0.5, rng)[0][0]
    v0 = 3 * _unit(chain, _random_tangent(chain, h0, rng))  # fast enough to meet a switch within T = 10
    W0 = _random_tangent(chain, h0, rng, 2)
    ts = np.linspace(0, 10, 21)
    charts = geometry.parallel_transport(chain, h0, v0, W0, 10.0, save=SaveAt(t_eval=ts), method="charts", q_out=0.55)
    hinges = geometry.parallel_transport(chain, h0, v0, W0, 10.0, save=SaveAt(t_eval=ts))
    assert charts.carried.solution.n_switches >= 1
    assert np.abs(charts.vectors - hinges.vectors).max() <= 1e-10
    J = [geometry.jacobi_field(chain, h0, v0, 0 * W0[0], W0[0], 10.0, save=SaveAt(t_eval=ts), method="charts",
                               q_out=0.55),
         geometry.jacobi_field(chain, h0, v0, 0 * W0[0], W0[0], 10.0, save=SaveAt(t_eval=ts))]
    assert np.abs(J[0].field - J[1].field).max() <= 1e-10 * max(1.0, np.abs(J[1].field).max())
    assert np.abs(J[0].field_derivative - J[1].field_derivative).max() <= 1e-10 * max(1.0, np.abs(J[1].field).max())


class _Stop(Exception):
    """Raised by a spy in place of a solve: what it was given is all a test needs."""


def test_the_compile_option_reaches_the_chart_stepper_and_not_the_hinge_solver_at_rest(monkeypatch):
    """``compact_mode`` with ``method="charts"`` compiles the charts' stepper so (nothing is compiled here: spies
    stand in for the solvers); a start at rest has no chart motion and runs the hinge solver, which keeps its own
    default for carried terms (compact: unrolled, a Jacobi field compiled for 20 s at n = 4)."""
    chain = Chain(4, 2.7)
    rng = np.random.default_rng(5)
    h0 = sample_starts(chain, 1, 0.5, rng)[0][0]
    v0, W0 = _unit(chain, _random_tangent(chain, h0, rng)), _random_tangent(chain, h0, rng)
    seen: dict = {}

    def chart_solve(*args, stepper, **kwargs):
        seen["stepper"], seen["chart options"] = stepper, kwargs
        raise _Stop

    def carried_solve(*args, **kwargs):
        seen["carried options"] = kwargs
        raise _Stop

    monkeypatch.setattr(geometry, "solve_chart_exp_ode", chart_solve)
    monkeypatch.setattr(geometry, "solve_carried", carried_solve)
    for compact_mode in (False, True):
        with pytest.raises(_Stop):
            geometry.parallel_transport(chain, h0, v0, W0, 1.0, method="charts", compact_mode=compact_mode)
        assert seen["stepper"].compact_mode is compact_mode and "compact_mode" not in seen["chart options"]
    with pytest.raises(_Stop):
        geometry.jacobi_field(chain, h0, 0 * v0, 0 * W0, W0, 1.0, method="charts", compact_mode=False)
    assert "compact_mode" not in seen["carried options"]


def test_the_default_method_is_free_motion_s():
    """``method="auto"``, as in ``free_motion``: transport and Jacobi fields in hinge coordinates on a generic chain,
    in the atlas (Sundman's time) on a nearly stretched one, where the hinge method loses digits; each the same
    numbers as the method named."""
    rng = np.random.default_rng(4)
    for chain, kind in ((Chain(5, 4.2), "constrained"), (Chain(5, 5 - 1e-4), "sundman")):
        h0 = sample_starts(chain, 1, 0.5, rng)[0][0]
        v0, W0 = _unit(chain, _random_tangent(chain, h0, rng)), _random_tangent(chain, h0, rng)
        named = {"method": choose_method(chain, {})}
        moved = [geometry.parallel_transport(chain, h0, v0, W0, 0.5, **kw) for kw in ({}, named)]
        fields = [geometry.jacobi_field(chain, h0, v0, 0 * W0, W0, 0.5, **kw) for kw in ({}, named)]
        assert kind in moved[0].carried.solution.method and kind in fields[0].carried.solution.method
        assert np.array_equal(moved[0].vectors, moved[1].vectors) and np.array_equal(fields[0].field, fields[1].field)


@pytest.mark.parametrize("scale", [0.0, 1e-20])
def test_a_jacobi_field_along_a_chain_at_rest_grows_linearly_in_both_methods(scale):
    """At rest the geodesic is a point and a Jacobi field is J0 + t U0; method='charts' hands such a start to the
    hinge coordinates (the chart solver's at-rest shortcut would carry nothing)."""
    chain = Chain(5, 3.4)
    rng = np.random.default_rng(2)
    h0 = sample_starts(chain, 1, 0.5, rng)[0][0]
    v0 = scale * _random_tangent(chain, h0, rng)
    j0, u0 = _random_tangent(chain, h0, rng), _random_tangent(chain, h0, rng)
    for method in ("charts", "hinges"):
        jf = geometry.jacobi_field(chain, h0, v0, j0, u0, 2.0, save=SaveAt(t_eval=[2.0]), method=method)
        assert np.abs(jf.field[-1] - (j0 + 2.0 * u0)).max() <= 1e-12


def test_log_takes_configurations_joined_only_through_a_vanishing_diagonal():
    """Flipping the turn of T_2 needs d_2 = 0 here (a face of lower dimension, where Chain.path is not built): two
    configurations with a small d_2 and opposite turns are close, and log still finds the geodesic between them."""
    chain = Chain([1, 1, 0.5, 0.5], 0.7)
    x = np.array([0.05, 0.5])
    h0, h1 = chain.from_diagonals(x, [1, 1, 1]), chain.from_diagonals(x, [-1, 1, 1])
    with pytest.raises(NotImplementedError):
        chain.path(h0, h1)
    result = geometry.log(chain, h0, h1)
    assert np.abs(geometry.exp(chain, h0, result.velocity) - h1).max() <= 1e-10
