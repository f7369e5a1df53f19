"""Bounded work and memory (``manifold.budget``): a solve stops where its budget of steps or of dense-output bytes is
spent, with its partial result and a message that names the budget and the need; the default is generous."""

from __future__ import annotations

import numpy as np
import pytest

from linkage import Chain
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from manifold import GeodesicIntegrationError, SaveAt, SolveStatus
from manifold.budget import DEFAULT_BUDGET, Budget

CHAIN = Chain(4, 2.6)
H, V = sample_starts(CHAIN, 1, 0.5, np.random.default_rng(0))


@pytest.mark.parametrize("method", ["hinges", "charts"])
def test_a_step_budget_stops_the_solve_with_its_partial_result(method):
    with pytest.raises(GeodesicIntegrationError, match=r"the budget of 500 steps .* would take about") as info:
        free_motion(CHAIN, H[0], V[0], 1000.0, method=method, budget=Budget(steps=500))
    sol = info.value.solution
    assert sol.status is SolveStatus.BUDGET_EXCEEDED and sol.n_steps == 500
    assert 0 < float(sol.t_reached) < 1000 and sol.relative_energy_error <= 1e-13
    reached = float(sol.t_reached)
    assert np.abs(sol(reached)[0] - sol.end_state()[0]).max() <= 1e-12  # dense output up to where it stopped
    quiet = free_motion(CHAIN, H[0], V[0], 1000.0, method=method, budget=Budget(steps=500), throw=False)
    assert quiet.solution.status is SolveStatus.BUDGET_EXCEEDED


@pytest.mark.parametrize("method", ["hinges", "charts"])
def test_a_memory_budget_limits_dense_output_and_the_end_state_needs_none(method):
    """The bytes a step keeps are estimated from the Taylor coefficients (within 2 % of what a Sundman segment
    holds: it keeps a little more per step)."""
    budget = Budget(dense_bytes=200_000)
    with pytest.raises(GeodesicIntegrationError, match="GiB of dense output") as info:
        free_motion(CHAIN, H[0], V[0], 1000.0, method=method, budget=budget)
    assert info.value.solution.dense_nbytes <= 1.05 * 200_000
    end = free_motion(CHAIN, H[0], V[0], 1000.0, method=method, budget=budget, save=SaveAt(dense=False))
    assert end.success and end.n_steps > 2000


def test_the_default_budget_and_bad_budgets():
    assert DEFAULT_BUDGET.steps == 10**8 and DEFAULT_BUDGET.dense_bytes == 2 * 2**30
    for bad in ({"steps": 0}, {"dense_bytes": -1}, {"steps": 1.5}, {"steps": True}):
        with pytest.raises(ValueError, match="Budget"):
            Budget(**bad)
    with pytest.raises(TypeError, match="budget must be a manifold.budget.Budget"):
        free_motion(CHAIN, H[0], V[0], 1.0, method="hinges", budget=1000)


def test_batch_sizes_beyond_what_simd_makes_useful_are_refused():
    """A 1000-lane batch integrator took 1.7 GB and minutes to compile: refused before, naming the SIMD width."""
    import heyoka as hy

    from linkage.motion import free_motions
    from manifold.constrained_batch import MAX_BATCH_LANES

    H2, V2 = sample_starts(CHAIN, 2, 0.5, np.random.default_rng(1))
    with pytest.raises(ValueError, match=f"batch_size=1000 is beyond what SIMD makes useful.*{hy.recommended_simd_size()}"):
        free_motions(CHAIN, H2, V2, 1.0, batch_size=1000)
    assert free_motions(CHAIN, H2, V2, 1.0, batch_size=MAX_BATCH_LANES * hy.recommended_simd_size()).success.all()
