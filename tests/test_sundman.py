"""Sundman's time on the chart path (:mod:`manifold.sundman`, :mod:`linkage.time_factor`).

The change of time variable must not change the motion: the same geodesic, the
same switches, the same energy, at physical times.  And the factor must be the
determinant it claims to be, positive off the singular configurations.
"""

from __future__ import annotations

import heyoka as hy
import mpmath as mp
import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

import manifold.progress
from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor, multiplier_determinant
from manifold import Precision, SaveAt, solve_chart_exp_ode
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.progress import ProgressUpdate
from manifold.steppers import TaylorStepper
from manifold.sundman import SundmanStepper

from .conftest import assert_same_motion, unit_speed_start


def _numpy_determinant(rods: np.ndarray, w: np.ndarray) -> float:
    """``det(G K^-1 G^T)`` with rows ``e_k`` on hinge ``k`` and ``-e_k`` on hinge ``k - 1`` (pins dropped)."""
    n = len(rods)
    G = np.zeros((n, 2 * (n - 1)))
    for k in range(n):
        if k < n - 1:
            G[k, 2 * k : 2 * k + 2] = rods[k]
        if k > 0:
            G[k, 2 * (k - 1) : 2 * k] = -rods[k]
    return float(np.linalg.det(G @ np.kron(np.diag(w), np.eye(2)) @ G.T))


def _coefficients(rods: np.ndarray, w: np.ndarray) -> tuple:
    l2 = np.sum(rods**2, axis=1)
    return w * w, w[1:] * l2[2:], w[:-1] * l2[:-2]


@settings(max_examples=60, deadline=None)
@given(n=st.integers(2, 8), seed=st.integers(0, 2**32 - 1), bend=st.sampled_from([1.0, 1e-3, 1e-7]))
@example(n=2, seed=11494, bend=1.0)  # two rods 4.5e-5 rad apart: their cross product carries 2e-12 of rounding
def test_the_factor_is_the_multiplier_determinant_and_positive_near_straight(n, seed, bend):
    """Against numpy's determinant, and near a straight chain (rods turning by ``bend``) against 50 digits:
    the continuant has no cancellation, so it keeps its relative accuracy where numpy's LU loses it."""
    rng = np.random.default_rng(seed)
    angles = np.cumsum(rng.uniform(-bend, bend, n))
    rods = rng.uniform(0.3, 2.0, n)[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    w = rng.uniform(0.1, 10.0, n - 1)
    got = multiplier_determinant([tuple(r) for r in rods], *_coefficients(rods, w))
    assert got > 0
    if bend == 1.0:
        assert got == pytest.approx(_numpy_determinant(rods, w), rel=1e-10)
    with mp.workdps(50):
        R = [[mp.mpf(float(x)) for x in r] for r in rods]
        n_ = len(R)
        G = mp.zeros(n_, 2 * (n_ - 1))
        for k in range(n_):
            if k < n_ - 1:
                G[k, 2 * k], G[k, 2 * k + 1] = R[k]
            if k > 0:
                G[k, 2 * (k - 1)], G[k, 2 * k - 1] = -R[k][0], -R[k][1]
        Kinv = mp.diag([mp.mpf(float(x)) for x in np.repeat(w, 2)])
        exact = mp.det(G * Kinv * G.T)
    # the cross products a x b of two float rods lose eps |a| |b| / |a x b| of their digits to cancellation
    # (rods nearly parallel away from the x axis): the continuant adds none, so the bound scales with that only
    norms = np.linalg.norm(rods, axis=1)
    cross = np.abs(rods[:-1, 0] * rods[1:, 1] - rods[:-1, 1] * rods[1:, 0])
    condition = float(np.max(norms[:-1] * norms[1:] / cross))
    assert abs(got - float(exact)) <= (1e-12 + 16 * np.finfo(float).eps * condition) * float(exact) + 1e-300


@pytest.mark.parametrize("lengths, L, masses", [
    ([1.0, 1.0, 1.0, 1.0], 2.6, [0.2, 1.0, 5.0]),
    ([1.5, 0.7, 1.1, 2.4, 0.9], 5.2, [1.0, 3.0, 0.5, 2.0]),
    ([0.01, 0.012, 0.009, 0.011], 0.03, 1e-4),
])
def test_the_chain_factor_is_det_M_over_its_scale_at_any_lengths_and_masses(lengths, L, masses):
    """The compiled route's expression with the packed parameters, on numbers: ``det(G K^-1 G^T) / c^n``
    with ``c = mean(1 / m) mean(l^2)``, of order 1 whatever the chain's size and masses (the rods have
    the chain's lengths, as on the chart path; their far end is put on the x-axis, where the pin is)."""
    chain = Chain(lengths, L, hinge_masses=masses)
    factor = ChainTimeFactor(chain)
    l = np.asarray(lengths, dtype=float)
    w = 1.0 / np.diag(chain.ambient_metric)[::2]
    c = np.mean(w) * np.mean(l**2)
    rng = np.random.default_rng(len(lengths))
    for _ in range(5):
        z = l * np.exp(1j * rng.uniform(-1.5, 1.5, len(l)))
        z = z * np.exp(-1j * np.angle(np.sum(z)))  # the chain ends on the x-axis, at |sum z|
        rods = np.stack([z.real, z.imag], axis=1)
        p = np.cumsum(rods, axis=0)[:-1].ravel()
        got = factor.expression(list(p), [abs(np.sum(z))] + list(factor.parameters()[1:]))
        assert got == pytest.approx(_numpy_determinant(rods, w) / c**chain.n, rel=1e-12)
        assert 1e-6 < got < 1e3


def _pair(chain: Chain, h0, v0, T: float, **kwargs):
    plain = solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), T, **kwargs)
    sundman = solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), T,
                                  stepper=SundmanStepper(ChainTimeFactor(chain)), **kwargs)
    return plain, sundman


@pytest.mark.parametrize("n, L, masses, T", [
    (3, 1.6, 1.0, 12.0), (4, 2.7, 1.0, 15.0), (4, 3.5, [0.1, 1.0, 10.0], -12.0), (4, 3.5, [0.1, 1.0, 10.0], -40.0),
    (5, 3.2, [0.3, 2.0, 1.0, 0.5], 10.0), (6, 4.9, 1.0, 8.0),
])
def test_sundman_time_gives_the_same_motion_switches_and_energy(n, L, masses, T):
    chain = Chain(n, L, hinge_masses=masses)
    rng = np.random.default_rng(n)
    h0, v0 = unit_speed_start(chain, rng.uniform(-1.0, 1.0, n - 2), rng.normal(size=n - 2))
    plain, sundman = _pair(chain, h0, v0, T)
    assert_same_motion(sundman, plain, T)
    ts = np.linspace(0.0, T, 51)
    times = np.asarray(sundman.energy_times, dtype=float)
    assert np.all(np.diff(times) * np.sign(T) > 0) and times[-1] == T  # physical, in order, ending at T
    grid = solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), T,
                               save=SaveAt(dense=False, t_eval=ts),
                               stepper=SundmanStepper(ChainTimeFactor(chain)))
    assert np.max(np.abs(grid.points - plain(ts)[0])) <= 1e-10


@pytest.mark.parametrize("lengths, masses", [([0.01] * 5, 1.0), ([1.0] * 4, 1e-4), ([1.0] * 4, 1e6), ([1.0] * 6, 1e3)])
def test_sundman_time_works_at_any_size_and_mass_scale(lengths, masses):
    """A raw ``det M`` scales like ``(l^2 / m)^n`` and overflowed the Taylor coefficients in ``tau`` on these
    chains (found by review: garbage times, energy check failed); the normalised factor runs them like ``t``."""
    n = len(lengths)
    chain = Chain(lengths, (n - 0.6) * lengths[0], hinge_masses=masses)
    rng = np.random.default_rng(n)
    atlas = chain.atlas()
    a = rng.uniform(-1.0, 1.0, n - 2)
    p0 = atlas.get_point(0, a)
    v0 = atlas.charts[0].tangent_vector(a, rng.normal(size=n - 2))
    v0 = v0 / np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))
    T = 5.0 * lengths[0] * np.sqrt(masses)  # unit energy: speed 1 / sqrt(m), so T covers a few rod lengths
    plain = solve_chart_exp_ode(chain.metric(), p0, v0, T)
    sundman = solve_chart_exp_ode(chain.metric(), p0, v0, T, stepper=SundmanStepper(ChainTimeFactor(chain)))
    assert sundman.t_reached == T and sundman.n_steps < plain.n_steps
    assert np.max(np.abs(sundman.end_state()[0] - plain.end_state()[0])) <= 1e-10 * max(lengths)


def test_a_segment_that_starts_at_t_final_is_empty_not_a_failure():
    chain = Chain(4, 2.7)
    h0, v0 = unit_speed_start(chain, [0.2, 0.3], [0.5, -0.9])
    sol = solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), 0.0,
                              stepper=SundmanStepper(ChainTimeFactor(chain)))
    assert sol.status.value == "success" and sol.n_steps == 0
    assert np.array_equal(sol.end_state()[0], solve_chart_exp_ode(chain.metric(), chain.to_point(h0),
                                                                  chain.to_point(v0), 0.0).end_state()[0])


@pytest.mark.parametrize("ambient", [False, True])
@pytest.mark.parametrize("sundman", [False, True])
def test_a_run_that_ends_on_a_switch_or_at_its_start_has_dense_output_there(sundman, ambient):
    """A switch that lands on ``t_final`` leaves a last segment without steps (so does ``t_final = 0``); its
    continuous output is its one state.  Ending the run at each switch time and its neighbours finds such runs;
    whether a switch lands exactly on ``t_final`` is a matter of rounding, so the test tries a few starts in turn
    and asks for one such run; at every ending tried the motion equals the long run's."""
    chain = Chain(4, 2.5)
    atlas = chain.atlas()
    velocity = ConstrainedVelocity(ChainSystem(chain)) if ambient else None
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=velocity) if sundman else TaylorStepper(velocity=velocity)
    empty = 0
    for a0, c0 in (([0.3, 1.0], [1.0, -0.5]), ([1.2, 0.4], [1.0, -0.5]), ([0.1, 2.0], [0.2, 1.0])):
        p0 = atlas.get_point(0, np.array(a0))
        i = atlas.get_chart_index(p0)
        w0 = atlas.charts[i].tangent_vector(atlas.get_parameters(i, p0), np.array(c0))
        long = solve_chart_exp_ode(chain.metric(), p0, w0, 20.0, stepper=stepper)
        assert long.n_switches >= 1
        for s in long.switches:
            for T in (s.time, np.nextafter(s.time, 0), np.nextafter(s.time, 30)):
                sol = solve_chart_exp_ode(chain.metric(), p0, w0, float(T), stepper=stepper)
                empty += sol.segments[-1].n_steps == 0
                assert np.abs(sol(np.array([T, T / 2]))[0] - long(np.array([T, T / 2]))[0]).max() <= 1e-12
        if empty:
            break
    assert empty >= 1
    start = solve_chart_exp_ode(chain.metric(), p0, w0, 0.0, stepper=stepper)
    assert np.abs(start(0.0)[0] - p0).max() <= 4e-16 * np.abs(p0).max()  # the start's chart point


def test_with_masses_the_weighted_factor_saves_steps_and_a_unit_one_would_not():
    """The point of the factor: steps fall where ``K`` is far from the identity, because the factor is that of
    the real ``K``; the same determinant with unit weights (a factor for the wrong metric) saves few."""

    class UnitWeights(ChainTimeFactor):
        key = ("unit-weight chain determinant (test)", 4)

        def parameters(self):
            values = super().parameters()
            values[1:] = ChainTimeFactor(Chain(4, 2.7)).parameters()[1:]
            return values

    chain = Chain(4, 2.7, hinge_masses=[0.1, 1.0, 10.0])
    counts = {"t": 0, "weighted": 0, "unit": 0}
    for seed in range(3):
        rng = np.random.default_rng(seed)
        h0, v0 = unit_speed_start(chain, rng.uniform(-1.0, 1.0, 2), rng.normal(size=2))
        p0, w0 = chain.to_point(h0), chain.to_point(v0)
        for name, stepper in (("t", TaylorStepper()), ("weighted", SundmanStepper(ChainTimeFactor(chain))),
                              ("unit", SundmanStepper(UnitWeights(chain)))):
            counts[name] += solve_chart_exp_ode(chain.metric(), p0, w0, 30.0, stepper=stepper,
                                                save=SaveAt(dense=False)).n_steps
    assert counts["weighted"] < 0.75 * counts["t"]
    assert counts["weighted"] < 0.8 * counts["unit"]


def test_sundman_time_in_real128_agrees_with_t_to_its_precision():
    chain = Chain(4, 2.6)
    h0, v0 = unit_speed_start(chain, [0.4, -0.3], [0.7, 0.5])
    plain, sundman = _pair(chain, h0, v0, 1.5, precision=Precision(hy.real128))
    ts = np.linspace(0.0, 1.5, 7)
    assert float(np.max(np.abs(sundman(ts)[0] - plain(ts)[0]))) <= 1e-31  # measured 3.9e-34
    E = sundman.energies
    assert max(abs(float(e / E[0] - 1)) for e in E) <= 1e-31


def test_progress_reports_physical_times(monkeypatch):
    monkeypatch.setattr(manifold.progress, "STEP_INTERVAL", 0.0)
    chain = Chain(4, 2.7)
    h0, v0 = unit_speed_start(chain, [0.2, 0.3], [0.5, -0.9])
    updates: list[ProgressUpdate] = []
    sol = solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), 6.0,
                              stepper=SundmanStepper(ChainTimeFactor(chain)), progress=updates.append)
    steps = [u.t for u in updates if u.kind == "step"]
    assert len(steps) == sol.n_steps and np.all(np.diff(steps) > 0) and abs(steps[-1] - 6.0) <= 1e-12
    assert updates[-1].kind == "done" and updates[-1].t == 6.0


def test_bad_factors_are_refused_by_name():
    with pytest.raises(TypeError, match="factor must be a manifold.sundman.TimeFactor"):
        SundmanStepper("det M")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="chain must be a linkage.Chain"):
        ChainTimeFactor("chain")  # type: ignore[arg-type]
    chain = Chain(4, 2.5)
    h0, v0 = unit_speed_start(chain, [0.2, 0.3], [0.5, -0.9])
    with pytest.raises(ValueError, match=r"factor: ChainTimeFactor\(n=5\) takes points of R\^8, the charts .* R\^6"):
        free_motion(chain, h0, v0, 1.0, stepper=SundmanStepper(ChainTimeFactor(Chain(5, 3.4))))


def test_a_stepper_that_is_not_one_is_refused_by_name():
    chain = Chain(4, 2.5)
    h0, v0 = unit_speed_start(chain, [0.2, 0.3], [0.5, -0.9])
    for bad in ("taylor", TaylorStepper):
        with pytest.raises(TypeError, match="stepper must be None or a manifold.steppers.Stepper instance"):
            free_motion(chain, h0, v0, 1.0, stepper=bad)
