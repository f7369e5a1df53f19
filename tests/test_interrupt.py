"""Ctrl-C stops a long solve or ensemble within a fraction of a second, with its partial result, and chunked
propagation changes no digit.

The interrupt is a real SIGINT sent to this process from a timer thread, during solves that would take minutes
(T = 1e7); each solve is compiled first, so the interrupt lands in the integration.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from linkage.ensemble import free_motions
from linkage.lyapunov import lyapunov_exponents
from linkage.motion import free_motion, lyapunov_exponent
from linkage.sampling import sample_starts
from manifold import SaveAt, SolveStatus
from manifold import interrupt
from manifold.interrupt import SolveInterrupted

CHAIN = Chain(4, 2.6)
H, V = sample_starts(CHAIN, 1, 0.5, np.random.default_rng(0))
RUNS = {
    "hinges": lambda T, **kw: free_motion(CHAIN, H[0], V[0], T, method="hinges", **kw),
    "hinges, no dense output": lambda T, **kw: free_motion(CHAIN, H[0], V[0], T, method="hinges",
                                                           save=SaveAt(dense=False), **kw),
    "hinges, a grid and no dense output": lambda T, **kw: free_motion(
        CHAIN, H[0], V[0], T, method="hinges", save=SaveAt(t_eval=np.linspace(0.0, T, 101), dense=False), **kw),
    "charts (Sundman's time)": lambda T, **kw: free_motion(CHAIN, H[0], V[0], T, method="charts", **kw),
    "lyapunov": lambda T, **kw: lyapunov_exponent(CHAIN, H[0], V[0], T, **kw),
}


def _press_ctrl_c_once_stepping(timeout: float = 120.0) -> None:
    """Send SIGINT to this process once a solve's Ctrl-C handler is installed, and 0.2 s after."""
    waited = 0.0
    while signal.getsignal(signal.SIGINT) is signal.default_int_handler and waited < timeout:
        time.sleep(0.01)
        waited += 0.01
    time.sleep(0.2)
    os.kill(os.getpid(), signal.SIGINT)


def _interrupted(run: Callable[[], object]) -> SolveInterrupted:
    """``run()`` with Ctrl-C pressed once it is stepping: the :class:`SolveInterrupted` it must raise."""
    threading.Thread(target=_press_ctrl_c_once_stepping, daemon=True).start()
    with pytest.raises(SolveInterrupted) as info:
        run()
    return info.value


@pytest.mark.parametrize("name", list(RUNS))
def test_ctrl_c_stops_a_long_solve_with_its_partial_result(name):
    run = RUNS[name]
    run(1.0)  # compiled before the clock starts
    # Ctrl-C once the solve is stepping: its flag handler in place, then a few chunks of steps (a fixed delay
    # landed before the handler on a loaded machine, while a Lyapunov run of T = 1e7 built its arrays)
    error = _interrupted(lambda: run(1e7))
    assert isinstance(error, KeyboardInterrupt)
    result = error.result
    assert result.status is SolveStatus.INTERRUPTED and "KeyboardInterrupt" in str(error)
    if name == "lyapunov":
        assert 0 < result.times[-1] < 1e7 and np.all(np.isfinite(result.exponents))
    else:
        reached = float(result.t_reached)
        assert 0 < reached < 1e7 and result.relative_energy_error <= 1e-12  # what it computed is sound
        end_point, _ = result.end_state()
        assert CHAIN.closure_residual(CHAIN.from_point(end_point.astype(float))) <= 1e-12
        if "no dense output" not in name:
            assert np.abs(result(reached)[0] - end_point).max() <= 1e-12
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_chunks_change_no_digit(monkeypatch):
    """Propagated in chunks of 16 steps against one chunk per segment: the same states, bit for bit."""
    monkeypatch.setattr(interrupt, "FIRST_CHUNK", 10**9)  # one chunk: heyoka's propagate_until as it is
    whole = {name: RUNS[name](30.0) for name in ("hinges", "charts (Sundman's time)")}
    monkeypatch.setattr(interrupt, "FIRST_CHUNK", 16)
    monkeypatch.setattr(interrupt, "CHUNK_SECONDS", 0.0)  # every chunk 16 steps
    for name, motion in whole.items():
        chunked = RUNS[name](30.0)
        ts = np.linspace(0, 30, 7)
        assert chunked.n_steps == motion.n_steps
        assert np.array_equal(chunked.solution(ts)[0], motion.solution(ts)[0])


def test_a_grid_is_sampled_in_one_heyoka_call(monkeypatch):
    """A grid sampled without dense output is one heyoka call whatever the chunk sizes (a grid restarted at a chunk
    would begin at a float64 time and the samples would hang on the machine's speed): the same bits either way."""
    run = RUNS["hinges, a grid and no dense output"]
    monkeypatch.setattr(interrupt, "FIRST_CHUNK", 10**9)
    whole = run(30.0).solution
    monkeypatch.setattr(interrupt, "FIRST_CHUNK", 16)
    monkeypatch.setattr(interrupt, "CHUNK_SECONDS", 0.0)
    chunked = run(30.0).solution
    assert chunked.n_steps == whole.n_steps > 16 * 5
    assert np.array_equal(chunked.points, whole.points) and np.array_equal(chunked.velocities, whole.velocities)


def _pendulum():
    x, v = hy.make_vars("x", "v")
    return hy.taylor_adaptive([(x, v), (v, -hy.sin(x))], [1.0, 0.0], tol=1e-15)


def test_propagate_grid_stopped_on_a_grid_time_and_resumed():
    """A grid with repeats and a time exactly where a step limit stops the run: the rows up to it (the state there),
    none beyond; resumed from there, the rest, all as heyoka's own ``propagate_grid`` gives them in one go."""
    probe = _pendulum()
    probe.propagate_until(100.0, max_steps=3)
    t3 = probe.time  # where three steps end
    grid = np.array([0.0, 0.0, 0.5 * t3, t3, t3, 1.5 * t3, 10.0, 10.0])
    ta = _pendulum()
    outcome, steps, stop, states = interrupt.propagate_grid(ta, grid, max_steps=3)
    assert (outcome, steps, stop) == (hy.taylor_outcome.step_limit, 3, interrupt.BUDGET) and ta.time == t3
    assert len(states) == 5 and np.array_equal(states[3], ta.state) and np.array_equal(states[4], ta.state)
    _, _, stop, rest = interrupt.propagate_grid(ta, grid[3:])
    assert stop is None and ta.time == 10.0 and len(rest) == 5
    reference = _pendulum().propagate_grid(np.unique(grid))[-1]
    ours = np.concatenate([states, rest[2:]])
    assert np.all(np.abs(ours - reference[[0, 0, 1, 2, 2, 3, 4, 4]]) <= 1e-15)


@pytest.mark.parametrize("method", ["hinges", "charts"])
def test_a_ctrl_c_is_not_swallowed_by_a_failure_of_the_same_segment(monkeypatch, method):
    """Ctrl-C pressed while the energy check fails the run: still a SolveInterrupted, even with throw=False."""
    from manifold.solution import GeodesicSolution

    def failing_check(self, start, tol, where):
        os.kill(os.getpid(), signal.SIGINT)  # lands while the solver's flag handler is in place
        return "energy check failed (planted)"

    RUNS["hinges"](1.0)
    monkeypatch.setattr(GeodesicSolution, "energy_violation", failing_check)
    with pytest.raises(SolveInterrupted, match="planted"):
        free_motion(CHAIN, H[0], V[0], 5.0, method=method, throw=False)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


H4, V4 = sample_starts(CHAIN, 6, 0.5, np.random.default_rng(1))
ENSEMBLES = {
    # SIMD batches (float64 hinges, Baumgarte): a step callback of propagate_grid reads the flag
    "SIMD batches, serial": lambda T: free_motions(CHAIN, H4, V4, T, method="hinges", chunk_size=1),
    "SIMD batches, threads": lambda T: free_motions(CHAIN, H4, V4, T, method="hinges", backend="threads",
                                                    chunk_size=1),
    # single solves in worker threads: they read the main thread's flag
    "single solves, threads": lambda T: free_motions(CHAIN, H4, V4, T, method="charts", backend="threads",
                                                     chunk_size=2),
}


@pytest.mark.parametrize("name", list(ENSEMBLES))
def test_ctrl_c_stops_an_ensemble_with_its_partial_results(name):
    run = ENSEMBLES[name]
    run(1.0)  # compiled before the clock starts
    error = _interrupted(lambda: run(1e7))
    ensemble = error.result
    assert len(ensemble) == len(H4) and "KeyboardInterrupt" in str(error)
    assert all(s is SolveStatus.INTERRUPTED for s in ensemble.status)
    reached = ensemble.t_reached
    assert np.all((reached >= 0) & (reached < 1e7)) and np.any(reached > 0)
    # what was computed is sound: energy, and the end states close
    assert np.all(ensemble.relative_energy_errors <= 1e-12)
    ends = CHAIN.from_point(ensemble.end_points)
    assert np.all(CHAIN.closure_residual(ends) <= 1e-12)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_stops_lyapunov_estimates_on_threads():
    lyapunov_exponents(CHAIN, H4[:2], V4[:2], 1.0, backend="threads", chunk_size=1)  # compiled first
    # 1e9 renormalisations planned: their end times were once one array of 8 GB
    results = _interrupted(lambda: lyapunov_exponents(CHAIN, H4[:2], V4[:2], 1e7, backend="threads", chunk_size=1,
                                                      interval=0.01)).result
    assert len(results) == 2 and all(r.status is SolveStatus.INTERRUPTED for r in results)
    assert sum(r.n_steps for r in results) > 0
    for r in results:  # each estimate as far as it got: its renormalisations, finite
        assert len(r.history) == len(r.times) and np.all((r.times > 0) & (r.times < 1e7))
        assert np.all(np.isfinite(r.history)) and r.relative_energy_error <= 1e-12


def test_a_solve_in_a_worker_thread_without_an_ensemble_is_not_interrupted():
    """A worker thread's solve reads the main thread's flag only while an ensemble holds it: here nothing does,
    and a Ctrl-C pressed earlier (a stale flag) must not stop it."""
    with interrupt.interruptible() as pressed:
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.05)
        assert pressed()
    out = []
    worker = threading.Thread(target=lambda: out.append(RUNS["hinges"](5.0)))
    worker.start()
    worker.join()
    assert out and out[0].success
