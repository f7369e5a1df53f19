"""The benchmarks behind the speed figures of ``docs/methods.md`` and ``docs/ensembles.md`` run end to end at a small
size, and compare like with like: what they time as "bare heyoka" integrates the very equations, state and
parameters the library's call integrates, so both end in the same place.  No timing is checked here."""

import ctypes
from pathlib import Path

import heyoka as hy
import numpy as np
import pytest

from benchmarks import call_cost, chart_scaling, ensemble_simd, simd_stack_phase, taylor_options
from benchmarks.study.experiments import generic_start
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


def test_taylor_options_flags_integrate_the_hinge_method_s_own_problem():
    # the scalar integrator of hinge_problem, unflagged, is the one free_motion steps: same end, bit for bit
    equations, Y, P, compact = taylor_options.hinge_problem(4, 3, 1.0)
    chain, p0, v0 = generic_start(4, seed=2)
    ta = hy.taylor_adaptive(equations, Y[2], compact_mode=compact)
    ta.pars[:] = P[2, : len(ta.pars)]
    ta.propagate_until(1.0)
    motion = free_motion(chain, chain.from_point(p0), chain.from_point(v0), 1.0, method="hinges",
                         save=SaveAt(dense=False))
    assert np.array_equal(ta.state[: 2 * (chain.n - 1)], motion.solution.end_state()[0])
    cache_was = hy.llvm_state.get_diskcache_enabled()
    rows = taylor_options.flag_variants(4, 0.5)
    assert hy.llvm_state.get_diskcache_enabled() == cache_was  # the cold compiles leave heyoka's setting as it was
    # flags and lanes change the rounding only
    assert max(r["apart"] for r in rows) <= 1e-13, [(r["name"], r["apart"]) for r in rows]


@pytest.mark.skipif(simd_stack_phase.GETCONTEXT is None, reason="reads the stack pointer with glibc's getcontext: "
                    "x86-64 Linux only")
def test_simd_stack_phase_moves_the_stack_and_changes_no_digit():
    context = ctypes.create_string_buffer(4096)
    pointers = np.array([simd_stack_phase.nested(level, lambda: simd_stack_phase.stack_pointer(context))
                         for level in range(4)])
    # each level calls through one more C frame of the interpreter: the stack (growing down) is deeper every time
    assert np.all(np.diff(pointers) < 0), pointers
    problem = taylor_options.hinge_problem(4, simd_stack_phase.COUNT, 0.2)
    run = simd_stack_phase.batches(problem, 8, problem[3], 0.2)
    out = simd_stack_phase.scan(run, rounds=1)
    # wherever the stack stands, the batch computes the same numbers to the last bit
    assert out["same"]


def test_chart_scaling_sorts_nodes_by_the_cost_of_their_recursion():
    """A system whose nodes are known by hand: x y, x / y, sqrt(x), 1 / y, sin y and cos y (one pair of nodes),
    atan2(x, y) with its two squares, and x x are products of series; p0 x, x / p1, 2 y and the constant 3 p2 are
    scaled; the rest are sums."""
    x, y = hy.make_vars("x", "y")
    f = [x * y + hy.par[0] * x + hy.sin(y) + 3.0 * hy.par[2],
         x / y + hy.sqrt(x) + hy.atan2(x, y) + x * x + 2.0 * y + x / hy.par[1] + 1.0 / y]
    ta = hy.taylor_adaptive(list(zip((x, y), f)), [1.0, 2.0], compact_mode=True)
    kinds = chart_scaling.node_kinds(ta.decomposition, 2)
    assert kinds["series"] == 10 and kinds["scaled"] == 4 and kinds["other"] == 0
    # every other node is a sum: 4 are the variables and outputs, 8 the series' own nodes (the squares sit in a sum)
    assert kinds["sums"] == len(ta.decomposition) - 4 - 8 - 4


def test_call_cost_measures_another_checkout_with_this_checkout_s_code(capsys):
    """``--baseline``: each side runs this checkout's benchmark, as a module (its imports are relative), on the
    library of its own tree; here both trees are this one, so the two sides measure the same code."""
    call_cost.side_by_side(4, 1, Path(call_cost.__file__).resolve().parent.parent)
    out = capsys.readouterr().out
    assert "fixed, dense" in out and "share of a T = 10 call in heyoka (dense)" in out
