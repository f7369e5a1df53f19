"""A link far shorter than the chain: what the samplers return, the solvers accept, to what rounding allows.

A 6e-9 link between hinges at distance ~6 from the pin rounds, in float64, to
about 1e-7 of its own length (``u R / l_k``): :meth:`DiagonalSpace.sample`
returns such configurations, and a closure check of 1e-9 relative to each rod
can never pass them.  Each constraint is judged against its own rounding
floor (``Chain.rounding_floors``, ``ConstrainedSystem.rounding_scales``),
and the solves still check energy and closure: here against numbers recomputed
from the returned states, not read from the solver.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from linkage import Chain
from linkage.chain import ConfigurationError
from linkage.constraints import ChainSystem, HingeConstraints
from linkage.motion import free_motion
from manifold.constrained import solve_constrained

TINY = 6e-9


def rigid_short_link_velocity(chain: Chain, hinges: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A tangent velocity whose short link does not turn at the start (its two ends move alike): a random one
    turns it at ~1e8 rad/s, a stiff motion that no solver follows far (and that they rightly refuse)."""
    k = int(np.argmin(chain.lengths))  # rod k joins hinges k - 1 and k (0-based), both interior here
    G = HingeConstraints(chain).jacobian(chain.to_point(hinges))
    same = np.zeros((2, G.shape[1]))
    same[0, 2 * k], same[1, 2 * k + 1], same[0, 2 * k - 2], same[1, 2 * k - 1] = 1, 1, -1, -1
    basis = scipy.linalg.null_space(np.vstack([G, same]))
    v = basis @ rng.standard_normal(basis.shape[1])
    return chain.from_point(v / np.sqrt(2 * chain.kinetic_energy(chain.from_point(v))))  # unit energy


def check_honest(chain: Chain, motion, h0: np.ndarray, v0: np.ndarray) -> None:
    """Start kept, energy and every rod's length as recomputed from the returned states."""
    start, _ = motion(0.0)
    # moved by no more than rounding: the projection onto c = 0 is a rounding-level correction
    assert np.max(np.abs(start - h0)) <= 64 * np.finfo(float).eps * np.sum(chain.lengths)
    E0 = chain.kinetic_energy(v0)
    E = chain.kinetic_energy(motion.velocities)
    assert np.max(np.abs(E - E0)) / E0 <= 1e-11
    rods = np.abs(np.diff(np.concatenate([np.zeros((len(E), 1)), motion.hinges,
                                          np.full((len(E), 1), chain.L)], axis=1), axis=1))
    # every rod's length to rounding of the chain's size, the short one included (1e-15 absolute: 2e-7 of it)
    assert np.max(np.abs(rods - chain.lengths)) <= 64 * np.finfo(float).eps * np.sum(chain.lengths)


@pytest.mark.parametrize("lengths, L, methods, T", [
    # no atlas (a torus-like space): hinge coordinates only
    ((1.3, 0.7, 1.0, TINY, 1.1, 0.9, 1.2), 4.9, ("hinges",), 1e-3),
    # within 2 TINY of stretched: the sphere of the suspension atlas, both methods (a short run: its diameter is 1e-4)
    ((1.0, 1.0, 1.0, TINY, 1.0, 1.0, 1.0), 6.0 - 3e-9, ("hinges", "charts"), 1e-6),
])
def test_sampled_short_link_configurations_are_accepted(lengths, L, methods, T) -> None:
    chain = Chain(np.array(lengths), L)
    assert chain.has_atlas == ("charts" in methods)
    rng = np.random.default_rng(5)
    hinges = chain.diagonal_space().sample(4, rng).hinges
    # the samples are as exact as float64 allows, and some beyond the common 1e-9 (why this test exists)
    assert np.max(chain.closure_residual(hinges)) > 1e-9
    assert np.all(chain.closure_residual(hinges) <= 4 * chain.rounding_floors.max())
    for h0 in hinges:
        v0 = rigid_short_link_velocity(chain, h0, rng)
        for method in methods:
            motion = free_motion(chain, h0, v0, T, method=method)
            assert motion.success, (method, motion.solution.message)
            check_honest(chain, motion, h0, v0)


def test_short_link_that_does_not_close_is_refused() -> None:
    """The floor is rounding's, not a blanket: the short link 1e-3 too long is still refused, by the chain's check
    and by the constrained solver's own start check."""
    chain = Chain(np.array((1.3, 0.7, 1.0, TINY, 1.1, 0.9, 1.2)), 4.9)
    h0 = chain.diagonal_space().sample(1, np.random.default_rng(1)).hinges[0]
    bad = h0.copy()
    bad[3:] += (h0[3] - h0[2]) * 1e-3  # rod 4 (hinges 2 -> 3) longer by 1e-3 of itself; the last rod takes 5e-12
    assert chain.closure_residual(bad) == pytest.approx(1e-3, rel=1e-3)
    with pytest.raises(ConfigurationError, match="does not close"):
        free_motion(chain, bad, np.zeros(6, dtype=complex), 1.0, method="hinges")
    system, v0 = ChainSystem(chain), np.zeros(12)
    with pytest.raises(ValueError, match=r"x0 is not on the constraint manifold: \|c_3\(x0\)\| = 0.002"):
        solve_constrained(system, chain.to_point(bad), v0, 1.0)
    sol = solve_constrained(system, chain.to_point(h0), v0, 1.0)  # at rest: stays
    assert np.max(np.abs(sol(1.0)[0] - chain.to_point(h0))) <= 64 * np.finfo(float).eps * np.sum(chain.lengths)


def test_a_whipping_short_link_is_refused_in_float64_with_its_remedy_which_holds_it() -> None:
    """A random velocity whips a link of 1e-6 round at ~1e6 rad/s.  Hinge coordinates hold its direction to about
    ``u R / l``: the float64 run fails its energy check, and the message names the short link (2.4e-7 of the total
    length 4.200001) and the remedy, the next wider type at the same tolerance; that type passes, and its short
    link's angle at the end is that of a real128 run at tolerance 1e-25 to 1e-9."""
    import mpmath

    from benchmarks.short_links import start
    from manifold import Precision, SaveAt
    from manifold.precision import wider_types
    from manifold.solution import SolveStatus

    chain = Chain(np.array([1.0, 1.3, 1e-6, 0.8, 1.1]), 2.5)
    wider = wider_types(float)[0]  # long double where it is wider than float64 (x86), else real128
    h0, v0 = start(chain, 0)
    run = {name: free_motion(chain, h0, v0, 2e-5, method="hinges", throw=False, save=SaveAt(dense=False),
                             precision=precision)
           for name, precision in (("float64", Precision()), ("wider", Precision(wider, 2.22e-16)),
                                   ("reference", Precision("real128", 1e-25)))}
    failed = run["float64"].solution
    assert failed.status is SolveStatus.ENERGY_CHECK_FAILED
    assert "the chain's shortest link is 2.4e-07 of its total length" in failed.message
    assert f"precision=Precision('{wider}', 2.22e-16)" in failed.message
    assert run["wider"].solution.message == "reached t_final" and run["reference"].success  # no hint on success
    with mpmath.workprec(128):
        ends = {name: [mpmath.mpf(str(u)) for u in run[name].solution.end_state()[0]] for name in run}
        short = {name: mpmath.mpc(e[4] - e[2], e[5] - e[3]) for name, e in ends.items()}  # hinge 2 to hinge 3
        assert abs(short["wider"] - short["reference"]) / 1e-6 <= 1e-9


@pytest.mark.parametrize("lengths, fp_type, remedy, names", [
    ([1.0, 1.3, 0.01, 0.8, 1.1], "float64", True, None),  # 2.4e-3 of the total: not short
    ([1.0, 1.3, 1e-6, 0.8, 1.1], "longdouble", True, "real128"),
    ([1.0, 1.3, 1e-6, 0.8, 1.1], "real128", True, ""),  # nothing wider to name
    ([1.0, 1.3, 1e-6, 0.8, 1.1], "float64", False, ""),  # a solver that runs in float64 only (Lyapunov)
    ([1.0, 1.3, 1e-8, 0.8, 1.1], "float64", True, "real128"),  # 2.4e-9: long double failed some whips too
])
def test_the_short_link_hint_names_a_type_that_can_help(lengths, fp_type, remedy, names) -> None:
    from manifold.precision import resolve_fp_type

    hint = ChainSystem(Chain(np.array(lengths), 2.5)).rounding_hint(resolve_fp_type(fp_type), 1e-15, remedy)
    if names is None:
        assert hint is None
    else:
        assert "shortest link" in hint
        assert (f"Precision('{names}', 1e-15)" in hint) if names else ("Precision(" not in hint)
