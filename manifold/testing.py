"""A conformance suite that every chart family, atlas and constrained system runs.

In the manner of ManifoldsBase.jl's shared test suite: one set of checks,
written once against the public interfaces, that a new manifold passes before
anything else is trusted on it.  Each function takes the object and sample
points (choosing them, toward the hard regions, is the caller's business),
runs its checks and returns a :class:`ConformanceReport`; ``report.raise_on_failure()``
turns it into one assertion for a test.

* :func:`check_atlas` (an :class:`~manifold.metric.InducedMetric` on an atlas):
  point round trips through every chart of sufficient quality, the Jacobian
  against central differences, tangent-vector round trips, the metric
  symmetric and positive definite, transition maps and their differentials
  (the same point, the same embedded vector, the same kinetic energy).
* :func:`check_geodesic_energy`: a geodesic solved through the atlas keeps its
  energy across its chart switches (and does switch).
* :func:`check_constrained` (a :class:`~manifold.constrained.ConstrainedSystem`):
  the samples lie on ``c = 0``, ``G v`` against central differences of ``c``, the
  metric symmetric and positive definite, a geodesic's energy, and parallel
  transport an isometry (:mod:`manifold.transport`).

Bounds are relative and chosen for float64 at points of chart quality at least
``min_quality``; each check reports its worst value beside its bound.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .carried import solve_carried
from .constrained import ConstrainedGeometry, ConstrainedSystem, solve_constrained
from .geodesic_solver import solve_chart_exp_ode
from .metric import InducedMetric
from .solution import energy_bound
from .steppers import taylor_relative_tolerance
from .transport import ParallelTransport
from .validation import check_real, real_array

__all__ = ["Check", "ConformanceReport", "check_atlas", "check_constrained", "check_geodesic_energy"]


@dataclass(frozen=True)
class Check:
    """One check: its ``name``, the ``worst`` value found (a relative error) and the ``bound`` it must not exceed."""

    name: str
    worst: float
    bound: float

    @property
    def passed(self) -> bool:
        """``worst <= bound`` (NaN fails)."""
        return bool(self.worst <= self.bound)


@dataclass
class ConformanceReport:
    """The checks run on one subject, in order."""

    subject: str
    checks: list[Check] = field(default_factory=list)

    def add(self, name: str, values: ArrayLike, bound: float) -> None:
        """Record a check: the largest of ``values`` (NaN if any is NaN; 0 if there are none) against ``bound``."""
        v = np.asarray(values, dtype=float).ravel()
        worst = float("nan") if np.any(np.isnan(v)) else float(np.max(v, initial=0.0))
        self.checks.append(Check(name, worst, bound))

    @property
    def ok(self) -> bool:
        """True if every check passed."""
        return all(c.passed for c in self.checks)

    def __repr__(self) -> str:
        rows = [f"{'ok ' if c.passed else 'FAIL'} {c.name}: {c.worst:.2e} (bound {c.bound:.0e})" for c in self.checks]
        return f"ConformanceReport({self.subject}: {sum(c.passed for c in self.checks)}/{len(self.checks)} passed)\n  " \
            + "\n  ".join(rows)

    def raise_on_failure(self) -> None:
        """``AssertionError`` naming every failed check, if any."""
        if not self.ok:
            raise AssertionError(repr(self))


def _relative(a: NDArray, b: NDArray, scale: Any) -> NDArray:
    return np.linalg.norm(np.asarray(a) - np.asarray(b), axis=-1) / np.maximum(scale, np.finfo(float).tiny)


def check_atlas(metric: InducedMetric, points: ArrayLike, *, min_quality: float = 0.3, step: float = 1e-6,
                rng: np.random.Generator | None = None) -> ConformanceReport:
    """The chart and atlas checks at ``points`` (shape ``(m, N)``), in every chart of quality at least ``min_quality``.

    Parameters
    ----------
    metric
        The induced metric on the atlas under test.
    points
        Points of the manifold, shape ``(m, N)``.
    min_quality
        Charts below this quality at a point are not checked there (they may be near their singular set).
    step
        The step of the central differences (relative to the parameters' scale 1).
    rng
        Random coefficients of tangent vectors (default ``numpy.random.default_rng(0)``).
    """
    min_quality = check_real("min_quality", min_quality, positive=True, at_most=1.0)
    step = check_real("step", step, positive=True)
    rng = np.random.default_rng(0) if rng is None else rng
    atlas = metric.atlas
    P = real_array("points", points)
    if P.ndim != 2 or P.shape[1] != atlas.ambient_dim:
        raise ValueError(f"points must have shape (m, {atlas.ambient_dim}), got {P.shape}")
    report = ConformanceReport(f"atlas of {len(atlas)} charts, dim {atlas.dim} in R^{atlas.ambient_dim}")
    trips, jac, coeff, sym, pos, moved, vec, energy = ([] for _ in range(8))
    quality = atlas.qualities(P)
    for p, q in zip(P, quality):
        scale = max(1.0, float(np.linalg.norm(p)))
        good = [i for i in range(len(atlas)) if q[i] >= min_quality]
        params = {i: atlas.get_parameters(i, p) for i in good}
        for i, a in params.items():
            chart = atlas.charts[i]
            trips.append(_relative(atlas.get_point(i, a), p, scale))
            J = chart.jacobian(a)
            fd = np.stack([(chart.get_point(a + step * e) - chart.get_point(a - step * e)) / (2 * step)
                           for e in np.eye(atlas.dim)], axis=-1)
            jac.append(np.linalg.norm(J - fd) / np.linalg.norm(J))
            c = rng.standard_normal(atlas.dim)
            coeff.append(_relative(chart.coefficients(a, chart.tangent_vector(a, c)), c, np.linalg.norm(c)))
            g = metric.local_metric(i, a)
            sym.append(np.linalg.norm(g - g.T) / np.linalg.norm(g))
            pos.append(max(0.0, -float(np.linalg.eigvalsh(g)[0])) / np.linalg.norm(g))
            for j in good:
                if j == i:
                    continue
                b = atlas.transition_map(i, j, a)
                moved.append(_relative(atlas.get_point(j, b), p, scale))
                cj = atlas.transition_map_diff(i, a, c, j)
                v = chart.tangent_vector(a, c)
                vec.append(_relative(atlas.charts[j].tangent_vector(b, cj), v, np.linalg.norm(v)))
                e_i, e_j = metric.kinetic_energy(i, a, c), metric.kinetic_energy(j, b, cj)
                energy.append(abs(e_j - e_i) / e_i)
    report.add("point round trip get_point(get_parameters(p)) = p", trips, 1e-11)
    report.add("Jacobian against central differences", jac, 1e-6)
    report.add("tangent round trip coefficients(tangent_vector(c)) = c", coeff, 1e-9)
    report.add("metric symmetric", sym, 1e-14)
    report.add("metric positive definite (negative part of the smallest eigenvalue)", pos, 0.0)
    report.add("transition maps: the same point", moved, 1e-11)
    report.add("transition differentials: the same embedded vector", vec, 1e-9)
    report.add("transition differentials: the same kinetic energy", energy, 1e-9)
    return report


def check_geodesic_energy(metric: InducedMetric, p0: ArrayLike, v0: ArrayLike, t_final: float, *,
                          bound: float = 1e-12, min_switches: int = 1, **options: Any) -> ConformanceReport:
    """A geodesic through the atlas keeps its energy to ``bound`` across at least ``min_switches`` chart switches.

    ``options`` go to :func:`manifold.solve_chart_exp_ode`.  A run with fewer
    switches than ``min_switches`` fails (the check would have said nothing).
    """
    sol = solve_chart_exp_ode(metric, p0, v0, t_final, **options)
    report = ConformanceReport(f"geodesic over t = 0 -> {t_final:g}, {sol.n_switches} switches")
    report.add("relative energy error across the switches", [sol.relative_energy_error], bound)
    report.add("switches missing (at least min_switches wanted)", [max(0, min_switches - sol.n_switches)], 0.0)
    return report


def check_constrained(system: ConstrainedSystem, x: ArrayLike, v: ArrayLike, *, t_final: float = 5.0,
                      step: float = 1e-6, bound: float | None = 1e-12, rng: np.random.Generator | None = None,
                      **options: Any) -> ConformanceReport:
    """The constrained system's checks at states ``x, v`` (shape ``(m, N)`` each; ``v`` is projected to tangent).

    Parameters
    ----------
    system
        The system under test.
    x, v
        Points on ``c = 0`` and velocities there.
    t_final
        The length of the geodesic and transport run from the first state.
    step
        The step of the central differences.
    bound
        The bound on the energy error and on the change of the transported vectors' Gram matrix; ``None``: each
        run's own energy bound, :func:`~manifold.solution.energy_bound` of its steps at the solvers' default
        tolerance (the bound the solvers themselves apply, which grows with the steps a hard system takes).
    rng
        Random tangent vectors to transport (default ``numpy.random.default_rng(0)``).
    **options
        Passed to :func:`~manifold.constrained.solve_constrained` and :func:`~manifold.carried.solve_carried`.
    """
    rng = np.random.default_rng(0) if rng is None else rng
    if bound is not None:
        bound = check_real("bound", bound, positive=True)

    def own_bound(n_steps: int) -> float:
        return energy_bound(n_steps, taylor_relative_tolerance(None, float))

    X, V = real_array("x", x), real_array("v", v)
    N = system.ambient_dim
    if X.ndim != 2 or X.shape[1] != N or V.shape != X.shape:
        raise ValueError(f"x and v must have one shape (m, {N}), got {X.shape} and {V.shape}")
    geo = ConstrainedGeometry(system, float)
    report = ConformanceReport(f"{system!r}")
    c, _, _, _ = geo(X, V)
    report.add("the samples lie on c = 0 (max |c_k|)", np.abs(c), 1e-12)
    V = geo.tangent(X, V)
    W = rng.standard_normal(X.shape)
    _, Gw, _, _ = geo(X, W)
    fd = (geo(X + step * W, V)[0] - geo(X - step * W, V)[0]) / (2 * step)
    report.add("G w against central differences of c", _relative(Gw, fd, np.linalg.norm(Gw, axis=-1) + 1.0), 1e-6)
    K = np.asarray(system.metric_matrix, dtype=float)
    report.add("metric symmetric", [np.linalg.norm(K - K.T) / np.linalg.norm(K)], 1e-15)
    report.add("metric positive definite (negative part of the smallest eigenvalue)",
               [max(0.0, -float(np.linalg.eigvalsh(K)[0]))], 0.0)
    sol = solve_constrained(system, X[0], V[0], t_final, throw=False, **options)
    report.add("geodesic: relative energy error", [sol.relative_energy_error if sol.success else np.nan],
               own_bound(sol.n_steps) if bound is None else bound)
    vectors = geo.tangent(np.repeat(X[:1], 2, axis=0), rng.standard_normal((2, N)))
    carried = solve_carried(system, X[0], V[0], t_final, [ParallelTransport(vectors)], throw=False, **options)
    if carried.solution.success:
        _, velocities, values = carried(np.linspace(0, t_final, 21))
        frames = np.concatenate([values[0]["vectors"], velocities[:, None, :]], axis=1).astype(float)
    else:
        frames = np.full((1, 3, N), np.nan)
    gram = (frames @ K) @ frames.transpose(0, 2, 1)
    norms = np.sqrt(np.diagonal(gram[0]))
    drift = np.abs(gram - gram[0]) / np.outer(norms, norms)
    report.add("parallel transport: change of the Gram matrix of (W1, W2, v)", drift,
               own_bound(carried.solution.n_steps) if bound is None else bound)
    return report
