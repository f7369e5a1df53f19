"""Topology of chains of any lengths against the stated rules, brute force and Euler characteristics.

Expected values come from the rules of the issue (Kapovich-Millson,
Farber-Schuetz) worked by hand, from an independent sampler of configurations
(random rod angles closed by the last triangle, no diagonals involved) and from
an independent Euler characteristic: the cell decomposition of the configuration
space into ``2^(n-1)`` copies of the diagonal polytope glued along flat walls.
"""

from __future__ import annotations

from math import comb

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from linkage.diagonal_demo import critical_bases, topology_table
from linkage.diagonals import DiagonalSpace
from linkage.topology import Topology, topology

EXAMPLE = (1.0, 2.0, 1.5, 2.5, 1.2)


# -- the rules, worked by hand ----------------------------------------------------------
@pytest.mark.parametrize("n", range(2, 9))
def test_unit_rods_sphere_regime_is_exactly_between_n_minus_2_and_n(n):
    eps = 1e-9
    inside = [n - 2 + eps, n - 2 + 0.5, n - 1, n - 0.5, n - eps]
    outside = [v for v in (n - 2 - eps, n - 2 - 0.5, n + eps, n + 0.5, 0.3) if v > 0 and not n - 2 < v < n]
    for L in inside:
        t = topology([1.0] * n, L)
        assert t.kind == "sphere" and t.dominant_side == n, (n, L, t)
        assert t.betti == ((2,) if n == 2 else (1,) + (0,) * (n - 3) + (1,))
    for L in outside:
        assert topology([1.0] * n, L).kind != "sphere", (n, L)


@pytest.mark.parametrize("L", [1e-9, 0.3, 0.999, 1.0, 1.5, 2 - 1e-9])
def test_four_unit_rods_below_two_is_a_genus_four_surface(L):
    t = topology([1, 1, 1, 1], L)
    assert (t.kind, t.betti, t.components, t.euler_characteristic) == ("manifold", (1, 8, 1), 1, -6)
    assert "genus 4" in str(t)


def test_named_cases():
    assert topology([1, 1, 1, 1], 4.5).kind == "empty"
    assert topology([1, 5], 1).kind == "empty"
    pt = topology([1, 1, 1, 1], 4)
    assert (pt.kind, pt.collinear, pt.betti) == ("point", ((1, 1, 1, 1),), (1,))
    assert topology([3, 1, 1], 1).collinear == ((1, -1, -1),)  # l_1 = P/2: rod 1 out, the rest back
    sing = topology([1, 1, 1, 1], 2)
    assert sing.kind == "singular" and not sing.generic and sing.betti is None
    assert set(sing.collinear) == {(1, 1, 1, -1), (1, 1, -1, 1), (1, -1, 1, 1), (-1, 1, 1, 1)}
    assert "(+, +, +, -)" in str(sing)
    assert str(topology([1] * 6, 2)).endswith("... (11 more)")  # C(6, 2) = 15 listed as 4 + 11
    # Grashof four-bars: crank-rocker (three long sides) = two circles; a triangle = two points
    assert (topology([0.5, 1.2, 1.0], 1.1).kind, topology([0.5, 1.2, 1.0], 1.1).betti) == ("tori", (2, 2))
    assert topology([0.5, 1.2, 1.0], 1.1).long_sides == (1, 2, 3)
    assert topology([1, 1, 1], 1.5).betti == (1, 1)  # one circle, dominant base
    assert (topology([1, 1], 1.5).kind, topology([1, 1], 1.5).betti) == ("sphere", (2,))
    t = topology([1, 1, 1, 0.2], 0.2)
    assert (t.kind, t.betti, t.components) == ("tori", (2, 4, 2), 2)
    t = topology([1, 2.5, 1, 1], 1)  # P/2 = 3.25: 2.5 < 3.25 < 2.5 + 1, so l_2 dominates
    assert (t.kind, t.dominant_side, t.betti) == ("sphere", 1, (1, 0, 1))


def test_bad_input_is_named():
    for lengths, L, word in [([1, -1], 1, "lengths[1]"), ([1, np.nan], 1, "lengths[1]"), ([1], 1, "at least 2"),
                             ([[1, 1]], 1, "1-D"), ([1, 1], 0, "L"), ([1, 1], np.inf, "L")]:
        with pytest.raises(ValueError, match=word.replace("[", r"\[")):
            topology(lengths, L)
    with pytest.raises(ValueError, match="must be <= 20, got 21"):
        topology([1.0] * 21, 20.5)


# -- the rules against each other, over random lengths ----------------------------------
@st.composite
def chains(draw, max_n=7):
    """Lengths and a base: uniform, within 1e-9 of a wall of the generic set, or at the range ends."""
    n = draw(st.integers(2, max_n))
    ls = [draw(st.floats(0.1, 3.0)) for _ in range(n)]
    kind = draw(st.sampled_from(["uniform", "near-signed-sum", "range-end"]))
    total = sum(ls)
    if kind == "uniform":
        L = draw(st.floats(0.01, total + 0.5))
    else:
        eps = np.array([draw(st.sampled_from([-1, 1])) for _ in range(n)])
        target = abs(float(eps @ ls)) if kind == "near-signed-sum" else total
        L = target + draw(st.sampled_from([-1, 1])) * 10.0 ** draw(st.floats(-9, -4))
    assume(L > 0)
    return ls, L


@given(chains())
def test_rules_agree_with_the_betti_formula(chain):
    ls, L = chain
    t = topology(ls, L)
    n, d = len(ls), len(ls) - 2
    assert isinstance(t, Topology) and t.kind in ("empty", "point", "sphere", "tori", "manifold", "singular")
    if t.generic:
        assert len(t.betti) == d + 1 and t.betti == t.betti[::-1]  # Poincare duality
        assert t.components == t.betti[0]
    if t.kind == "sphere" and n > 2:
        assert t.betti == (1,) + (0,) * (d - 1) + (1,)
    if t.kind == "tori":
        assert t.betti == tuple(2 * comb(d, i) for i in range(d + 1))
    if t.kind == "manifold":
        assert t.components == 1  # disconnected only with three long sides
    if t.kind == "singular":
        for eps in t.collinear:
            assert abs(np.dot(eps, ls) - L) <= 1e-12 * (sum(ls) + L)


@given(st.lists(st.integers(1, 16), min_size=2, max_size=7), st.data())
def test_exact_signed_sums_are_singular(ints, data):
    ls = [v / 8 for v in ints]  # dyadic: every signed sum is exact
    eps = data.draw(st.lists(st.sampled_from([-1, 1]), min_size=len(ls), max_size=len(ls)))
    L = float(np.dot(eps, ls))
    assume(L > 0)
    t = topology(ls, L)
    assert t.kind in ("singular", "point")
    assert tuple(eps) in t.collinear


# -- brute force: components of sampled configurations -----------------------------------
def sample_by_angles(lengths, L, N, rng):
    """Configurations from uniform rod angles ``theta_1..theta_{n-2}``, closed by the last triangle (both ways)."""
    l = np.asarray(lengths, float)
    n, out, count = l.size, [], 0
    while count < N:
        q = np.cumsum(l[: n - 2] * np.exp(1j * rng.uniform(-np.pi, np.pi, (4 * N, n - 2))), axis=1)
        g = L - q[:, -1]
        r = np.abs(g)
        ok = (r >= abs(l[-2] - l[-1])) & (r <= l[-2] + l[-1])
        q, g, r = q[ok], g[ok], r[ok]
        beta = np.arccos(np.clip((l[-2] ** 2 + r**2 - l[-1] ** 2) / (2 * l[-2] * r), -1, 1))
        last = q[:, -1] + l[-2] * np.exp(1j * (np.angle(g) + rng.choice([-1, 1], r.size) * beta))
        out.append(np.concatenate([q, last[:, None]], axis=1))
        count += r.size
    return np.concatenate(out)[:N]


def graph_components(h, radius):
    """Components (at least 1% of the points) of the ``radius``-neighbourhood graph, and their labels."""
    X = np.concatenate([h.real, h.imag], axis=1)
    pairs = cKDTree(X).query_pairs(radius, output_type="ndarray")
    N = X.shape[0]
    G = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(N, N))
    _, lab = connected_components(G, directed=False)
    big = np.flatnonzero(np.bincount(lab) >= 0.01 * N)
    return big.size, lab, X


@pytest.mark.parametrize(
    "lengths, L, N, radius",
    [
        ((0.5, 1.2, 1.0), 1.1, 3000, 0.1),  # crank-rocker: two circles
        ((1, 1, 1), 1.5, 3000, 0.1),  # one circle
        ((1, 1, 1, 1), 1.0, 20000, 0.3),  # genus 4
        ((1, 1, 1, 1), 2.5, 20000, 0.3),  # S^2
        ((1, 1, 1, 0.2), 0.2, 20000, 0.3),  # two T^2
        (EXAMPLE, 3.0, 30000, 0.6),  # a connected 3-manifold
    ],
)
def test_components_against_a_neighbourhood_graph(lengths, L, N, radius):
    rng = np.random.default_rng(10)
    count, lab, X = graph_components(sample_by_angles(lengths, L, N, rng), radius)
    assert count == topology(lengths, L).components
    if count == 2:  # the split is no artefact of the radius: the two clouds are far apart
        a, b = np.unique(lab, return_counts=True)[0][:2]
        gap = cKDTree(X[lab == a]).query(X[lab == b])[0].min()
        assert gap > 3 * radius


# -- Euler characteristic from the cells of the diagonal parameterization ------------------
def euler_characteristic_from_cells(lengths, L):
    """``chi = sum over open faces F of D of (-1)^dim F * 2^(#fan triangles not flat on F)``.

    Over the relative interior of a face the fibre is ``2^(#non-flat)`` points, or
    contains a circle where a diagonal vanishes (a hinge on the origin, free to
    turn), which contributes ``chi = 0``.  Faces come from the vertices' tight
    sets closed under intersection.
    """
    space = DiagonalSpace(lengths, L)
    V = space.vertices()
    tol = 1e-9 * (sum(lengths) + L)
    tight = [frozenset(np.flatnonzero(s <= tol)) for s in space.slacks(V)]
    family = set(tight)
    while True:
        grown = family | {a & b for a in family for b in family}
        if grown == family:
            break
        family = grown
    faces = {tuple(i for i, t in enumerate(tight) if E <= t) for E in family}
    chi = 0
    for idx in faces:
        F = V[list(idx)]
        if np.any(np.all(np.abs(F) <= tol, axis=0)):
            continue
        E = frozenset.intersection(*(tight[i] for i in idx))
        dim = np.linalg.matrix_rank(F - F[0], tol=tol) if len(idx) > 1 else 0
        flat = len({row // 3 for row in E})
        chi += (-1) ** dim * 2 ** (space.n - 1 - flat)
    return chi


@pytest.mark.parametrize(
    "lengths, L",
    [
        ((1, 1, 1, 1), 1.0),  # -6 by hand (genus 4)
        ((1, 1, 1, 1), 2.5),  # 2 (S^2)
        ((1, 1, 1, 0.2), 0.2),  # 0 (two tori)
        ((1, 1.3, 0.7, 2.1), 1.9),
        ((1, 1, 1, 1, 1, 1), 0.5),
        ((1, 1, 1, 1, 1, 1), 2.5),
        ((1, 1, 1, 1, 1, 1), 4.5),  # S^4
        ((0.7, 1.1, 1.9, 0.6, 1.4, 1.0), 1.35),
    ],
)
def test_euler_characteristic_against_the_cell_decomposition(lengths, L):
    t = topology(lengths, L)
    assert t.generic
    assert euler_characteristic_from_cells(lengths, L) == t.euler_characteristic


def test_hand_values_of_the_euler_characteristic():
    assert euler_characteristic_from_cells((1, 1, 1, 1), 1.0) == -6
    assert euler_characteristic_from_cells((1, 1, 1, 1, 1, 1), 4.5) == 2


def test_worked_example_changes_only_at_critical_bases():
    crit = critical_bases(EXAMPLE)
    assert crit[0] == pytest.approx(0.2) and crit[-1] == pytest.approx(8.2)  # 1 + 2 - 1.5 - 2.5 + 1.2 .. the sum
    for label, t in topology_table(EXAMPLE):  # generic exactly on the open intervals below the sum
        assert t.generic == ("<" in label), label
    assert topology(EXAMPLE, 8.2 - 1e-6).kind == "sphere" and topology(EXAMPLE, 6.2 + 1e-6).kind == "sphere"
    assert topology(EXAMPLE, 6.2 - 1e-6).kind == "manifold"
