"""The conformance suite (``manifold.testing``) on every chart family and constrained system of the library.

The suspension families (unit rods, L near both ends of its range), the any-length families (base dominant and
link dominant), the stereographic charts of the round sphere (``manifold.stereographic``, the "your own manifold"
example), the chain's rod constraints and the sphere's constraint all pass the same checks.
"""

from __future__ import annotations

import numpy as np
import pytest

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.sampling import sample_configurations, sample_velocities
from manifold import StartCheck
from manifold.stereographic import UnitSphere, sphere_metric
from manifold.testing import ConformanceReport, check_atlas, check_constrained, check_geodesic_energy

CHAINS = [
    Chain(3, 2.5), Chain(3, 3 - 1e-4), Chain(4, 2.0 + 1e-3), Chain(4, 2.6, hinge_masses=[1.0, 5.0, 0.2]),
    Chain(5, 4 - 1e-3, rod_densities=0.5), Chain(6, 4.4), Chain(7, 5.5, hinge_masses=[1, 2, 3, 4, 5, 6]),
    Chain((1.0, 2.0, 1.5, 2.5, 1.2), 7.0),            # any lengths, the base dominant
    Chain((1.0, 7.5, 1.5, 2.0, 1.2), 3.0),            # any lengths, a link dominant
]


def _samples(chain: Chain, m: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    hinges = sample_configurations(chain, m, rng)
    return chain.to_point(hinges), chain.to_point(sample_velocities(chain, hinges, 0.5, rng))


@pytest.mark.parametrize("chain", CHAINS, ids=repr)
def test_suspension_and_any_length_atlases_conform(chain):
    points, velocities = _samples(chain, 6)
    check_atlas(chain.metric(), points).raise_on_failure()
    # a chain of three rods has one chart, the circle, which never switches (it wraps); the others switch at a
    # threshold of 0.45 (the default 0.25 lets a run of T = 60 stay in one chart), below every best chart's quality
    check_geodesic_energy(chain.metric(), points[0], velocities[0], 60.0, min_switches=int(chain.n > 3), q_out=0.45,
                          start=StartCheck(project_velocity=True)).raise_on_failure()


@pytest.mark.parametrize("chain", CHAINS, ids=repr)
def test_chain_constraints_conform(chain):
    points, velocities = _samples(chain, 6, seed=1)
    # within 1e-3 of the stretched chain the rods carry tensions of order E / (n - L) that act on the state's
    # rounding, and the hinge method's errors grow with the steps (docs/methods.md): there, the solvers' own bound
    # for the steps taken (n = 3, L = 3 - 1e-4: the transported Gram matrix moved 1.2e-12 over T = 5)
    near_top = sum(chain.lengths) - chain.L < 1e-3
    check_constrained(ChainSystem(chain), points, velocities, bound=None if near_top else 1e-12).raise_on_failure()


def test_the_stereographic_sphere_conforms_by_charts_and_by_its_constraint():
    rng = np.random.default_rng(3)
    p = rng.standard_normal((8, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    v = np.cross(p, rng.standard_normal((8, 3)))
    metric = sphere_metric()
    check_atlas(metric, p).raise_on_failure()
    check_geodesic_energy(metric, p[0], v[0], 10.0, min_switches=2, q_out=0.45).raise_on_failure()
    check_constrained(UnitSphere(), p, v).raise_on_failure()


def test_the_suite_can_fail():
    """A report with a failed check raises, naming it; a chart whose Jacobian is wrong fails its check."""
    report = ConformanceReport("a subject")
    report.add("passes", [0.5], 1.0)
    report.add("fails", [2.0], 1.0)
    report.add("NaN fails", [np.nan], 1.0)
    assert [c.passed for c in report.checks] == [True, False, False]
    with pytest.raises(AssertionError, match="FAIL fails"):
        report.raise_on_failure()

    metric = sphere_metric()
    chart = metric.atlas.charts[0]
    wrong = type("WrongJacobian", (type(chart),), {"jacobian": lambda self, a: 1.01 * type(chart).jacobian(self, a)})
    metric.atlas.charts[0] = wrong(False)
    p = np.array([[0.6, 0.0, -0.8]])
    failed = [c.name for c in check_atlas(metric, p).checks if not c.passed]
    assert "Jacobian against central differences" in failed
