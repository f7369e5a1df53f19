"""The Taylor method in hinge coordinates (``free_motion(..., method="hinges")``).

It integrates the Lagrange-multiplier equations of the rod constraints, an
independent route to the same geodesics as the chart method: the two must
agree, and each must keep energy and closure.
"""

from __future__ import annotations

from fractions import Fraction

import heyoka as hy
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from charts.chain_geometry import closure_tolerances
from linkage import Chain
from linkage.constraints import ChainSystem, HingeConstraints
from linkage.motion import free_motion
from manifold import Precision, SaveAt, SolveStatus, StartCheck
from manifold.constrained import ConstrainedGeometry, ConstrainedSystem, compiled_constrained, solve_constrained
from manifold.expression_linalg import ldl_solve
from manifold.precision import MultiPrecision, as_fp

from .conftest import unit_speed_start

EPS = float(np.finfo(float).eps)


def _start(chain: Chain, seed: int = 0, pole: bool = False):
    """A unit-speed start at chart-0 parameters: generic, or exactly on a pole of chart 0 (latitude pi/2).

    At a pole chart 0 has no Jacobian, so the velocity comes from the best chart there.
    """
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1.2, 1.2, chain.n - 2)
    c = rng.normal(size=chain.n - 2)
    if not pole:
        return unit_speed_start(chain, a, c)
    a[0] = np.pi / 2
    atlas = chain.atlas()
    p0 = atlas.get_point(0, a)
    i, b = atlas.best_chart(p0)
    v0 = chain.from_point(atlas.charts[i].tangent_vector(b, c))
    return chain.from_point(p0), v0 / np.sqrt(2 * chain.kinetic_energy(v0))


@pytest.mark.parametrize("k, band", [(1, 0), (4, 1), (6, 1), (5, 2), (6, 5)])
def test_ldl_solve_agrees_with_numpy_and_skips_structural_zeros(k, band):
    rng = np.random.default_rng(k + 10 * band)
    A = np.zeros((k, k))
    for d in range(band + 1):
        A += np.diag(rng.normal(size=k - d), -d)
    M = A @ A.T + k * np.eye(k)  # SPD with bandwidth band (lower triangle)
    rhs = rng.normal(size=k)
    syms = [[hy.expression(f"m{i}_{j}") if j <= i and abs(i - j) <= band else None for j in range(k)] for i in range(k)]
    r = [hy.expression(f"r{i}") for i in range(k)]
    x = ldl_solve(syms, r)
    names = [f"m{i}_{j}" for i in range(k) for j in range(k) if syms[i][j] is not None] + [f"r{i}" for i in range(k)]
    cf = hy.cfunc(x, [hy.expression(nm) for nm in names])
    vals = [M[i, j] for i in range(k) for j in range(k) if syms[i][j] is not None] + list(rhs)
    assert np.allclose(cf(np.array(vals)), np.linalg.solve(M, rhs), rtol=1e-13, atol=1e-13)


@given(n=st.integers(3, 8), seed=st.integers(0, 10**6), densities=st.booleans())
@settings(max_examples=15)
def test_symbolic_equations_agree_with_the_numpy_multiplier_solve(n, seed, densities):
    """The compiled acceleration ``K^{-1} G^T M^{-1} (-G' v)`` against ``HingeConstraints`` (numpy, dense solve)."""
    rng = np.random.default_rng(seed)
    chain = Chain(n, rng.uniform(n - 2 + 1e-3, n - 1e-3), hinge_masses=rng.uniform(0.1, 10, n - 1),
                  rod_densities=rng.uniform(0, 3, n) if densities else 0.0)
    h0, v0 = _start(chain, seed)
    x, v = chain.to_point(h0), chain.to_point(v0)
    ref = HingeConstraints(chain)
    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    pars = comp.layout.pack(system, 0.0, float)
    r = rng.normal(size=n)
    out = comp.geometry(float)(np.concatenate([x, v, r]), pars=pars[: comp.geometry(float).nparams])
    c, Gv, d, E = out[:n], out[n : 2 * n], out[2 * n : -1], out[-1]
    assert np.allclose(c, ref.constraints(x), atol=1e-14)
    assert np.allclose(Gv, ref.jacobian(x) @ v, atol=1e-12)
    assert np.allclose(d, ref.min_norm_correction(ref.jacobian(x), r), rtol=1e-10, atol=1e-11)
    assert np.isclose(E, 0.5 * v @ ref.K @ v, rtol=1e-14)
    # the integrator's right-hand side x''
    P = comp.pieces(float)
    rhs = hy.cfunc([e for _, e in P.equations(False)][len(x):], P.x + P.v)
    acc = rhs(np.concatenate([x, v]), pars=pars[: rhs.nparams])
    assert np.allclose(acc, ref.acceleration(x, v), rtol=1e-10, atol=1e-11)
    # off the constraints, with a velocity off the tangent space: G v and the Baumgarte-damped right-hand side
    # -(G' v + 2 alpha G v + alpha^2 c), where the terms the tangent start hides (G v, c) are of order one
    x, v, alpha = x + rng.normal(scale=0.05, size=x.size), rng.normal(size=v.size), rng.uniform(0.1, 10)
    out = comp.geometry(float)(np.concatenate([x, v, r]), pars=pars[: comp.geometry(float).nparams])
    G = ref.jacobian(x)
    assert np.allclose(out[n : 2 * n], G @ v, rtol=1e-12, atol=1e-12)
    rates = np.diff(np.concatenate([[0.0, 0.0], v, [0.0, 0.0]]).reshape(-1, 2), axis=0)  # e_k', pins at rest
    damped = 2 * np.sum(rates**2, axis=1) / chain.lengths**2 + 2 * alpha * G @ v + alpha**2 * ref.constraints(x)
    rhs = hy.cfunc([e for _, e in P.equations(True)][len(x):], P.x + P.v)
    acc = rhs(np.concatenate([x, v]), pars=comp.layout.pack(system, alpha, float)[: rhs.nparams])
    assert np.allclose(acc, ref.min_norm_correction(G, -damped), rtol=1e-10, atol=1e-10 * np.abs(acc).max())


@given(n=st.integers(3, 8), seed=st.integers(0, 10**6), off=st.sampled_from([0.0, 1e-11, 1e-3]),
       speed=st.floats(1e-3, 1e3), longdouble=st.booleans())
@settings(max_examples=25, deadline=None)
def test_the_one_call_projection_gives_the_three_calls_numbers(n, seed, off, speed, longdouble):
    """``ConstrainedGeometry.projection`` (one compiled function) gives what the geometry function gives in three
    calls (``c`` and ``G v``; ``v`` minus the correction of ``r = G v``; the energy there), on and off ``c = 0``, in
    float64 and long double: ``c``, ``G v`` and the energy of its ``u`` bit for bit, ``u`` to rounding (in one function
    heyoka may fuse ``v - K^-1 f`` into one multiply-add: 2.4 ulp of ``max |v|`` at most in 320 velocities far off
    the tangent space, none for normal parts of 1e-9), and ``u`` is the numpy K-orthogonal projection."""
    fp = np.longdouble if longdouble else float
    rng = np.random.default_rng(seed)
    chain = Chain(n, rng.uniform(n - 2 + 1e-2, n - 1e-2), hinge_masses=rng.uniform(0.1, 10, n - 1))
    h0, v0 = _start(chain, seed)
    x = chain.to_point(h0) + off * rng.normal(size=2 * (n - 1))
    v = speed * chain.to_point(v0) + rng.normal(size=2 * (n - 1))  # not tangent: the projection has work to do
    geo = ConstrainedGeometry(ChainSystem(chain), fp)
    X, V = as_fp(x[None], fp), as_fp(v[None], fp)
    c, Gv, u, E = geo.projection(X, V)
    c3, Gv3, _, _ = geo(X, V)
    u3 = V - geo(X, V, Gv3)[2]
    assert np.array_equal(c, c3) and np.array_equal(Gv, Gv3) and np.array_equal(E, geo(X, u)[3])
    assert np.abs((u - u3).astype(float)).max() <= 4 * geo.eps * np.abs(v).max()
    ref = HingeConstraints(chain)
    G = ref.jacobian(x)
    assert np.allclose(u[0].astype(float), v - ref.min_norm_correction(G, G @ v), rtol=1e-12, atol=1e-12 * np.abs(v).max())
    assert np.isclose(float(E[0]), 0.5 * u[0].astype(float) @ ref.K @ u[0].astype(float), rtol=1e-13)


@pytest.mark.parametrize("fp", [float, np.longdouble])
def test_a_start_off_the_constraints_is_projected_in_the_working_precision(fp):
    """A start within the start tolerance but off ``c = 0`` beyond rounding is moved onto it by Gauss-Newton, its
    velocity projected there and its energy taken there (the one-call projection at the moved point)."""
    chain = Chain(5, 3.3)
    h0, v0 = _start(chain, 3)
    rng = np.random.default_rng(3)
    x0, w0 = chain.to_point(h0) + 1e-11 * rng.normal(size=8), chain.to_point(v0)
    geo = ConstrainedGeometry(ChainSystem(chain), fp)
    X, V, E, _ = geo.start(x0[None], w0[None], 1.0, 1.0)
    assert not np.array_equal(X[0].astype(float), x0)  # moved
    c, Gv, _, E1 = geo(X, V)
    assert (np.abs(c.astype(float)) <= geo.floors).all()
    assert np.abs(Gv.astype(float)).max() <= 1e3 * geo.eps and np.array_equal(E, E1)
    assert np.isclose(float(E[0]), 0.5, rtol=1e-9)  # a unit-energy start, moved by 1e-11


@given(n=st.integers(3, 8), seed=st.integers(0, 10**6))
@settings(max_examples=10, deadline=None)
def test_the_chains_short_forms_equal_the_generic_ones_off_the_constraints(n, seed):
    """The chain writes the Baumgarte term ``(dG/dt) v + 2 alpha G v + alpha^2 c`` and the forces ``G^T lambda``
    by hand, in fewer products; they must equal the generic forms identically, so here at points off ``c = 0``
    with velocities off the tangent space, any ``alpha`` and any multipliers (the integrator's states are
    never exactly on the constraints)."""
    rng = np.random.default_rng(seed)
    chain = Chain(n, rng.uniform(n - 2 + 1e-3, n - 1e-3), hinge_masses=rng.uniform(0.1, 10, n - 1))
    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    P = comp.pieces(float)
    params = [hy.par[1 + i] for i in range(comp.layout.n_parameters)]
    lam = [hy.expression(f"lam{k}") for k in range(n)]
    ours = P.damped + system.transpose_product_expressions(P.x, params, P.G, lam)
    generic = (ConstrainedSystem.baumgarte_term_expressions(system, P.x, P.v, params, P.c, P.Gv, P.curvature,
                                                             hy.par[0])
               + ConstrainedSystem.transpose_product_expressions(system, P.x, params, P.G, lam))
    cf = hy.cfunc(ours + generic, P.x + P.v + lam)
    x = chain.to_point(_start(chain, seed)[0]) + rng.normal(scale=0.1, size=2 * (n - 1))
    inputs = np.concatenate([x, rng.normal(size=2 * (n - 1)), rng.normal(size=n)])
    pars = comp.layout.pack(system, rng.uniform(0.1, 10), float)[: cf.nparams]
    out = cf(inputs, pars=pars)
    half = len(out) // 2
    assert np.allclose(out[:half], out[half:], rtol=1e-12, atol=1e-12 * np.abs(out).max())


@pytest.mark.parametrize("n, pole, masses", [(3, False, False), (4, True, False), (5, False, True), (6, True, True),
                                             (7, False, False), (8, True, True)])
def test_hinge_method_agrees_with_the_chart_method(n, pole, masses):
    kw = {"hinge_masses": np.linspace(0.5, 2.0, n - 1), "rod_densities": 0.3} if masses else {}
    chain = Chain(n, n - 1.3, **kw)
    h0, v0 = _start(chain, seed=n, pole=pole)
    T, ts = 10.0, np.linspace(0, 10.0, 41)
    # compact mode: one cold compile per (n, mass sparsity) in seconds, not tens of seconds (CI starts cold)
    hinges = free_motion(chain, h0, v0, T, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
    charts = free_motion(chain, h0, v0, T, method="charts", save=SaveAt(t_eval=ts))
    assert hinges.success and charts.success
    assert np.abs(hinges.hinges - charts.hinges).max() <= 1e-10
    assert np.abs(hinges.velocities - charts.velocities).max() <= 1e-10
    assert hinges.relative_energy_error <= 1e-13
    assert hinges.closure_residuals.max() <= 1e-14


def test_energy_and_closure_over_a_long_run():
    chain = Chain(4, 2.5)
    h0, v0 = _start(chain, seed=3)
    m = free_motion(chain, h0, v0, 1000.0, method="hinges", save=SaveAt(dense=False, t_eval=np.linspace(0, 1000, 101)))
    assert m.relative_energy_error <= 1e-13
    assert m.closure_residuals.max() <= 1e-14
    assert np.abs(m.energies - m.energies[0]).max() <= 1e-13 * m.energies[0]



def _pivots(chain: Chain, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The compiled pivots of ``M = G K^{-1} G^T`` at ``x`` (float64), and the generic Thomas recursion on
    ``M`` evaluated in float64."""
    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    P = comp.pieces(float)
    cf = hy.cfunc(P.pivots, P.x)
    ours = cf(x, pars=comp.layout.pack(system, 0.0, float)[: cf.nparams])
    G, W = HingeConstraints(chain).jacobian(x), np.linalg.inv(chain.ambient_metric)
    M = G @ W @ G.T
    return ours, np.array(_thomas_pivots(np.diag(M), np.diag(M, -1)))


def _thomas_pivots(diagonal, below) -> list:
    """``D_0 = M_00``, ``D_k = M_kk - M_{k,k-1}^2 / D_{k-1}`` of a tridiagonal ``M``, in the entries' own arithmetic."""
    D = [diagonal[0]]
    for d, b in zip(diagonal[1:], below):
        D.append(d - b * b / D[-1])
    return D


def _exact_pivots(chain: Chain, x: np.ndarray) -> list[Fraction]:
    """The same pivots in rational arithmetic from the float64 ``x``, masses and lengths taken exact."""
    n = chain.n
    hinges = [(Fraction(0), Fraction(0))] + [(Fraction(x[2 * j]), Fraction(x[2 * j + 1])) for j in range(n - 1)]
    hinges.append((Fraction(chain.L), Fraction(0)))
    g = [tuple(2 * (b - a) / Fraction(l) ** 2 for a, b in zip(hinges[k], hinges[k + 1]))
         for k, l in enumerate(chain.lengths)]
    w = [Fraction(0)] + [1 / Fraction(m) for m in np.diag(chain.mass_matrix)] + [Fraction(0)]
    diagonal = [(w[k] + w[k + 1]) * (g[k][0] ** 2 + g[k][1] ** 2) for k in range(n)]
    below = [-w[k] * (g[k - 1][0] * g[k][0] + g[k - 1][1] * g[k][1]) for k in range(1, n)]
    return _thomas_pivots(diagonal, below)


@given(bend=st.floats(1e-9, 1e-2), turn=st.floats(0.1, 0.5))
@settings(max_examples=20, deadline=None)
def test_pivots_are_exact_to_rounding_where_a_light_hinge_is_straight(bend, turn):
    """Hinge 1 (mass 1e-3, neighbours to 1e2) with its two rods at angle ``bend``: the Thomas pivots written
    with Lagrange's identity are exact to a few eps (against rational arithmetic); the generic recursion
    subtracts and loses up to ``w_1 / w_2 ~ 300`` eps there."""
    chain = Chain(4, 2.5, hinge_masses=np.geomspace(1e-3, 1e2, 3))
    p1 = np.exp(1j * turn)
    p2 = p1 + np.exp(1j * (turn + bend))
    mid, d = (p2 + chain.L) / 2, chain.L - p2  # p3: unit distance from p2 and from the pin L
    x = chain.to_point(np.array([p1, p2, mid + 1j * d / abs(d) * np.sqrt(1 - abs(d) ** 2 / 4)]))
    ours, _ = _pivots(chain, x)
    exact = np.array([float(D) for D in _exact_pivots(chain, x)])
    assert np.max(np.abs(ours / exact - 1)) <= 32 * EPS


@pytest.mark.parametrize("n", [4, 6])
def test_pivots_are_exact_to_rounding_near_the_stretched_chain(n):
    """``L = n - 1e-8``: every joint nearly straight.  The generic recursion loses ~1e-8 of the pivots (it is
    what made the hinge method fail its energy check beyond ``L = n - 1e-6``); Lagrange's identity keeps them."""
    chain = Chain(n, n - 1e-8)
    h0, _ = _start(chain, seed=n)
    x = chain.to_point(h0)
    ours, generic = _pivots(chain, x)
    exact = np.array([float(D) for D in _exact_pivots(chain, x)])
    assert np.max(np.abs(ours / exact - 1)) <= 32 * EPS
    assert np.max(np.abs(generic / exact - 1)) >= 1e-10  # the trap is real at this configuration


def test_a_light_hinge_passing_straight_keeps_the_energy():
    """Hinge masses 1e-3..1e2, a start whose light hinge whips through straight near t = 13.08 (accelerations
    1e3): the energy jumped by 1.4e-11 there with the generic Thomas pivots, 3.7e-14 with the chain's own;
    unit masses keep ~2e-15."""
    chain = Chain(4, 2.5, hinge_masses=np.geomspace(1e-3, 1e2, 3))
    rng = np.random.default_rng(0)
    a = np.append(rng.uniform(-1.2, 1.2, 1), rng.uniform(-np.pi, np.pi))
    h0, v0 = unit_speed_start(chain, a, rng.normal(size=2))
    motion = free_motion(chain, h0, v0, 20.0, method="hinges", save=SaveAt(dense=False))
    assert motion.relative_energy_error <= 2e-13


@given(n=st.integers(3, 6), seed=st.integers(0, 2**16), densities=st.booleans(), descending=st.booleans())
@settings(max_examples=12, deadline=None)
def test_rods_hold_with_masses_spread_over_five_decades(n, seed, densities, descending):
    """Hinge masses spread over 1e-3..1e2: the rods once drifted by 1.5e-12 over T = 20 (unit masses: 1e-15),
    because the Baumgarte rate followed the heavy hinges' speed; it now follows the fastest hinge.

    What is left are spikes where a light hinge whips through straight (joint angle ~1e-3, speed 3..27,
    rod tensions ~3e5): the float64 state cannot be tangent to better than ``eps |v|``, and the tensions
    act on that.  Over 400 starts of this strategy the largest closure residual was 9.3e-14, each at
    such a whip; the bound leaves 2x over that and still catches the old drift 7x over.

    A run whose energy leaves the solver's bound says so; it is never a success with more.
    """
    masses = np.geomspace(1e-3, 1e2, n - 1)
    chain = Chain(n, n - 1.5, hinge_masses=masses[::-1] if descending else masses,
                  rod_densities=1e-2 if densities else 0.0)
    h0, v0 = _start(chain, seed)
    motion = free_motion(chain, h0, v0, 20.0, method="hinges", compact_mode=True,
                         save=SaveAt(t_eval=np.linspace(0, 20, 81)),
                         throw=False)
    assert motion.success or motion.solution.status is SolveStatus.ENERGY_CHECK_FAILED, motion.solution.message
    residuals = motion.closure_residuals
    assert np.max(residuals[np.isfinite(residuals)], initial=0.0) <= 2e-13  # a failed run records a partial grid


def test_near_the_top_the_velocity_error_of_three_rods_is_the_phase_lag_of_the_energy_error():
    """``L = 3 - 1e-5``: the orbit turns at ~300 rad per unit time and the rods carry tensions ~3.5e4 E, so
    the float64 hinge velocities end 1e-10..2e-9 off the chart method's (accurate to 1e-12 there).  For three
    rods, whose configuration space is a curve, that error is a time shift ``dt`` along the orbit, and the
    shift is the integral of the energy error, ``dt = integral (E/E0 - 1) dt`` (measured within 6 % on four
    starts at n = 3 and 4; the speed alone, ``dE / 2E``, accounts for half, the orbit's size, which the rods'
    length residuals change with the energy, presumably for the rest).  Shifted back, the velocities agree
    to the charts' accuracy.  From n = 5 on part of the error lies across the orbit (docs/methods.md)."""
    chain = Chain(3, 3 - 1e-5)
    h0, v0 = _start(chain, 0)
    T, d = 3.0, 1e-6
    ts = np.linspace(0, T, 301)
    hinges = free_motion(chain, h0, v0, T, method="hinges", save=SaveAt(t_eval=ts))
    charts = free_motion(chain, h0, v0, T + d, method="charts", save=SaveAt(t_eval=[0.0, T - d, T, T + d]))
    v_h = chain.to_point(hinges.velocities[-1])
    v_c = np.array([chain.to_point(v) for v in charts.velocities[1:]])
    acceleration = (v_c[2] - v_c[0]) / (2 * d)
    error = v_h - v_c[1]
    dt = error @ acceleration / (acceleration @ acceleration)
    lag = np.trapezoid(hinges.energies / hinges.energies[0] - 1, ts)
    assert abs(dt - lag) <= 0.2 * abs(lag) + 1e-13
    assert np.max(np.abs(error - dt * acceleration)) <= 3e-12


@pytest.mark.parametrize("stabilisation", ["baumgarte", "projection"])
def test_backward_run_returns_to_the_start(stabilisation):
    chain = Chain(5, 3.3, hinge_masses=[1.0, 2.0, 0.5, 1.5])
    h0, v0 = _start(chain, seed=7)
    fwd = free_motion(chain, h0, v0, 30.0, method="hinges", stabilisation=stabilisation, projection_interval=7.0)
    h1, w1 = fwd.solution.end_state()
    back = free_motion(chain, chain.from_point(h1.astype(float)), chain.from_point(w1.astype(float)), -30.0,
                       method="hinges", stabilisation=stabilisation, projection_interval=7.0)
    h2, w2 = back.solution.end_state()
    assert np.abs(chain.from_point(h2.astype(float)) - h0).max() <= 1e-11
    assert np.abs(chain.from_point(w2.astype(float)) - v0).max() <= 1e-11


def test_stabilisations_agree_and_none_drifts_more():
    chain = Chain(4, 2.6)
    h0, v0 = _start(chain, seed=1)
    ts = np.linspace(0, 200, 11)
    runs = {s: free_motion(chain, h0, v0, 200.0, method="hinges", stabilisation=s, save=SaveAt(t_eval=ts), throw=False)
            for s in ("baumgarte", "projection", "none")}
    assert runs["baumgarte"].success and runs["projection"].success
    assert np.abs(runs["baumgarte"].hinges - runs["projection"].hinges).max() <= 1e-9
    assert runs["baumgarte"].closure_residuals.max() <= 1e-14
    assert runs["none"].closure_residuals.max() > runs["baumgarte"].closure_residuals.max()


@pytest.mark.parametrize("fp_type, T", [(np.longdouble, 5.0), ("real128", 2.0), (MultiPrecision(150), 1.0)])
def test_higher_precisions_agree_with_float64_and_keep_energy(fp_type, T):
    chain = Chain(4, 2.7, hinge_masses=[1.0, 3.0, 0.7])
    h0, v0 = _start(chain, seed=5)
    ref = free_motion(chain, h0, v0, T, method="hinges")
    hi = free_motion(chain, h0, v0, T, method="hinges", precision=Precision(fp_type=fp_type))
    p_ref, _ = ref.solution.end_state()
    p_hi, _ = hi.solution.end_state()
    assert np.abs(p_hi.astype(float) - p_ref).max() <= 1e-12
    eps = {np.longdouble: 2.0**-64, "real128": 2.0**-113}.get(fp_type, 2.0**-150)
    assert hi.solution.relative_energy_error <= 1e3 * eps
    fp, system = hi.solution.fp_type, ChainSystem(chain)
    comp = compiled_constrained(system)
    geo = comp.geometry(fp)
    args = as_fp(np.concatenate([p_hi, np.zeros(len(p_hi) + chain.n, dtype=p_hi.dtype)]), fp)
    c = geo(args, pars=comp.layout.pack(system, 0.0, fp)[: geo.nparams])[: chain.n]
    assert max(abs(float(ck)) for ck in c) <= 1e3 * eps  # closed in the working precision


def test_dense_output_grid_and_chart_parameters_on_demand():
    chain = Chain(4, 2.4)
    h0, v0 = _start(chain, seed=2, pole=True)
    ts = np.linspace(0, 15, 31)
    m = free_motion(chain, h0, v0, 15.0, method="hinges", save=SaveAt(t_eval=ts))
    p, v = m.solution(ts)
    assert np.abs(p - m.solution.points).max() <= 1e-15
    charts, a, c = m.solution.parameters(ts)
    atlas = chain.atlas()
    for i, ai, ci, pi, vi in zip(charts, a, c, p, v):
        assert np.abs(atlas.get_point(i, ai) - pi).max() <= 1e-12
        assert np.abs(atlas.charts[i].tangent_vector(ai, ci) - vi).max() <= 1e-11
    assert m.n_switches == 0 and m.chart_ids == []


def test_bad_options_are_refused():
    chain = Chain(4, 2.5)
    h0, v0 = _start(chain)
    with pytest.raises(ValueError, match="method must be one of"):
        free_motion(chain, h0, v0, 1.0, method="hinge")
    with pytest.raises(ValueError, match="stabilisation must be one of"):
        free_motion(chain, h0, v0, 1.0, method="hinges", stabilisation="Baumgarte")
    for kw, name in [({"rate": 0.0}, "rate"), ({"rate": np.nan}, "rate"),
                     ({"projection_interval": -1.0}, "projection_interval")]:
        with pytest.raises(ValueError, match=name):
            free_motion(chain, h0, v0, 1.0, method="hinges", **kw)
    with pytest.raises(ValueError, match="tol"):
        free_motion(chain, h0, v0, 1.0, method="hinges", precision=Precision(tol=0.5))
    with pytest.raises(TypeError, match="dense"):
        free_motion(chain, h0, v0, 1.0, method="hinges", save=SaveAt(dense=1))
    with pytest.raises(TypeError):
        free_motion(chain, h0, v0, 1.0, method="hinges", q_out=0.3)  # a chart option
    system = ChainSystem(chain)
    x0, w0 = chain.to_point(h0), chain.to_point(v0)
    with pytest.raises(ValueError, match="not on the constraint manifold"):
        solve_constrained(system, x0 + 1e-6, w0, 1.0)
    with pytest.raises(ValueError, match=r"x0 must have shape \(6,\)"):
        solve_constrained(system, x0[:4], w0, 1.0)
    with pytest.raises(ValueError, match="t_eval"):
        solve_constrained(system, x0, w0, 1.0, save=SaveAt(t_eval=[0.5, 2.0]))


def _stretched_rod(chain: Chain, h0: np.ndarray, k: int, excess: float) -> np.ndarray:
    """``h0`` with rod ``k`` (``k < n - 1``) lengthened along itself, the hinges after it moved with it, so that the
    chain's closure excess (:meth:`Chain.closure_excess`, 1 at its tolerance) is ``excess`` to a few parts in 1e6
    (the last rod takes up the move, and may be the one that sets the excess)."""
    e = chain.rods(h0)[k]

    def moved(f: float) -> np.ndarray:
        h = h0.copy()
        h[k:] += f * e
        return h

    f = closure_tolerances(chain.lengths, 1e-9)[k]  # a first move of the size of rod k's tolerance
    for _ in range(3):  # the excess is linear in f to ~f: the secant lands on the target
        f *= excess / float(chain.closure_excess(moved(f)))
    return moved(f)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 6), st.booleans(),
       st.sampled_from([0.5, 0.9, 0.999, 1.1, 1.5]))
def test_the_solver_takes_every_start_the_chains_check_takes(seed, n, short_link, excess):
    """The hinge solver's start check on ``c_k = |e_k|^2 / l_k^2 - 1`` (:attr:`ChainSystem.start_tolerances`) takes
    exactly the starts the chain's own check on relative rod lengths takes: a rod off by up to its tolerance
    (0.999 of it) passes both, one off by 1.1 of it fails both.  With the generic bound ``|c_k| <= 1e-9`` a rod
    0.6e-9 too long, which the chain accepts, was refused; a short link's tolerance is its rounding floor's."""
    rng = np.random.default_rng(seed)
    lengths = rng.uniform(0.5, 1.5, n)
    if short_link:
        lengths[rng.integers(n - 1)] = 10.0 ** -rng.uniform(3, 8)
    low = max(0.0, 2 * lengths.max() - lengths.sum())  # L from low to the sum closes (a polygon's sides)
    chain = Chain(lengths, low + rng.uniform(0.1, 0.9) * (lengths.sum() - low))
    h0 = chain.diagonal_space().sample(1, rng).hinges[0]
    k = int(np.argmin(lengths[:-1])) if short_link else int(rng.integers(n - 1))
    h = _stretched_rod(chain, h0, k, excess)
    geo = ConstrainedGeometry.of(ChainSystem(chain), float)
    x = chain.to_point(h)[None, :]
    v = np.zeros_like(x)
    actual = float(chain.closure_excess(h))
    assert abs(actual / excess - 1) < 0.05  # a short link's length moves in steps of eps |h| / l_k: up to 1 %
    if actual <= 1:
        chain.check_configuration(h)
        geo.start(x, v, 1.0, 1.0)
    else:
        with pytest.raises(ValueError, match="does not close"):
            chain.check_configuration(h)
        if actual >= 1.05:  # just above 1 the solver may still take it: c_k's own rounding is allowed on top
            with pytest.raises(ValueError, match="not on the constraint manifold"):
                geo.start(x, v, 1.0, 1.0)


def test_a_start_the_chain_takes_runs_with_every_method():
    """A rod 0.8e-9 too long (relative): within the chain's tolerance, so the hinges, one start of an ensemble and
    the charts all integrate it (the hinges and the ensemble refused it before their bound on ``c`` matched)."""
    from linkage.ensemble import free_motions
    from linkage.sampling import sample_starts

    chain = Chain(4, 2.6)
    H, V = sample_starts(chain, 1, 0.5, np.random.default_rng(0))
    h = H[0] * (1 + 0.8e-9)
    assert 0.75e-9 < chain.closure_residual(h) < 0.85e-9
    start = StartCheck(project_velocity=True)  # the scaled hinges' velocity is no longer tangent to 1e-9
    for method in ("hinges", "charts"):
        assert free_motion(chain, h, V[0], 1.0, method=method, start=start).success
    assert free_motions(chain, h[None], V[:1], 1.0, start=start).success.all()


def _tilted(chain: Chain, h0: np.ndarray, w0: np.ndarray, k: int, ratio: float) -> np.ndarray:
    """``w0`` (tangent) plus a K-normal push that changes rod ``k``'s length, sized so that the tangency residual
    ``max_j l_j |(G w)_j|`` is ``ratio`` times the allowance ``1e-9 max(1, |w|)`` (numpy's measure, start_state's)."""
    hc = HingeConstraints(chain)
    x, w = chain.to_point(h0), chain.to_point(w0)
    d = hc.K_inv @ hc.jacobian(x)[k]  # K^-1 G^T e_k: normal to the tangent space
    s = 1e-9
    for _ in range(3):  # the residual is linear in s, the allowance nearly constant: the secant lands on the target
        s *= ratio * float(StartCheck().allowance(w + s * d)) / float(hc.tangency_residual(x, w + s * d))
    return chain.from_point(w + s * d)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(3, 6), st.booleans(), st.sampled_from([0.5, 0.9, 1.1, 2.0]))
def test_the_hinge_path_checks_tangency_once_and_as_start_state_does(seed, n, short_link, ratio):
    """``free_motion(method="hinges")`` checks its start once, in the compiled call that also projects it, not in
    numpy first: a velocity pushed off the tangent space to 0.9 of the allowance passes both that check and
    :func:`start_state`'s; pushed to 1.1 of it, both refuse it, and the refusal is start_state's, naming
    ``velocity0``.  Short links (1e-3..1e-8, tolerances set by rounding) included."""
    from linkage.constraints import start_state

    rng = np.random.default_rng(seed)
    lengths = rng.uniform(0.5, 1.5, n)
    if short_link:
        lengths[rng.integers(n - 1)] = 10.0 ** -rng.uniform(3, 8)
    low = max(0.0, 2 * lengths.max() - lengths.sum())
    chain = Chain(lengths, low + rng.uniform(0.1, 0.9) * (lengths.sum() - low))
    h0 = chain.diagonal_space().sample(1, rng).hinges[0]
    x0 = chain.to_point(h0)
    v0 = HingeConstraints(chain).project_velocity(x0, rng.uniform(0.1, 3.0) * rng.normal(size=x0.shape))
    w = _tilted(chain, h0, chain.from_point(v0), int(rng.integers(n)), ratio)
    T = 1e-3 * lengths.min() / np.abs(v0).max()  # a random velocity whips a short link round at |v| / l: a short run
    if ratio < 1:
        start_state(chain, h0, w, T, StartCheck())
        assert free_motion(chain, h0, w, T, method="hinges").success
    else:
        with pytest.raises(ValueError, match="velocity0 is not tangent"):
            start_state(chain, h0, w, T, StartCheck())
        with pytest.raises(ValueError, match=r"^velocity0 is not tangent to the configuration space: max_k l_k"):
            free_motion(chain, h0, w, T, method="hinges")
        projected = free_motion(chain, h0, w, T, method="hinges", start=StartCheck(project_velocity=True),
                                save=SaveAt(t_eval=[0.0]))
        _, _, v_numpy, _ = start_state(chain, h0, w, T, StartCheck(project_velocity=True))
        assert np.allclose(chain.to_point(projected.velocities[0]), v_numpy, rtol=0, atol=1e-13 * np.abs(v_numpy).max())


def test_the_hinge_path_runs_no_numpy_start_check(monkeypatch):
    """On a good start the hinge path runs neither the chain's closure check nor the numpy tangency check: the
    compiled start check of the solve is the only one (the issue of a start checked two or three times a solve)."""
    import linkage.motion
    from linkage.sampling import sample_starts

    chain = Chain(5, 3.3)
    H, V = sample_starts(chain, 1, 1.0, np.random.default_rng(3))
    calls = {"start_state": 0, "check_configuration": 0, "tangency_residual": 0, "ConstrainedGeometry.start": 0}

    def counted(name, f):
        def wrapper(*args, **kwargs):
            calls[name] += 1
            return f(*args, **kwargs)
        return wrapper

    monkeypatch.setattr(linkage.motion, "start_state", counted("start_state", linkage.motion.start_state))
    for owner, name in [(Chain, "check_configuration"), (HingeConstraints, "tangency_residual"),
                        (ConstrainedGeometry, "start")]:
        monkeypatch.setattr(owner, name, counted(name if owner is not ConstrainedGeometry else f"ConstrainedGeometry.{name}",
                                                 getattr(owner, name)))
    assert free_motion(chain, H[0], V[0], 1.0, method="hinges").success
    assert calls == {"start_state": 0, "check_configuration": 0, "tangency_residual": 0, "ConstrainedGeometry.start": 1}
    with pytest.raises(ValueError, match="configuration does not close"):  # a refusal in the chain's words
        free_motion(chain, H[0] * (1 + 1e-6), V[0], 1.0, method="hinges")


class _Sphere(ConstrainedSystem):
    """The sphere ``|x|^2 / 4 - 1 = 0`` of radius 2 in Euclidean ``R^3``."""

    ambient_dim, n_constraints = 3, 1
    key = ("test sphere of radius 2",)
    metric_matrix = np.eye(3)

    def constraint_expressions(self, x, p, fp_type):
        return [(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) * hy.expression(fp_type(0.25)) - hy.expression(fp_type(1.0))]


def test_solve_constrained_checks_tangency_with_a_start_check():
    """With ``start=StartCheck(...)``, :func:`solve_constrained` checks ``v0`` too: ``(G v)_1 = x . v / 2`` on the
    sphere of radius 2 (weight 1), refused above ``tangent_tol max(1, |v0|)`` with :class:`StartRefused` naming
    ``v0``; with ``project_velocity`` the motion is that from the projected velocity; without a check, as before."""
    from manifold.constrained import StartRefused

    x0 = np.array([1.2, 0.0, 1.6])
    tangent = np.array([0.0, 1.0, 0.0])
    v0 = tangent + 1e-7 * x0  # (G v)_1 = x0 . v0 / 2 = 2e-7
    with pytest.raises(StartRefused, match=r"v0 is not tangent to the constraint manifold: max_k w_k \|\(G v0\)_k\| = "
                                           r"2e-07 exceeds tangent_tol \* max\(1, \|v0\|\) = 1e-09"):
        solve_constrained(_Sphere(), x0, v0, 1.0, start=StartCheck())
    assert solve_constrained(_Sphere(), x0, v0, 1.0, start=StartCheck(tangent_tol=3e-7)).success
    assert solve_constrained(_Sphere(), x0, v0, 1.0).success  # no check: the projection takes it
    a = solve_constrained(_Sphere(), x0, v0, 2.0, start=StartCheck(project_velocity=True))
    b = solve_constrained(_Sphere(), x0, tangent, 2.0)  # the K-orthogonal projection of v0 (x0 . tangent = 0)
    assert np.allclose(a(2.0)[0], b(2.0)[0], rtol=0, atol=1e-14)
    # a great circle of radius 2 at speed 1: the angle 2.0 / 2 turned from x0 towards tangent
    assert np.allclose(a(2.0)[0], np.cos(1.0) * x0 + 2 * np.sin(1.0) * tangent, rtol=0, atol=1e-13)


@pytest.mark.parametrize("gap, fp_type, push", [(1e-6, "float64", 1e6), (1e-4, "float64", 1e3), (0.1, "float64", 1e6),
                                                (1e-6, "longdouble", 1.0)])
def test_a_velocity_far_off_the_tangent_space_is_projected_to_rounding(gap, fp_type, push):
    """``StartCheck(project_velocity=True)`` on the hinges: a velocity pushed ``push |v|`` off the tangent space of
    a nearly stretched chain (``L = 4 - gap``) runs as its projection does.  One compiled projection pass left
    ``cond(G) eps`` of the push, which the Baumgarte term turned into an energy error 700x its bound at
    ``gap = 1e-6``; the two passes of :meth:`HingeConstraints.project_velocity` leave rounding."""
    chain = Chain(4, 4 - gap)
    rng = np.random.default_rng(0)
    h0 = chain.diagonal_space().sample(1, rng).hinges[0]
    x0, hc = chain.to_point(h0), HingeConstraints(chain)
    vt = hc.project_velocity(x0, rng.normal(size=x0.shape))
    normal = hc.K_inv @ hc.jacobian(x0).T @ rng.normal(size=4)
    w = chain.from_point(vt + push * np.linalg.norm(vt) * normal / np.linalg.norm(normal))
    pushed = free_motion(chain, h0, w, 1.0, method="hinges", precision=Precision(fp_type=fp_type),
                         start=StartCheck(project_velocity=True))
    tangent = free_motion(chain, h0, chain.from_point(vt), 1.0, method="hinges", precision=Precision(fp_type=fp_type))
    assert pushed.success and tangent.success
    assert np.abs(pushed.hinges[-1] - tangent.hinges[-1]).max() <= 1e-9
