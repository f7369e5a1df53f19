"""free_motion's default method, ``"auto"`` (:func:`linkage.motion.choose_method`): the hinges, the faster by
measurement, except for a nearly stretched chain with an atlas, where the hinge method loses digits, and where an
option only one method takes is given."""

from __future__ import annotations

import numpy as np
import pytest

from linkage import Chain
from linkage.chain import STRETCHED_GAP
from linkage.motion import choose_method, free_motion
from linkage.sampling import sample_starts
from manifold import SaveAt
from manifold.steppers import TaylorStepper
from manifold.budget import Budget


@pytest.mark.parametrize("chain, options, expected", [
    (Chain(4, 3.0), {}, "hinges"),
    (Chain(7, 5.5, hinge_masses=np.geomspace(1e-3, 1e3, 6)), {}, "hinges"),
    (Chain(4, 4 - 1e-4), {}, "charts"),  # nearly stretched: gap 1e-4 / 8 of the perimeter
    (Chain([1.0, 5.0, 1.2, 0.9], 1.905), {}, "charts"),  # a link dominant, nearly stretched: gap 5e-3 of 9.9
    (Chain([1.0, 5.0, 1.2, 0.9], 2.5), {}, "hinges"),  # a link dominant, not stretched
    (Chain(4, 3.0), {"stepper": TaylorStepper()}, "charts"),  # only the chart solver takes a stepper
    (Chain(4, 4 - 1e-4), {"rate": 2.0}, "hinges"),  # only the hinge solver takes a Baumgarte rate
    (Chain(4, 4 - 1e-4), {"compact_mode": True}, "charts"),  # both take compact_mode: the chain decides
    (Chain(4, 3.0), {"compact_mode": False}, "hinges"),
    (Chain(4, 3.0), {"throw": False, "budget": Budget()}, "hinges"),  # both take these
])
def test_the_method_that_auto_stands_for(chain, options, expected):
    assert choose_method(chain, options) == expected


def test_the_threshold_is_a_share_of_the_perimeter():
    # unit rods, n = 4: perimeter 4 + L, gap 4 - L
    below, above = 4 - 0.5 * STRETCHED_GAP * 8, 4 - 2 * STRETCHED_GAP * 8
    assert choose_method(Chain(4, below), {}) == "charts" and choose_method(Chain(4, above), {}) == "hinges"


def test_the_default_runs_the_chosen_method_and_equals_it():
    for chain, kind in ((Chain(5, 4.2), "constrained"), (Chain(5, 5 - 1e-4), "sundman")):
        h, v = sample_starts(chain, 1, 1.0, np.random.default_rng(2))
        T = 0.5
        default = free_motion(chain, h[0], v[0], T, save=SaveAt(t_eval=[T]))
        named = free_motion(chain, h[0], v[0], T, method=choose_method(chain, {}), save=SaveAt(t_eval=[T]))
        assert kind in default.solution.method
        assert np.array_equal(default.hinges, named.hinges)


def test_a_bad_method_names_the_choices():
    chain = Chain(4, 3.0)
    h, v = sample_starts(chain, 1, 1.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match=r"method must be one of \('charts', 'hinges', 'auto'\)"):
        free_motion(chain, h[0], v[0], 1.0, method="fastest")


def test_a_failed_hinge_run_on_a_stretched_chain_says_why_and_points_to_the_charts():
    """5e-10 of the perimeter short of full stretch the rods' tensions are ~2e9 times the energy: the hinge method's
    energy check refuses the run and its message says why and names the charts, which the default runs and which
    pass; a Lyapunov run (hinge coordinates only) gets the why without a remedy it could not take."""
    from linkage.motion import lyapunov_exponent
    from manifold import SolveStatus

    chain = Chain(4, 4 - 4e-9)
    h, v = sample_starts(chain, 1, 1.0, np.random.default_rng(0))
    failed = free_motion(chain, h[0], v[0], 2.0, method="hinges", throw=False, save=SaveAt(dense=False)).solution
    assert failed.status is SolveStatus.ENERGY_CHECK_FAILED
    assert "the chain is 5e-10 of its perimeter short of full stretch" in failed.message
    assert "free_motion(method='charts')" in failed.message
    assert free_motion(chain, h[0], v[0], 2.0, save=SaveAt(dense=False)).success
    exponents = lyapunov_exponent(chain, h[0], v[0], 2.0, k=1, throw=False)
    assert not exponents.success and "short of full stretch" in exponents.message and "charts" not in exponents.message
