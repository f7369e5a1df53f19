"""The option groups (manifold.options): each checks its fields once, and a keyword that moved is refused by name."""

import inspect
import pickle
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage import Chain, geometry
from linkage.motion import free_motion, free_motions, lyapunov_exponent, lyapunov_exponents
from linkage.sampling import sample_starts
from linkage.sensitivity import sensitivity
from linkage.ambient import integrate_ambient
from linkage.constraints import ChainSystem, HingeConstraints
from manifold import Precision, SaveAt, StartCheck, solve_chart_exp_ode
from manifold.carried import solve_carried
from manifold.constrained import solve_constrained
from manifold.constrained_batch import solve_constrained_ensemble
from manifold.lyapunov import lyapunov_spectrum
from manifold.options import (DEFAULT_START, MOVED_OPTIONS, TANGENT_TOL, check_group, refuse_moved_options,
                              takes_option_groups)
from manifold.precision import MultiPrecision
from manifold.steppers import TaylorStepper
from manifold.transport import ParallelTransport


def test_save_at_keeps_its_own_read_only_copy_of_the_grid():
    times = np.array([0.0, 0.5, 1.0])
    save = SaveAt(t_eval=times)
    times[1] = 0.9  # the caller's array changes; the group does not
    assert save.t_eval is not None and list(save.t_eval) == [0.0, 0.5, 1.0]
    with pytest.raises(ValueError):
        save.t_eval[0] = 1.0
    assert SaveAt().t_eval is None and SaveAt().grid(1.0) is None
    copy = pickle.loads(pickle.dumps(save))  # a SaveAt travels to Dask workers
    assert copy.t_eval is not None and list(copy.t_eval) == [0.0, 0.5, 1.0] and not copy.t_eval.flags.writeable


@pytest.mark.parametrize("default", [True, False])
def test_save_at_leaves_dense_to_the_solver_unless_told(default):
    assert SaveAt().keeps_dense(default) is default
    assert SaveAt(dense=True).keeps_dense(default) is True and SaveAt(dense=False).keeps_dense(default) is False


@settings(max_examples=50, deadline=None)
@given(st.floats(0.1, 1e3), st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20), st.booleans())
def test_save_at_accepts_any_grid_in_integration_order(t_final, fractions, backward):
    T = -t_final if backward else t_final
    grid = np.sort(np.array(fractions)) * T
    np.testing.assert_array_equal(SaveAt(t_eval=grid).grid(T), grid)
    if len(set(grid)) > 1:  # the reverse order is refused, naming t_eval and the interval
        with pytest.raises(ValueError, match="t_eval must be a 1-d array of times within"):
            SaveAt(t_eval=grid[::-1]).grid(T)


@pytest.mark.parametrize("t_eval, error, match", [
    ([[0.0, 1.0]], ValueError, "t_eval must be a 1-d array"),
    ([0.0, np.nan], ValueError, "t_eval must be finite"),
    ([0.0, 1j], TypeError, "t_eval must be a real array"),
    (["0", "1"], TypeError, "t_eval must be a real array"),
    ([True, False], TypeError, "t_eval must be a real array"),
])
def test_save_at_refuses_a_bad_grid_by_name(t_eval, error, match):
    with pytest.raises(error, match=match):
        SaveAt(t_eval=t_eval)


def test_save_at_refuses_a_grid_outside_the_interval():
    with pytest.raises(ValueError, match=r"within \[0, 2\]"):
        SaveAt(t_eval=[0.0, 3.0]).grid(2.0)


@pytest.mark.parametrize("dense", [1, 0, "no", np.array([True])])
def test_save_at_dense_must_be_a_bool(dense):
    with pytest.raises(TypeError, match="dense must be True or False"):
        SaveAt(dense=dense)


def test_precision_resolves_names_once():
    assert Precision().fp_type is float and Precision().tol is None
    assert Precision("longdouble").fp_type is np.longdouble
    assert Precision("float64", 1e-10) == Precision(float, 1e-10)
    assert Precision("mp256").fp_type == MultiPrecision(256)
    p = Precision(np.longdouble, 1e-12)
    assert pickle.loads(pickle.dumps(p)) == p and hash(p) == hash(Precision("longdouble", 1e-12))


@pytest.mark.parametrize("tol", [0, -1e-10, 0.5, np.nan, np.inf, "1e-10", True])
def test_precision_refuses_a_tolerance_outside_its_range(tol):
    with pytest.raises(ValueError, match=r"tol must be a real number in \(0, 0.01\]"):
        Precision(tol=tol)


def test_precision_refuses_an_unknown_type():
    with pytest.raises(ValueError, match="fp_type must be one of"):
        Precision("float32")
    with pytest.raises(TypeError):
        Precision(np.float32)


def test_a_group_of_the_wrong_kind_is_refused_by_name():
    with pytest.raises(TypeError, match=r"save must be a manifold.SaveAt \(save=SaveAt\(...\)\), got"):
        check_group("save", [0.0, 1.0], SaveAt)
    assert check_group("precision", Precision(), Precision) == Precision()


def test_start_check_checks_its_fields_once():
    assert DEFAULT_START == StartCheck() == StartCheck(TANGENT_TOL, False) and TANGENT_TOL == 1e-9
    check = StartCheck(np.float64(1e-6), np.bool_(True))
    assert type(check.tangent_tol) is float and check.project_velocity is True
    assert pickle.loads(pickle.dumps(check)) == check and hash(check) == hash(StartCheck(1e-6, True))


@pytest.mark.parametrize("tol", [0, -1e-9, np.nan, np.inf, "1e-9", True, 1j])
def test_start_check_refuses_a_tolerance_outside_its_range(tol):
    with pytest.raises(ValueError, match=r"tangent_tol must be a real number in \(0, inf\)"):
        StartCheck(tangent_tol=tol)


@pytest.mark.parametrize("project", ["yes", 1, 0, None, np.array([True])])
def test_start_check_project_velocity_must_be_a_bool(project):
    with pytest.raises(TypeError, match="project_velocity must be True or False"):
        StartCheck(project_velocity=project)


@pytest.mark.parametrize("name, home", [
    ("t_eval", "save=SaveAt(t_eval=...)"),
    ("dense", "save=SaveAt(dense=...)"),
    ("fp_type", "precision=Precision(fp_type=...)"),
    ("tol", "precision=Precision(tol=...)"),
    ("tangent_tol", "start=StartCheck(tangent_tol=...)"),
    ("project_velocity", "start=StartCheck(project_velocity=...)"),
])
def test_a_moved_keyword_names_its_new_home(name, home):
    assert name in MOVED_OPTIONS
    with pytest.raises(TypeError, match=re.escape(f"solve() does not take {name}=: {name}= is given as {home}")):
        refuse_moved_options("solve", [name, "rate"])
    refuse_moved_options("solve", ["rate", "stepper"])  # nothing moved: nothing raised


def test_the_decorator_keeps_the_signature_and_refuses_moved_keywords():
    def solve(x: float, *, save: SaveAt = SaveAt(), rate: float = 1.0) -> tuple:
        return x, save, rate

    checked = takes_option_groups(solve)
    assert inspect.signature(checked) == inspect.signature(solve) and checked.__name__ == "solve"
    assert checked(2.0, rate=3.0)[::2] == (2.0, 3.0)
    with pytest.raises(TypeError, match=r"dense= is given as save=SaveAt\(dense=\.\.\.\)"):
        checked(2.0, dense=False)
    # a keyword moved into a group the function does not take is not sent there: Python's own error
    with pytest.raises(TypeError, match="unexpected keyword argument 'tangent_tol'"):
        checked(2.0, tangent_tol=1e-9)


def test_refusal_can_be_limited_to_the_groups_a_function_takes():
    with pytest.raises(TypeError, match=re.escape("solve() does not take tol=: tol= is given as precision=")):
        refuse_moved_options("solve", ["tol", "tangent_tol"], ("save", "precision"))
    refuse_moved_options("solve", ["tangent_tol", "project_velocity"], ("save", "precision"))


@pytest.mark.parametrize("solver", [solve_chart_exp_ode, solve_constrained, free_motion, free_motions, geometry.exp,
                                    geometry.parallel_transport, geometry.jacobi_field, geometry.log,
                                    geometry.distance, sensitivity, lyapunov_exponent, lyapunov_exponents])
@pytest.mark.parametrize("name, home", [("t_eval", "save=SaveAt(t_eval=...)"),
                                        ("fp_type", "precision=Precision(fp_type=...)")])
def test_every_public_solver_names_the_new_home_of_a_moved_keyword(solver, name, home):
    with pytest.raises(TypeError, match=re.escape(f"{solver.__name__}() does not take {name}=: {name}= is given "
                                                  f"as {home}")):
        solver(None, None, None, 1.0, **{name: None})


#: Every public function that checks a start velocity, each called with its positional arguments as None.
START_CHECKERS = [(solve_chart_exp_ode, 4), (free_motion, 4), (free_motions, 4), (geometry.exp, 4),
                  (geometry.parallel_transport, 5), (geometry.jacobi_field, 6), (sensitivity, 4),
                  (lyapunov_exponent, 4), (lyapunov_exponents, 4), (integrate_ambient, 4)]


@pytest.mark.parametrize("solver, n_args", START_CHECKERS, ids=lambda f: getattr(f, "__name__", ""))
@pytest.mark.parametrize("name", ["tangent_tol", "project_velocity"])
def test_every_start_check_names_the_new_home_of_its_moved_keywords(solver, n_args, name):
    with pytest.raises(TypeError, match=re.escape(f"{solver.__name__}() does not take {name}=: {name}= is given as "
                                                  f"start=StartCheck({name}=...)")):
        solver(*[None] * n_args, **{name: True})


@pytest.mark.parametrize("solver, n_args", START_CHECKERS, ids=lambda f: getattr(f, "__name__", ""))
def test_every_start_check_refuses_a_start_that_is_not_a_start_check(solver, n_args):
    chain = Chain(4, 2.6)
    h0, v0 = sample_starts(chain, 2, 0.5, np.random.default_rng(5))
    if solver is solve_chart_exp_ode:
        args = [chain.metric(), chain.to_point(h0[0]), chain.to_point(v0[0]), 1.0]
    elif solver in (free_motions, lyapunov_exponents):
        args = [chain, h0, v0, 1.0]
    else:
        args = [chain, h0[0], v0[0], *[v0[0]] * (n_args - 4), 1.0]
    with pytest.raises(TypeError, match=r"start must be a manifold.StartCheck \(start=StartCheck\(...\)\), got"):
        solver(*args, start={"project_velocity": True})


def test_the_start_check_reaches_every_check_of_the_start_and_projects_only_the_velocity():
    """A velocity tilted off the tangent space by 1e-7 of its size: refused by default and by a tolerance of 1e-8,
    accepted at 1e-6 as it is, and projected (K-orthogonally: the projection of the tangent velocity is itself)
    with ``project_velocity``.  A transported vector so tilted is refused however the velocity is checked."""
    chain = Chain(4, 2.6)
    h0, v0 = (a[0] for a in sample_starts(chain, 1, 0.5, np.random.default_rng(6)))
    constraints, x0 = HingeConstraints(chain), chain.to_point(h0)
    normal = np.linalg.lstsq(constraints.jacobian(x0), np.ones(chain.n), rcond=None)[0]  # G w != 0
    tilted = v0 + 1e-7 * np.linalg.norm(chain.to_point(v0)) * chain.from_point(normal / np.linalg.norm(normal))
    projected = chain.from_point(constraints.project_velocity(x0, chain.to_point(tilted)))
    assert np.abs(projected - v0).max() < 1e-12 * np.abs(v0).max() and np.abs(tilted - v0).max() > 1e-8
    for start in (DEFAULT_START, StartCheck(tangent_tol=1e-8)):
        with pytest.raises(ValueError, match="velocity0 is not tangent"):
            geometry.exp(chain, h0, tilted, 0.5, start=start)
        with pytest.raises(ValueError, match="velocity0 is not tangent"):
            lyapunov_exponent(chain, h0, tilted, 1.0, start=start)
    as_given = geometry.exp(chain, h0, tilted, 0.5, start=StartCheck(tangent_tol=1e-6))
    reference = geometry.exp(chain, h0, projected, 0.5)
    assert geometry.exp(chain, h0, tilted, 0.5, start=StartCheck(project_velocity=True)).tobytes() == \
        reference.tobytes()  # the same start velocity, bit for bit, so the same end
    # accepted, the tilt is then removed by the hinge method's own completion of the start to the constraints
    np.testing.assert_allclose(as_given, reference, rtol=0, atol=1e-12)
    motion = geometry.parallel_transport(chain, h0, tilted, v0, 0.5, start=StartCheck(project_velocity=True))
    np.testing.assert_allclose(motion.velocities[0], projected, rtol=0, atol=1e-15)  # the tilt was 1e-7
    with pytest.raises(ValueError, match="vectors0 is not tangent"):
        geometry.parallel_transport(chain, h0, v0, tilted, 0.5, start=StartCheck(project_velocity=True))
    metric = chain.metric()
    with pytest.raises(ValueError, match="v0 is not tangent at p0"):
        solve_chart_exp_ode(metric, x0, chain.to_point(tilted), 0.5, save=SaveAt(dense=False))
    sol = solve_chart_exp_ode(metric, x0, chain.to_point(tilted), 0.5, save=SaveAt(dense=False),
                              start=StartCheck(tangent_tol=1e-6))
    assert sol.status.name == "SUCCESS"


def test_lyapunov_spectrum_takes_its_tolerance_in_precision():
    with pytest.raises(TypeError, match=re.escape("lyapunov_spectrum() does not take tol=: tol= is given as "
                                                  "precision=Precision(tol=...)")):
        lyapunov_spectrum(None, None, None, 1.0, tol=1e-10)
    with pytest.raises(TypeError, match=r"precision must be a manifold.Precision"):
        lyapunov_spectrum(None, None, None, 1.0, precision=1e-10)


@pytest.mark.parametrize("name, home", [("t_eval", "save=SaveAt(t_eval=...)"), ("tol", "precision=Precision(tol=...)")])
def test_the_simd_ensemble_names_the_new_home_of_a_moved_keyword(name, home):
    with pytest.raises(TypeError, match=re.escape(f"solve_constrained_ensemble() does not take {name}=: {name}= is "
                                                  f"given as {home}")):
        solve_constrained_ensemble(None, None, None, 1.0, **{name: None})


def test_the_simd_ensemble_refuses_dense_output_and_other_precisions():
    chain = Chain(4, 2.6)
    h0, v0 = sample_starts(chain, 2, 0.5, np.random.default_rng(7))
    X0, V0 = chain.to_point(h0), chain.to_point(v0)
    with pytest.raises(TypeError, match=r"keeps no dense output: ask for states with save=SaveAt\(t_eval=...\)"):
        solve_constrained_ensemble(ChainSystem(chain), X0, V0, 1.0, save=SaveAt([0.5], dense=True))
    with pytest.raises(ValueError, match="the SIMD batches integrate in float64"):
        solve_constrained_ensemble(ChainSystem(chain), X0, V0, 1.0, precision=Precision("longdouble"))
    with pytest.raises(TypeError, match="precision must be a manifold.Precision"):
        solve_constrained_ensemble(ChainSystem(chain), X0, V0, 1.0, precision=1e-10)


def test_solve_carried_names_the_new_home_of_a_moved_keyword():
    with pytest.raises(TypeError, match=re.escape("solve_carried() does not take tol=: tol= is given as "
                                                  "precision=Precision(tol=...)")):
        solve_carried(None, None, None, 1.0, [ParallelTransport(np.eye(2))], tol=1e-10)
    with pytest.raises(TypeError, match=re.escape("solve_carried() does not take tangent_tol=: tangent_tol= is given "
                                                  "as start=StartCheck(tangent_tol=...)")):  # solve_constrained's
        solve_carried(None, None, None, 1.0, [ParallelTransport(np.eye(2))], tangent_tol=1e-10)


def test_the_tolerance_of_precision_reaches_the_chart_method_stepper():
    chain = Chain(4, 2.7)
    h0, v0 = sample_starts(chain, 1, 0.5, np.random.default_rng(1))
    tight = free_motion(chain, h0[0], v0[0], 2.0, method="charts", save=SaveAt(dense=False))
    loose = free_motion(chain, h0[0], v0[0], 2.0, method="charts", save=SaveAt(dense=False),
                        precision=Precision(tol=1e-6))
    assert loose.n_steps < tight.n_steps  # a looser tolerance takes longer steps
    assert loose.relative_energy_error > tight.relative_energy_error
    with pytest.raises(ValueError, match="give tol to the stepper"):
        free_motion(chain, h0[0], v0[0], 2.0, method="charts", stepper=TaylorStepper(),
                    precision=Precision(tol=1e-10))


def test_the_float64_only_functions_take_float64_by_any_name_and_refuse_the_others():
    chain = Chain(4, 2.6)
    h0, v0 = sample_starts(chain, 1, 0.5, np.random.default_rng(3))
    for name in ("longdouble", "real128"):
        with pytest.raises(ValueError, match="Lyapunov exponents are computed in float64"):
            lyapunov_exponent(chain, h0[0], v0[0], 1.0, precision=Precision(name))
        with pytest.raises(ValueError, match="Lyapunov exponents are computed in float64"):
            lyapunov_spectrum(ChainSystem(chain), chain.to_point(h0[0]), chain.to_point(v0[0]), 1.0,
                              precision=Precision(name))
        with pytest.raises(ValueError, match="Lyapunov exponents are computed in float64"):  # before any chunk runs
            lyapunov_exponents(chain, h0, v0, 1.0, precision=Precision(name), backend="threads")
        with pytest.raises(ValueError, match="log shoots in float64"):
            geometry.log(chain, h0[0], h0[0], precision=Precision(name))
    for name in (float, np.float64, "float64"):  # the same configuration: the zero velocity, at once
        assert geometry.log(chain, h0[0], h0[0], precision=Precision(name)).distance == 0.0


def test_the_carried_quantities_refuse_to_drop_the_dense_output_they_are_read_from():
    chain = Chain(4, 2.6)
    h0, v0 = sample_starts(chain, 1, 0.5, np.random.default_rng(4))
    with pytest.raises(TypeError, match=r"read from dense output: save=SaveAt\(dense=False\) is not taken"):
        geometry.parallel_transport(chain, h0[0], v0[0], v0[0], 1.0, save=SaveAt(dense=False))
    with pytest.raises(TypeError, match=r"read from dense output: save=SaveAt\(dense=False\) is not taken"):
        sensitivity(chain, h0[0], v0[0], 1.0, save=SaveAt([0.0, 1.0], dense=False))
    with pytest.raises(TypeError, match=r"precision must be a manifold.Precision"):
        geometry.exp(chain, h0[0], v0[0], 1.0, precision="longdouble")
