"""Everything a user might ship to another process pickles at every point of its life, and evaluates the same after.

Compiled artefacts hold locks and LLVM states: objects that cache them (charts after a solve, solutions, carried
geometry) drop the cache when pickled and rebuild it on demand.  Each stage below uses the objects one more way
and then round-trips all of them.
"""

from __future__ import annotations

import pickle

import numpy as np

from linkage import Chain, geometry
from linkage.motion import free_motion, free_motions, lyapunov_exponent
from linkage.sampling import sample_starts
from manifold import SaveAt


def _round_trip(*objects):
    return [pickle.loads(pickle.dumps(obj)) for obj in objects]


def test_objects_pickle_after_every_kind_of_use():
    chain = Chain(4, 2.6, hinge_masses=[1.0, 2.0, 0.5])
    H, V = sample_starts(chain, 3, 0.5, np.random.default_rng(0))
    _round_trip(chain)  # new
    metric = chain.metric()
    _round_trip(chain, metric, chain.atlas())  # with its atlas built
    p = chain.to_point(H[0])
    metric.gaussian_curvature(p)
    _round_trip(chain, metric)  # after compiled curvature
    ts = np.array([0.0, 0.7, 2.0])
    for method in ("charts", "hinges"):
        motion = free_motion(chain, H[0], V[0], 2.0, method=method)
        (copy, chain_copy) = _round_trip(motion, chain)  # after a solve
        assert np.array_equal(copy(ts)[0], motion(ts)[0])
        assert np.array_equal(free_motion(chain_copy, H[0], V[0], 2.0, method=method)(ts)[0], motion(ts)[0])
    ensemble = free_motions(chain, H, V, 2.0, save=SaveAt(t_eval=ts))
    (copy,) = _round_trip(ensemble)
    assert np.array_equal(copy.hinges, ensemble.hinges)
    lyapunov = lyapunov_exponent(chain, H[0], V[0], 5.0)
    _round_trip(lyapunov, chain)
    pt = geometry.parallel_transport(chain, H[0], V[0], V[0], 2.0)
    (copy,) = _round_trip(pt)
    assert np.array_equal(copy(ts).vectors, pt(ts).vectors)
    _round_trip(chain, metric, chain.atlas())  # after all of it
