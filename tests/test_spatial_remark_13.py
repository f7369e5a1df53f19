"""Remark 13 of the bond paper: bonds with a joint coordinate ``inf`` ("bonds at infinity").

The paper says that none occur in its examples but that such linkages exist.  Where they can
occur follows from two facts checked here:

* ``b(k)`` (the joint length, Theorem 19 for the coupling curve ``C_{k-1,k}``, a line) is the
  degree of ``t_k`` on the curve: the fibre over any value holds ``b(k)`` places.  The home
  pose (real, all ``t_k = inf``) and, with a bond ``beta`` there, ``beta`` and its conjugate
  (a different bond) lie in the fibre over ``t_k = inf``.  So a bond at infinity at joint ``k``
  needs ``b(k) >= 3``, or ``b(k) = 0`` (joint ``k`` at rest: the degenerate component of
  ``test_spatial_traps.py``).
* Assembling the linkage in another real configuration ``t^0`` (``RevoluteChain.reposed``)
  changes each joint value by a real Moebius map (``s = (1 + t^0 t)/(t^0 - t)``) and keeps the
  bonds' local distances.  A bond can be moved to infinity at joint ``k`` only if ``t_k(beta)``
  is real and taken at a real configuration too, i.e. again ``b(k) >= 3``.

All joints of the paper's Examples 1-3, 11, 12 and of the Goldberg, cubic 6R and double Bennett
linkages have length 1 or 2, so none of them has a bond at infinity in any pose; Bricard's joints
of length 4 have no real value at a bond (``tests/test_spatial_bricard.py``).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy

from linkage.spatial import ConfigurationCurve, RevoluteChain
from linkage.spatial.examples import (
    bennett,
    cubic_6r,
    double_bennett_6r,
    example_11,
    example_12,
    goldberg_5r,
    planar_four_bar,
    spherical_four_bar,
)

from .test_spatial_traps import shared_axis_chain

R = sympy.Rational
INF = complex("inf")

BUILDERS = {
    "Example 1 (Bennett)": bennett,
    "Example 2 (spherical)": spherical_four_bar,
    "Example 3 (planar)": planar_four_bar,
    "Example 11": example_11,
    "Example 12": example_12,
    "Goldberg 5R": lambda: goldberg_5r()[2],
    "cubic 6R": cubic_6r,
    "double Bennett": lambda: double_bennett_6r()[2],
}


@functools.lru_cache(maxsize=None)
def linkage(name: str) -> RevoluteChain:
    return BUILDERS[name]()


def joint_lengths(chain: RevoluteChain) -> list[int]:
    d, n = chain.distance_matrix(), chain.n
    return [int(d[(k - 1) % n, k]) for k in range(n)]


def at_i(z: complex) -> bool:
    return not np.isinf(abs(z)) and abs(z * z + 1) < 1e-12


def is_real(z: complex) -> bool:
    return np.isinf(abs(z)) or abs(z.imag) < 1e-12 * max(1.0, abs(z))


def movable_to_infinity(chain: RevoluteChain) -> list[tuple]:
    """``(bond, k)`` with ``t_k`` real at the bond on a joint of length ``>= 3`` (1-based ``k``):
    the only places a bond at infinity can come from, in this pose or another."""
    b = joint_lengths(chain)
    return [
        (bond.joints, k + 1)
        for bond in chain.bonds()
        for k, z in enumerate(bond.joints)
        if not at_i(z) and is_real(z) and b[k] >= 3
    ]


@pytest.mark.parametrize("name", list(BUILDERS))
def test_no_bond_at_infinity_in_any_pose(name):
    chain = linkage(name)
    bonds = chain.bonds()
    assert bonds and not any(np.isinf(abs(z)) for bond in bonds for z in bond.joints)  # "not in our examples"
    assert max(joint_lengths(chain)) <= 2
    assert movable_to_infinity(chain) == []


def test_the_degenerate_bonds_at_infinity_sit_on_joints_at_rest():
    """Axes 1 and 3 on one line, joints 2 and 4 at the identity: the bonds at infinity are on
    joints of length 0, as the fibre count demands."""
    t = sympy.Symbol("t")
    chain = shared_axis_chain(ConfigurationCurve([t, 1, t, 1], [0, 0, 0, 0], [1, 0, 1, 0]))
    b = joint_lengths(chain)
    for bond in chain.bonds():
        resting = [k for k, z in enumerate(bond.joints) if np.isinf(abs(z))]
        assert resting == [1, 3] and all(b[k] == 0 for k in resting)


def test_a_real_bond_coordinate_of_a_length_two_joint_is_taken_only_by_the_bond_pair():
    """Example 2 has bonds with a real coordinate (t3 = -3, t3 = 1/3, t2 = -1, t2 = 1), on joints of
    length 2.  The whole fibre of the curve over that value, solved from the curve's formula
    ``t_k = (a_k + b_k w)/c_k``, is the bond and its conjugate: no real configuration takes the
    value, so no choice of home pose puts the bond at infinity."""
    chain = linkage("Example 2 (spherical)")
    curve = chain.configuration_curve()
    t = sympy.Symbol("t")
    checked = 0
    for bond in chain.bonds():
        for k, z in enumerate(bond.joints):
            if at_i(z) or not is_real(z):
                continue
            r = sympy.nsimplify(round(z.real, 12))
            a, b, c, g = (p.as_expr() for p in (curve.a[k], curve.b[k], curve.c[k], curve.g))
            fibre = sympy.Poly(sympy.expand((a - r * c) ** 2 - b**2 * g), t)
            places = []
            for t0 in fibre.nroots(n=30):
                for place in curve.places(t0):
                    if abs(place.joint_values()[k] - complex(r)) < 1e-20:
                        places.append(place)
            assert not any(abs(p.joint_values()[k] - complex(r)) < 1e-9 for p in curve.places(INF))
            assert len(places) == joint_lengths(chain)[k] == 2
            for p in places:  # both are bonds: the conjugate pair, none real
                values = p.joint_values()
                assert any(np.allclose(values, other.joints, atol=1e-12) for other in chain.bonds())
                assert any(at_i(v) for v in values)
            checked += 1
    assert checked == 8


@pytest.mark.parametrize(
    "name, home",
    [("Example 1 (Bennett)", (R(1), R(2), R(1), R(-2))), ("Example 2 (spherical)", (R(1), R(-1, 2), R(-1, 2), R(1)))],
)
def test_reposed_linkage_has_the_moebius_images_of_the_bonds(name, home):
    """The linkage assembled in another real configuration: its curve from the new axes alone
    (exact elimination), its bonds the images under ``s = (1 + t^0 t)/(t^0 - t)`` with the same
    local distances, and still none at infinity."""
    chain = linkage(name)
    moved = chain.reposed(home)
    # h_1 and h_n lie on the base link o_n, which stays (P_{n-1} ~ (t^0_n - h_n)^-1 commutes
    # with h_n); the axes in between move
    assert moved.axes[0] == chain.axes[0] and moved.axes[-1] == chain.axes[-1]
    assert not any(x == y for x, y in zip(moved.axes[1:-1], chain.axes[1:-1]))
    new = moved.bonds()
    assert len(new) == len(chain.bonds())
    for bond in chain.bonds():
        image = tuple((1 + float(h0) * z) / (float(h0) - z) for z, h0 in zip(bond.joints, home))
        (twin,) = [nb for nb in new if np.allclose(nb.joints, image, atol=1e-9)]
        assert np.array_equal(twin.local_distances, bond.local_distances)
    assert np.array_equal(moved.distance_matrix(), chain.distance_matrix())
    assert movable_to_infinity(moved) == []


def test_reposed_refuses_a_point_that_is_not_a_configuration():
    chain = linkage("Example 1 (Bennett)")
    with pytest.raises(ValueError, match="is not a configuration"):
        chain.reposed((R(1), R(2), R(1), R(2)))
    with pytest.raises(ValueError, match="n = 4 entries"):
        chain.reposed((R(1), R(2), R(1)))
    with pytest.raises(ValueError, match=r"joints\[1\] .* is not real"):
        chain.reposed((R(1), 2 + 1j, R(1), R(-2)))


def test_reposed_at_a_numerical_configuration_point():
    """A float configuration from ``configuration_point`` (complex dtype, zero imaginary parts)
    gives float axes; the old home pose, ``t_k = inf``, is ``s_k = -t^0_k`` in the new chain."""
    chain = linkage("Example 1 (Bennett)")
    home = chain.configuration_point(2.3, joint=2, guess=[1.3, 2.3, 1.3, -2.3])
    moved = chain.reposed(home)
    assert moved.data == "float"
    old_home = moved.closure([-z.real for z in home])
    assert max(abs(x) for x in old_home.coefficients[1:]) <= 1e-12 * abs(old_home[0])
    off = moved.closure([-z.real + 0.1 for z in home])
    assert max(abs(x) for x in off.coefficients[1:]) > 1e-3 * abs(off[0])  # the check can fail
