"""Equation terms (``manifold.terms``): a compiled integrator is the composition of its terms, keyed by them.

A term written here, outside the library (a constant rescaling of time, ``dt = lambda dtau``), composes with the
chart geodesic without touching ``manifold``: the rescaled run reaches at ``tau = T / lambda`` the state that the
plain run reaches at ``T``, and its parameter sits where the composition puts it.
"""

from __future__ import annotations

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.time_factor import ChainTimeFactor
from manifold import compiled
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.events import RISING, Event
from manifold.sundman import SundmanTime
from manifold.terms import ChartGeodesic, Term

from .sphere_family import sphere_metric


class ScaledTime(Term):
    """``dy/dtau = lambda dy/dt`` with ``lambda = par[offset]``, and an event where ``tau``'s clock ``w`` reaches 1."""

    key = "scaled-time"
    n_params = 1

    def equations(self, pieces, equations, offset):
        w = hy.expression("clock")
        return [(lhs, hy.par[offset] * rhs) for lhs, rhs in equations] + [(w, hy.expression(1.0))]

    def events(self, equations):
        return [Event(equations[-1][0] - 1.0, RISING, "stop")]


def _sphere_state():
    metric = sphere_metric()
    numerics = metric.atlas.charts[0].numerics(metric.K, metric.atlas.switch_threshold)
    return compiled(metric.atlas.charts[0].family), numerics.pars, np.array([0.3, -0.2, 0.4, 0.1])  # (a, c)


def test_a_term_written_outside_the_library_composes_with_the_geodesic():
    family, pars, y0 = _sphere_state()
    T, lam = 0.6, 2.5  # short of the chart's switch event and of the clock's
    with family.integrator(float) as plain:
        plain.state[:], plain.time, plain.pars[:] = y0, 0.0, pars[: len(plain.pars)]
        assert plain.propagate_until(T)[0] == hy.taylor_outcome.time_limit
        end = np.array(plain.state)
    with family.integrator(float, terms=(ChartGeodesic(), ScaledTime())) as scaled:
        assert len(scaled.pars) == family.layout.terms_index + 1  # its parameter right after the chart's
        assert len(scaled.t_events) == len(family.events()) + 1  # its event after the family's
        scaled.state[:], scaled.time = np.append(y0, 0.0), 0.0
        scaled.pars[:] = np.append(pars, lam)
        assert scaled.propagate_until(T / lam)[0] == hy.taylor_outcome.time_limit
        assert np.abs(scaled.state[:-1] - end).max() <= 1e-13
        assert abs(scaled.state[-1] - T / lam) <= 1e-15
        scaled.state[:], scaled.time = np.append(y0, 0.0), 0.0
        scaled.pars[-1] = 0.5  # tau = 1 is t = 0.5, before the switch
        outcome = scaled.propagate_until(10.0)[0]  # its stop event: the clock reaches 1 at tau = 1
        assert outcome == hy.taylor_outcome(-len(family.events()) - 1) and abs(scaled.time - 1.0) <= 1e-14


def test_integrators_are_keyed_by_the_composition():
    family, _, _ = _sphere_state()
    with family.integrator(float, terms=(ChartGeodesic(),)) as a:
        first = id(a)
    with family.integrator(float) as b:  # the default composition is the same
        assert id(b) == first
    with family.integrator(float, terms=(ChartGeodesic("christoffel"),)) as c:
        assert id(c) != first


def test_the_parameters_follow_the_terms_in_order():
    chain = Chain(4, 2.9)
    family = compiled(chain.atlas().charts[0].family)
    velocity, factor = ConstrainedVelocity(ChainSystem(chain)), ChainTimeFactor(chain)
    with family.integrator(float, terms=(velocity, SundmanTime(factor))) as ta:
        assert len(ta.pars) == family.layout.terms_index + velocity.n_params + 1 + factor.n_params


@pytest.mark.parametrize("terms", [(SundmanTime(ChainTimeFactor(Chain(4, 2.9))),), (ChartGeodesic(), ChartGeodesic()),
                                   ("embedded",), ()])
def test_a_composition_without_one_state_term_first_is_refused(terms):
    family, _, _ = _sphere_state()
    with pytest.raises(TypeError, match="terms must be a manifold.terms.StateTerm followed by other Terms"):
        with family.integrator(float, terms=terms):
            pass


def test_a_bad_form_is_refused_by_name():
    with pytest.raises(ValueError, match="form must be one of"):
        ChartGeodesic("hamiltonian")
