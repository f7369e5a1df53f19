"""The hinge method keeps only the positions' Taylor polynomials (``manifold.solution.SecondOrderDense``).

On ``x' = v`` the velocity's coefficients are ``(j + 1) x_{j+1}``: the positions' polynomials, with the
velocity's last coefficient, must give what the full polynomials of both give, on the same run, in
every precision, forward and backward, at half the bytes.
"""

import heyoka as hy
import numpy as np
import pytest

from linkage import Chain
from linkage.constraints import ChainSystem
from linkage.motion import free_motion
from linkage.sampling import sample_starts
from manifold import SaveAt
from manifold.constrained import ConstrainedGeometry, compiled_constrained
from manifold.precision import unit_roundoff
from manifold.solution import SecondOrderDense, TaylorDense
from manifold.steppers import taylor_advance


def _both(chain: Chain, fp_type, T: float, seed: int = 0):
    """One start, advanced twice on the same integrator: full Taylor polynomials, then the positions' only."""
    system = ChainSystem(chain)
    comp = compiled_constrained(system)
    H, V = sample_starts(chain, 1, 0.5, np.random.default_rng(seed))
    geo = ConstrainedGeometry(system, fp_type)
    xs, vs, _, alphas = geo.start(chain.to_point(H)[:1], chain.to_point(V)[:1], T, 1.0)
    y0, pars = np.concatenate([xs[0], vs[0]]), geo.packed(float(alphas[0]))
    N = system.ambient_dim
    with comp.integrator(fp_type, None, True, True) as ta:
        full = taylor_advance(ta, fp_type(0.0), y0, fp_type(T), pars, True, fp_type)
        half = taylor_advance(ta, fp_type(0.0), y0, fp_type(T), pars, True, fp_type, positions=N)
    return full, half, N


@pytest.mark.parametrize("fp_type, T", [(float, 20.0), (float, -20.0), (np.longdouble, 10.0), (hy.real128, 2.0)],
                         ids=["float64", "float64 backward", "long double", "real128"])
def test_positions_polynomials_give_both(fp_type, T):
    chain = Chain(5, 3.6, hinge_masses=[1.0, 0.3, 2.0, 0.7])
    full, half, N = _both(chain, fp_type, T)
    assert type(full.dense) is TaylorDense and isinstance(half.dense, SecondOrderDense)
    assert full.n_steps == half.n_steps and np.array_equal(full.step_times, half.step_times)
    assert np.array_equal(full.step_states, half.step_states)  # v_0 = x_1 exactly: the same checks run
    order = full.dense.tcs.shape[-1] - 1
    assert half.dense.nbytes == full.n_steps * (N * (order + 2)) * full.dense.tcs.itemsize + full.dense.times.nbytes
    assert half.dense.nbytes < 0.55 * full.dense.nbytes
    ts = np.linspace(0.0, T, 997)[1:-1]
    a, b = full.dense(ts), half.dense(ts)
    assert np.array_equal(a[:, :N], b[:, :N])  # positions: the same coefficients
    scale = float(np.max(np.abs(a[:, N:].astype(float))))
    # velocities: the coefficients differ by the rounding of x_{j+1} = v_j / (j + 1), a few units in the last place
    assert float(np.max(np.abs((a[:, N:] - b[:, N:]).astype(float)))) <= 50 * unit_roundoff(fp_type) * scale


def test_free_motion_keeps_half_the_bytes_and_the_same_motion():
    chain = Chain(4, 2.7)
    H, V = sample_starts(chain, 1, 0.5, np.random.default_rng(3))
    m = free_motion(chain, H[0], V[0], 30.0, method="hinges")
    with compiled_constrained(ChainSystem(chain)).integrator() as ta:
        order = ta.order
    N = 6
    assert m.solution.dense_nbytes == m.n_steps * (N * (order + 2) + 1) * 8 + 8
    ts = np.linspace(0, 30, 301)
    grid = free_motion(chain, H[0], V[0], 30.0, method="hinges", save=SaveAt(t_eval=ts, dense=False))
    p, v = m.solution(ts)
    # the grid without dense output is heyoka's own evaluation (propagate_grid) of the same steps' polynomials: the
    # positions to a few ulp of the evaluation, the velocities (heyoka's own polynomials, ours the positions'
    # derivative) to the 50 ulp above
    u = unit_roundoff(np.float64)
    assert np.abs(p - grid.solution.points).max() <= 16 * u * np.abs(p).max()
    assert np.abs(v - grid.solution.velocities).max() <= 50 * u * np.abs(v).max()
    assert grid.n_steps == m.n_steps
    # the velocity is the positions' derivative: against central differences of the dense positions
    h = 1e-4
    fd = (m.solution(ts[1:-1] + h)[0] - m.solution(ts[1:-1] - h)[0]) / (2 * h)
    assert np.abs(fd - v[1:-1]).max() <= 1e-7


def test_positions_need_a_state_of_positions_and_velocities():
    chain = Chain(4, 2.7)
    comp = compiled_constrained(ChainSystem(chain))
    with comp.integrator() as ta, pytest.raises(ValueError, match="positions = 5 needs a state"):
        taylor_advance(ta, 0.0, np.zeros(12), 1.0, np.zeros(len(ta.pars)), True, float, positions=5)


@pytest.mark.parametrize("fp_type", [float, np.longdouble], ids=["float64", "long double"])
@pytest.mark.parametrize("positions", [0, 1], ids=["full polynomials", "positions' polynomials"])
def test_every_step_keeps_its_own_coefficients(fp_type, positions):
    """The oscillator ``x' = v, v' = -x`` from ``(1, 0)``: the dense output of every step gives ``(cos t, -sin t)``,
    and agrees with heyoka's own continuous output of the same run.

    (Each step's coefficients are copied from the integrator's buffer, which heyoka fills in place: a copy of the
    wrong step, or of the last one for all, would miss by the step's length.)
    """
    x, v = hy.make_vars("x", "v")
    ta = hy.taylor_adaptive([(x, v), (v, -x)], np.array([1.0, 0.0]).astype(fp_type), fp_type=fp_type)
    y0 = np.array([1.0, 0.0]).astype(fp_type)
    adv = taylor_advance(ta, fp_type(0.0), y0, fp_type(10.0), np.zeros(0, dtype=fp_type), True, fp_type,
                         positions=positions)
    assert adv.n_steps >= 8  # steps of about 1: the picture changes from step to step
    ts = np.linspace(0.0, 10.0, 401)
    got = adv.dense(ts.astype(fp_type))
    eps = unit_roundoff(fp_type)
    np.testing.assert_allclose(got.astype(float), np.stack([np.cos(ts), -np.sin(ts)], axis=1), rtol=0, atol=1e-14)
    if fp_type is np.longdouble:  # closer than float64 can show: against mpmath's cos and sin at 30 digits
        import mpmath
        with mpmath.workdps(30):
            exact = [[mpmath.cos(mpmath.mpf(t)), -mpmath.sin(mpmath.mpf(t))] for t in ts[::20]]
            err = max(abs(mpmath.mpf(str(g)) - e) for g, e in zip(got[::20].ravel(), np.ravel(exact)))
        assert err < 1e3 * eps
    ta.state[:] = y0
    ta.time = fp_type(0.0)
    c_out = ta.propagate_until(fp_type(10.0), c_output=True)[4]  # c_out(t) is a view of a buffer it reuses: copied
    theirs = np.array([c_out(t).copy() for t in ts.astype(fp_type)])
    assert np.abs(got - theirs).max() < 100 * eps  # in the working precision
