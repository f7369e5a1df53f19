"""RATTLE: second order, exact constraints, bounded energy error, reversibility, input errors."""

import numpy as np
import pytest

from benchmarks.baselines.rattle import integrate_rattle
from linkage import Chain, ConfigurationError
from linkage.ambient import integrate_ambient
from manifold import SaveAt, StartCheck

from .conftest import unit_speed_start


start = unit_speed_start


CASES = [
    (Chain(4, 2.6), [0.3, 0.5], [1.0, 0.7]),
    (Chain(5, 3.4, hinge_masses=[1, 2, 1, 0.5], rod_densities=0.3), [0.3, -0.5, 1.0], [1.0, 0.2, -0.5]),
]


# -- accuracy ----------------------------------------------------------------------------
@pytest.mark.parametrize("chain, a, c", CASES)
def test_second_order_convergence_against_the_ambient_reference(chain, a, c):
    h0, v0 = start(chain, a, c)
    ref = integrate_ambient(chain, h0, v0, 1.0, save=SaveAt(t_eval=[1.0]), rtol=1e-12, atol=1e-12)
    hs = [0.1, 0.05, 0.025, 0.0125]
    err = []
    for h in hs:
        sol = integrate_rattle(chain, h0, v0, 1.0, h)
        assert sol.t[-1] == 1.0 and sol.n_steps == round(1.0 / h)
        err.append(np.max(np.abs(sol.hinges[-1] - ref.hinges[-1])))
    ratios = np.array(err[:-1]) / np.array(err[1:])
    assert np.all(np.abs(ratios - 4.0) < 0.1), ratios  # measured 4.000 .. 4.008
    assert err[-1] < 2e-5


@pytest.mark.parametrize("chain, a, c", CASES)
def test_every_step_is_on_the_constraints_with_a_tangent_velocity(chain, a, c):
    h0, v0 = start(chain, a, c)
    sol = integrate_rattle(chain, h0, v0, 20.0, 0.1)
    assert len(sol.t) == sol.n_steps + 1 == 201
    assert np.max(sol.constraint_residual) < 1e-12  # measured ~5e-15
    e = chain.rods(sol.hinges)
    ed = np.diff(np.pad(sol.velocities, ((0, 0), (1, 1))), axis=-1)
    assert np.max(np.abs((np.conj(e) * ed).real)) < 1e-12  # d/dt |e_k|^2 / 2 = 0
    assert sol.newton_iterations <= 4 * sol.n_steps  # ~2 per step from the previous multipliers


@pytest.mark.parametrize("chain, a, c", CASES)
def test_energy_error_is_bounded_over_a_long_run(chain, a, c):
    h0, v0 = start(chain, a, c)
    sol = integrate_rattle(chain, h0, v0, 200.0, 0.05)
    assert sol.t[-1] == 200.0 and sol.n_steps == 4000
    rel = sol.relative_energy_error
    half = len(rel) // 2
    first, second = rel[:half].max(), rel[half:].max()
    assert max(first, second) < 1e-2  # O(h^2): measured 4.0e-3 and 7.0e-3
    # no drift: the error oscillates (spikes where the path curves most) around a constant level.
    # Measured: half maxima 4.0e-3 / 3.6e-3 and 6.8e-3 / 7.0e-3, half means 2.6e-4 / 2.3e-4, 2.2e-4 / 2.1e-4
    assert second < 1.5 * first
    assert rel[half:].mean() < 1.2 * rel[:half].mean()
    assert np.max(sol.constraint_residual) < 1e-12
    # the error is O(h^2): halving h quarters it (over a shorter run)
    e1 = integrate_rattle(chain, h0, v0, 20.0, 0.1).relative_energy_error.max()
    e2 = integrate_rattle(chain, h0, v0, 20.0, 0.05).relative_energy_error.max()
    assert 3.0 < e1 / e2 < 5.0


@pytest.mark.parametrize("chain, a, c", CASES)
def test_time_reversibility(chain, a, c):
    """Forward T then backward T with the same steps returns to the start (rounding only).

    Over much longer times rounding is amplified by the flow's sensitivity
    (4e-14 at T = 20, 7e-10 at T = 100 for the first case).
    """
    h0, v0 = start(chain, a, c)
    fwd = integrate_rattle(chain, h0, v0, 10.0, 0.05)
    back = integrate_rattle(chain, fwd.hinges[-1], fwd.velocities[-1], -10.0, 0.05)
    assert back.t[-1] == -10.0 and np.all(np.diff(back.t) < 0)
    assert np.max(np.abs(back.hinges[-1] - h0)) < 1e-10
    assert np.max(np.abs(back.velocities[-1] - v0)) < 1e-10
    # the backward run from the start is the forward run with reversed velocity
    rev = integrate_rattle(chain, h0, -v0, 10.0, 0.05)
    neg = integrate_rattle(chain, h0, v0, -10.0, 0.05)
    assert np.max(np.abs(rev.hinges - neg.hinges)) < 1e-14
    assert np.max(np.abs(rev.velocities + neg.velocities)) < 1e-14


def test_negative_ragged_time_and_record_every():
    chain = Chain(4, 3.2)
    h0, v0 = start(chain, [0.5, 0.1], [1.0, 1.0])
    sol = integrate_rattle(chain, h0, v0, -1.03, 0.1, record_every=3)
    assert sol.n_steps == 11
    np.testing.assert_allclose(sol.t, [0.0, -0.3, -0.6, -0.9, -1.03], rtol=0, atol=1e-15)
    assert sol.t[-1] == -1.03 and sol.hinges.shape == (5, 3) and sol.velocities.shape == (5, 3)
    ref = integrate_ambient(chain, h0, v0, -1.03, save=SaveAt(t_eval=[-1.03]))
    assert np.max(np.abs(sol.hinges[-1] - ref.hinges[-1])) < 2e-3  # O(h^2), h = 0.1
    # a t_final that is a multiple of h up to rounding leaves no sliver of a step
    assert integrate_rattle(chain, h0, v0, 0.3, 0.1).n_steps == 3
    # a single step shorter than h
    one = integrate_rattle(chain, h0, v0, 0.01, 0.1)
    assert one.n_steps == 1 and one.t.tolist() == [0.0, 0.01]


def test_a_chain_of_two_rods_stays_put():
    chain = Chain(2, 1.5)
    h0 = np.array([0.75 + 1j * np.sqrt(1 - 0.75**2)])
    sol = integrate_rattle(chain, h0, [0j], 1.0, 0.1)
    assert np.allclose(sol.hinges, h0, atol=1e-15) and np.all(sol.energy == 0)


# -- errors -------------------------------------------------------------------------------
class TestErrors:
    chain = Chain(4, 2.6)
    h0, v0 = start(chain, [0.3, 0.5], [1.0, 0.7])

    def test_bad_start_configuration(self):
        with pytest.raises(ConfigurationError, match="does not close"):
            integrate_rattle(self.chain, self.h0 * 1.01, self.v0, 1.0, 0.1)
        with pytest.raises(ConfigurationError, match="finite"):
            integrate_rattle(self.chain, self.h0 * np.nan, self.v0, 1.0, 0.1)
        with pytest.raises(ConfigurationError, match="n - 1 = 3"):
            integrate_rattle(self.chain, self.h0[:2], self.v0, 1.0, 0.1)

    def test_bad_velocity(self):
        with pytest.raises(ValueError, match="finite"):
            integrate_rattle(self.chain, self.h0, self.v0 * np.nan, 1.0, 0.1)
        with pytest.raises(ValueError, match="n - 1 = 3"):
            integrate_rattle(self.chain, self.h0, self.v0[:2], 1.0, 0.1)
        normal = self.chain.rods(self.h0)[:3]  # p_1 = e_1: moving hinge 1 along e_1 stretches rod 1
        with pytest.raises(ValueError, match="not tangent"):
            integrate_rattle(self.chain, self.h0, self.v0 + 0.1 * np.eye(3)[0] * normal[0], 1.0, 0.1)
        sol = integrate_rattle(self.chain, self.h0, self.v0 + 0.1 * np.eye(3)[0] * normal[0], 1.0, 0.1,
                               start=StartCheck(project_velocity=True))
        assert np.max(sol.constraint_residual) < 1e-12

    @pytest.mark.parametrize("h", [0.0, -0.1, np.inf, np.nan, "x"])
    def test_bad_step(self, h):
        with pytest.raises(ValueError, match="h must be"):
            integrate_rattle(self.chain, self.h0, self.v0, 1.0, h)

    @pytest.mark.parametrize("T", [0.0, np.inf, np.nan])
    def test_bad_final_time(self, T):
        with pytest.raises(ValueError, match="t_final"):
            integrate_rattle(self.chain, self.h0, self.v0, T, 0.1)

    @pytest.mark.parametrize("k", [0, -1, 1.5, True])
    def test_bad_record_every(self, k):
        with pytest.raises(ValueError, match="record_every"):
            integrate_rattle(self.chain, self.h0, self.v0, 1.0, 0.1, record_every=k)

    def test_newton_failure_is_reported(self):
        with pytest.raises(RuntimeError, match="did not converge at step 1 of"):
            integrate_rattle(self.chain, self.h0, self.v0, 1.0, 0.5, max_newton_iterations=1)
