"""Motion between two configurations (``Chain.path``, ``linkage.diagonal_path``).

The path is checked for what it promises: it starts and ends at the given configurations, every point closes,
it is continuous (straight pieces in the diagonals, and a flip changed only where its triangle is exactly flat:
the hinges move like the square root of the step near a wall, never by a jump), and two configurations get a path
exactly when they lie in one connected component, counted independently by the topology (Kapovich-Millson).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from linkage import Chain
from linkage.diagonal_path import DifferentComponentsError
from linkage.diagonals import triangle_slacks

from .test_diagonals import chains


def _configurations(chain: Chain, flips: np.ndarray, seed: int) -> np.ndarray:
    x = chain.diagonal_space().sample(len(flips), np.random.default_rng(seed)).x
    return chain.from_diagonals(x, flips)


@given(chain_data=chains(max_n=7), seed=st.integers(0, 2**16), data=st.data())
@settings(max_examples=40)
def test_a_path_joins_two_configurations_continuously(chain_data, seed, data):
    ls, L = chain_data
    chain = Chain(ls, L)
    assume(chain.topology().generic and chain.diagonal_space().interior_point()[1] > 1e-6)
    flips = np.array([[data.draw(st.sampled_from([-1, 1])) for _ in range(chain.n - 1)] for _ in range(2)])
    H = _configurations(chain, flips, seed)
    try:
        path = chain.path(H[0], H[1])
    except (DifferentComponentsError, NotImplementedError):
        return  # which pairs a path joins is the next test's business
    P = ls.sum() + L
    assert np.abs(path(0.0) - H[0]).max() <= 1e-12 * P and np.abs(path(1.0) - H[1]).max() <= 1e-12 * P
    s = np.linspace(0, 1, 32001)
    h = path(s)
    assert chain.closure_residual(h).max() <= 1e-12
    # continuous: refined three times 1000-fold around the largest step between samples, the largest step falls
    # (like a power of the sampling near a wall, where a diagonal is small; a jump would not fall at all), down to
    # the resolution of the path's values there: a hinge that moves like the square root of a rounded quantity of
    # size P steps in quanta of sqrt(eps P) (7 unit rods at L = 7 - 7e-5 stepped by 3.9e-8 between s 3e-14 apart)
    steps = np.abs(np.diff(h, axis=0)).max(axis=1)
    first = steps.max()
    for _ in range(3):
        i = int(np.argmax(steps))
        s = np.linspace(s[i], s[i + 1], 1001)
        steps = np.abs(np.diff(path(s), axis=0)).max(axis=1)
    assert steps.max() <= max(1e-3 * first, 2 * np.sqrt(np.finfo(float).eps * P))
    # a flip changes only at a corner where its triangle is exactly flat: both flips give the same configuration
    d = np.concatenate([np.full((len(path.corners), 1), ls[0]), path.corners, np.full((len(path.corners), 1), L)], 1)
    for m in range(1, len(path.flips)):
        (t,) = np.nonzero(path.flips[m] != path.flips[m - 1])[0]
        assert min(triangle_slacks(d[m, t], ls[t + 1], d[m, t + 1])) <= 0.0
        before, after = (chain.from_diagonals(path.corners[m], path.flips[i]) for i in (m - 1, m))
        assert np.abs(before - after).max() <= 1e-14 * P


@pytest.mark.parametrize("lengths, L", [((1, 1, 1), 0.5), ((1, 1, 1), 2.5), ((1, 2, 1.5, 2.5, 1.2), 3.0),
                                        ((1, 2, 1.5, 2.5, 1.2), 6.0), ((3, 1, 1, 1), 2.5), ((1, 1, 1, 1, 1), 0.5),
                                        ((2, 2, 1, 1), 1.2), ((1, 1, 1, 1), 3.5)])
def test_paths_exist_exactly_within_the_components_that_the_topology_counts(lengths, L):
    """Over all pairs of flip vectors: the classes of 'a path exists' number ``topology().components``."""
    chain = Chain(lengths, L)
    flips = np.array(list(itertools.product([-1, 1], repeat=chain.n - 1)))
    H = _configurations(chain, flips, 0)
    classes: list[list[int]] = []
    for i in range(len(H)):
        for cls in classes:
            try:
                chain.path(H[cls[0]], H[i])
            except DifferentComponentsError:
                continue
            except NotImplementedError:  # one component, crossed only through a face where a diagonal vanishes
                pass
            cls.append(i)
            break
        else:
            classes.append([i])
    assert len(classes) == chain.topology().components


def test_bad_input_is_refused_by_name():
    chain = Chain(4, 2.5)
    H = _configurations(chain, np.array([[1, 1, 1], [-1, 1, -1]]), 1)
    with pytest.raises(ValueError, match="hinges0 must be one configuration"):
        chain.path(H, H[1])
    path = chain.path(H[0], H[1])
    with pytest.raises(ValueError, match="s must lie in"):
        path(1.5)


def test_a_path_ends_exactly_at_its_configurations_even_near_a_wall():
    # found by the stress profile: the second configuration has a fan triangle 3.3e-7 from flat (L = 0.001), where
    # rebuilding it from its own diagonals amplified their 4e-16 rounding to 1.7e-11 in the hinges
    ls, L = np.array([1.0, 1.0, 1.0, 1.0, 0.125, 2.0]), 0.001000001
    chain = Chain(ls, L)
    H = _configurations(chain, -np.ones((2, chain.n - 1), dtype=int), 892)
    assert chain.diagonal_space().slacks(chain.diagonals(H[1])[0]).min() < 1e-6  # the hard region, as found
    path = chain.path(H[0], H[1])
    assert np.array_equal(path(0.0), H[0]) and np.array_equal(path(1.0), H[1])
    assert np.array_equal(path(np.array([1.0, 0.0])), H[::-1])
    # and the path stays continuous into its ends: the points next to them are as close as the rebuild allows
    near = path(np.array([1e-12, 1 - 1e-12]))
    assert np.abs(near - H).max() <= 1e-9
