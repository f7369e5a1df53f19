"""The chain model: validation, mass model, configurations and conversions."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from linkage import Chain, ConfigurationError

from .conftest import base_lengths


@pytest.mark.parametrize(
    "n, L, match",
    [
        (4, 2.0, r"2 < L < 4"),
        (4, 4.0, r"2 < L < 4"),
        (4, 1.0, r"got L = 1.0"),
        (4, float("nan"), r"finite"),
        (4, float("inf"), r"finite"),
        (1, 0.5, r"n \(number of rods\) must be an integer >= 2, got 1"),
        (3.0, 1.5, r"integer"),
        (True, 0.5, r"integer"),
        (4, "x", r"real number"),
    ],
)
def test_bad_chain_is_refused_with_the_valid_range(n, L, match):
    with pytest.raises(ValueError, match=match):
        Chain(n, L)


@pytest.mark.parametrize("kw", [{"hinge_masses": 0.0}, {"hinge_masses": [1, 2]}, {"rod_densities": -1.0},
                                {"hinge_masses": np.nan}])
def test_bad_masses_are_refused(kw):
    with pytest.raises(ValueError):
        Chain(4, 3.0, **kw)


def test_mass_matrix_is_the_kinetic_energy_of_hinges_and_rods():
    """Compare ``1/2 v^T K v`` with a quadrature of the rod integrals of the seed's T."""
    rng = np.random.default_rng(3)
    M, lam = rng.uniform(0.5, 2, 4), rng.uniform(0, 2, 5)
    chain = Chain(5, 4.2, hinge_masses=M, rod_densities=lam)
    v = rng.normal(size=4) + 1j * rng.normal(size=4)
    vf = np.concatenate([[0], v, [0]])  # pins do not move
    s, w = np.polynomial.legendre.leggauss(4)
    s, w = (s + 1) / 2, w / 2
    rods = sum(lam[k] * np.sum(w * np.abs((1 - s) * vf[k] + s * vf[k + 1]) ** 2) for k in range(5))
    expected = 0.5 * np.sum(M * np.abs(v) ** 2) + 0.5 * rods
    assert chain.kinetic_energy(v) == pytest.approx(expected, rel=1e-14)
    A = chain.mass_matrix
    assert np.allclose(A, A.T) and np.all(np.linalg.eigvalsh(A) > 0)


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
    with pytest.raises(ConfigurationError, match="2 complex hinges"):
        chain.as_hinges(point, "velocity")
    for real in (h.real, h.real.astype(int), [1.0, 1.0]):
        with pytest.raises(ConfigurationError, match=r"a velocity is expected as complex hinges.*dtype.*from_point"):
            chain.as_hinges(real, "velocity")
    with pytest.raises(ConfigurationError, match="^a configuration is expected as complex hinges"):
        chain.closure_residual(h.real)
    with pytest.raises(ConfigurationError, match="velocity must be finite"):
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
