"""Suspension charts for links of any lengths, ``L`` the dominant side (issue 10).

Independent routes: the chart against a 60-digit evaluation of the plain
``acos`` recursion, against the rod constraints (closure), against its own
inverse, against finite differences and heyoka's symbolic differentiation,
the length-parameter family against the unit-rod family at unit lengths, and
free motion in charts against free motion in hinge coordinates.  Hard regions:
``L`` within 1e-12 of both ends of its range ``(R - 2 mu, R)``, a very short
and a very long link, two nearly equal shortest links (the fold), poles.
"""

from __future__ import annotations

from fractions import Fraction

import mpmath
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from charts import SuspensionAtlas, SuspensionChart
from charts import suspension_formula as formula
from charts.chain_geometry import relabel_hinges, sphere_range, validate_sphere_chain
from charts.suspension_symbolic import SuspensionFamily
from linkage import Chain
from linkage.motion import free_motion
from linkage.time_factor import ChainTimeFactor
from manifold import Precision, SaveAt, compiled
from manifold.backends import NUMPY
from manifold.sundman import SundmanStepper

from .conftest import HALF_PI, DifferentiatedFamily, chart_parameters, parameter_rounding_floor, rod_orders

EPS = np.finfo(float).eps
EXAMPLE = (1.0, 2.0, 1.5, 2.5, 1.2)  # the tutorial's chain: a sphere S^3 with L dominant for 6.2 < L < 8.2


@st.composite
def sphere_chains(draw, n_min: int = 3, n_max: int = 6, ends: bool = True):
    """Lengths and ``L`` with a dominant side: moderate lengths, a very short and a very long link, or two
    nearly equal shortest links; the dominant side ``L`` (mostly) or a link, uniform in its range
    ``(R' - 2 mu', R')`` (``R'``, ``mu'``: sum and minimum of the other sides) or within 1e-12 .. 1e-3 of its
    width from an end (not with ``ends=False``)."""
    n = draw(st.integers(n_min, n_max))
    kind = draw(st.sampled_from(["moderate", "short-and-long", "near-equal"]))
    sides = [draw(st.floats(0.3, 3.0)) for _ in range(n)]  # the sides other than the dominant one
    if kind == "short-and-long":
        sides[0], sides[1] = draw(st.floats(0.03, 0.1)), draw(st.floats(3.0, 6.0))
    elif kind == "near-equal":
        m = draw(st.floats(0.2, 0.3))
        sides[0], sides[1] = m, m * (1 + draw(st.sampled_from([-1, 1])) * 10.0 ** draw(st.floats(-9, -2)))
    sides = list(np.array(sides)[np.array(draw(st.permutations(range(n))))])
    lo, hi = sphere_range(sides)
    where = draw(st.sampled_from(["uniform", "low", "high"] if ends else ["uniform"]))
    if where == "uniform":
        dominant = lo + (hi - lo) * draw(st.floats(1e-3, 1 - 1e-3))
    else:
        gap = (hi - lo) * 10.0 ** draw(st.floats(-12, -3))
        dominant = lo + gap if where == "low" else hi - gap
    j = draw(st.sampled_from([n] * 3 + list(range(n))))  # the dominant side: L, or the link l_{j+1}
    if j == n:
        ls, L = np.array(sides), dominant
    else:
        ls, L = np.array(sides[:j] + [dominant] + sides[j:-1]), sides[-1]
    try:
        validate_sphere_chain(ls, L)
    except ValueError:
        assume(False)
    return ls, float(L)


def cases(n_min: int = 3, n_max: int = 6, ends: bool = True):
    """A chain, chart parameters (poles and circle poles among them) and a rod order."""
    return sphere_chains(n_min, n_max, ends).flatmap(
        lambda c: st.tuples(st.just(c), chart_parameters(c[0].size), rod_orders(c[0].size)))


def chart_order(ls: np.ndarray, L: float, perm: np.ndarray) -> np.ndarray:
    """A rod order drawn as a permutation of ``0 .. n-1``, as a side order of the chain's chart: the sides other
    than the dominant one (``n`` standing for ``L``) in the order ``perm`` gives them."""
    base = validate_sphere_chain(ls, L)[2]
    sides = np.array([s for s in range(ls.size + 1) if s != base])
    return sides[perm]


def _wrap(x):
    return (x + np.pi) % (2 * np.pi) - np.pi


def chart_frame(chart: SuspensionChart) -> tuple[float, np.ndarray]:
    """The chart's base (the dominant side) and its links (the other sides, in chart order)."""
    sides = np.append(chart.lengths, chart.L)
    return float(sides[chart.base]), sides[chart.order]


def own_order(chart: SuspensionChart, q: np.ndarray) -> np.ndarray:
    """60-digit chart-frame hinges ``q`` (:func:`reference_hinges`) as the chain's hinges in its own order:
    turned back by the direction of the base side ``L`` where a link is the chart's base, then relabeled."""
    with mpmath.workdps(60):
        if chart.base != chart.n:
            k0 = int(np.flatnonzero(chart.order == chart.n)[0])
            D = mpmath.mpf(chart_frame(chart)[0])
            ends = [mpmath.mpc(0)] + list(q) + [D]
            F = ends[k0 + 1] - ends[k0]
            W = np.cumsum(chart.order == chart.n)
            q = [-mpmath.conj(F) / chart.L * (ends[k + 1] - int(W[k]) * (D + F)) for k in range(chart.n - 1)]
        return relabel_hinges(np.array([complex(h) for h in q]), chart.links, chart.L)


def closure_tolerance(ls: np.ndarray) -> np.ndarray:
    """``1e-13`` relative to each link, plus the floor of representing hinges of size ``R`` in float64
    (a link far shorter than the chain is a difference of two hinges, each rounded by ``eps R``)."""
    return 1e-13 * ls + 4 * EPS * ls.sum()


@given(cases(3, 8))
def test_every_link_keeps_its_length(case):
    (ls, L), a, order = case
    chart = SuspensionChart(ls, L, chart_order(ls, L, order))
    rods = np.abs(np.diff(np.concatenate([[0], chart.hinges(a), [L]])))
    assert np.all(np.abs(rods - ls) <= closure_tolerance(ls)), (rods - ls) / ls
    D, sides = chart_frame(chart)
    z = formula.hinges(list(a), D, NUMPY, rods=chart.rods)  # the numpy formula, in the chart's own frame and order
    rods = np.abs(np.diff([0] + [h.re + 1j * h.im for h in z] + [D]))
    assert np.all(np.abs(rods - sides) <= closure_tolerance(sides))


def reference_hinges(a, L, ls, digits: bool = False):
    """The chart by the plain recursion: ``alpha = acos(...)``, ``y = sqrt(l_1^2 - x^2)``; complex128, or the
    multi-digit values with ``digits``.

    Numerical trap: at a pole ``acos`` near 1 takes a square root of its argument's rounding, so nested
    poles halve the digits level by level (n = 7 with poles at three levels: 60 digits left the first
    hinge 2.7e-8 off).  The working precision doubles per level: ``20 * 2^len(a)`` digits.
    """
    with mpmath.workdps(20 * 2 ** len(a)):
        ls = [mpmath.mpf(float(x)) for x in ls]
        D, frame, outer, n = mpmath.mpf(float(L)), mpmath.mpc(1), [], len(ls)
        for k, phi in enumerate(a[:-1]):
            l, R = ls[n - k - 1], sum(ls[: n - k - 1])
            theta = mpmath.acos((D**2 + l**2 - R**2) / (2 * D * l)) * mpmath.sin(float(phi))
            p = D - l * mpmath.exp(1j * theta)
            outer.append(frame * p)
            frame, D = frame * p / abs(p), abs(p)
        t = mpmath.mpf(float(a[-1]))
        l1, l2, l3 = ls[:3]
        theta = mpmath.acos((D**2 + l3**2 - (l1 + l2) ** 2) / (2 * D * l3)) * mpmath.sin(t)
        p2 = D - l3 * mpmath.exp(1j * theta)
        d = abs(p2)
        x = (d**2 + l1**2 - l2**2) / (2 * d)
        y = mpmath.sign(mpmath.cos(t)) * mpmath.sqrt(max(l1**2 - x**2, 0))
        out = [frame * p2 * (x + 1j * y) / d, frame * p2] + outer[::-1]
        return out if digits else np.array([complex(h) for h in out])


@given(cases(3, 7))
@example(((np.array([1, 1, 1, 0.5, 2, 1, 2.0]), 8.0), np.array([-HALF_PI, 0, -HALF_PI, HALF_PI - 0.1, -1]),
          np.arange(7)))  # poles at three levels: CI's draw that 60 reference digits could not resolve
@example(((np.array([3.96875625, 1, 3.0]), 0.03125), np.array([0.0]), np.array([1, 2, 0])))  # CI's draw: a link
# base turned back by the side L 127x shorter than the chain, whose vector was 1 - c (cancelling): 3.9e-14
@settings(max_examples=40)
def test_the_chart_is_the_plain_recursion_to_rounding(case):
    """Against the textbook formulas in many digits: the carried slacks keep full accuracy where ``acos``
    in float64 would not (near both ends of the L range, near poles).  Near a fold of the first two links
    (two nearly equal shortest links, ``|p_2|`` small) the map itself amplifies the rounding of its inputs
    by ``R / |p_2|`` (the elbow direction ``p_2 / |p_2|``): measured ``<= 0.55 eps R (1 + R / |p_2|)``."""
    (ls, L), a, order = case
    chart = SuspensionChart(ls, L, chart_order(ls, L, order))
    D, sides = chart_frame(chart)
    R = sides.sum()
    digits = reference_hinges(a, D, sides, digits=True)
    ref = np.array([complex(h) for h in digits])
    got = formula.hinges(list(a), D, NUMPY, rods=chart.rods)
    got = np.array([h.re + 1j * h.im for h in got])
    tol = 4 * EPS * R * (1 + R / abs(ref[1]))
    assert np.abs(got - ref).max() <= tol
    # the compiled family, in the chain's own frame and order (turned back where a link is the base, relabeled)
    assert np.abs(chart.hinges(a) - own_order(chart, digits)).max() <= ls.size * tol


@given(cases(3, 7))
@example(((np.array([3.96875625, 1, 3.0]), 0.03125), np.array([0.0]), np.array([2, 0, 1])))  # a short first side
@example(((np.array([3.96875625, 1, 3.0]), 0.03125), np.array([0.0]), np.array([1, 2, 0])))  # a short second side
@settings(max_examples=40)
def test_link_vectors_are_accurate_relative_to_their_own_links(case):
    """Each link vector of :func:`chain_vectors` to ``6 eps l_k (1 + R / |p_2|)`` of the 60-digit one (measured
    ``<= 2.8`` over 3000 draws): a link base turns the chain by the pinned side's vector, so a short side that
    came out as a difference of ``O(R)`` numbers would turn every hinge by ``eps R / l`` (it did: 49x)."""
    (ls, L), a, order = case
    chart = SuspensionChart(ls, L, chart_order(ls, L, order))
    D, sides = chart_frame(chart)
    digits = reference_hinges(a, D, sides, digits=True)
    with mpmath.workdps(60):
        ends = [mpmath.mpc(0)] + list(digits) + [mpmath.mpf(D)]
        ref = np.array([complex(q - o) for o, q in zip(ends[:-1], ends[1:])])
    got = np.array([e.re + 1j * e.im for e in formula.chain_vectors(list(a), D, NUMPY, rods=chart.rods)[1]])
    assert np.all(np.abs(got - ref) <= 6 * EPS * sides * (1 + sides.sum() / abs(ref[0] + ref[1])))


@given(cases())
def test_inverse_round_trip_where_the_chart_is_good(case):
    (ls, L), a, order = case
    chart = SuspensionChart(ls, L, chart_order(ls, L, order))
    assume(chart.quality(a) >= 0.05)
    back = chart.get_parameters(chart.get_point(a))
    err = np.abs(_wrap(back - a))
    assert err.max() <= max(1e-12, parameter_rounding_floor(chart, a)), (err, a)


@given(cases())
@example(((np.array([1.5, 1.078125, 2.8475746663123274, 1, 1, 1]), 6.4256998663123275), np.array([0, 0, -HALF_PI, 0]),
          np.arange(6)))  # 2e-7 above the lower end: the inverse's polar asin lost 1.2e-12 of the equator's latitudes
@example(((np.array([1.00000002, 1.0, 1.0]), 1.0), np.array([1e-9]), np.arange(3)))  # 2e-8 above the lower end,
# |J| = 1.5e8: the polish's wrap of t rounded t = 1e-9 to a multiple of ulp(pi) and undid it (3.7e-11 off)
def test_point_round_trip_everywhere_including_poles(case):
    """``get_point(get_parameters(p)) = p`` on the singular set too (backward stability)."""
    (ls, L), a, order = case
    chart = SuspensionChart(ls, L, chart_order(ls, L, order))
    p = chart.get_point(a)
    assert np.abs(chart.get_point(chart.get_parameters(p)) - p).max() <= 1e-12 * ls.sum()


def test_the_parameter_clamp_wraps_t_and_keeps_a_small_one_exact():
    chart = SuspensionChart(np.array([1.0, 2.0, 1.5, 2.5]), 6.0)
    small = np.array([0.25, -0.5, 1e-9])
    assert np.array_equal(chart.clamp_parameters(small), small)  # no round trip through pi
    wrapped = chart.clamp_parameters(np.array([[2.0, 0.0, 4.0], [0.0, 0.0, -np.pi], [0.0, 0.0, np.pi]]))
    assert np.allclose(wrapped, [[HALF_PI, 0.0, 4.0 - 2 * np.pi], [0.0, 0.0, -np.pi], [0.0, 0.0, -np.pi]], atol=1e-15)


@given(cases(3, 6, ends=False))
@settings(max_examples=30)
def test_jacobian_and_inverse_derivative_match_finite_differences(case):
    """``J`` (from the jets) against central differences of the map, and the inverse's derivative along a
    tangent ``v = J c`` against ``c``."""
    (ls, L), a, order = case
    # drawn away from the ends of the sphere range (ends=False): there the map curves like 1 / sqrt(slack) and
    # differences of any step in the sweep miss J (L = 1.0002, unit rods: best 1.9e-2); the jets are checked at
    # the ends against symbolic derivatives (test_jets_agree_with_symbolic_differentiation)
    chart = SuspensionChart(ls, L, chart_order(ls, L, order))
    a = np.append(np.clip(a[:-1], -1.3, 1.3), a[-1])  # keep the stencil inside the chart
    J = chart.jacobian(a)
    scale = max(ls.sum(), np.abs(J).max())
    errs = []
    for h in 10.0 ** -np.arange(2, 8):
        cols = [(chart.get_point(a + h * e) - chart.get_point(a - h * e)) / (2 * h) for e in np.eye(chart.dim)]
        errs.append(np.abs(J - np.stack(cols, axis=-1)).max())
    assert min(errs) <= 1e-7 * scale  # a correct J agrees at some step of the sweep, a wrong one at none
    assume(chart.quality(a) >= 0.1)
    c = np.random.default_rng(0).normal(size=chart.dim)
    c /= np.abs(c).max()
    v, p = J @ c, chart.get_point(a)
    errs = []
    for h in 10.0 ** -np.arange(4, 8):  # p +- h v leaves the manifold by O(h^2): within its closure check
        try:
            da = _wrap(chart.get_parameters(p + h * v) - chart.get_parameters(p - h * v)) / (2 * h)
        except ValueError:  # the step left the manifold by more than the closure tolerance (a small sphere)
            continue
        errs.append(np.abs(da - c).max())
    assert errs and min(errs) <= 1e-5


#: Two nearly equal shortest links; with L near the lower end of (3.0000001, 3.5000001) the first two links of
#: some charts can fold back onto each other (q_A).
NEAR_EQUAL = (0.25, 0.2500001, 1.0, 2.0)


@pytest.mark.parametrize("ls, L", [((0.7, 1.9, 1.3, 2.2), 5.3), (NEAR_EQUAL, sphere_range(NEAR_EQUAL)[0] + 1e-9)])
def test_jets_agree_with_symbolic_differentiation(ls, L):
    """The geodesic acceleration and the velocity transfer: one forward sweep of jets against ``hy.diff_tensors``."""
    chain = Chain(ls, L, rod_densities=0.3)
    rng = np.random.default_rng(1)
    for chart in chain.atlas().charts:
        pars = chart.numerics(chain.ambient_metric, -2.0).pars
        jet, diff = compiled(SuspensionFamily(4, lengths=True)), compiled(DifferentiatedFamily(4, lengths=True))
        for _ in range(5):
            x = np.concatenate([[rng.uniform(-1.3, 1.3), rng.uniform(-np.pi, np.pi)], rng.normal(size=2)])
            y = np.concatenate([x, rng.normal(size=6)])
            for name, args in (("acceleration", x), ("transfer", y)):
                f, g = getattr(jet, name)(float), getattr(diff, name)(float)
                u, w = f(args, pars=pars[: f.nparams]), g(args, pars=pars[: g.nparams])
                assert np.abs(u - w).max() <= 1e-11 * max(1.0, np.abs(w).max())


class MpmathOps:
    """:mod:`charts.suspension_formula`'s backend on mpmath scalars: the same formula in many digits."""

    sin, cos, sqrt, atan2, sinc = (staticmethod(f) for f in (mpmath.sin, mpmath.cos, mpmath.sqrt, mpmath.atan2,
                                                               mpmath.sinc))
    abs, minimum = staticmethod(abs), staticmethod(min)

    @staticmethod
    def asin_clipped(x):
        return mpmath.asin(max(-1, min(1, x)))

    @staticmethod
    def where(cond, x, y):
        return x if cond else y

    @staticmethod
    def gt(x, y):
        return x > y

    @staticmethod
    def ge(x, y):
        return x >= y

    @staticmethod
    def one_minus_sin(x):
        return 1 - mpmath.sin(x)

    @staticmethod
    def one_plus_sin(x):
        return 1 + mpmath.sin(x)

    @staticmethod
    def ratio_or_zero(a, b):
        return 0 if b == 0 else a / b


def fold_jacobian(a, L: float, n: int) -> np.ndarray:
    """``dz / da`` of the unit-rod chart by central differences of the formula in 60 digits (step 1e-25:
    truncation ``h^2 |z_aaa| ~ 1e-50 / |p_2|^2``, rounding ``1e-60 / h``, both far below float64 here)."""
    with mpmath.workdps(60):
        h, rods = mpmath.mpf("1e-25"), formula.Rods([mpmath.mpf(1)] * n, MpmathOps)

        def z(b):
            return [c for q in formula.hinges(b, mpmath.mpf(L), MpmathOps, rods=rods) for c in (q.re, q.im)]

        a = [mpmath.mpf(float(x)) for x in a]
        cols = []
        for j in range(len(a)):
            up, dn = z([x + h * (i == j) for i, x in enumerate(a)]), z([x - h * (i == j) for i, x in enumerate(a)])
            cols.append([float((u - d) / (2 * h)) for u, d in zip(up, dn)])
    return np.array(cols).T


@given(st.integers(3, 6), st.sampled_from([1e-12, 1e-9, 1e-6]), st.floats(-13, -1),
       st.sampled_from([-1.0, 1.0]), st.sampled_from([0.0, np.pi]))
@example(4, 1e-12, np.log10(1.67839375e-06), 1.0, 0.0)  # CI's draw: the families 1.4e-10 apart at |p_2| = 5.3e-6
@settings(max_examples=30)
def test_both_families_near_the_fold_are_the_sixty_digit_jacobian_to_its_conditioning(n, gap, e, sign, t0):
    """The unit and the general family against :func:`fold_jacobian` where the circle level's first two links
    fold (``L = n - 2 + gap``, every latitude 0, ``t`` within ``10^e`` of 0 or ``pi``): each within
    ``max(1, |J|) (1e-13 + 8 eps R / |p_2|)``, the bound that holds them to each other below."""
    L = n - 2 + gap
    a = np.append(np.zeros(n - 3), t0 + sign * 10.0**e)
    ref = fold_jacobian(a, L, n)
    theta = np.array([L, *np.ones(n), *formula.top_slacks(np.ones(n), L)])
    for family, pars in ((SuspensionFamily(n), [L]), (SuspensionFamily(n, lengths=True), theta)):
        z, J = compiled(family).evaluate_jacobian(pars, np.array([a] * 8))  # 8 rows: the SIMD path too
        tol = max(1.0, np.abs(ref).max()) * (1e-13 + 8 * EPS * n / np.hypot(z[:, 2], z[:, 3]))
        assert np.all(np.abs(J - ref).max(axis=(1, 2)) <= tol), family


@given(st.integers(3, 8), st.data())
@settings(max_examples=20)
def test_unit_lengths_as_parameters_reproduce_the_unit_family(n, data):
    """The family with lengths as runtime parameters, at ``l_k = 1``, against the unit-rod family (whose
    lengths are exact integers in the expressions): the same map, Jacobian, quality and inverse.

    Near a fold of the first two links (``L`` near ``n - 2``, ``t`` near 0 or ``pi``: ``|p_2|`` small) the
    Jacobian is a sum of terms of size ``1 / |p_2|`` (the elbow direction ``p_2 / |p_2|`` turning) that cancel
    to ``O(1)``, so both families carry ``eps R / |p_2|`` of rounding there.  Measured against 60 digits of the
    same formula (:func:`fold_jacobian`): at ``L = 2 + 1e-12``, ``t = 1.7e-6`` the unit family is
    8.7e-12 off, the general one 7.5e-11.  Over 86,000 rows (n = 3..8, ``L`` at both ends and inside the range,
    ``t`` within 1e-13 .. 3 of 0, ``pi/2`` and ``pi``) ``|J_1 - J_2|`` stayed within
    ``2 max(1, |J|) (1e-13 + eps R / |p_2|)`` per row of ``J``; the bound allows 8 eps."""
    L = data.draw(st.sampled_from([n - 2 + 1e-12, n - 2 + 1e-6, n - 1.3, n - 1e-6, n - 1e-12]))
    a = np.array([data.draw(chart_parameters(n)) for _ in range(8)])
    unit, general = compiled(SuspensionFamily(n)), compiled(SuspensionFamily(n, lengths=True))
    theta = np.array([L, *np.ones(n), *formula.top_slacks(np.ones(n), L)])
    assert np.array_equal(theta[-2:], [n - L, L - (n - 2)])  # the exact slacks of unit rods
    z1, J1 = unit.evaluate_jacobian([L], a)
    z2, J2 = general.evaluate_jacobian(theta, a)
    assert np.abs(z1 - z2).max() <= 1e-15 * L
    good = np.all(np.abs(a[:, :-1]) < 1.5, axis=1)  # off the poles, where J is finite
    fold = n / np.hypot(z1[:, 2], z1[:, 3])  # R / |p_2|: the circle level's elbow amplifies rounding
    tol = np.maximum(1.0, np.abs(J1).max(axis=(1, 2))) * (1e-13 + 8 * EPS * fold)
    assert np.all((np.abs(J1 - J2).max(axis=(1, 2)) <= tol)[good])
    assert np.abs(unit.evaluate_quality([L], a) - general.evaluate_quality(theta, a)).max() <= 1e-15
    b1, q1 = unit.evaluate_inverse([L], z1)
    b2, q2 = general.evaluate_inverse(theta, z1)
    assert np.abs(_wrap(b1 - b2))[good].max(initial=0) <= 1e-12 and np.abs(q1 - q2)[good].max(initial=0) <= 1e-12


#: A sphere whose dominant side is the link l_4 = 3.5: for 0.5 < L < 2.5 (the sides (1, 1, 1, L) sum to more
#: than 3.5 and, less twice their shortest, to less).
LINK_DOMINANT = (1.0, 1.0, 1.0, 3.5)


@pytest.mark.parametrize("ls, lo, hi", [(EXAMPLE, 6.2, 8.2), ((0.05, 1.0, 2.0, 3.0, 1.5, 0.7), 8.15, 8.25),
                                        (NEAR_EQUAL, *sphere_range(NEAR_EQUAL)), ((3.0, 1, 1, 1, 1), 5.0, 7.0),
                                        (LINK_DOMINANT, 0.5, 2.5)])
@pytest.mark.parametrize("where", [1e-12, 1e-6, 0.5, 1 - 1e-6, 1 - 1e-12])
def test_best_chart_is_well_conditioned(ls, lo, hi, where):
    """Folds, folded triples, poles and random points: the best chart keeps ``1/cond(J)`` bounded and its
    quality above the measured floor for these lengths (``docs/atlas_quality.md``)."""
    ls = np.array(ls, dtype=float)
    L = lo + (hi - lo) * where
    atlas = SuspensionAtlas(ls, L)
    rng = np.random.default_rng(ls.size)
    n = ls.size
    params = [np.append(np.zeros(n - 3), t) for t in (0.0, np.pi, HALF_PI, -HALF_PI)]  # folds, folded triples
    params += [np.append(np.full(n - 3, HALF_PI), t) for t in (0.3, 2.0)]  # every latitude at a pole
    params += [np.append(rng.uniform(-1.5, 1.5, n - 3), rng.uniform(-np.pi, np.pi)) for _ in range(8)]
    for order in (np.arange(n), rng.permutation(n)):
        chart = SuspensionChart(ls, L, chart_order(ls, L, order))
        for a in params:
            p = chart.get_point(a)
            i, a_best, q = atlas.chart_choice(p)
            s = np.linalg.svd(atlas.charts[i].jacobian(a_best), compute_uv=False)
            assert q >= 0.45, (order, a, i, q)
            assert s[-1] / s[0] >= 0.05, (order, a, i, s)


def test_the_charts_decide_the_sphere_range_exactly():
    """``R - 2 mu < L < R`` in rationals: float sums of the lengths would misjudge an ``L`` a rounding away.

    ``(0.1, 0.2, 0.3, 0.4)`` sum to 1.0 in float64 but to ``1 + 2.8e-17`` exactly, so ``L = 1.0`` lies
    inside (a sphere of radius ~1e-8, whose charts still close); the lower end ``R - 0.2`` is
    ``0.8 - 2.8e-17``, so ``L = 0.8`` lies inside too.
    """
    ls = (0.1, 0.2, 0.3, 0.4)
    R = sum(Fraction(x) for x in ls)
    assert sum(ls) == 1.0 < R and Fraction(0.8) > R - 2 * Fraction(0.1)
    for L, inside in [(1.0, True), (np.nextafter(1.0, 2), False), (0.8, True), (np.nextafter(0.8, 0), False)]:
        if inside:
            atlas = SuspensionAtlas(ls, float(L))
            p = atlas.get_point(1, np.array([0.4, 1.0]))
            z = np.concatenate([[0], Chain(ls, float(L)).from_point(p), [L]])
            assert np.all(np.abs(np.abs(np.diff(z)) - ls) <= closure_tolerance(np.array(ls)))
        else:
            with pytest.raises(ValueError, match="dominant side"):
                SuspensionAtlas(ls, float(L))


@pytest.mark.parametrize("gap, inside", [(0.0, False), (1e-13, False), (1e-10, True)])
def test_a_chain_has_an_atlas_where_its_topology_is_a_sphere_with_L_dominant(gap, inside):
    """``Chain.has_atlas`` follows ``topology()``: an ``L`` within ``RTOL * P`` of an end is that end (the
    lengths of EXAMPLE sum to 8.2 in float64 but to ``8.2 + 5.6e-17`` exactly: ``L = 8.2`` means stretched)."""
    for L, end in ((8.2 - gap * 16.4, "point"), (6.2 + gap * 16.4, "singular")):
        chain = Chain(EXAMPLE, L)
        assert chain.topology().kind == ("sphere" if inside else end) and chain.has_atlas == inside
        if inside:
            assert chain.topology().dominant_side == 5 and len(chain.atlas()) == 5
        else:
            with pytest.raises(ValueError, match=rf"only where the configuration space is a sphere.*the base L for "
                                                 rf"6.2 < L < 8.2.*{end}.*method='hinges'"):
                chain.atlas()


@pytest.mark.parametrize("lengths, L", [((1.0, 2.0), 2.9999), ((1.0, 2.0), 1.0001), ((0.5, 0.7), 0.4)])
def test_two_links_are_the_two_elbows(lengths, L):
    chain = Chain(lengths, L)
    atlas = chain.atlas()
    ends = []
    for chart, sheet in zip(atlas.charts, (1, -1)):
        (p1,) = chart.hinges(np.zeros(0))
        assert abs(abs(p1) - lengths[0]) <= 4 * EPS and abs(abs(L - p1) - lengths[1]) <= 4 * EPS
        assert np.sign(p1.imag) == sheet
        ends.append(p1)
    assert ends[0] == np.conj(ends[1])


@pytest.mark.parametrize("lengths, L, match", [
    ((1.0, -2.0, 1.0), 1.0, "finite numbers > 0"),
    ((1.0, np.inf, 1.0), 1.0, "finite numbers > 0"),
    ((1.0, 2.0, 1.5, 2.5, 1.2), 3.0, r"6.2 < L < 8.2 .*dominant side.*got L = 3.0"),
    ((1.0, 2.0, 1.5, 2.5, 1.2), 8.3, r"6.2 < L < 8.2"),
    ((1.0, 2.0, 1.5, 2.5, 1.2), "7", r"6.2 < L < 8.2 .*got L = '7'"),
])
def test_bad_chains_are_refused_by_the_charts(lengths, L, match):
    for make in (lambda: SuspensionChart(lengths, L), lambda: SuspensionAtlas(lengths, L)):
        with pytest.raises(ValueError, match=match):
            make()


def pole_start(chain: Chain, chart: int, seed: int):
    """A unit-speed start exactly at a pole of ``chart`` (its first three links of order in one line)."""
    rng = np.random.default_rng(seed)
    atlas = chain.atlas()
    a = np.append(rng.uniform(-1.2, 1.2, chain.n - 3), rng.uniform(-np.pi, np.pi))
    a[-2] = HALF_PI  # phi_4: the chart's first three links stretched
    p0 = atlas.get_point(chart, a)
    assert atlas.charts[chart].quality(atlas.get_parameters(chart, p0)) < 1e-6
    i, b = atlas.best_chart(p0)
    v0 = chain.from_point(atlas.charts[i].tangent_vector(b, rng.normal(size=chain.n - 2)))
    return chain.from_point(p0), v0 / np.sqrt(2 * chain.kinetic_energy(v0))


#: (lengths, L, masses, velocity tolerance against the long-double hinge method).  Within 1e-3 of an end of
#: the range the hinge method's multiplier system is nearly singular and its own error sets the tolerance: at
#: L = 0.501 for LINK_DOMINANT the long-double hinges were 2.2e-10 off in the velocities, where the float64
#: charts agreed with real128 hinges to 2.2e-11 (``test_near_an_end_the_charts_match_real128_hinges``).
MOTIONS = [
    (EXAMPLE, 7.0, {}, 1e-10),
    (EXAMPLE, 6.2 + 1e-9, {}, 1e-10),  # near the lower end: folds and folded triples
    (EXAMPLE, 8.2 - 1e-3, {"hinge_masses": [1.0, 2.0, 0.5, 1.5], "rod_densities": 0.3}, 1e-9),  # near the upper end
    ((0.05, 1.0, 2.0, 0.7), 3.7, {}, 1e-10),  # a very short link
    (NEAR_EQUAL, sphere_range(NEAR_EQUAL)[0] + 1e-6, {"rod_densities": [0.0, 1.0, 0.2, 0.5]}, 1e-9),  # near the fold
    (LINK_DOMINANT, 1.3, {}, 1e-10),  # the link l_4 is the charts' base
    (LINK_DOMINANT, 0.5 + 1e-3, {"hinge_masses": [1.0, 0.5, 2.0]}, 1e-9),  # l_4 nearly stretched against the rest
]


@pytest.mark.parametrize("lengths, L, masses, velocity_tol", MOTIONS)
def test_charts_and_hinges_agree_through_the_poles_of_every_chart(lengths, L, masses, velocity_tol):
    """Free motion from an exact pole of each chart in turn, for T = 10: the chart method (float64, switching
    at events) and the hinge method (no chart) follow the same geodesic, and the chart method keeps the
    energy across every switch.

    The hinge method runs in long double (at ``tol = 1e-17``: it is the reference, and near the upper end
    its energy error, 1.5e-14, just exceeds its own bound at the default ``tol``): in float64 it loses
    accuracy near the ends of the range, where its multiplier system is nearly singular (at L = R - 1e-3
    it failed its own energy check, 3.5e-11 .. 2.3e-10, and was 7.6e-10 off in the hinges, while the chart
    method kept the energy to 1.8e-14 and agreed with the long-double hinges to 6e-14).  Near the lower end
    a tip (the shortest link reversed, the rest stretched) is a point of high curvature in any coordinates
    (``docs/atlas_quality.md``): the energy error reached 2.4e-12 at 1e-6 from the end."""
    chain = Chain(lengths, L, **masses)
    assert chain.has_atlas
    T, ts = 10.0, np.linspace(0, 10.0, 41)
    switches = 0
    for s in range(chain.n):
        h0, v0 = pole_start(chain, s, seed=s)
        charts = free_motion(chain, h0, v0, T, method="charts", save=SaveAt(t_eval=ts))
        hinges = free_motion(chain, h0, v0, T, method="hinges", save=SaveAt(t_eval=ts),
                             precision=Precision(fp_type=np.longdouble, tol=1e-17), compact_mode=True)
        assert charts.success and hinges.success
        assert np.abs(charts.hinges - hinges.hinges).max() <= 1e-10
        assert np.abs(charts.velocities - hinges.velocities).max() <= velocity_tol
        E0 = chain.kinetic_energy(v0)
        assert charts.relative_energy_error <= 1e-11
        assert np.abs(charts.energies - E0).max() <= 1e-11 * E0  # at t_eval, across the switches
        assert max((sw.point_gap for sw in charts.solution.switches), default=0.0) <= 1e-14 * sum(lengths)
        assert np.all(np.abs(np.abs(chain.rods(charts.hinges)) - chain.lengths) <= closure_tolerance(chain.lengths))
        switches += charts.n_switches
    assert switches >= 1  # the motions cross from chart to chart (each starts on a chart's pole)


def test_near_an_end_the_charts_match_real128_hinges():
    """1e-3 from an end of the range, from a pole, through 2 switches: float64 charts against real128 hinges
    (the long-double hinges are 2.2e-10 off here).  In the state ``(a, c)``: measured 6.7e-14 in the hinges,
    3.2e-12 in the velocities.  The default state ``(a, J c)`` takes the multiplier system's conditioning near
    the end: 1.2e-12 and 4.9e-11 (undamped 5.9e-13 and 3.8e-11; ``docs/methods.md``, "Where the state
    ``(a, J c)`` is less accurate")."""
    chain = Chain(LINK_DOMINANT, 0.5 + 1e-3, hinge_masses=[1.0, 0.5, 2.0])
    ts = np.linspace(0, 10.0, 41)
    h0, v0 = pole_start(chain, 3, seed=3)
    hinges = free_motion(chain, h0, v0, 10.0, method="hinges", save=SaveAt(t_eval=ts),
                         precision=Precision(fp_type="real128"), compact_mode=True,
                         throw=False)  # its energy error 2.4e-28 just exceeds its (real128) bound: see the test's doc
    assert float(hinges.solution.t_reached) == 10.0
    embedded = SundmanStepper(ChainTimeFactor(chain))
    for stepper, bound in ((None, 3e-12), (embedded, 3e-13)):
        charts = free_motion(chain, h0, v0, 10.0, method="charts", save=SaveAt(t_eval=ts), stepper=stepper)
        assert charts.n_switches >= 1
        assert np.abs(charts.hinges - hinges.hinges).max() <= bound
        assert np.abs(charts.velocities - hinges.velocities).max() <= 1e-10
    assert hinges.relative_energy_error <= 1e-27


def test_energy_is_kept_across_many_switches():
    """q_out = 0.5 (below the measured worst best-chart quality 0.70 of this chain) switches often: the
    energy and the point are kept across each switch, and switching does not chatter."""
    chain = Chain(EXAMPLE, 6.9, rod_densities=0.2)
    h0, v0 = pole_start(chain, 0, seed=3)
    m = free_motion(chain, h0, 3 * v0, 400.0, method="charts", save=SaveAt(dense=False), q_out=0.5)
    assert m.n_switches >= 100
    assert m.relative_energy_error <= 1e-12
    assert max(s.point_gap for s in m.solution.switches) <= 1e-14 * chain.lengths.sum()
    times = np.array([s.time for s in m.solution.switches])
    assert np.all(np.diff(times) > 1e-3), "chattering: two switches in a row"
