"""Forward-mode jets against heyoka's symbolic differentiation of the same chart formula."""

import re

import heyoka as hy
import numpy as np
import pytest

from charts.suspension_symbolic import SuspensionFamily
from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.time_factor import ChainTimeFactor
from manifold import compiled
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.events import heyoka_events
from manifold.geodesic_system import SymbolicPieces
from manifold.jets import Jet
from manifold.sundman import SundmanStepper

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


def test_a_plain_operand_keeps_its_side():
    """``x * J`` and ``x + J`` with ``x`` a plain expression build ``x * v`` and ``x + v``, as plain code builds them:
    heyoka's common-subexpression elimination does not see ``v * x`` as ``x * v``."""
    x, a, c = hy.make_vars("x", "a", "c")
    jet = Jet.variable(a, c, 0, 1)
    assert (x * jet).v == x * a and (x + jet).v == x + a
    assert (jet * x).v == a * x and (jet + x).v == a + x
    assert (x * jet).g[0] == x * 1 and (x * jet).d1 == x * c


def _canonical_duplicates(decomposition, n_vars: int) -> list[str]:
    """Nodes of a Taylor decomposition that repeat an earlier one up to the order of the terms of a sum or product
    (their inputs replaced by the earlier nodes they repeat)."""
    first: dict[str, int] = {}
    same: dict[int, int] = {}
    repeated = []
    for i in range(n_vars, len(decomposition) - n_vars):
        node = re.sub(r"u_(\d+)", lambda m: f"u_{same.get(int(m.group(1)), int(m.group(1)))}", str(decomposition[i][0]))
        for op in (" * ", " + "):
            terms = node[1:-1].split(op) if node.startswith("(") and node.endswith(")") else []
            if len(terms) > 1 and all(re.fullmatch(r"[up]_?\d+|-?[\d.e+-]+", t) for t in terms):
                node = "(" + op.join(sorted(terms)) + ")"
        if node in first:
            same[i] = first[node]
            repeated.append(node)
        else:
            first[node] = i
    return repeated


@pytest.mark.parametrize("n", [4, 6])
def test_the_chart_step_computes_nothing_twice(n):
    """The default chart integrator (the state ``(a, J c)`` in Sundman's time) with every switch event (near the
    lower end of the range of ``L`` the fold events are compiled too): its velocity solve, built on jets, shares the
    chart formula's nodes with the events' plain formula.  When jets put a plain operand on the other side of a
    product or sum, 40 nodes (25 full recursions) were computed twice at n = 4, and 118 at n = 6."""
    chain = Chain(n, n - 2 + 0.05)
    family = compiled(chain.atlas().charts[0].family)
    stepper = SundmanStepper(ChainTimeFactor(chain), velocity=ConstrainedVelocity(ChainSystem(chain)))
    equations, events = family.composition(float, stepper.composition(family, "embedded"), None)
    ta = hy.taylor_adaptive(equations, np.zeros(len(equations)), compact_mode=True,
                            t_events=heyoka_events(events, False, float))
    assert _canonical_duplicates(ta.decomposition, len(equations)) == []
