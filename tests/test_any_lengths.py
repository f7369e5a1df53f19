"""Free motion of chains of any link lengths, in hinge coordinates, whatever the topology.

The hinge-coordinate Taylor method (``free_motion(..., method="hinges")``) is
checked against the chart-free DOP853 reference (``integrate_ambient``), an
independent integrator of the same Lagrange-multiplier equations, on spheres,
higher-genus manifolds and tori; and by what holds whatever the integrator:
energy, rod lengths, time reversal, and the component of a torus.  Starts are
sampled through the diagonal parameterization, with a random velocity
projected onto the tangent space.
"""

from __future__ import annotations

from fractions import Fraction

import itertools
import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from linkage import Chain
from linkage.ambient import integrate_ambient
from linkage.constraints import ChainSystem, HingeConstraints
from linkage.motion import free_motion, free_motions
from manifold import SaveAt
from manifold.constrained import compiled_constrained

EXAMPLE = (1.0, 2.0, 1.5, 2.5, 1.2)
#: Three long sides (l_1, l_2 and L = 3: each pair exceeds P/2 = 5.1): two tori T^3.
TORUS = (3.0, 3.0, 0.5, 0.4, 0.3)


def start(chain: Chain, rng: np.random.Generator, x: np.ndarray | None = None, flips: np.ndarray | None = None):
    """A configuration from the diagonals (sampled uniformly in ``D`` unless given) and a unit-energy tangent velocity."""
    if x is None:
        s = chain.diagonal_space().sample(1, rng)
        x, flips = s.x[0], s.flips[0]
    h0 = chain.from_diagonals(x, flips)
    x0 = chain.to_point(h0)
    v0 = chain.from_point(HingeConstraints(chain).project_velocity(x0, rng.normal(size=x0.size)))
    return h0, v0 / np.sqrt(2 * chain.kinetic_energy(v0))


#: The torus chain's motion is chaotic: a 1e-10 perturbation of the start grew 1e5-fold by t = 10 (Lyapunov
#: exponent ~1.2), and so does any integrator's rounding.  Trajectories are compared over a horizon where
#: that growth stays below ~100 (the agreement then measures the methods, not the chaos).
TORUS_HORIZON = 4.0

CASES = [
    (EXAMPLE, 0.5, "manifold", {}, 10.0),  # betti (1, 6, 6, 1)
    (EXAMPLE, 3.0, "manifold", {}, 10.0),  # betti (1, 7, 7, 1)
    (EXAMPLE, 4.5, "manifold", {"hinge_masses": [1.0, 2.0, 0.5, 1.5]}, 10.0),
    (EXAMPLE, 7.0, "sphere", {}, 10.0),  # the base dominates: S^3, with an atlas of suspension charts
    (TORUS, 3.0, "tori", {}, TORUS_HORIZON),
    ((0.7, 1.9, 1.3, 2.2), 1.1, "manifold", {"rod_densities": [0.3, 1.0, 0.0, 2.0]}, 10.0),  # dense K^-1
]


@pytest.mark.parametrize("lengths, L, kind, masses, T", CASES)
def test_hinge_method_agrees_with_the_ambient_reference(lengths, L, kind, masses, T):
    chain = Chain(lengths, L, **masses)
    assert chain.topology().kind == kind and chain.has_atlas == (kind == "sphere")
    h0, v0 = start(chain, np.random.default_rng(int(10 * L) + len(lengths)))
    ts = np.linspace(0, T, 41)
    # compact mode: one cold compile per (n, mass sparsity) in seconds (CI starts cold)
    hinges = free_motion(chain, h0, v0, T, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
    ref = integrate_ambient(chain, h0, v0, T, save=SaveAt(t_eval=ts), rtol=1e-13, atol=1e-13)
    assert hinges.success and ref.success
    assert np.abs(hinges.hinges - ref.hinges).max() <= 1e-9
    assert np.abs(hinges.velocities - ref.velocities).max() <= 1e-9
    E0 = chain.kinetic_energy(v0)
    assert hinges.relative_energy_error <= 1e-13
    assert np.abs(hinges.energies - E0).max() <= 1e-13 * E0
    assert hinges.closure_residuals.max() <= 1e-13
    rods = np.abs(chain.rods(hinges.hinges))  # each rod keeps its own length
    assert np.abs(rods / chain.lengths - 1).max() <= 1e-13
    if chain.has_atlas:  # chart parameters on demand, and they map back to the hinges
        charts, a, _ = hinges.solution.parameters(ts[:2])
        back = [chain.atlas().get_point(int(i), x) for i, x in zip(charts, a)]
        assert np.abs(chain.from_point(np.array(back)) - hinges.hinges[:2]).max() <= 1e-12
    else:
        with pytest.raises(ValueError, match="no atlas"):
            hinges.solution.parameters(ts[:2])


def test_a_torus_component_is_kept():
    """Two tori: the long rods ``e_1, e_2`` can never be parallel (``|e_1 + e_2|`` stays in ``[1.8, 4.2]``), so the
    sign of ``Im(conj(e_1) e_2)`` names the component, and a motion keeps it; both components move alike."""
    chain = Chain(TORUS, 3.0)
    rng = np.random.default_rng(4)
    space = chain.diagonal_space()
    x = space.sample(1, rng).x[0]
    T, ts = 20.0, np.linspace(0, 20.0, 201)
    runs = {}
    for sign in (1, -1):
        h0, v0 = start(chain, np.random.default_rng(5), x, np.array([sign, 1, -1, 1]))
        e = chain.rods(h0)
        assert np.sign(np.imag(np.conj(e[0]) * e[1])) == sign  # sigma_2 is the orientation of (p_1, p_2)
        m = free_motion(chain, h0, v0, T, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
        assert m.relative_energy_error <= 1e-13 and m.closure_residuals.max() <= 1e-13
        e = chain.rods(m.hinges)
        cross = np.imag(np.conj(e[:, 0]) * e[:, 1])
        assert np.all(np.sign(cross) == sign) and np.abs(cross).min() > 0.5
        runs[sign] = m
    # the components are mirror images (conjugation), and so are their motions (up to the chaos: TORUS_HORIZON)
    h0, v0 = start(chain, np.random.default_rng(5), x, np.array([1, 1, -1, 1]))
    ts = np.linspace(0, TORUS_HORIZON, 41)
    ref = free_motion(chain, h0, v0, TORUS_HORIZON, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
    mirror = free_motion(chain, np.conj(h0), np.conj(v0), TORUS_HORIZON, method="hinges", save=SaveAt(t_eval=ts),
                         compact_mode=True)
    assert np.abs(mirror.hinges - np.conj(ref.hinges)).max() <= 1e-11


@pytest.mark.parametrize("lengths, L, T", [(EXAMPLE, 3.0, 25.0), (TORUS, 3.0, TORUS_HORIZON)])
def test_backward_run_returns_to_the_start(lengths, L, T):
    chain = Chain(lengths, L)
    h0, v0 = start(chain, np.random.default_rng(11))
    fwd = free_motion(chain, h0, v0, T, method="hinges", compact_mode=True)
    h1, w1 = fwd.solution.end_state()
    back = free_motion(chain, chain.from_point(h1.astype(float)), chain.from_point(w1.astype(float)), -T,
                       method="hinges", compact_mode=True)
    h2, w2 = back.solution.end_state()
    assert np.abs(chain.from_point(h2.astype(float)) - h0).max() <= 1e-11
    assert np.abs(chain.from_point(w2.astype(float)) - v0).max() <= 1e-11


@st.composite
def generic_chains(draw, n_min: int = 3, n_max: int = 6):
    """Lengths in ``[0.2, 3]``, ``L`` anywhere the space is non-empty and generic, and a start that may sit
    within ``1e-12 .. 1e-4`` (times the perimeter) of a wall of ``D`` (a flat fan triangle)."""
    n = draw(st.integers(n_min, n_max))
    ls = np.array([draw(st.floats(0.2, 3.0)) for _ in range(n)])
    L = draw(st.floats(0.05, float(ls.sum()) - 0.05))
    assume(2 * max(ls.max(), L) < ls.sum() + L)
    chain = Chain(ls, L)
    assume(chain.topology().generic)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    space = chain.diagonal_space()
    assume(space.interior_point()[1] > 1e-3)  # enough room to sample
    x = space.sample(1, rng, method="hit-and-run").x[0]
    if draw(st.booleans()):  # move x along a random direction to within gap of the nearest wall
        gap = 10.0 ** draw(st.floats(-12, -4)) * (ls.sum() + L)
        u = rng.normal(size=x.size)
        rate = space.A @ u
        t = np.where(rate > 0, space.slacks(x) / np.where(rate > 0, rate, 1.0), np.inf)
        i = int(np.argmin(t))  # the wall hit first; at t_i - gap / rate_i its slack is gap
        x = x + max(t[i] - gap / rate[i], 0.0) * u
    flips = rng.choice([-1, 1], size=n - 1)
    return chain, x, flips, rng


@given(generic_chains())
@settings(max_examples=12)
def test_property_hinge_method_matches_reference_for_any_generic_lengths(case):
    chain, x, flips, rng = case
    h0, v0 = start(chain, rng, x, flips)
    ts = np.linspace(0, 2.0, 9)
    hinges = free_motion(chain, h0, v0, 2.0, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
    ref = integrate_ambient(chain, h0, v0, 2.0, save=SaveAt(t_eval=ts), rtol=1e-13, atol=1e-13)
    scale = float(chain.lengths.sum() + chain.L)
    assert np.abs(hinges.hinges - ref.hinges).max() <= 1e-9 * scale
    assert hinges.relative_energy_error <= 1e-13
    assert hinges.closure_residuals.max() <= 1e-13


@pytest.mark.parametrize("scale", [1e-3, 1e4])
def test_a_scaled_chain_moves_as_the_chain(scale):
    """Rods in millimetres or in kilometres: the motion of ``s lengths`` at ``s L``, started at ``s h0`` with
    ``s v0``, is ``s`` times the motion of the chain (the same rod angles), and every check passes alike."""
    chain, big = Chain(EXAMPLE, 3.0), Chain(scale * np.array(EXAMPLE), scale * 3.0)
    h0, v0 = start(chain, np.random.default_rng(8))
    ts = np.linspace(0, 10.0, 21)
    m = free_motion(chain, h0, v0, 10.0, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
    ms = free_motion(big, scale * h0, scale * v0, 10.0, method="hinges", save=SaveAt(t_eval=ts), compact_mode=True)
    assert ms.success and ms.relative_energy_error <= 1e-13 and ms.closure_residuals.max() <= 1e-13
    # the same time scales: no stiffer Baumgarte damping, so no more steps (a tiny chain takes fewer, as
    # heyoka's tolerance acts as an absolute one on states below 1)
    assert ms.n_steps <= 1.1 * m.n_steps
    assert np.abs(ms.hinges / scale - m.hinges).max() <= 1e-12
    ref = integrate_ambient(big, scale * h0, scale * v0, 10.0, save=SaveAt(t_eval=ts), rtol=1e-13, atol=1e-13 * scale)
    assert np.abs(ref.hinges - ms.hinges).max() <= 1e-9 * scale


@given(st.integers(3, 7), st.integers(0, 2**32 - 1))
@settings(max_examples=10)
def test_compiled_constraints_and_acceleration_match_numpy_for_any_lengths(n, seed):
    """``ChainSystem`` (heyoka, lengths as runtime parameters) against ``HingeConstraints`` (numpy, dense solve)."""
    rng = np.random.default_rng(seed)
    ls = rng.uniform(0.3, 3.0, n)
    L = rng.uniform(0.1, 0.9) * ls.sum()
    assume(2 * max(ls.max(), L) < ls.sum() + L)
    chain = Chain(ls, L)
    assume(chain.topology().generic)
    h0, v0 = start(chain, rng)
    x, v = chain.to_point(h0), chain.to_point(v0)
    ref, system = HingeConstraints(chain), ChainSystem(chain)
    comp = compiled_constrained(system)
    geo = comp.geometry(float)
    r = rng.normal(size=n)
    out = geo(np.concatenate([x, v, r]), pars=comp.layout.pack(system, 0.0, float)[: geo.nparams])
    c, Gv, d = out[:n], out[n: 2 * n], out[2 * n: -1]
    assert np.abs(c - ref.constraints(x)).max() <= 1e-13 * ls.max() ** 2
    assert np.abs(ref.constraints(x)).max() <= 1e-13 * ls.max() ** 2  # the start closes with these lengths
    assert np.allclose(Gv, ref.jacobian(x) @ v, atol=1e-12)
    assert np.allclose(d, ref.min_norm_correction(ref.jacobian(x), r), rtol=1e-9, atol=1e-10)
    acc = comp.acceleration(float, stabilised=False)
    a = acc(np.concatenate([x, v]), pars=comp.layout.pack(system, 0.0, float)[: acc.nparams])
    assert np.allclose(a, ref.acceleration(x, v), rtol=1e-9, atol=1e-10)


def test_an_ensemble_of_any_lengths_matches_single_solves():
    """``free_motions`` (SIMD batches) for unequal rods: each lane ends where its single solve ends."""
    chain = Chain(EXAMPLE, 4.5)
    rng = np.random.default_rng(12)
    H, V = map(np.array, zip(*[start(chain, rng) for _ in range(3)]))
    ens = free_motions(chain, H, V, 5.0)
    assert np.all(ens.relative_energy_errors <= 1e-13) and np.all(ens.closure_residuals <= 1e-13)
    for h, v, end in zip(H, V, ens.end_hinges):
        single = free_motion(chain, h, v, 5.0, method="hinges", compact_mode=True).solution.end_state()[0]
        assert np.abs(chain.from_point(single.astype(float)) - end).max() <= 1e-12


def test_one_compiled_integrator_serves_every_length():
    unit, other = Chain(5, 3.5), Chain(EXAMPLE, 3.0)
    assert compiled_constrained(ChainSystem(unit)) is compiled_constrained(ChainSystem(other))
    assert list(ChainSystem(other).parameters) == [3, *(1 / Fraction(l) ** 2 for l in EXAMPLE)]


@pytest.mark.parametrize("L", [2.2, 1.8, 0.2, 8.2])
def test_non_generic_lengths_are_refused_naming_the_collinear_configuration(L):
    chain = Chain(EXAMPLE, L)
    # brute force: the sign vectors with sum_k eps_k l_k = L are the collinear configurations
    collinear = [e for e in itertools.product((1, -1), repeat=5) if abs(np.dot(e, EXAMPLE) - L) < 1e-12]
    assert collinear and not chain.topology().generic
    h0 = np.cumsum(np.array(collinear[0]) * np.array(EXAMPLE))[:-1].astype(complex)  # it closes
    chain.check_configuration(h0)
    name = re.escape("rods (" + ", ".join("+" if e > 0 else "-" for e in collinear[0]) + ")")
    for method in ("hinges", "charts"):
        with pytest.raises(ValueError, match=rf"smooth configuration space.*collinear.*{name}"):
            free_motion(chain, h0, np.zeros(4, complex), 1.0, method=method)
    with pytest.raises(ValueError, match=rf"collinear.*{name}"):
        integrate_ambient(chain, h0, np.zeros(4, complex), 1.0)


def test_a_nearly_singular_L_is_named_in_full_with_the_tolerance():
    """L = 3.2 + 1e-13 is within the equality tolerance of a signed sum: the message gives L to every digit and the
    tolerance (RTOL times the perimeter 8.2 + 3.2, 1.14e-11 here), not the rounded 3.2 of the summary."""
    L = 3.2 + 1e-13
    with pytest.raises(ValueError, match=re.escape(f"= L = {L!r} to within 1.14e-11, RTOL = 1e-12 times")):
        Chain(EXAMPLE, L).check_generic()
    Chain(EXAMPLE, 3.2 + 1e-10).check_generic()  # beyond the tolerance: generic


#: A sphere whose dominant side is the link l_4 = 3.5 (sides (1, 1, 1, 3.5, L = 1), half the perimeter 3.75).
LINK_DOMINANT = ((1.0, 1.0, 1.0, 3.5), 1.0)


def test_charts_outside_the_spheres_name_the_hinge_method():
    for chain in (Chain(EXAMPLE, 3.0), Chain(4, 1.0)):
        assert not chain.has_atlas
        h0, v0 = start(chain, np.random.default_rng(0))
        with pytest.raises(ValueError, match=r"method='hinges'"):
            free_motion(chain, h0, v0, 1.0, method="charts")


def test_a_sphere_dominated_by_a_link_has_an_atlas_on_that_link():
    chain = Chain(*LINK_DOMINANT)
    assert chain.topology().kind == "sphere" and chain.topology().dominant_side == 3 and chain.has_atlas
    atlas = chain.atlas()
    assert atlas.base == 3 and {c.family.key for c in atlas.charts} == {("suspension", 4, "link-base")}
