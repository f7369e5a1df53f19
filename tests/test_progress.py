"""Progress reports: compiles say what they compile, solves report the time reached, and asking changes no result.

The round sphere of ``tests/sphere_family.py`` keeps it fast; a fresh family
``variant`` gives a family that no other test has compiled yet.
"""

import io
import re
import sys
import threading

import numpy as np
import pytest

import manifold.progress
from linkage import Chain
from linkage.demo import pole_start
from linkage.motion import free_motion
from manifold import solve_chart_exp_ode
from manifold.progress import ProgressUpdate, TqdmProgress, as_callback, reporting

from .sphere_family import StereographicFamily, sphere_metric

P0 = np.array([1.0, 0.0, 0.0])
V0 = np.array([0.0, 0.6, 0.8])  # tangent at P0, through both projection poles' neighbourhoods: switches
T = 12.0


def _solve(metric, **kw):
    return solve_chart_exp_ode(metric, P0, V0, T, **kw)


def test_a_cold_solve_reports_each_compile_then_every_segment_then_the_end():
    updates: list[ProgressUpdate] = []
    metric = sphere_metric(StereographicFamily("progress-cold"))
    sol = _solve(metric, progress=updates.append)
    kinds = [u.kind for u in updates]
    compiles = [u for u in updates if u.kind == "compile"]
    finished = [u for u in updates if u.kind == "compiled"]
    # every compile is reported twice (start, end), nested or not, and all of them precede the first segment
    assert compiles and len(compiles) == len(finished)
    assert kinds.index("solve") > max(k for k, kind in enumerate(kinds) if kind.startswith("compile"))
    assert {u.message.split(" (")[0].removeprefix("compiling ") for u in compiles} == {
        u.message.removeprefix("compiled ").rsplit(" in ", 1)[0] for u in finished}
    assert any("Taylor integrator" in u.message for u in compiles)
    machine = [u for u in compiles if "symbolic" not in u.message]
    assert machine and all("disk cache" in u.message for u in machine)
    assert all(u.seconds >= 0 for u in finished)
    # one report per segment, at the segment's end, in time order; then one "done" at t_final
    solve = [u for u in updates if u.kind == "solve"]
    assert [u.t for u in solve] == [float(s.t_end) for s in sol.segments]
    assert np.all(np.diff([u.t for u in solve]) > 0)
    assert sol.n_switches > 0 and [u.n_switches for u in solve][-1] == sol.n_switches
    assert kinds[-1] == "done" and updates[-1].t == T and updates[-1].fraction == 1.0
    assert updates[-1].n_steps == sol.n_steps and updates[-1].message == sol.message


def test_asking_for_progress_changes_no_digit_of_the_solution(monkeypatch):
    monkeypatch.setattr(manifold.progress, "STEP_INTERVAL", 0.0)  # a report from every step
    metric = sphere_metric()
    ts = np.linspace(0, T, 37)
    quiet, loud = _solve(metric), _solve(metric, progress=lambda u: None)
    assert np.array_equal(quiet(ts)[0], loud(ts)[0])
    assert quiet.energies == loud.energies


def test_between_segments_every_step_can_report_its_time(monkeypatch):
    monkeypatch.setattr(manifold.progress, "STEP_INTERVAL", 0.0)
    updates: list[ProgressUpdate] = []
    sol = _solve(sphere_metric(), progress=updates.append)
    steps = [u for u in updates if u.kind == "step"]
    assert len(steps) == sol.n_steps  # heyoka calls back once per step
    assert [u.n_steps for u in steps] == list(range(1, sol.n_steps + 1))
    assert np.all(np.diff([u.t for u in steps]) > 0) and steps[-1].t == T
    # the switches counted are those logged before the step; the step that meets a switch's event is
    # reported before the switch is made (heyoka calls back before it truncates the step to the event)
    switch_times = [s.time for s in sol.switches]
    for u in steps:
        before = sum(st < u.t for st in switch_times)
        assert before - 1 <= u.n_switches <= before
    assert steps[-1].n_switches == sol.n_switches > 0


def test_the_hinge_method_reports_its_progress_too(monkeypatch):
    monkeypatch.setattr(manifold.progress, "STEP_INTERVAL", 0.0)
    chain = Chain(4, 3.5)
    h0, v0 = pole_start(chain)
    updates: list[ProgressUpdate] = []
    loud = free_motion(chain, h0, v0, 5.0, method="hinges", progress=updates.append)
    quiet = free_motion(chain, h0, v0, 5.0, method="hinges")
    assert np.array_equal(loud.solution.end_state()[0], quiet.solution.end_state()[0])
    steps = [u for u in updates if u.kind == "step"]
    assert len(steps) == loud.n_steps and steps[-1].t == 5.0
    assert updates[-1].kind == "done" and updates[-1].t == 5.0 and updates[-1].n_steps == loud.n_steps


def test_warm_solves_compile_nothing_and_a_backward_solve_reports_negative_times():
    metric = sphere_metric()
    solve_chart_exp_ode(metric, P0, V0, -1.0)  # compiles the backward integrator
    updates: list[ProgressUpdate] = []
    sol = solve_chart_exp_ode(metric, P0, V0, -T, progress=updates.append)
    assert not any(u.kind.startswith("compile") for u in updates)
    solve = [u for u in updates if u.kind == "solve"]
    assert np.all(np.diff([u.t for u in solve]) < 0) and solve[-1].t == -T == float(sol.t_reached)
    assert solve[-1].fraction == 1.0 and all(0 <= u.fraction <= 1 for u in solve)


def test_reporting_block_reaches_inner_solves_unless_they_say_false():
    metric = sphere_metric()
    seen: list[ProgressUpdate] = []
    with reporting(seen.append) as callback:
        assert callback == seen.append
        _solve(metric)
        n_inherited = len(seen)
        _solve(metric, progress=False)
    assert n_inherited > 0 and len(seen) == n_inherited
    _solve(metric)  # outside the block: silent again
    assert len(seen) == n_inherited


def test_a_new_thread_does_not_inherit_the_callback():
    found = []
    with reporting(lambda u: None):
        thread = threading.Thread(target=lambda: found.append(as_callback(None)))
        thread.start()
        thread.join()
        assert as_callback(None) is not None
    assert found == [None]


def test_a_failed_solve_still_ends_its_report():
    metric = sphere_metric()
    updates: list[ProgressUpdate] = []
    sol = _solve(metric, progress=updates.append, max_switches=1, throw=False)
    assert not sol.success
    assert updates[-1].kind == "done" and updates[-1].message == sol.message and updates[-1].t < T


@pytest.mark.parametrize("bad", ["yes", 3, 1.0, [print]])
def test_a_bad_progress_argument_is_refused_by_name(bad):
    with pytest.raises(ValueError, match=r"progress must be .*got " + re.escape(repr(bad))):
        _solve(sphere_metric(), progress=bad)


def test_the_tqdm_bar_shows_the_time_reached():
    out = io.StringIO()
    sol = _solve(sphere_metric(), progress=TqdmProgress(file=out, mininterval=0))
    text = out.getvalue()
    assert f"t = {T:.4g} / {T:.4g}" in text and f"switches={sol.n_switches}" in text
    assert "reached t_final" in text


def test_without_tqdm_a_bar_is_refused_with_the_fix(monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm", None)  # import tqdm now raises ImportError
    with pytest.raises(ImportError, match=r"tqdm is not installed: pip install 'linkage-manifolds\[progress\]'"):
        _solve(sphere_metric(), progress=True)
