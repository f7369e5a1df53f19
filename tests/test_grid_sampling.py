"""The hinge method's samples on a ``t_eval`` grid without dense output, which heyoka evaluates itself
(``propagate_grid``), against the same solve with dense output, whose grid is read from the kept Taylor
coefficients: the same steps, the same samples to rounding, and the same checks and stops."""

from __future__ import annotations

import heyoka as hy
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage import Chain
from linkage.motion import free_motion
from manifold import Precision, SaveAt, SolveStatus
from manifold.budget import Budget

from .conftest import unit_speed_start

CHAIN = Chain(4, 2.6)
INTERVAL = 3.0  # between projections, for stabilisation="projection"


def _both(h0, v0, T, ts, **kw):
    """The solve with dense output (the grid read from it) and without (the grid sampled by heyoka)."""
    runs = [free_motion(CHAIN, h0, v0, T, method="hinges", save=SaveAt(t_eval=ts, dense=dense), **kw)
            for dense in (True, False)]
    return runs[0].solution, runs[1].solution


def _assert_same_samples(dense, sampled, rows: int) -> None:
    assert sampled.n_steps == dense.n_steps and sampled.status is dense.status
    for got, ref in ((sampled.points[:rows], dense.points[:rows]), (sampled.velocities[:rows], dense.velocities[:rows])):
        got, ref = got.astype(float), ref.astype(float)
        assert np.all(np.abs(got - ref) <= 1e-13 * np.maximum(1.0, np.abs(ref)))


@settings(max_examples=30, deadline=None)
@given(a=st.lists(st.floats(-1.2, 1.2), min_size=2, max_size=2),
       c=st.lists(st.floats(-1.0, 1.0), min_size=2, max_size=2).filter(lambda c: max(map(abs, c)) > 0.1),
       T=st.floats(0.5, 12.0), backward=st.booleans(), projection=st.booleans(),
       fractions=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=40),
       with_ends=st.booleans(), repeat=st.booleans())
def test_sampled_grid_agrees_with_the_dense_output(a, c, T, backward, projection, fractions, with_ends, repeat):
    """Random starts, horizons both ways and grids (with the ends, every projection's segment end and repeated
    times, or without): the same steps, status and samples within 1e-13."""
    h0, v0 = unit_speed_start(CHAIN, a, c)
    T = -T if backward else T
    ts = list(np.array(fractions) * T)
    if with_ends:
        ts += [0.0, T] + [T * j / np.ceil(abs(T) / INTERVAL - 1e-9) for j in range(1, 5)]  # projection ends
    if repeat:
        ts += ts[:3]
    ts = sorted(t for t in ts if abs(t) <= abs(T))
    ts = np.array(ts[::-1] if backward else ts)
    kw = {"stabilisation": "projection", "projection_interval": INTERVAL} if projection else {}
    dense, sampled = _both(h0, v0, T, ts, **kw)
    assert dense.status is SolveStatus.SUCCESS and sampled.t_reached == T
    _assert_same_samples(dense, sampled, len(ts))
    for got, ref in zip(sampled.end_state(), dense.end_state()):  # heyoka clamps the last step its own way: rounding
        assert np.abs(got - ref).max() <= 1e-14
    # without dense output the energy is checked at the kept states: the start, the samples and each segment's end
    kept = np.unique(np.concatenate([[0.0], ts, [float(s.t_end) for s in sampled.segments]]))
    assert np.array_equal(np.sort(np.array(sampled.energy_times, dtype=float)), kept)
    assert sampled.relative_energy_error <= 1e-13


def test_a_budget_stops_both_at_the_same_step_with_the_same_samples():
    h0, v0 = unit_speed_start(CHAIN, [0.3, -0.4], [0.6, 0.8])
    ts = np.linspace(0.0, 20.0, 101)
    dense, sampled = _both(h0, v0, 20.0, ts, budget=Budget(steps=100), throw=False)
    assert sampled.status is SolveStatus.BUDGET_EXCEEDED and sampled.t_reached == dense.t_reached < 20.0
    assert "budget of 100 steps" in sampled.message
    rows = int(np.searchsorted(ts, float(sampled.t_reached), side="right"))
    assert 0 < rows < len(ts)
    _assert_same_samples(dense, sampled, rows)


def test_samples_in_real128():
    h0, v0 = unit_speed_start(CHAIN, [0.3, -0.4], [0.6, 0.8])
    ts = np.linspace(0.0, 2.0, 9)
    dense, sampled = _both(h0, v0, 2.0, ts, precision=Precision(fp_type=hy.real128))
    assert sampled.points.dtype == dense.points.dtype and sampled.n_steps == dense.n_steps
    assert np.abs(sampled.points - dense.points).max() <= 2.0**-100
    assert sampled.relative_energy_error <= 1e3 * 2.0**-113


def test_the_end_state_is_kept_without_dense_output_or_grid():
    """``end_hinges`` and ``end_velocities`` need no dense output: without it the solve ends where the dense one does
    (the same steps), and both equal the dense output's value at ``T`` to rounding, for either method; the recorded
    states, which do need it, say where the end state is."""
    h0, v0 = unit_speed_start(CHAIN, [0.4, 0.3], [1.0, 0.5])
    T = 6.0
    for method in ("hinges", "charts"):
        dense = free_motion(CHAIN, h0, v0, T, method=method)
        bare = free_motion(CHAIN, h0, v0, T, method=method, save=SaveAt(dense=False))
        assert np.array_equal(bare.end_hinges, dense.end_hinges)
        assert np.array_equal(bare.end_velocities, dense.end_velocities)
        at_T = dense(T)
        assert np.abs(dense.end_hinges - at_T[0]).max() <= 1e-13
        assert np.abs(dense.end_velocities - at_T[1]).max() <= 1e-13
        assert np.abs(CHAIN.closure_residual(bare.end_hinges)) <= 1e-14
        with pytest.raises(ValueError, match=r"SaveAt\(dense=False\): no continuous output .* end_state\(\)"):
            bare.hinges
