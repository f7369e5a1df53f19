"""Forward-mode jets against heyoka's symbolic differentiation of the same chart formula."""

import heyoka as hy
import numpy as np
import pytest

from charts.suspension_symbolic import SuspensionFamily
from linkage import Chain
from manifold import compiled
from manifold.geodesic_system import SymbolicPieces

from .conftest import DifferentiatedFamily


@pytest.mark.parametrize("n", [3, 4, 6])
def test_jet_and_symbolic_geodesic_accelerations_agree(n):
    chain = Chain(n, n - 1.3, rod_densities=0.3)
    chart = chain.atlas().charts[1]
    pars = chart.numerics(chain.ambient_metric, -2.0).pars
    rng = np.random.default_rng(n)
    for fam in (SuspensionFamily(n), DifferentiatedFamily(n)):
        cf = compiled(fam).acceleration(float)
        tr = compiled(fam).transfer(float)
        if fam.key[0] == "suspension":
            jet_cf, jet_tr = cf, tr
        else:
            diff_cf, diff_tr = cf, tr
    for _ in range(20):
        a = np.append(rng.uniform(-1.3, 1.3, n - 3), rng.uniform(-np.pi, np.pi))
        c = rng.normal(size=n - 2)
        u = rng.normal(size=2 * (n - 1))
        x = np.concatenate([a, c])
        acc_jet = jet_cf(x, pars=pars[: jet_cf.nparams])
        acc_diff = diff_cf(x, pars=pars[: diff_cf.nparams])
        assert np.abs(acc_jet - acc_diff).max() <= 1e-11 * max(1.0, np.abs(acc_diff).max())
        y = np.concatenate([x, u])
        t_jet, t_diff = jet_tr(y, pars=pars[: jet_tr.nparams]), diff_tr(y, pars=pars[: diff_tr.nparams])
        assert np.abs(t_jet - t_diff).max() <= 1e-11 * max(1.0, np.abs(t_diff).max())


def test_jets_shrink_the_taylor_decomposition():
    """The reason for jets: the forward sweep is several times smaller for deep formulas."""
    sizes = {}
    for name, fam in (("jets", SuspensionFamily(6)), ("differentiated", DifferentiatedFamily(6))):
        ta = hy.taylor_adaptive(SymbolicPieces(fam, float).equations(), np.zeros(8), compact_mode=True)
        sizes[name] = len(ta.decomposition)
    assert sizes["jets"] * 2 < sizes["differentiated"], sizes
