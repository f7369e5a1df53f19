"""The chain model: validation, mass model, configurations and conversions."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from linkage import Chain, ConfigurationError

from .conftest import base_lengths


@pytest.mark.parametrize(
    "lengths, L, match",
    [
        (4, 4.5, r"empty: L = 4.5 exceeds the sum 4 of the other sides.*2 < L < 4"),
        ([1, 5, 1], 2.0, r"empty: lengths\[1\] = 5.0 exceeds the sum 4"),
        (4, float("nan"), r"L \(base length\) must be a finite number > 0"),
        (4, float("inf"), r"finite"),
        (4, 0.0, r"> 0, got L = 0.0"),
        (4, "2.5", r"got L = '2.5'"),  # a string is not a number, even if float() would take it
        (1, 0.5, r"lengths must be an integer n >= 2 \(n unit rods\) or a sequence"),
        (3.0, 1.5, r"integer"),
        (True, 0.5, r"integer"),
        ([1.0, -2.0, 1.0], 1.0, r"lengths\[1\] = -2.0"),
        ([1.0, np.inf, 1.0], 1.0, r"lengths\[1\] = inf"),
        ([1.0], 1.0, r"at least 2"),
        (["1", "2"], 1.0, r"finite numbers"),
    ],
)
def test_bad_chain_is_refused_naming_the_value(lengths, L, match):
    with pytest.raises(ValueError, match=match):
        Chain(lengths, L)


@pytest.mark.parametrize("n, L, kind", [(4, 2.0, "singular"), (4, 4.0, "point"), (4, 1.0, "manifold"),
                                        (5, 2.5, "manifold"), (3, 0.5, "tori")])
def test_unit_rods_outside_the_sphere_range_are_a_chain_without_an_atlas(n, L, kind):
    """Not a sphere but not empty: the chain exists, its charts do not, and the message keeps the range."""
    chain = Chain(n, L)
    assert chain.unit_rods and not chain.has_atlas and chain.topology().kind == kind
    for method in (chain.atlas, chain.metric):
        with pytest.raises(ValueError, match=rf"{n - 2} < L < {n}.*method='hinges'"):
            method()
    generic = chain.topology().generic
    if generic:
        chain.check_generic()
    else:
        with pytest.raises(ValueError, match=r"not.*collinear .*rods \([+-]"):
            chain.check_generic()


def test_lengths_given_as_ones_are_unit_rods():
    chain = Chain([1, 1, 1, 1], 2.5)
    assert chain.unit_rods and chain.has_atlas and repr(chain) == repr(Chain(4, 2.5)) == "Chain(n=4, L=2.5)"
    assert np.array_equal(chain.mass_matrix, Chain(4, 2.5).mass_matrix)
    other = Chain([1, 2, 1.5, 2.5, 1.2], 3.0)
    assert not other.unit_rods and not other.has_atlas and other.n == 5
    with pytest.raises(ValueError, match="only where the configuration space is a sphere.*the base L for "
                                         "6.2 < L < 8.2.*closed orientable 3-manifold.*method='hinges'"):
        other.atlas()
    with pytest.raises(ValueError):
        other.lengths[0] = 2.0  # read-only


@pytest.mark.parametrize("kw", [{"hinge_masses": 0.0}, {"hinge_masses": [1, 2]}, {"rod_densities": -1.0},
                                {"hinge_masses": np.nan}])
def test_bad_masses_are_refused(kw):
    with pytest.raises(ValueError):
        Chain(4, 3.0, **kw)


@pytest.mark.parametrize("lengths", [5, [1.0, 2.0, 1.5, 2.5, 1.2], [0.3, 4.0, 0.7, 1.1, 2.2]])
def test_mass_matrix_is_the_kinetic_energy_of_hinges_and_rods(lengths):
    """``1/2 v^T K v`` against a quadrature, over arc length, of the rods' kinetic energy density.

    A uniform rod of line density ``lambda`` and length ``l`` has mass ``lambda l``:
    ``T_rod = 1/2 int_0^l lambda |v(sigma)|^2 dsigma`` with ``v`` interpolating the
    end velocities linearly in arc length ``sigma``.
    """
    rng = np.random.default_rng(3)
    M, lam = rng.uniform(0.5, 2, 4), rng.uniform(0, 2, 5)
    chain = Chain(lengths, 4.2, hinge_masses=M, rod_densities=lam)
    ls = chain.lengths
    v = rng.normal(size=4) + 1j * rng.normal(size=4)
    vf = np.concatenate([[0], v, [0]])  # pins do not move
    s, w = np.polynomial.legendre.leggauss(4)
    rods = 0.0
    for k in range(5):
        sigma, wk = ls[k] * (s + 1) / 2, ls[k] * w / 2  # nodes and weights on [0, l_k]
        vel = vf[k] + (sigma / ls[k]) * (vf[k + 1] - vf[k])
        rods += lam[k] * np.sum(wk * np.abs(vel) ** 2)
    expected = 0.5 * np.sum(M * np.abs(v) ** 2) + 0.5 * rods
    assert chain.kinetic_energy(v) == pytest.approx(expected, rel=1e-14)
    A = chain.mass_matrix
    assert np.allclose(A, A.T) and np.all(np.linalg.eigvalsh(A) > 0)
    if chain.unit_rods:
        return
    heavier = Chain(2 * ls, 8.4, hinge_masses=M, rod_densities=lam)  # doubled rods: doubled rod masses
    assert np.allclose(heavier.mass_matrix - np.diag(M), 2 * (A - np.diag(M)), rtol=1e-15, atol=0)


def test_default_mass_model_is_unit_hinge_masses():
    assert np.array_equal(Chain(4, 3.0).ambient_metric, np.eye(6))


@given(st.integers(3, 8).flatmap(lambda n: st.tuples(st.just(n), base_lengths(n))), st.integers(0, 2**32 - 1))
def test_angles_and_hinges_convert_both_ways(nL, seed):
    n, L = nL
    chain = Chain(n, L)
    h = chain.atlas().get_point(0, _random_parameters(n, seed))
    h = chain.from_point(h)
    assert chain.closure_residual(h) < 1e-13
    back = chain.hinges_from_angles(chain.angles(h))
    assert np.max(np.abs(back - h)) < 1e-13


def _random_parameters(n, seed):
    rng = np.random.default_rng(seed)
    return np.append(rng.uniform(-1.5, 1.5, n - 3), rng.uniform(-np.pi, np.pi))


def test_as_hinges_takes_complex_hinges_only():
    chain = Chain(3, 2.0)
    h = np.array([np.exp(1j * np.pi / 3), 1 + np.exp(1j * np.pi / 3)])
    for values in (h, h.astype(np.complex64), list(h), np.stack([h, h])):
        out = chain.as_hinges(values)
        assert out.dtype == np.complex128 and out.shape == np.shape(values)
        np.testing.assert_array_equal(out, np.asarray(values).astype(complex))
    point = chain.to_point(h)  # the interleaved real form of the same hinges is refused, by name
    assert point.dtype.kind == "f"
    with pytest.raises(ConfigurationError, match=r"2 complex hinges.*got shape \(4,\) \(a real array of 2 \(n - 1\) "
                                                 r"entries is an interleaved point: use Chain.from_point\)"):
        chain.as_hinges(point, "velocity")
    with pytest.raises(ConfigurationError, match=r"got shape \(5,\)$"):  # no such hint for another length
        chain.as_hinges(np.zeros(5), "velocity")
    for real in (h.real, h.real.astype(int), [1.0, 1.0]):
        with pytest.raises(ConfigurationError, match=r"^velocity must hold complex hinges.*dtype.*from_point"):
            chain.as_hinges(real, "velocity")
    with pytest.raises(ConfigurationError, match="^configuration must hold complex hinges"):
        chain.closure_residual(h.real)
    with pytest.raises(ConfigurationError, match=r"^velocity must be finite, got velocity\[0\] = \(inf\+infj\)"):
        chain.as_hinges(h * np.inf, "velocity")
    # to_point and from_point are inverse to each other on complex hinges
    np.testing.assert_array_equal(chain.as_hinges(chain.from_point(point)), h)


def test_closure_residual_measures_the_defect():
    chain = Chain(3, 2.0)
    h = np.array([np.exp(1j * np.pi / 3), 1 + np.exp(1j * np.pi / 3)])  # closes: rods 1, 1, 1
    assert chain.closure_residual(h) < 1e-15
    assert chain.closure_residual(h * 1.01) == pytest.approx(0.01, rel=1e-6)
    with pytest.raises(ConfigurationError, match="does not close"):
        chain.check_configuration(h * 1.01)
    with pytest.raises(ConfigurationError, match="finite"):
        chain.check_configuration([np.nan + 0j, 1.0 + 0j])
    with pytest.raises(ConfigurationError, match="2 complex hinges"):
        chain.check_configuration([1.0, 1.0, 1.0])
    with pytest.raises(ConfigurationError, match="do not close"):
        chain.hinges_from_angles([0.0, 0.0, 0.0])


def test_closure_uses_the_rod_lengths():
    """A 3-4-5 triangle by hand: ``p_1 = (9 + 12 i) / 5`` closes rods 3 and 4 on the base 5."""
    chain = Chain([3.0, 4.0], 5.0)
    h = np.array([(9 + 12j) / 5])
    assert chain.closure_residual(h) < 1e-15
    # |p_1| = 3.03 is 1% long; rod 2, |5 - 1.01 p_1| = sqrt(16.0010) ~ 4.0001, is off by 3e-5 relative
    assert chain.closure_residual(h * 1.01) == pytest.approx(0.01, rel=1e-9)
    with pytest.raises(ConfigurationError, match="does not close"):
        chain.check_configuration(h * 1.01)
    assert Chain(2, 5 / 3).closure_residual(h / 3) == pytest.approx(1 / 3, rel=1e-14)  # rods 1, 4/3: unit rods miss by 1/3
    # relative to each rod: the same triangle 1000 times smaller closes as well, and fails as much
    small = Chain([3e-3, 4e-3], 5e-3)
    assert small.closure_residual(h * 1e-3) < 1e-15
    assert small.closure_residual(h * 1.01e-3) == pytest.approx(0.01, rel=1e-9)
    th = chain.angles(h)
    assert np.allclose(th, [np.arctan2(12, 9), np.arctan2(-12, 16)], rtol=0, atol=1e-15)
    np.testing.assert_allclose(chain.hinges_from_angles(th), h, rtol=0, atol=1e-15)
    with pytest.raises(ConfigurationError, match=r"sum_k l_k e\^\(i theta_k\) - L"):
        chain.hinges_from_angles(th + 0.1)


def test_closure_tolerance_is_the_one_asked_for_in_any_order():
    """The rods' accepted errors are kept per tolerance: a check at one tolerance never answers for another.

    The 3-4-5 triangle with ``p_1`` 1e-7 too long (relative) closes to 1e-6 but not to 1e-9, whichever is asked first.
    """
    h = np.array([(9 + 12j) / 5 * (1 + 1e-7)])
    for order in ((1e-9, 1e-6), (1e-6, 1e-9)):
        chain = Chain([3.0, 4.0], 5.0)
        for tol in order + order:
            if tol == 1e-6:
                np.testing.assert_array_equal(chain.check_configuration(h, tol=tol), h)
                assert 0.099 < chain.closure_excess(h, tol) < 0.101  # 1e-7 relative on rod 1, against 1e-6
            else:
                assert 99 < chain.closure_excess(h, tol) < 101
                with pytest.raises(ConfigurationError, match="does not close"):
                    chain.check_configuration(h, tol=tol)


@given(st.integers(0, 2**32 - 1), st.integers(2, 7), st.integers(1, 3))
def test_rods_of_batches_are_the_hinge_differences(seed, n, rows):
    """``e_1 = p_1``, ``e_k = p_k - p_{k-1}``, ``e_n = L - p_{n-1}``, row by row, for any batch shape."""
    rng = np.random.default_rng(seed)
    chain = Chain(n, 0.5 + (n - 1) * rng.uniform())
    h = rng.normal(size=(rows, 2, n - 1)) + 1j * rng.normal(size=(rows, 2, n - 1))
    e = chain.rods(h)
    assert e.shape == (rows, 2, n) and e.dtype == complex
    for idx in np.ndindex(rows, 2):
        p = np.concatenate([[0.0], h[idx], [chain.L]])
        assert np.array_equal(e[idx], [p[k + 1] - p[k] for k in range(n)])
    np.testing.assert_array_equal(chain.rods(h[0, 0]), e[0, 0])  # one configuration as a row of the batch


@given(st.integers(0, 2**32 - 1))
def test_diagonals_of_the_chain_round_trip(seed):
    chain = Chain([1.0, 2.0, 1.5, 2.5, 1.2], 3.0)
    rng = np.random.default_rng(seed)
    sample = chain.diagonal_space().sample(50, rng)
    h = chain.from_diagonals(sample.x, sample.flips)
    assert np.abs(h - sample.hinges).max() == 0.0  # the same map
    assert chain.closure_residual(h).max() < 1e-13
    chain.check_configuration(h)
    x, flips = chain.diagonals(h)
    np.testing.assert_allclose(x, sample.x, rtol=0, atol=1e-13)
    assert np.array_equal(flips, sample.flips)  # Lebesgue samples lie off the walls almost surely
    np.testing.assert_allclose(chain.hinges_from_angles(chain.angles(h)), h, rtol=0, atol=1e-13)
    with pytest.raises(ConfigurationError, match="must hold complex hinges"):
        chain.diagonals(h.real)
