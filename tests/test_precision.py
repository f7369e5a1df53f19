"""Floating types of the compiled solvers: heyoka's multiprecision ``real`` end to end."""

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from manifold import Precision, solve_chart_exp_ode
from manifold.precision import MultiPrecision, as_fp, unit_roundoff


def start(chain: Chain, a, c):
    atlas = chain.atlas()
    a = np.asarray(a, float)
    return atlas.get_point(0, a), atlas.charts[0].tangent_vector(a, np.asarray(c, float))


@pytest.mark.parametrize("bits", [0, 23, 1001, 2.5, True, "64"])
def test_bad_precision_is_named_with_its_range(bits):
    with pytest.raises(ValueError, match=r"\[24, 1000\]"):
        MultiPrecision(bits)


def test_multiprecision_arrays_hold_exactly_the_requested_bits():
    fp = MultiPrecision(200)
    x = as_fp(np.array([[0.1, 2.0], [1e-300, -3.5]]), fp)
    assert x.shape == (2, 2) and {v.prec for v in x.ravel()} == {200}
    assert [float(v) for v in x.ravel()] == [0.1, 2.0, 1e-300, -3.5]  # doubles convert exactly
    ints = as_fp(np.array([3, -7]), fp)  # numpy integers, which heyoka.real does not take as they are
    assert [float(v) for v in ints] == [3.0, -7.0] and {v.prec for v in ints} == {200}
    assert as_fp(3, fp).item().prec == 200


def test_unit_roundoff():
    assert unit_roundoff(float) == 2.0**-53
    assert unit_roundoff(hy.real128) == 2.0**-113
    assert unit_roundoff(MultiPrecision(300)) == 2.0**-300
    with pytest.raises(TypeError, match="float32"):
        unit_roundoff(np.float32)


def test_solver_rejects_an_unknown_floating_type():
    chain = Chain(3, 1.5)
    p0, v0 = start(chain, [0.3], [1.0])
    with pytest.raises(TypeError, match="fp_type must be"):
        solve_chart_exp_ode(chain.metric(), p0, v0, 1.0, precision=Precision(fp_type=np.float32))


def test_multiprecision_circle_chain_agrees_with_real128():
    """n = 3 in 160-bit ``real``: energy to 1e3 unit roundoffs, the path equal to real128's to its accuracy."""
    chain = Chain(3, 2.2)
    p0, v0 = start(chain, [0.4], [1.3])
    fp = MultiPrecision(160)
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, 3.0, precision=Precision(fp_type=fp))
    ref = solve_chart_exp_ode(chain.metric(), p0, v0, 3.0, precision=Precision(fp_type=hy.real128))
    assert sol.relative_energy_error <= 1e3 * unit_roundoff(fp)
    p, _ = sol(2.0)
    assert {v.prec for v in p.ravel()} == {160}
    assert _max_abs(p - as_fp(ref(2.0)[0], fp)) <= 1e-30


@pytest.mark.slow
def test_multiprecision_crosses_a_chart_switch_and_agrees_with_real128():
    """n = 4 through a switch in 256-bit ``real``: energy and the switch's point gap within
    1e3 unit roundoffs, the end point equal to real128's to 1e-30."""
    chain = Chain(4, 3.2)
    p0, v0 = start(chain, [0.3, 0.4], [0.5, -0.7])
    fp = MultiPrecision(256)
    sol = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, precision=Precision(fp_type=fp))
    ref = solve_chart_exp_ode(chain.metric(), p0, v0, 2.0, precision=Precision(fp_type=hy.real128))
    assert sol.n_switches >= 1 and ref.n_switches == sol.n_switches
    assert sol.relative_energy_error <= 1e3 * unit_roundoff(fp)
    assert max(s.point_gap for s in sol.switches) <= 1e3 * unit_roundoff(fp)
    assert _max_abs(sol.end_state()[0] - as_fp(ref.end_state()[0], fp)) <= 1e-30


def _max_abs(x) -> float:
    return max(abs(float(v)) for v in np.ravel(x))


def test_wider_types_have_more_significant_bits():
    """``wider_types``: real128 (113 bits) from float64 (53), long double only where it has more bits than the type
    (x86: 64; elsewhere 53, or 113 like real128), nothing from real128."""
    from manifold.precision import wider_types

    long_bits = np.finfo(np.longdouble).nmant + 1
    assert wider_types(float) == (["longdouble"] if long_bits > 53 else []) + ["real128"]
    assert wider_types(np.longdouble) == (["real128"] if long_bits < 113 else [])
    assert wider_types(hy.real128) == []
