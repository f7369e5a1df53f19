"""Ensembles (``free_motions``): the same trajectories as single solves, wherever and however they run.

An ensemble only reorganises work (SIMD lanes, threads, Dask workers), so
every trajectory must be the one a single ``free_motion`` call computes from
the same start, each failure must stay with its own trajectory, and the
mathematics (energy, closure, reversibility) must hold per trajectory.
"""

from __future__ import annotations

import pickle
import sys

import distributed  # the 'distributed' extra, part of the 'test' extra
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage import Chain
from linkage.motion import free_motion, free_motions
from manifold import SaveAt, SolveStatus, StartCheck
from manifold.constrained import constraint_bound, verdict
from manifold.constrained_batch import judge_lanes
from manifold.solution import energy_bound, energy_violation

from .conftest import base_lengths, unit_speed_start

# compact mode in tests: one cold compile per n in seconds (CI starts cold); results agree with it on both sides
FAST = {"compact_mode": True}


def _starts(chain: Chain, count: int, seed: int = 0, pole: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """``count`` unit-speed starts at random chart-0 parameters; the first exactly on a pole of chart 0 if ``pole``."""
    rng = np.random.default_rng(seed)
    hs, vs = [], []
    for k in range(count):
        a = rng.uniform(-1.4, 1.4, chain.n - 2)
        c = rng.normal(size=chain.n - 2)
        if pole and k == 0 and chain.n > 3:
            atlas = chain.atlas()
            a[0] = np.pi / 2
            p0 = atlas.get_point(0, a)
            i, b = atlas.best_chart(p0)
            v = chain.from_point(atlas.charts[i].tangent_vector(b, c))
            h, v = chain.from_point(p0), v / np.sqrt(2 * chain.kinetic_energy(v))
        else:
            h, v = unit_speed_start(chain, a, c)
        hs.append(h)
        vs.append(v)
    return np.array(hs), np.array(vs)


def _singles(chain, H, V, T, ts, **kw):
    return [free_motion(chain, h, v, T, save=SaveAt(t_eval=ts), throw=False, **kw) for h, v in zip(H, V)]


def _max_gap(ens, singles) -> float:
    """Largest difference of hinges and velocities (grid and end) between an ensemble and single solves."""
    gaps = []
    for k, s in enumerate(singles):
        end_p, end_v = s.solution.end_state()
        gaps += [np.abs(ens.hinges[k] - s.hinges).max(), np.abs(ens.velocities[k] - s.velocities).max(),
                 np.abs(ens.end_hinges[k] - s.chain.from_point(end_p.astype(float))).max(),
                 np.abs(ens.end_velocities[k] - s.chain.from_point(end_v.astype(float))).max()]
    return float(max(gaps))


def test_batches_threads_and_single_calls_agree():
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 9)  # 9: two full batches of 4 lanes and a short one
    T = 20.0
    ts = np.array([0.0, 0.0, 3.5, 10.0, 10.0, 17.25, 20.0])  # repeated times and both ends
    singles = _singles(chain, H, V, T, ts, method="hinges", **FAST)
    runs = {}
    # batch sizes given where backends are compared bit by bit below: the default follows heyoka's SIMD width (4 on
    # AVX2, 8 on AVX-512), and the test must not assume one
    for backend, batch_size, chunk_size in [("serial", None, None), ("serial", 1, None), ("serial", 4, None),
                                            ("threads", 4, 4), ("threads", 3, 3), ("threads", 1, 2)]:
        ens = free_motions(chain, H, V, T, save=SaveAt(t_eval=ts), backend=backend, batch_size=batch_size,
                           chunk_size=chunk_size,
                           **FAST)
        assert ens.success.all(), ens.messages
        assert _max_gap(ens, singles) <= 1e-12
        # a lane takes the steps of its single solve (to a step: the step sizes are rounded differently)
        assert np.abs(ens.n_steps - [s.n_steps for s in singles]).max() <= 1
        assert ens.relative_energy_errors.max() <= 1e-13
        assert ens.closure_residuals.max() <= 1e-14
        assert np.all(np.isclose(ens.solution.t_reached, T, rtol=0, atol=0))
        runs[(backend, ens.solution.batch_size)] = ens
    # where chunks run does not change a single bit
    for lanes in (1, 4):
        serial, threads = runs[("serial", lanes)], runs[("threads", lanes)]
        assert np.array_equal(serial.hinges, threads.hinges) and np.array_equal(serial.end_velocities,
                                                                                threads.end_velocities)


@given(n=st.integers(3, 6), data=st.data(), count=st.integers(1, 6), backward=st.booleans(), seed=st.integers(0, 99))
@settings(max_examples=8)
def test_ensembles_agree_with_single_calls_across_chains(n, data, count, backward, seed):
    """Any n, L near both ends of its range, masses, forward or backward: lane by lane the single solve, to rounding.

    SIMD lanes and scalar code round differently, so they agree to the
    solve's own rounding error: below 1e-12 where that is (the test above),
    a few times the energy error where the hinge equations lose digits
    (``L`` within 1e-2 of ``n``: measured gap / energy error <= 5).  A solve
    that passes its checks alone with a margin of 10 passes them in a batch.

    Near the top of the range the velocities also collect a tangential
    error that the energy bounds only in part: at n = 3, L = 3 - 1e-5, T = 3
    both the single solve and its lane were 1.5e-10 off a long-double run
    (charts: 6e-13) and 2.9e-10 apart, with energy errors of 2e-12.  At
    n = 3 it is a phase lag (a time shift, the integral of the energy error,
    along an orbit that turns at ~300 rad per unit time); from n = 5 on part
    of it lies across the orbit (docs/methods.md).  It grows with the steps
    and the turning rate ``~1 / sqrt(n - L)``, so the bound has an envelope
    term ``0.1 eps steps / (distance of L to its nearer range end)`` (~1e-8
    at that case).

    And some trajectories there are chaotic: at n = 4, L = 3.9999 (seed 60) a
    change of 1e-14 in the start grows to 1e-7 by T = 3 in long double, and
    float64 charts, float64 hinges and long-double charts all end 1e-6 off a
    long-double hinge run, lane and single solve 1.5e-6 apart.  So the bound
    also allows 10 times what the single solve itself does with its start
    speed changed by 4 eps: the problem's own amplification of a rounding.
    """
    L = data.draw(base_lengths(n))
    rng = np.random.default_rng(seed)
    chain = Chain(n, L, hinge_masses=rng.uniform(0.2, 5.0, n - 1),
                  rod_densities=rng.uniform(0, 2, n) if seed % 2 else 0.0)
    H, V = _starts(chain, count, seed, pole=bool(seed % 3))
    T = -3.0 if backward else 3.0
    ts = np.linspace(0, T, 4)
    singles = _singles(chain, H, V, T, ts, method="hinges", **FAST)
    nudged = _singles(chain, H, V * (1 + 4 * 2.0**-52), T, ts, method="hinges", **FAST)
    ens = free_motions(chain, H, V, T, save=SaveAt(t_eval=ts), backend="threads", **FAST)
    for k, s in enumerate(singles):
        # the batch checks fewer states (the grid and the end), rounded differently: near the bound either may
        # fail.  Where the hinge equations lose digits the two scatter independently: at n = 3, L = n - 5.6e-4,
        # 32 starts gave energy errors of median 1.9e-11 (scalar) and 1.6e-11 (SIMD lanes), one start 7.1e-12
        # alone and 4.8e-11 in a lane.  With a margin of 10 both pass.
        if not s.relative_energy_error <= 0.1 * energy_bound(s.n_steps, 2.0**-52):
            continue
        assert ens.success[k], ens.messages[k]
        end_gap = min(L - (n - 2), n - L)
        sensitivity = max(np.abs(nudged[k].hinges - s.hinges).max(), np.abs(nudged[k].velocities - s.velocities).max())
        tol = max(1e-12, 100 * s.relative_energy_error, 0.1 * 2.0**-52 * s.n_steps / end_gap, 10 * sensitivity)
        assert _max_gap(_subset(ens, [k]), [s]) <= tol


def test_a_failed_trajectory_does_not_sink_the_others():
    """Starts at 1e100 and 1e150 times unit speed overflow float64 in the first step; their batch neighbours do not."""
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 6, seed=3)
    V[2] *= 1e100
    V[4] *= 1e150
    ts = np.linspace(0, 5.0, 6)
    singles = _singles(chain, H, V, 5.0, ts, method="hinges", **FAST)
    for batch_size in (None, 1):
        ens = free_motions(chain, H, V, 5.0, save=SaveAt(t_eval=ts), batch_size=batch_size, **FAST)
        assert list(ens.success) == [True, True, False, True, False, True]
        assert ens.status == [s.solution.status for s in singles]  # judged by the same rules
        assert ens.messages[2] == singles[2].solution.message
        assert [m for m, good in zip(ens.messages, ens.success) if good] == [
            s.solution.message for s in singles if s.success]
        ok = ens.success
        assert _max_gap(_subset(ens, ok), [s for s, good in zip(singles, ok) if good]) <= 1e-12
        assert np.isnan(ens.hinges[~ok]).all() and np.isnan(ens.end_hinges[~ok]).all()
        assert np.isnan(ens.relative_energy_errors[~ok]).all()
        assert ens.n_failed == 2


#: Multiples of a bound drawn for a checked quantity: below, at, just above and far above it, and NaN.
_NEAR_BOUND = st.sampled_from([0.0, 0.5, 1.0 - 1e-12, 1.0, 1.0 + 1e-12, 3.0, float("nan")])


@given(data=st.data(), lanes=st.integers(1, 6), grid=st.integers(0, 4), backward=st.booleans())
@settings(max_examples=200)
def test_lanes_are_judged_exactly_as_one_by_one(data, lanes, grid, backward):
    """``judge_lanes`` finds the passing lanes all at once; it must say what ``verdict`` says of each lane alone
    (the energy check over the grid times reached and the end, then the constraints, then the stepper), the
    system's hint after a failed energy or constraint check only."""
    T = -2.0 if backward else 2.0
    times = np.linspace(0.0, T, grid + 2)
    eps = 2.0**-52
    steps = np.array(data.draw(st.lists(st.integers(0, 10**6), min_size=lanes, max_size=lanes)))
    reached = data.draw(st.lists(st.sampled_from([T, 0.3 * T, 0.0, float("nan")]), min_size=lanes, max_size=lanes))
    failure = data.draw(st.lists(st.sampled_from([None, "err_nf_state", "stopped before t_final (time_limit)"]),
                                 min_size=lanes, max_size=lanes))
    t_reached = np.array(reached)
    shape = st.lists(_NEAR_BOUND, min_size=len(times), max_size=len(times))
    deviations = np.array([[f * energy_bound(int(s), eps) for f in data.draw(shape)] for s in steps])
    drifts = np.array([[f * constraint_bound(int(s), eps) for f in data.draw(shape)] for s in steps])
    def hint(tol: float) -> str:  # a system's sentence for a failed check (ConstrainedSystem.rounding_hint)
        return f"hint at tol {tol:g}"

    errors, status, messages = judge_lanes(deviations, drifts, times, t_reached, steps, eps, failure, hint)
    for k in range(lanes):
        rows = np.append(np.abs(times[1:]) <= abs(t_reached[k]), True)
        expected = verdict(energy_violation(deviations[k, rows], np.append(times[1:], t_reached[k])[rows],
                                            int(steps[k]), eps, "ambient coordinates"),
                           float(np.max(drifts[k, rows])), int(steps[k]), eps, float(t_reached[k]), failure[k], hint)
        assert (status[k], messages[k]) == expected
        checks = (SolveStatus.ENERGY_CHECK_FAILED, SolveStatus.CONSTRAINT_CHECK_FAILED)
        assert messages[k].endswith(f"; hint at tol {eps:g}") == (status[k] in checks)
        assert np.array_equal(errors[k], np.max(deviations[k, rows]), equal_nan=True)


class _subset:
    """The trajectories ``mask`` of an ensemble, read like one."""

    def __init__(self, ens, mask):
        self.hinges, self.velocities = ens.hinges[mask], ens.velocities[mask]
        self.end_hinges, self.end_velocities = ens.end_hinges[mask], ens.end_velocities[mask]


def test_the_default_method_is_free_motion_s():
    """``method="auto"``, as in ``free_motion``: the hinges in SIMD batches on a generic chain, the charts (single
    solves in Sundman's time) on a nearly stretched one, each trajectory the one ``free_motion``'s default computes."""
    for chain, method in ((Chain(5, 4.2), "constrained"), (Chain(5, 5 - 1e-4), "sundman")):
        H, V = _starts(chain, 3, seed=3, pole=False)
        ts = np.linspace(0, 1.0, 3)
        ens = free_motions(chain, H, V, 1.0, save=SaveAt(t_eval=ts))
        singles = _singles(chain, H, V, 1.0, ts)
        assert method in ens.solution.method and all(method in s.solution.method for s in singles)
        assert ens.success.all() and _max_gap(ens, singles) <= 1e-12
    stretched = Chain(5, 5 - 1e-4)
    H, V = _starts(stretched, 2, seed=3, pole=False)
    batched = free_motions(stretched, H, V, 0.5, batch_size=2)  # a batch size asks for the hinges' SIMD batches
    assert "constrained" in batched.solution.method and batched.solution.batch_size == 2


def test_charts_method_keeps_each_failure_to_its_trajectory():
    """Single chart solves per trajectory: too few switches allowed fails some; grid rows after a failure are NaN."""
    chain = Chain(4, 3.5)  # these starts switch 0, 2 or 3 times by T = 12
    H, V = _starts(chain, 6, seed=5)
    T = 12.0
    ts = np.linspace(0, T, 25)
    singles = _singles(chain, H, V, T, ts, method="charts", max_switches=2)
    ens = free_motions(chain, H, V, T, save=SaveAt(t_eval=ts), method="charts", max_switches=2, backend="threads",
                       chunk_size=2)
    assert ens.status == [s.solution.status for s in singles]
    assert 0 < ens.n_failed < len(H)  # the case must have both kinds
    for k, s in enumerate(singles):
        reached = ts <= float(s.solution.t_reached)
        if s.success:
            assert np.abs(ens.hinges[k] - s.hinges).max() <= 1e-12
        else:
            assert ens.status[k] is SolveStatus.MAX_SWITCHES
            assert np.isnan(ens.hinges[k][~reached]).all() and np.isfinite(ens.hinges[k][reached]).all()
            p, _ = s.solution.end_state()
            assert np.abs(ens.end_hinges[k] - chain.from_point(p)).max() <= 1e-12


def test_forward_then_backward_returns_every_start():
    chain = Chain(5, 3.3, hinge_masses=[1.0, 2.0, 0.5, 1.5])
    H, V = _starts(chain, 7, seed=11)
    fwd = free_motions(chain, H, V, 15.0, backend="threads", **FAST)
    back = free_motions(chain, fwd.end_hinges, fwd.end_velocities, -15.0, backend="threads", **FAST)
    assert fwd.success.all() and back.success.all()
    assert np.abs(back.end_hinges - H).max() <= 1e-10
    assert np.abs(back.end_velocities - V).max() <= 1e-10


def test_memory_does_not_grow_with_the_steps():
    """No dense output: a ten times longer run keeps exactly as many numbers (the grid and the ends)."""
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 4, seed=2)
    sizes = []
    for T in (5.0, 50.0):
        ens = free_motions(chain, H, V, T, save=SaveAt(t_eval=np.linspace(0, T, 11)), **FAST)
        assert ens.n_steps.min() > 0
        sizes.append(len(pickle.dumps(ens.solution)))
    steps_ratio = free_motions(chain, H, V, 50.0, **FAST).n_steps.sum() / free_motions(chain, H, V, 5.0,
                                                                                       **FAST).n_steps.sum()
    assert steps_ratio > 5
    assert abs(sizes[1] - sizes[0]) <= 64  # a few bytes of numbers printed in messages, nothing per step
    bare = free_motions(chain, H, V, 5.0, **FAST)
    assert bare.solution.points is None
    with pytest.raises(ValueError, match="t_eval"):
        bare.hinges


def test_dask_local_cluster_agrees_with_serial():
    """On a chain that has already been solved on in charts (its atlas then holds compiled numerics, which once
    made it unpicklable: 'cannot pickle _thread.RLock'), the cluster gives the serial numbers bit for bit."""
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 10, seed=4)
    free_motion(chain, H[0], V[0], 1.0, method="charts")
    ts = np.linspace(0, 10.0, 5)
    serial = free_motions(chain, H, V, 10.0, save=SaveAt(t_eval=ts), **FAST)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            ens = free_motions(chain, H, V, 10.0, save=SaveAt(t_eval=ts), backend="dask", client=client, chunk_size=4,
                               **FAST)
    assert ens.solution.backend == "dask"
    assert np.array_equal(ens.hinges, serial.hinges) and np.array_equal(ens.end_velocities, serial.end_velocities)
    assert ens.status == serial.status


def test_progress_bar_counts_trajectories(capsys):
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 5)
    free_motions(chain, H, V, 1.0, progress=True, chunk_size=2, **FAST)
    assert "5/5" in capsys.readouterr().err


def test_progress_callback_counts_trajectories():
    """A callable (manifold.progress protocol) hears each chunk: ``t`` trajectories done of ``t_final = N``."""
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 5)
    updates = []
    free_motions(chain, H, V, 1.0, progress=updates.append, batch_size=1, chunk_size=2, backend="threads", **FAST)
    assert [u.kind for u in updates] == ["solve"] * 3 + ["done"]
    assert sorted(np.diff([0.0] + [u.t for u in updates[:3]])) == [1.0, 2.0, 2.0]  # chunks of 2, 2 and 1
    assert updates[-1].fraction == 1.0 and updates[-1].t_final == 5.0


@pytest.mark.parametrize("module, kwargs, extra", [("distributed", {"backend": "dask", "client": object()}, "distributed"),
                                                   ("tqdm", {"progress": True}, "progress")])
def test_optional_extras_missing_give_a_clear_error(monkeypatch, module, kwargs, extra):
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 2)
    for name in [m for m in sys.modules if m == module or m.startswith(module + ".")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, module, None)  # import now raises ImportError
    with pytest.raises(ImportError, match=rf"linkage-manifolds\[{extra}\]"):
        free_motions(chain, H, V, 1.0, **kwargs, **FAST)


@pytest.mark.parametrize("change, error, match", [
    ({"backend": "mpi"}, ValueError, "backend must be one of"),
    ({"backend": "dask"}, TypeError, "needs client=a dask.distributed.Client"),
    ({"client": object()}, ValueError, "client is only used with backend='dask'"),
    ({"batch_size": 0}, ValueError, "batch_size must be an integer >= 1, got 0"),
    ({"chunk_size": 2.5}, ValueError, "chunk_size must be an integer >= 1"),
    ({"save": SaveAt(dense=True)}, TypeError, "free_motions keeps no dense output"),
    ({"dense": False}, TypeError, "dense= is given as save=SaveAt"),
    ({"throw": False}, TypeError, "free_motions does not take throw="),
    ({"method": "charts", "batch_size": 4}, ValueError, "SIMD batches run the hinge method .* not with method='charts'"),
    ({"batch_size": 4, "q_out": 0.3}, ValueError, "not with q_out=0.3; without batch_size it runs single solves"),
    ({"method": "rk4"}, ValueError, "method must be one of"),
    ({"progress": "yes"}, ValueError, "progress must be None, False, True, 'tqdm' or a callable"),
    ({"save": SaveAt(t_eval=[0.0, 2.0])}, ValueError, "t_eval must be a 1-d array of times within \\[0, 1\\]"),
])
def test_bad_arguments_are_refused_by_name(change, error, match):
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 3)
    with pytest.raises(error, match=match):
        free_motions(chain, H, V, 1.0, **{**FAST, **change})


def test_bad_starts_are_refused_with_their_index():
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 3)
    with pytest.raises(ValueError, match=r"shape \(N, n - 1\)"):
        free_motions(chain, H[0], V[0], 1.0)
    with pytest.raises(ValueError, match="shape"):
        free_motions(chain, H, V[:2], 1.0)
    bad = H.copy()
    bad[1, 0] += 1e-3
    with pytest.raises(ValueError, match=r"start 1 \(hinges0\[1\], velocities0\[1\]\): configuration does not close"):
        free_motions(chain, bad, V, 1.0)
    W = V.copy()
    W[2] += 0.5
    with pytest.raises(ValueError, match=r"start 2 .*not tangent"):
        free_motions(chain, H, W, 1.0)
    with pytest.raises(ValueError, match="complex hinges"):
        free_motions(chain, chain.to_point(H), V, 1.0)
    W = V.copy()
    W[2, 1] = np.nan  # a non-finite start is named by its entry, not by printing every start
    with pytest.raises(ValueError, match=r"^velocities0 must be finite, got velocities0\[2, 1\] = \(?nan"):
        free_motions(chain, H, W, 1.0)


def test_projected_starts_match_single_calls():
    """``StartCheck(project_velocity=True)``: non-tangent rows are projected exactly as ``free_motion`` projects them."""
    chain = Chain(4, 2.6)
    H, V = _starts(chain, 5, seed=8)
    W = V.copy()
    W[[1, 3]] += 0.3 * H[[1, 3]]  # a radial push: not tangent
    project = StartCheck(project_velocity=True)
    singles = _singles(chain, H, W, 4.0, np.linspace(0, 4, 3), method="hinges", start=project, **FAST)
    ens = free_motions(chain, H, W, 4.0, save=SaveAt(t_eval=np.linspace(0, 4, 3)), start=project, **FAST)
    assert _max_gap(ens, singles) <= 1e-12
    assert np.abs(ens.velocities[[0, 2, 4], 0] - V[[0, 2, 4]]).max() <= 1e-15  # tangent rows are left alone
    assert np.abs(ens.velocities[[1, 3], 0] - W[[1, 3]]).max() > 0.01


@pytest.mark.parametrize("options", [{"method": "charts"}, {"precision": "longdouble"}])
def test_single_solves_take_the_starts_as_the_ensembles_check_took_them(options):
    """An ensemble that runs single solves (the charts, long double) takes the starts as ``free_motions`` checked
    them, with the user's ``StartCheck``: a velocity 1e-7 off the tangent space passes ``tangent_tol=1e-6`` and
    runs; each single solve checked it again at the default 1e-9 and refused it."""
    from linkage.constraints import HingeConstraints
    from manifold import Precision

    chain = Chain(4, 2.6)
    rng = np.random.default_rng(5)
    h0 = chain.diagonal_space().sample(2, rng).hinges
    hc = HingeConstraints(chain)
    X = chain.to_point(h0)
    V = np.array([hc.project_velocity(x, rng.normal(size=x.shape)) for x in X])
    V /= np.linalg.norm(V, axis=1)[:, None]
    normal = np.array([hc.K_inv @ hc.jacobian(x).T @ np.ones(4) for x in X])
    W = chain.from_point(V + 1e-7 * normal / np.linalg.norm(normal, axis=1)[:, None])
    kw = {k: (Precision(fp_type=v) if k == "precision" else v) for k, v in options.items()}
    with pytest.raises(ValueError, match="not tangent"):
        free_motions(chain, h0, W, 0.5, **kw)
    save = SaveAt(t_eval=[0.5])
    out = free_motions(chain, h0, W, 0.5, start=StartCheck(tangent_tol=1e-6), save=save, **kw)
    assert out.success.all()
    ref = free_motions(chain, h0, chain.from_point(V), 0.5, save=save, **kw)  # the tangent part alone: the same motion
    assert np.abs(out.hinges[:, -1] - ref.hinges[:, -1]).max() <= 1e-6
