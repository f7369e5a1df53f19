"""Bounded work and memory (``manifold.budget``): a solve stops where its budget of steps, of dense-output bytes or
of CPU seconds is spent, with its partial result and a message that names the budget and the need; the default is
generous."""

from __future__ import annotations

import numpy as np
import pytest

from linkage import Chain
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from manifold import GeodesicIntegrationError, SaveAt, SolveStatus
from manifold.budget import DEFAULT_BUDGET, Budget

from .conftest import unit_speed_start

CHAIN = Chain(4, 2.6)
H, V = sample_starts(CHAIN, 1, 0.5, np.random.default_rng(0))


@pytest.mark.parametrize("method", ["hinges", "charts"])
def test_a_step_budget_stops_the_solve_with_its_partial_result(method):
    with pytest.raises(GeodesicIntegrationError, match=r"the budget of 500 steps, .* would take about") as info:
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


@pytest.mark.parametrize("method, save", [("hinges", SaveAt(dense=False)), ("charts", SaveAt(dense=False)),
                                          ("hinges", SaveAt(t_eval=np.linspace(0, 100, 11), dense=False))],
                         ids=["hinges", "charts", "hinges, sampled by heyoka"])
def test_a_cpu_time_budget_stops_a_solve_that_steps_alone_would_let_run_for_hours(method, save):
    """Motions that outlast a small budget of CPU seconds well within the step budget: masses 1e-8..1e8 (the light
    hinge whips: on this start 57,000 steps over T = 100, 0.25-0.5 s of CPU, so T = 1e4 outlasts the budget on a
    machine a hundred times faster; other starts take millions of steps per unit time),
    also sampled by heyoka without dense output (where the step callback reads the clock), and a chain within 1e-9
    of stretched (a chart solve's 1e5 steps and thousands of switches per unit time).  A budget of 0.2 CPU seconds
    stops them with their partial result, checked like any other, and the message names the seconds."""
    if method == "hinges":
        chain = Chain(4, 2.6, hinge_masses=[1e-8, 1.0, 1e8])
        h, v = unit_speed_start(chain, [0.3, 0.5], [1.0, -0.4])
    else:
        chain = Chain(5, 5 - 1e-9)
        h, v = unit_speed_start(chain, [0.3, 0.5, -0.2], [1.0, -0.4, 0.7])
    with pytest.raises(GeodesicIntegrationError, match=r"and 0.2 s of CPU is spent at t = .* s of CPU here") as info:
        free_motion(chain, h, v, 1e4, method=method, budget=Budget(seconds=0.2), save=save)
    sol = info.value.solution
    assert sol.status is SolveStatus.BUDGET_EXCEEDED
    assert 0 < float(sol.t_reached) < 1e4 and 0 < sol.n_steps < 10**8
    assert sol.relative_energy_error <= 1e-9


def test_the_default_budget_and_bad_budgets():
    assert DEFAULT_BUDGET.steps == 10**8 and DEFAULT_BUDGET.dense_bytes == 2 * 2**30
    assert DEFAULT_BUDGET.seconds == 300
    for bad in ({"steps": 0}, {"dense_bytes": -1}, {"steps": 1.5}, {"steps": True}, {"seconds": 0},
                {"seconds": -1.0}, {"seconds": float("nan")}, {"seconds": float("inf")}, {"seconds": "60"},
                {"seconds": True}):
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


def test_a_solves_step_count_reads_each_segment_once():
    """The solvers ask for the step count after every segment, and a chart solve near the stretched chain has 1e5
    of them (3,000 chart switches per unit time at ``L = n - 1e-9``): the count goes on from the new segments,
    where a sum over all of them each time made the loop quadratic in its segments."""
    from manifold.solution import GeodesicSolution

    reads = []

    class CountedSegment:
        def __init__(self, steps: int) -> None:
            self.steps = steps

        @property
        def n_steps(self) -> int:
            reads.append(1)
            return self.steps

    sol = GeodesicSolution(None, float, "test", (0.0, 1.0), {})
    for k in range(1, 1001):
        sol.segments.append(CountedSegment(k))
        assert sol.n_steps == k * (k + 1) // 2
    assert len(reads) == 1000
