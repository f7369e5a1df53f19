"""One geometry per system object and precision, one ChainSystem per chain: what a call reuses changes no result.

The caches are keyed by object, and chains of one ``n`` share their compiled code with different runtime
parameters (``L``, lengths): so solves of two such chains, alternated on the cached objects, must give bitwise what
a fresh ``ChainSystem`` (which builds its own geometry) gives, and each chain's geometry must hold its own numbers.
"""

from __future__ import annotations

import gc
import weakref

import numpy as np
import pytest

from linkage import Chain
from linkage.constraints import ChainSystem, HingeConstraints, chain_system
from manifold import SaveAt
from manifold.constrained import ConstrainedGeometry, solve_constrained


def start(chain: Chain, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed configuration of ``chain`` (a point of its atlas) and a unit-energy tangent velocity."""
    rng = np.random.default_rng(seed)
    x = chain.atlas().get_point(0, np.append(rng.uniform(-1, 1, chain.n - 3), 0.3))
    w = HingeConstraints(chain).project_velocity(x, rng.normal(size=x.size))
    return x, w / np.sqrt(w @ chain.ambient_metric @ w)


def fingerprint(sol) -> tuple:
    _, x, v = sol.final_state
    return sol.n_steps, x.tobytes(), v.tobytes(), np.array([float(e) for e in sol.energies]).tobytes()


def test_one_system_per_chain_and_one_geometry_per_system():
    a, b = Chain(4, 2.7), Chain(4, 2.5)
    assert chain_system(a) is chain_system(a) and chain_system(a) is not chain_system(b)
    geo = ConstrainedGeometry.of(chain_system(a), float)
    assert ConstrainedGeometry.of(chain_system(a), float) is geo
    assert ConstrainedGeometry.of(chain_system(a), np.longdouble) is not geo
    # the same compiled code, each chain's own parameter values (L first after alpha)
    assert ConstrainedGeometry.of(chain_system(b), float).cf is geo.cf
    assert geo.pars[1] == 2.7 and ConstrainedGeometry.of(chain_system(b), float).pars[1] == 2.5


def test_the_caches_let_a_chain_go():
    chain = Chain(4, 2.6)
    ConstrainedGeometry.of(chain_system(chain), float)
    gone = weakref.ref(chain)
    del chain
    gc.collect()
    assert gone() is None


@pytest.mark.parametrize("n", [4, 5])
def test_alternated_chains_solve_as_fresh_systems(n):
    chains = [Chain(n, n - 1.3), Chain(n, n - 1.45)]
    starts = [start(chain, seed) for seed, chain in enumerate(chains)]
    cached, fresh = [], []
    for _ in range(2):
        for chain, (x, w) in zip(chains, starts):
            cached.append(fingerprint(solve_constrained(chain_system(chain), x, w, 2.0, save=SaveAt(dense=False))))
            fresh.append(fingerprint(solve_constrained(ChainSystem(chain), x, w, 2.0, save=SaveAt(dense=False))))
    assert cached == fresh
    assert cached[0] != cached[1]  # the two chains' motions differ: the test would see one chain's numbers used for both
