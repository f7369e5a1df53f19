"""The benchmarks behind the speed figures of ``docs/methods.md`` and ``docs/ensembles.md`` run end to end at a small
size, and compare like with like: what they time as "bare heyoka" integrates the very equations, state and
parameters the library's call integrates, so both end in the same place.  No timing is checked here."""

import numpy as np

from benchmarks import call_cost, ensemble_simd
from linkage.motion import free_motion
from manifold import SaveAt


def test_call_cost_bare_heyoka_ends_where_the_call_ends():
    chain, h0, w0 = call_cost.start(4, seed=3)
    N = 2 * (chain.n - 1)
    end = call_cost.bare(chain, h0, w0, 2.0)()
    motion = free_motion(chain, h0, w0, 2.0, method="hinges", save=SaveAt(dense=False))
    # the same compiled integrator from the same state: heyoka's chunks of steps change no digit
    assert np.array_equal(end[:N], motion.solution.end_state()[0])
    ts = np.linspace(0.0, 2.0, 11)
    states = call_cost.bare(chain, h0, w0, ts)()
    sampled = free_motion(chain, h0, w0, 2.0, method="hinges", save=SaveAt(t_eval=ts, dense=False))
    assert np.abs(states[:, :N] - chain.to_point(sampled.hinges)).max() <= 1e-14


def test_ensemble_simd_rows_end_where_single_solves_end():
    best, gaps = ensemble_simd.measure(4, count=6, T=1.0, rounds=1)
    assert set(best) == set(gaps) | {"bare batch, pair alone", "free_motions serial, pair alone"}
    # SIMD lanes round differently from scalar code: agreement to rounding, not to the bit
    assert max(gaps.values()) <= 1e-13, gaps
    assert all(np.isfinite(t) and t > 0 for t in best.values())
