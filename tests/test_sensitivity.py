"""The sensitivity of a motion to its start (:mod:`linkage.sensitivity`): the linearised flow's growth and the error
it implies, against finite differences of whole solves and against two methods' disagreement."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import linkage.geometry
from linkage import Chain
from linkage.constraints import HingeConstraints
from linkage.geometry import tangent_basis
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from linkage.sensitivity import SensitivityWarning, sensitivity
from manifold import SaveAt, StartCheck

CHAIN = Chain(4, 3.1, hinge_masses=[0.5, 2.0, 1.0])
T = 4.0


def _start(seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    h, v = sample_starts(CHAIN, 1, 1.0, np.random.default_rng(seed))
    return h[0], v[0]


@pytest.fixture(scope="module")
def measured():
    h0, v0 = _start()
    with warnings.catch_warnings():
        warnings.simplefilter("error", SensitivityWarning)  # a tame motion: no warning at the default threshold
        return h0, v0, sensitivity(CHAIN, h0, v0, T, save=SaveAt(t_eval=np.linspace(0.0, T, 9)))


def test_the_amplification_starts_at_one_and_bounds_finite_differences_of_whole_solves(measured):
    h0, v0, s = measured
    assert s.amplification[0] == pytest.approx(1.0, abs=1e-12)
    # velocity perturbations along a kinetic-orthonormal basis, scaled by tau as the norm does: whole solves
    basis, eps = tangent_basis(CHAIN, h0), 1e-6
    R = np.linalg.cholesky(CHAIN.ambient_metric).T
    base = free_motion(CHAIN, h0, v0, T, method="hinges", save=SaveAt(t_eval=[T]))
    # D_t J is the tangent part of dJ/dt: project the velocities' difference K-orthogonally at the end point
    Q = CHAIN.to_point(tangent_basis(CHAIN, base.hinges[-1]))
    K = CHAIN.ambient_metric
    columns = []
    for e in basis:
        moved = free_motion(CHAIN, h0, v0 + eps * e / s.time_scale, T, method="hinges", save=SaveAt(t_eval=[T]))
        dx = R @ CHAIN.to_point(moved.hinges[-1] - base.hinges[-1])
        dv = CHAIN.to_point(moved.velocities[-1] - base.velocities[-1])
        dv = R @ (Q.T @ (Q @ K @ dv)) * s.time_scale
        columns.append(np.concatenate([dx, dv]) / eps)
    sigma = np.linalg.svd(np.array(columns), compute_uv=False)[0]  # the velocity half of Phi(T)
    assert 1.5 < sigma <= s.amplification[-1] * (1 + 1e-4)  # it grew, and the full Phi bounds its half
    assert sigma >= 0.3 * s.amplification[-1]  # ... of the same size: half of the directions, not a different map


def test_the_estimate_covers_the_disagreement_of_the_two_methods(measured):
    h0, v0, s = measured
    charts = free_motion(CHAIN, h0, v0, T, save=SaveAt(t_eval=[T]))
    hinges = free_motion(CHAIN, h0, v0, T, method="hinges", save=SaveAt(t_eval=[T]))
    size = np.max(np.abs(h0))
    difference = np.max(np.abs(charts.hinges[-1] - hinges.hinges[-1])) / size
    assert difference <= 10 * s.estimated_error[-1]


def test_a_motion_past_the_threshold_warns_with_its_numbers(measured):
    h0, v0, s = measured
    with pytest.warns(SensitivityWarning, match=r"amplifies errors of its start .*-fold .*exceeds 1e-16"):
        sensitivity(CHAIN, h0, v0, T, threshold=1e-16)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_threshold_is_refused_by_name(bad):
    h0, v0 = _start()
    with pytest.raises(ValueError, match="threshold must be a finite number > 0"):
        sensitivity(CHAIN, h0, v0, T, threshold=bad)


def test_the_start_is_checked_once_and_by_the_tangent_tolerance_given(monkeypatch):
    """One ``start_state`` and one closure check per call; ``StartCheck.tangent_tol`` reaches that one check: a velocity
    tilted off the tangent space by 1e-7 of its size is refused by default (1e-9) and accepted at 1e-6."""
    h0, v0 = _start()
    calls = {"start_state": 0, "check_configuration": 0}
    start_state, check = linkage.geometry.start_state, Chain.check_configuration

    def counted_start_state(*args, **kwargs):
        calls["start_state"] += 1
        return start_state(*args, **kwargs)

    def counted_check(self, *args, **kwargs):
        calls["check_configuration"] += 1
        return check(self, *args, **kwargs)

    monkeypatch.setattr(linkage.geometry, "start_state", counted_start_state)
    monkeypatch.setattr(Chain, "check_configuration", counted_check)
    sensitivity(CHAIN, h0, v0, 0.1)
    assert calls == {"start_state": 1, "check_configuration": 1}
    x0 = CHAIN.to_point(h0)
    normal = np.linalg.lstsq(HingeConstraints(CHAIN).jacobian(x0), np.ones(CHAIN.n), rcond=None)[0]  # G w != 0
    tilted = v0 + 1e-7 * np.linalg.norm(CHAIN.to_point(v0)) * CHAIN.from_point(normal / np.linalg.norm(normal))
    with pytest.raises(ValueError, match="velocity0 is not tangent"):
        sensitivity(CHAIN, h0, tilted, 0.1)
    with pytest.raises(ValueError, match="velocity0 is not tangent"):
        sensitivity(CHAIN, h0, tilted, 0.1, start=StartCheck(tangent_tol=1e-8))
    assert sensitivity(CHAIN, h0, tilted, 0.1, start=StartCheck(tangent_tol=1e-6)).amplification[0] == \
        pytest.approx(1.0, abs=1e-12)


def test_the_default_method_is_free_motion_s():
    """``method="auto"``: on a nearly stretched chain the fields ride beside the atlas's geodesic, as ``free_motion``'s
    default runs it; the same numbers as ``method="charts"``, and not those of the hinges."""
    chain = Chain(4, 4 - 1e-4)
    h, v = sample_starts(chain, 1, 1.0, np.random.default_rng(5))
    save = SaveAt(t_eval=[0.0, 0.2])
    runs = {method: sensitivity(chain, h[0], v[0], 0.2, save=save, **({} if method == "auto" else {"method": method}))
            for method in ("auto", "charts", "hinges")}
    assert np.array_equal(runs["auto"].amplification, runs["charts"].amplification)
    assert not np.array_equal(runs["auto"].amplification, runs["hinges"].amplification)
