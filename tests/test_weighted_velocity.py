"""The chart path with the mass-weighted velocity as state (:mod:`manifold.weighted_velocity`).

The state ``(a, w)``, ``w = (R (x) I_2) J c`` with ``R^T R = B``, is a change of variables of ``(a, J c)``: it must
give the same motion, switches and energy, in ``t`` and in Sundman's time, for every mass model, backward, with its
dense output read back; and its ``w`` must carry the kinetic energy, ``|w|^2 = 2 E``.
"""

from __future__ import annotations

import pickle

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import solve_chart_exp_ode
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.compiled import compiled
from manifold.precision import as_fp
from manifold.steppers import TaylorStepper
from manifold.sundman import SundmanStepper
from manifold.terms import SegmentStart
from manifold.testing import check_geodesic_energy
from manifold.weighted_velocity import WeightedVelocity

from .conftest import atlas_start, unit_speed_start



@pytest.mark.parametrize("sundman", [False, True])
@pytest.mark.parametrize("lengths, L, masses, densities, T", [
    (4, 2.7, 1.0, 0.0, 15.0),  # through switches
    (4, 3.5, [1e-3, 1.0, 1e2], 0.0, -12.0),  # spread masses, backward
    (5, 3.2, [3e-4, 20.0, 1.0, 5e-2], 0.0, 10.0),
    (5, 3.4, [0.3, 2.0, 1.0, 0.5], 0.2, 10.0),  # rod densities: a dense B, R with off-diagonal entries
    ((3.0, 1.0, 1.2, 0.9), 0.3, [1.0, 0.5, 2.0], 0.0, 10.0),  # the link l_1 dominant: charts on a link base
])
def test_the_weighted_velocity_gives_the_same_motion_switches_and_energy(lengths, L, masses, densities, T, sundman):
    chain = Chain(lengths, L, hinge_masses=masses, rod_densities=densities)
    p0, v0 = atlas_start(chain, chain.n)
    factor = [ChainTimeFactor(chain)] if sundman else []
    kind = SundmanStepper if sundman else TaylorStepper
    system = ChainSystem(chain)
    ambient = solve_chart_exp_ode(chain.metric(), p0, v0, T, stepper=kind(*factor, velocity=ConstrainedVelocity(system)))
    weighted = solve_chart_exp_ode(chain.metric(), p0, v0, T,
                                   stepper=kind(*factor, velocity=WeightedVelocity(system, block=2)))
    assert weighted.t_reached == T and weighted.success and ambient.success
    assert weighted.method.endswith(" (a, w)") and ambient.method.endswith(" (a, J c)")  # the state integrated
    assert [(s.from_chart, s.to_chart) for s in weighted.switches] == [(s.from_chart, s.to_chart)
                                                                        for s in ambient.switches]
    assert np.allclose([s.time for s in weighted.switches], [s.time for s in ambient.switches], atol=1e-9, rtol=0)
    assert weighted.relative_energy_error <= 1e-12
    ts = np.linspace(0.0, T, 51)  # the dense output, read back through (a, w) -> (a, V) -> (a, c)
    assert np.max(np.abs(weighted(ts)[0] - ambient(ts)[0])) <= 1e-10
    assert np.max(np.abs(weighted(ts)[1] - ambient(ts)[1])) <= 1e-10
    assert np.max(np.abs(weighted.end_state()[1] - ambient.end_state()[1])) <= 1e-10


def test_free_motion_with_the_weighted_state_agrees_with_the_hinge_method_both_ways():
    chain = Chain(5, 3.3, hinge_masses=[2e-4, 0.4, 3e2, 1.0])
    h0, v0 = unit_speed_start(chain, [0.3, -0.5, 1.1], [0.4, 1.0, -0.7])
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=WeightedVelocity(ChainSystem(chain), block=2))
    for T in (6.0, -6.0):
        charts = free_motion(chain, h0, v0, T, stepper=stepper)
        hinges = free_motion(chain, h0, v0, T, method="hinges")
        ts = np.linspace(0.0, T, 21)
        assert np.max(np.abs(charts(ts)[0] - hinges(ts)[0])) <= 1e-10
        assert charts.closure_residuals.max() <= 1e-13
        assert charts.relative_energy_error <= 1e-13


def _segment(chain: Chain, fp_type, chart: int = 0) -> tuple[SegmentStart, np.ndarray]:
    """A segment start in ``chart`` at a generic point and velocity, and the hinge velocity there."""
    atlas, rng = chain.atlas(), np.random.default_rng(7)
    ch = atlas.charts[chart]
    a, c = rng.uniform(-0.8, 0.8, chain.n - 2), rng.normal(size=chain.n - 2)
    pars = ch.numerics(chain.ambient_metric, atlas.switch_threshold, fp_type).pars
    y = as_fp(np.concatenate([a, c]), fp_type)
    segment = SegmentStart(compiled(ch.family), fp_type, as_fp([0.0], fp_type)[0], y, as_fp([1.0], fp_type)[0],
                           pars)
    return segment, chain.from_point(ch.tangent_vector(a, c))


@pytest.mark.parametrize("fp_type", [float, hy.real128])
@pytest.mark.parametrize("densities", [0.0, 0.3])
def test_the_weighted_velocity_carries_the_kinetic_energy_in_every_chart(fp_type, densities):
    """``R^T R = B``, ``R R^{-1} = I`` in the working precision, and ``|w|^2 = 2 E`` with ``E`` the chain's own
    ``1/2 v^T K v`` of the hinge velocity (no chart)."""
    chain = Chain(5, 3.4, hinge_masses=[1e-4, 3.0, 1e3, 0.2], rod_densities=densities)
    term, eps = WeightedVelocity(ChainSystem(chain), block=2), 2 * float(np.finfo(float).eps)
    for chart in range(len(chain.atlas().charts)):
        segment, v = _segment(chain, fp_type, chart)
        R, R_inv = term.factors(segment)
        lay = segment.family.layout
        B = np.zeros(R.shape, dtype=R.dtype)
        B[np.triu_indices(len(B))] = segment.pars[lay.n_theta : lay.n_theta + lay.n_metric]
        B = np.triu(B) + np.triu(B, 1).T
        scale = float(np.max(np.abs(B.astype(float))))
        residual = (R.T @ R - B).astype(float)
        tol = eps if fp_type is float else 1e-30
        assert np.max(np.abs(residual)) <= 8 * tol * scale
        assert np.max(np.abs((R @ R_inv - np.eye(len(R))).astype(float))) <= 8 * tol * np.linalg.cond(B.astype(float))
        w = term.enter(segment)[chain.n - 2 :]
        assert abs(float(w @ w) / (2 * float(chain.kinetic_energy(v))) - 1) <= 1e-13


def test_with_hinge_masses_the_identity_chart_weighs_each_hinge_by_the_root_of_its_mass():
    """Chart 0 maps its ``z`` to the hinges unchanged (``M = I``), so ``B`` is the mass matrix and ``R`` its root."""
    masses = np.array([1e-4, 3.0, 1e3, 0.2])
    chain = Chain(5, 3.4, hinge_masses=masses)
    segment, _ = _segment(chain, float, 0)
    assert np.array_equal(chain.atlas().charts[0].linear_map, np.eye(8))
    R, R_inv = WeightedVelocity(ChainSystem(chain), block=2).factors(segment)
    assert np.allclose(R, np.diag(np.sqrt(masses)), rtol=1e-15, atol=0)
    assert np.allclose(R_inv, np.diag(1 / np.sqrt(masses)), rtol=1e-15, atol=0)


def test_bad_arguments_are_refused_by_name():
    chain = Chain(4, 2.5)
    with pytest.raises(TypeError, match="system must be a manifold.constrained.ConstrainedSystem"):
        WeightedVelocity(chain, block=2)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="block must be an integer >= 1, got 0"):
        WeightedVelocity(ChainSystem(chain), block=0)
    with pytest.raises(ValueError, match="block must divide the system's ambient dimension 6, got 4"):
        WeightedVelocity(ChainSystem(chain), block=4)
    with pytest.raises(ValueError, match="rate must be a finite real number >= 0"):
        WeightedVelocity(ChainSystem(chain), block=2, rate=-1.0)
    p0, v0 = atlas_start(chain, 1)
    with pytest.raises(ValueError, match="block: .* weighs blocks of 3, the charts of .* have blocks of 2"):
        solve_chart_exp_ode(chain.metric(), p0, v0, 1.0,
                            stepper=TaylorStepper(velocity=WeightedVelocity(ChainSystem(chain), block=3)))


def test_the_stepper_pickles_and_runs_the_same():
    chain = Chain(4, 2.5, hinge_masses=[1e-2, 1.0, 30.0])
    p0, v0 = atlas_start(chain, 3)
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=WeightedVelocity(ChainSystem(chain), 2, rate=2.0))
    copy = pickle.loads(pickle.dumps(stepper))
    assert copy.velocity.block == 2 and copy.velocity.velocity.rate == 2.0
    first = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, stepper=stepper)
    again = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, stepper=copy)
    assert np.array_equal(first.end_state()[1], again.end_state()[1])


def test_the_weighted_velocity_passes_the_conformance_energy_check_across_switches():
    """``manifold.testing``'s energy check, as the default state passes it: spread masses, at least two switches."""
    chain = Chain(5, 3.3, hinge_masses=[2e-3, 5.0, 0.1, 40.0])
    p0, v0 = atlas_start(chain, 11)
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=WeightedVelocity(ChainSystem(chain), block=2))
    check_geodesic_energy(chain.metric(), p0, v0, 30.0, min_switches=2, q_out=0.45,
                          stepper=stepper).raise_on_failure()
