"""Chart velocities by forward substitution (:meth:`manifold.geodesic_system.SymbolicPieces.velocity_coefficients`).

The chart path's state ``(a, V)`` reads ``a'`` from the ambient velocity ``V``.  An iterated suspension's
hinge ``p_j`` moves with the levels above it only, so ``J`` is block triangular and ``a'`` follows level by
level in ``O(n)`` nodes instead of the normal equations' ``O(n^3)``.  On tangent vectors both must give the
coefficients ``c`` of ``V = J c``, for every family (unit rods, any lengths, a link as base) and chart.
"""

from __future__ import annotations

import heyoka as hy
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from linkage import Chain
from manifold.compiled import Transfer, compiled
from manifold.expression_linalg import block_triangular_order

CHAINS = [Chain(4, 2.6), Chain(6, 5.3), Chain([1.0, 0.7, 1.3, 0.9, 1.1], 3.9),
          Chain([0.8, 5.0, 1.0, 1.2, 0.6, 1.1], 1.0)]  # the last: a link, not the base, is the dominant side


def test_a_triangular_pattern_is_found_in_any_row_and_column_order():
    x = hy.expression("x")
    # columns 0, 1, 2; row blocks of 2: block 2 sees column 1 only, block 0 columns 1 and 2, block 1 all three
    A = [[0, x, x], [0, x, 0], [x, x, x], [x, 0, x], [0, x, 0], [0, 0, 0]]
    assert block_triangular_order(A, 2) == [(1, (4, 5)), (2, (0, 1)), (0, (2, 3))]


def test_every_block_that_isolates_a_column_is_used_and_a_dense_pattern_has_no_order():
    x = hy.expression("x")
    assert block_triangular_order([[x, 0], [x, x], [x, x]], 1) == [(0, (0,)), (1, (1, 2))]
    assert block_triangular_order([[x, x], [x, x]], 1) is None
    assert block_triangular_order([[x, 0], [hy.expression(0.0), x]], 1) == [(0, (0,)), (1, (1,))]


def _coefficient_functions(chain: Chain):
    """``a, V -> (forward substitution, g^-1 J^T W V)`` compiled for the chain's family, and the family."""
    family = compiled(chain.atlas().charts[0].family)
    P = family.pieces(float)
    V = [hy.expression(f"V{r}") for r in range(P.N)]
    outputs = P.velocity_coefficients(V) + P.tangent_coefficients(V)
    return hy.cfunc(outputs, P.a + V, compact_mode=True), family


FUNCTIONS: dict = {}


@pytest.mark.parametrize("case", range(len(CHAINS)))
def test_suspensions_with_the_base_dominant_are_triangular(case):
    """The forward substitution is taken where the base is the dominant side (unit rods, any lengths); where a
    link is, the chart frame is that link's and every hinge moves with every level: the normal equations."""
    chain = CHAINS[case]
    P = compiled(chain.atlas().charts[0].family).pieces(float)
    order = block_triangular_order(P.J, P.block)
    if case < 3:
        # levels in order, each isolated by its last hinge; the circle level by the two hinges p_1 and p_2
        k = chain.n - 2
        assert [column for column, _ in order] == list(range(k))
        assert [len(rows) for _, rows in order] == [2] * (k - 1) + [4]
    else:
        assert order is None


@settings(max_examples=40, deadline=None)
@given(case=st.sampled_from(range(len(CHAINS))), chart=st.integers(0, 20), seed=st.integers(0, 2**32 - 1))
def test_forward_substitution_gives_the_tangent_coefficients(case, chart, seed):
    chain = CHAINS[case]
    if case not in FUNCTIONS:
        FUNCTIONS[case] = _coefficient_functions(chain)
    function, family = FUNCTIONS[case]
    atlas = chain.atlas()
    ch = atlas.charts[chart % len(atlas.charts)]
    numerics = ch.numerics(chain.ambient_metric, atlas.switch_threshold, float)
    rng = np.random.default_rng(seed)
    k, N = chain.n - 2, 2 * (chain.n - 1)
    a = rng.uniform(-1.2, 1.2, k)  # latitudes within 1.2 of the equator: quality cos(1.2) = 0.36 or better
    c = rng.normal(size=k)
    V = Transfer(family, float, numerics.pars)(a[:, None], c[:, None], np.zeros((N, 1)))[N : 2 * N, 0]
    out = function(np.concatenate([a, V]), pars=numerics.pars[: function.nparams])
    forward, orthogonal = out[:k], out[k:]
    assert np.max(np.abs(forward - c)) <= 1e-12 * np.max(np.abs(c))
    assert np.max(np.abs(orthogonal - c)) <= 1e-11 * np.max(np.abs(c))


def test_the_velocity_solve_grows_linearly_with_the_chain():
    """Nodes of ``a'(a, V)`` in heyoka's decomposition at n = 5, 10, 15: the forward substitution adds the same
    number per link (measured 232, 587, 942: +355, +355), the normal equations more and more (``J^T W J`` with
    a dense ``W`` and Cholesky are ``O(n^3)``: 284, 1,184, 2,609: +900, +1,425)."""
    counts = []
    for n in (5, 10, 15):
        P = compiled(Chain(n, n - 1.0).atlas().charts[0].family).pieces(float)
        V = [hy.expression(f"V{r}") for r in range(P.N)]
        counts.append([len(hy.cfunc(exprs, P.a + V, compact_mode=True).dc)
                       for exprs in (P.velocity_coefficients(V), P.tangent_coefficients(V))])
    (f5, o5), (f10, o10), (f15, o15) = counts
    assert f15 - f10 <= 1.05 * (f10 - f5)
    assert o15 - o10 >= 1.3 * (o10 - o5)


RECURSION_CHAINS = CHAINS[:3] + [Chain(4, 2 + 1e-6), Chain(5, 5 - 1e-7), Chain(3, 1.5),
                                 Chain([1.0, 0.7, 1.3, 0.9], 3.9 - 1e-6)]


def _recursion_functions(chain: Chain):
    """``a, V -> (a', J a')`` of the suspension's level recursion, then of the forward substitution and the jets."""
    family = compiled(chain.atlas().charts[0].family)
    P = family.pieces(float)
    V = [hy.expression(f"V{r}") for r in range(P.N)]
    recursion = family.family.velocity_solve(P.a, V, float)
    c = P.velocity_coefficients(V)
    outputs = recursion[0] + recursion[1] + c + P.along(c)
    return hy.cfunc(outputs, P.a + V, compact_mode=True)


@settings(max_examples=40, deadline=None)
@given(case=st.sampled_from(range(len(RECURSION_CHAINS))), chart=st.integers(0, 20),
       polar=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_the_level_recursion_is_the_forward_substitution(case, chart, polar, seed):
    """:func:`charts.suspension_velocity.chart_velocity` against the generic forward substitution on the jets,
    for any ``V``, tangent or not (the same least squares per level, so the same oblique projection), in every
    chart, down to latitudes of quality 0.12 and at both ends of the range of ``L``."""
    chain = RECURSION_CHAINS[case]
    key = ("recursion", case)
    if key not in FUNCTIONS:
        FUNCTIONS[key] = _recursion_functions(chain)
    function = FUNCTIONS[key]
    atlas = chain.atlas()
    ch = atlas.charts[chart % len(atlas.charts)]
    numerics = ch.numerics(chain.ambient_metric, atlas.switch_threshold, float)
    rng = np.random.default_rng(seed)
    k, N = chain.n - 2, 2 * (chain.n - 1)
    reach = 1.45 if polar else 1.0  # cos(1.45) = 0.12: past the default switch threshold
    a = np.append(rng.uniform(-reach, reach, k - 1), rng.uniform(-np.pi, np.pi))
    V = rng.normal(size=N)
    out = function(np.concatenate([a, V]), pars=numerics.pars[: function.nparams])
    m = k + N
    recursion, generic = out[:m], out[m:]
    scale = np.max(np.abs(generic))
    assert np.all(np.isfinite(recursion))
    assert np.max(np.abs(recursion - generic)) <= 1e-12 * scale, (recursion - generic) / scale


def test_the_level_recursion_costs_less_than_the_jets():
    """Nodes of ``(a', J a')`` at n = 5 and 10: the level recursion's grow by fewer per link than the generic
    forward substitution's on the jets (the recursion's products per latitude level against the jets' derivative
    of the whole level's formula), and are fewer (measured 190 and 415 against 278 and 683)."""
    counts = []
    for n in (5, 10):
        P = compiled(Chain(n, n - 1.0).atlas().charts[0].family).pieces(float)
        V = [hy.expression(f"V{r}") for r in range(P.N)]
        c = P.velocity_coefficients(V)
        recursion = P.family.velocity_solve(P.a, V, float)
        counts.append([len(hy.cfunc(exprs, P.a + V, compact_mode=True).dc)
                       for exprs in (recursion[0] + recursion[1], c + P.along(c))])
    (r5, g5), (r10, g10) = counts
    assert r5 < g5 and r10 < g10
    assert r10 - r5 < 0.7 * (g10 - g5), counts
