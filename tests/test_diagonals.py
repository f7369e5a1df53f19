"""The diagonal parameterization: closure, round trips, walls, the polytope, its volume and samplers.

Hypothesis leans toward the hard regions: diagonals exactly on or within 1e-12
of a wall of ``D`` (flat fan triangles), and ``L`` near the ends of its range.
Expected values come from exact rational arithmetic, hand formulas, Monte
Carlo, or the independent angle sampler of ``tests/test_topology.py``.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from charts.chain_geometry import rod_vectors
from linkage import Chain
from linkage.diagonal_demo import circular_configurations, flip_patterns, plot_sampled_configurations
from linkage.diagonals import (
    DiagonalSpace,
    diagonals,
    from_diagonals,
    hinge_jacobian,
    riemannian_density,
    triangle_slacks,
)
from tests.test_topology import sample_by_angles

EXAMPLE = (1.0, 2.0, 1.5, 2.5, 1.2)
EPS = np.finfo(float).eps


# -- strategies ----------------------------------------------------------------------
def _offset(draw, lo: float, hi: float) -> float:
    """A point of ``[lo, hi]``: uniform, exactly at an end, or within 1e-12 of one."""
    kind = draw(st.sampled_from(["uniform", "uniform", "lo", "hi", "near-lo", "near-hi"]))
    gap = min(10.0 ** draw(st.floats(-12, -9)), (hi - lo) / 2)
    return {
        "uniform": lo + (hi - lo) * draw(st.floats(0, 1)),
        "lo": lo,
        "hi": hi,
        "near-lo": lo + gap,
        "near-hi": hi - gap,
    }[kind]


@st.composite
def chains(draw, min_n=3, max_n=7, dyadic=False):
    """Lengths in [0.1, 3] (or multiples of 1/64) and ``L`` in its range ``[r_n, R_n]``, often near an end."""
    n = draw(st.integers(min_n, max_n))
    if dyadic:
        ls = np.array([draw(st.integers(8, 192)) / 64 for _ in range(n)])
    else:
        ls = np.array([draw(st.floats(0.1, 3.0)) for _ in range(n)])
    R, r = ls.sum(), max(0.0, 2 * ls.max() - ls.sum())
    if dyadic:  # every sum of sides is then exact, so walls are hit exactly
        L = draw(st.integers(int(r * 64) + 1, int(R * 64) - 1)) / 64
    else:
        L = _offset(draw, max(r, 1e-3), R)
    assume(max(r, 1e-3) < L < R)
    return ls, L


@st.composite
def points(draw, ls, L, dyadic=False):
    """``x`` in ``D``, built forward: ``d_k`` in its triangle interval intersected with what the rest can reach."""
    n = ls.size
    d_prev, xs = ls[0], []
    for k in range(2, n):  # d_k; rods after it: l_{k+1}..l_n = ls[k:]
        rest = ls[k:]
        Rr, rr = rest.sum(), max(0.0, 2 * rest.max() - rest.sum())
        lo = max(abs(d_prev - ls[k - 1]), L - Rr, rr - L)
        hi = min(d_prev + ls[k - 1], L + Rr)
        assume(hi >= lo)
        d = _offset(draw, lo, hi)
        if dyadic:
            d = draw(st.sampled_from([lo, hi]))
        xs.append(d)
        d_prev = d
    return np.array(xs)


@st.composite
def configurations(draw, dyadic=False):
    ls, L = draw(chains(dyadic=dyadic))
    x = draw(points(ls, L, dyadic=dyadic))
    flips = np.array([draw(st.sampled_from([-1, 1])) for _ in range(ls.size - 1)])
    return ls, L, x, flips


def closure_error(ls, L, hinges):
    return np.max(np.abs(np.abs(rod_vectors(hinges, L)) - ls))


# -- the map --------------------------------------------------------------------------
#: A diagonal of 1e-323: the fan rotation's ``g2 h2`` underflowed and the complex division overflowed (NaN hinges).
SUBNORMAL_DIAGONAL = (np.ones(6), 0.001000001, np.array([1e-323, 1.0, 0.0, 1.0]), -np.ones(5, dtype=int))


@given(configurations())
@example(SUBNORMAL_DIAGONAL)
def test_closure_to_1e13_also_within_1e12_of_a_wall(conf):
    ls, L, x, flips = conf
    h = from_diagonals(ls, L, x, flips)
    assert closure_error(ls, L, h) <= 1e-13
    assert np.allclose(np.abs(h[1:]), x, rtol=4 * EPS * ls.size, atol=0)


@given(configurations())
@example(SUBNORMAL_DIAGONAL)
def test_configuration_against_50_digit_reference(conf):
    """The angles near a wall: ``acos`` of the law of cosines would be off by ``1e-8`` here."""
    mp = pytest.importorskip("mpmath")
    ls, L, x, flips = conf
    h = from_diagonals(ls, L, x, flips)
    with mp.workdps(50):
        d = [mp.mpf(v) for v in np.concatenate([[ls[0]], x, [L]])]
        phi, ref = mp.mpf(0), []
        for k in range(ls.size - 1, 0, -1):  # triangle T_{k+1}: sides d[k-1], l_{k+1}, d[k]
            a, l, c = d[k - 1], mp.mpf(ls[k]), d[k]
            cos_g = (a * a + c * c - l * l) / (2 * a * c) if a * c > 0 else mp.mpf(1)
            phi -= int(flips[k - 1]) * mp.acos(max(-1, min(1, cos_g)))
            ref.append(complex(a * mp.cos(phi), a * mp.sin(phi)))
    ref = np.array(ref[::-1])
    assert np.max(np.abs(h - ref)) <= 8 * ls.size * EPS * (ls.sum() + L)


@given(configurations())
@example(SUBNORMAL_DIAGONAL)
def test_round_trip_x_exactly_and_flips_where_the_triangle_is_not_flat(conf):
    ls, L, x, flips = conf
    x2, f2 = diagonals(ls, L, from_diagonals(ls, L, x, flips))
    assert np.all(np.abs(x2 - x) <= 4 * EPS * ls.size * x)
    slack = DiagonalSpace(ls, L).slacks(x).reshape(-1, 3).min(axis=1)
    assert np.array_equal(f2[slack > 0], flips[slack > 0])
    assert np.all(f2[slack <= 0] == 1)  # a flat triangle reports +1


@given(configurations(dyadic=True), st.data())
def test_both_flips_give_the_same_configuration_on_a_wall(conf, data):
    ls, L, x, flips = conf  # dyadic: the walls are hit exactly, slack == 0
    slack = DiagonalSpace(ls, L).slacks(x).reshape(-1, 3).min(axis=1)
    flat = np.flatnonzero(slack <= 0)
    assume(flat.size)
    other = flips.copy()
    other[flat] *= -1
    assert np.array_equal(from_diagonals(ls, L, x, flips), from_diagonals(ls, L, x, other))


def test_flips_only_matter_off_the_wall():
    ls, L = np.array([1.0, 1.0, 1.0, 1.0]), 2.5
    for x in ([2.0, 2.5], [1.0 + 2.0**-20, 2.0]):  # T_2 flat; then 2^-20 inside
        a = from_diagonals(ls, L, x, [1, 1, 1])
        b = from_diagonals(ls, L, x, [-1, 1, 1])
        assert (np.max(np.abs(a - b)) == 0) == (x[0] == 2.0)


@given(configurations())
def test_slacks_are_exact_near_their_walls(conf):
    ls, L, x, _ = conf
    d = np.concatenate([[ls[0]], x, [L]])
    a, l, c = d[:-1], ls[1:], d[1:]
    got = np.stack(triangle_slacks(a, l, c), axis=-1)
    for k in range(a.size):
        A, Lk, C = Fraction(a[k]), Fraction(l[k]), Fraction(c[k])
        exact = [A + Lk - C, C + Lk - A, A + C - Lk]
        for s, e in zip(got[k], exact):
            if 0 <= e <= Fraction(min(a[k], l[k], c[k])) / 2:  # Sterbenz: both subtractions exact
                assert Fraction(s) == e
            else:
                assert abs(Fraction(s) - e) <= 2 * EPS * (a[k] + l[k] + c[k])


def test_independent_configurations_come_back():
    rng = np.random.default_rng(3)
    for ls, L in [(EXAMPLE, 3.0), (EXAMPLE, 0.7), ((1, 1, 1, 0.2), 0.2), ((0.5, 1.2, 1.0), 1.1)]:
        h = sample_by_angles(ls, L, 2000, rng)
        x, f = diagonals(ls, L, h)
        assert np.all(DiagonalSpace(ls, L).contains(x, tol=1e-12))
        assert np.max(np.abs(from_diagonals(ls, L, x, f) - h)) <= 1e-9


def test_vectorised_over_leading_axes():
    ls, L = np.array(EXAMPLE), 3.0
    space = DiagonalSpace(ls, L)
    s = space.sample(6, np.random.default_rng(1))
    x = s.x.reshape(2, 3, 3)
    flips = np.array([1, -1, -1, 1])
    h = from_diagonals(ls, L, x, flips)
    assert h.shape == (2, 3, 4)
    for i in range(2):
        for j in range(3):
            assert np.array_equal(h[i, j], from_diagonals(ls, L, x[i, j], flips))
    x2, f2 = diagonals(ls, L, h)
    assert x2.shape == (2, 3, 3) and f2.shape == (2, 3, 4) and np.all(f2 == flips)
    assert space.slacks(x).shape == (2, 3, 12) and space.contains(x).shape == (2, 3)


def test_bad_input_names_argument_value_and_range():
    ls, L = [1.0, 2.0, 1.5, 2.5, 1.2], 3.0
    with pytest.raises(ValueError, match=r"d_2 in \[1, 3\].*got d_2 = 3.5"):
        from_diagonals(ls, L, [3.5, 2.0, 3.0], [1, 1, 1, 1])
    with pytest.raises(ValueError, match=r"x\[\(1,\)\] is outside"):
        from_diagonals(ls, L, [[2.0, 2.0, 3.0], [2.0, 9.0, 3.0]], [1, 1, 1, 1])
    with pytest.raises(ValueError, match=r"flips must be \+1 or -1, got flips\[\(2,\)\] = 0"):
        from_diagonals(ls, L, [2.0, 2.0, 3.0], [1, 1, 0, 1])
    with pytest.raises(ValueError, match="n - 2 = 3 free diagonals"):
        from_diagonals(ls, L, [2.0, 2.0], [1, 1, 1, 1])
    with pytest.raises(ValueError, match="n - 1 = 4 signs"):
        from_diagonals(ls, L, [2.0, 2.0, 3.0], [1, 1, 1])
    with pytest.raises(ValueError, match=r"x must be finite, got x\[1\] = nan"):
        from_diagonals(ls, L, [2.0, np.nan, 3.0], [1, 1, 1, 1])
    with pytest.raises(ValueError, match=r"lengths\[3\] = -2.5"):
        from_diagonals([1, 2, 1.5, -2.5, 1.2], L, [2.0, 2.0, 3.0], [1, 1, 1, 1])
    with pytest.raises(ValueError, match="L .base length. must be a finite number > 0"):
        DiagonalSpace(ls, -1)
    with pytest.raises(ValueError, match="not a closed chain"):
        diagonals(ls, L, np.zeros(4, complex))
    with pytest.raises(ValueError, match="needs n >= 3"):
        DiagonalSpace([1, 1], 1)
    with pytest.raises(ValueError, match="empty"):
        DiagonalSpace([1, 1, 1], 3.5).volume()


# -- the polytope ---------------------------------------------------------------------
@given(chains(max_n=6), st.data())
def test_half_spaces_and_slacks_agree(chain, data):
    ls, L = chain
    space = DiagonalSpace(ls, L)
    x = data.draw(points(ls, L))
    assert space.A.shape == (3 * (ls.size - 1), ls.size - 2)
    assert np.allclose(space.slacks(x), space.b - space.A @ x, rtol=0, atol=8 * EPS * (ls.sum() + L))


@given(chains(max_n=7))
def test_cuboid_contains_D(chain):
    ls, L = chain
    space = DiagonalSpace(ls, L)
    _, radius = space.interior_point()
    assume(radius > 1e-9)
    v = space.vertices()
    tol = 1e-9 * (ls.sum() + L)
    assert np.all(space.contains(v, tol=tol))
    assert np.all(v >= space.lower - tol) and np.all(v <= space.upper + tol)


def test_cuboid_by_hand():
    space = DiagonalSpace([1.0, 3.0, 0.5, 1.0], 2.0)
    # R = (1, 4, 4.5), r = (max(0, 2 - 1), max(0, 6 - 4), max(0, 6 - 4.5)) = (1, 2, 1.5)
    assert np.array_equal(space.lower, [2.0, 1.5]) and np.array_equal(space.upper, [4.0, 4.5])


def test_volume_by_hand():
    for ls, L in [((0.5, 1.2, 1.0), 1.1), ((1, 1, 1), 1.5), ((2, 0.5, 1), 2.2)]:
        lo = max(abs(ls[0] - ls[1]), abs(L - ls[2]))
        hi = min(ls[0] + ls[1], L + ls[2])
        assert DiagonalSpace(ls, L).volume() == pytest.approx(hi - lo, rel=1e-14)
    # four unit rods: area of { |d_2 - 1| <= d_3 <= d_2 + 1, |d_3 - L| <= 1 <= d_3 + L }, 0 <= d_2 <= 2
    # L = 2.5: d_3 in [1.5, d_2 + 1] for d_2 in [0.5, 2]: 1.5^2 / 2
    assert DiagonalSpace([1, 1, 1, 1], 2.5).volume() == pytest.approx(9 / 8, rel=1e-13)
    # L = 1: d_3 in [|d_2 - 1|, min(d_2 + 1, 2)]: int_0^1 2 d_2 + int_1^2 (3 - d_2) = 1 + 3/2
    assert DiagonalSpace([1, 1, 1, 1], 1.0).volume() == pytest.approx(5 / 2, rel=1e-13)


@pytest.mark.parametrize(
    "ls, L",
    [((1, 1, 1, 1), 2.5), ((1, 1, 1, 1), 1.0), (EXAMPLE, 3.0), (EXAMPLE, 0.7), ((0.7, 1.1, 1.9, 0.6, 1.4, 1.0), 1.35)],
)
def test_volume_against_monte_carlo(ls, L):
    space = DiagonalSpace(ls, L)
    rng = np.random.default_rng(7)
    N = 200_000
    p = space.contains(rng.uniform(space.lower, space.upper, (N, space.dim))).mean()
    box = np.prod(space.upper - space.lower)
    se = box * np.sqrt(p * (1 - p) / N)
    assert abs(space.volume() - box * p) <= 5 * se


# -- samplers -------------------------------------------------------------------------
def _moments_agree(a, b, sigmas=5.0):
    """Means and covariances of two iid samples agree within ``sigmas`` standard errors."""
    na, nb = len(a), len(b)
    se = np.sqrt(a.var(0) / na + b.var(0) / nb)
    assert np.all(np.abs(a.mean(0) - b.mean(0)) <= sigmas * se)
    ca, cb = a - a.mean(0), b - b.mean(0)
    pa, pb = ca[:, :, None] * ca[:, None, :], cb[:, :, None] * cb[:, None, :]
    se_c = np.sqrt(pa.var(0) / na + pb.var(0) / nb)
    assert np.all(np.abs(pa.mean(0) - pb.mean(0)) <= sigmas * se_c)


def test_hit_and_run_agrees_with_rejection():
    space = DiagonalSpace(EXAMPLE, 3.0)
    rng = np.random.default_rng(11)
    rej = space.sample(10000, rng, method="rejection")
    har = space.sample(10000, rng, method="hit-and-run")
    assert rej.method == "rejection" and 0.1 < rej.acceptance < 0.5
    assert np.all(space.contains(har.x))
    _moments_agree(rej.x, har.x)
    assert abs(har.flips.mean()) < 0.05 and rej.measure == har.measure == "lebesgue"


def test_hit_and_run_with_one_chain_at_a_time():
    """Too few chains for an ensemble covariance (N = 1 gave NaN): isotropic directions throughout, still uniform."""
    space = DiagonalSpace(EXAMPLE, 7.0)  # the sphere regime: D is 2% of its cuboid
    rng = np.random.default_rng(13)
    one = space.sample(1, rng, method="hit-and-run")
    assert np.all(np.isfinite(one.hinges)) and np.all(space.contains(one.x))
    few = np.concatenate([space.sample(8, rng, method="hit-and-run").x for _ in range(40)])  # 8 < 10 (n-1)
    assert np.all(space.contains(few))
    _moments_agree(space.sample(8000, rng, method="rejection").x, few)


def test_hit_and_run_where_cuboid_rejection_is_hopeless():
    ls, L = np.ones(7), 6.9  # nearly stretched: D is a thin sliver of the cuboid
    space = DiagonalSpace(ls, L)
    rng = np.random.default_rng(12)
    box = np.prod(space.upper - space.lower)
    assert space.volume() / box < 1e-4
    har = space.sample(6000, rng)  # 'auto' must choose hit-and-run
    assert har.method == "hit-and-run" and np.all(space.contains(har.x))
    # reference: rejection from the vertices' bounding box (written here, not the library's)
    v = space.vertices()
    lo, hi = v.min(0), v.max(0)
    ref = []
    while sum(len(r) for r in ref) < 20000:
        c = rng.uniform(lo, hi, (200000, space.dim))
        ref.append(c[space.contains(c)])
    _moments_agree(np.concatenate(ref)[:20000], har.x)
    with pytest.raises(RuntimeError, match="hit-and-run"):
        space.sample(10, rng, method="rejection", max_draws=10**5)


def test_jacobian_against_finite_differences():
    ls, L = np.array(EXAMPLE), 3.0
    space = DiagonalSpace(ls, L)
    s = space.sample(20, np.random.default_rng(5))
    J = hinge_jacobian(ls, L, s.x, s.flips)
    h = 1e-6
    for m in range(space.dim):
        e = np.zeros(space.dim)
        e[m] = h
        fd = (from_diagonals(ls, L, s.x + e, s.flips) - from_diagonals(ls, L, s.x - e, s.flips)) / (2 * h)
        scale = np.max(np.abs(J[..., m]), axis=-1, keepdims=True)
        assert np.all(np.abs(fd - J[..., m]) <= 1e-6 * scale)


def test_riemannian_sampler_matches_arclength_of_a_four_bar():
    """Crank-rocker (two circles): mean of ``d_2 = |p_2|`` over arclength in hinge space, computed on the curve."""
    ls, L = np.array([0.5, 1.2, 1.0]), 1.1
    theta = np.linspace(-np.pi, np.pi, 200001)
    num = den = 0.0
    for branch in (-1, 1):  # the rod-1 angle theta goes all the way round on each circle
        p1 = ls[0] * np.exp(1j * theta)
        g = L - p1
        r = np.abs(g)
        beta = np.arccos((ls[1] ** 2 + r**2 - ls[2] ** 2) / (2 * ls[1] * r))
        p2 = p1 + ls[1] * np.exp(1j * (np.angle(g) + branch * beta))
        seg = np.sqrt(np.abs(np.diff(p1)) ** 2 + np.abs(np.diff(p2)) ** 2)
        mid = (np.abs(p2[1:]) + np.abs(p2[:-1])) / 2
        num, den = num + (seg * mid).sum(), den + seg.sum()
    exact = num / den
    space = DiagonalSpace(ls, L)
    rng = np.random.default_rng(21)
    rie = space.sample(20000, rng, measure="riemannian", pool=20)
    leb = space.sample(20000, rng)
    assert rie.measure == "riemannian" and rie.ess > 5000
    se = rie.x.std() / np.sqrt(min(len(rie), rie.ess))
    assert abs(rie.x.mean() - exact) <= 5 * se
    assert abs(leb.x.mean() - exact) > 5 * se  # the weighting matters: dx alone is another measure
    assert closure_error(ls, L, rie.hinges) <= 1e-13


def test_riemannian_density_is_the_volume_of_the_parallelotope():
    ls, L = np.array(EXAMPLE), 3.0
    s = DiagonalSpace(ls, L).sample(5, np.random.default_rng(2))
    J = hinge_jacobian(ls, L, s.x, s.flips)
    real = np.concatenate([J.real, J.imag], axis=-2)  # a row permutation of the interleaved J
    sv = np.linalg.svd(real, compute_uv=False)
    assert np.allclose(riemannian_density(ls, L, s.x, s.flips), sv.prod(-1), rtol=1e-12)


def test_riemannian_sampler_matches_weighted_angle_samples_in_two_dimensions():
    """Four unequal rods (a genus-3 surface): the Riemannian mean of ``x`` from uniform rod angles.

    Independent of the diagonals: ``(theta_1, theta_2)`` uniform, the last
    triangle closed both ways, each sample weighted by ``sqrt(det J_theta^T J_theta)``
    (central differences), which turns the pushforward of ``dtheta`` into the
    Riemannian volume.
    """
    ls, L = np.array([1.0, 1.3, 0.7, 2.1]), 1.9
    rng = np.random.default_rng(31)

    def angle_map(th, s):
        q = ls[0] * np.exp(1j * th[:, 0]) + ls[1] * np.exp(1j * th[:, 1])
        g = L - q
        r = np.abs(g)
        beta = np.arccos(np.clip((ls[2] ** 2 + r**2 - ls[3] ** 2) / (2 * ls[2] * r), -1, 1))
        return np.stack([ls[0] * np.exp(1j * th[:, 0]), q, q + ls[2] * np.exp(1j * (np.angle(g) + s * beta))], -1)

    th, s = rng.uniform(-np.pi, np.pi, (300000, 2)), rng.choice([-1, 1], 300000)
    r = np.abs(L - ls[0] * np.exp(1j * th[:, 0]) - ls[1] * np.exp(1j * th[:, 1]))
    keep = (r > abs(ls[2] - ls[3])) & (r < ls[2] + ls[3])
    th, s = th[keep], s[keep]
    cols = []
    for m in range(2):
        e = np.zeros(2)
        e[m] = 1e-6
        d = (angle_map(th + e, s) - angle_map(th - e, s)) / 2e-6
        cols.append(np.concatenate([d.real, d.imag], axis=-1))
    J = np.stack(cols, axis=-1)
    w = np.sqrt(np.linalg.det(np.einsum("nim,nik->nmk", J, J)))
    x = np.abs(angle_map(th, s)[:, 1:])
    mean = (w[:, None] * x).sum(0) / w.sum()
    se_ref = np.sqrt((w[:, None] ** 2 * (x - mean) ** 2).sum(0)) / w.sum()

    rie = DiagonalSpace(ls, L).sample(10000, rng, measure="riemannian")
    se = rie.x.std(0) / np.sqrt(min(len(rie), rie.ess))
    assert np.all(np.abs(rie.x.mean(0) - mean) <= 5 * np.hypot(se, se_ref))


# -- the paper's picture ----------------------------------------------------------------
def test_circular_configurations_start_along_the_axis_and_end_on_the_circle():
    ls, L = np.array(EXAMPLE), 3.0
    space = DiagonalSpace(ls, L)
    rng = np.random.default_rng(21)
    for flips in flip_patterns(5):
        s = space.sample(200, rng)
        z = circular_configurations(from_diagonals(ls, L, s.x, flips), L)
        np.testing.assert_allclose(z[:, 0], ls[0], rtol=0, atol=1e-14)  # rod 1 on the positive real axis
        np.testing.assert_allclose(np.abs(z[:, -1]), L, rtol=0, atol=1e-13)  # the end on |z| = L
        rods = np.abs(np.diff(np.concatenate([np.zeros((200, 1)), z], axis=1), axis=1))
        np.testing.assert_allclose(rods, np.broadcast_to(ls, rods.shape), rtol=0, atol=1e-13)
        assert np.array_equal(diagonals(ls, L, s.hinges)[1], s.flips)
        np.testing.assert_allclose(np.abs(z[:, 1:-1]), s.x, rtol=0, atol=1e-13)  # a rotation keeps the diagonals


def test_sampled_configurations_figure_is_written(tmp_path):
    fig = plot_sampled_configurations(cases=((EXAMPLE, 3.0), ((1, 1, 1, 1), 2.5)), per_panel=3)
    assert len(fig.axes) == 4  # two chains by two flip vectors
    fig.savefig(tmp_path / "c.png", dpi=40)
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@given(seed=st.integers(0, 2**16), densities=st.booleans())
@settings(max_examples=25, deadline=None)
@example(seed=9919, densities=True)  # a thin triangle: plain central differences were 7e-6 off
def test_riemannian_density_with_masses_against_finite_differences(seed, densities):
    """``sqrt(det(J^T K J))`` with the chain's kinetic metric, ``J`` by central differences of ``from_diagonals``
    (not the analytic ``hinge_jacobian``); the diagonal space of a chain carries its masses."""
    rng = np.random.default_rng(seed)
    chain = Chain([1.0, 2.0, 1.5, 2.5, 1.2], 4.3, hinge_masses=10.0 ** rng.uniform(-2, 2, 4),
                  rod_densities=rng.uniform(0, 2, 5) if densities else 0.0)
    space = chain.diagonal_space()
    s = space.sample(1, rng)
    x, flips = s.x[0], s.flips[0]
    def point(y):
        return chain.to_point(chain.from_diagonals(y, flips))

    def differenced(h):
        J = np.stack([(point(x + h * e) - point(x - h * e)) / (2 * h) for e in np.eye(space.dim)], axis=-1)
        return np.sqrt(np.linalg.det(J.T @ chain.ambient_metric @ J))

    # central differences are off by O(h^2), 7e-6 relative at h = 1e-6 near a thin triangle: Richardson's
    # extrapolation cancels that term (1.7e-8 at worst over 5,000 draws)
    expected = (4 * differenced(5e-7) - differenced(1e-6)) / 3
    got = riemannian_density(chain.lengths, chain.L, x, flips, chain.mass_matrix)
    assert np.isclose(got, expected, rtol=1e-7)
    # uniform masses c scale the volume by c^(dim/2)
    assert np.isclose(riemannian_density(chain.lengths, chain.L, x, flips, 3.0 * np.eye(4)),
                      3.0 ** (space.dim / 2) * riemannian_density(chain.lengths, chain.L, x, flips), rtol=1e-12)
    assert np.array_equal(space.mass_matrix, chain.mass_matrix)
