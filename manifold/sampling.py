"""Random points uniform in the Riemannian volume of an induced metric, and velocities on an energy sphere.

**Volume** (:func:`sample_volume`).  Chart ``i`` pulls the Riemannian volume back
to ``dvol = sqrt(det g_i(a)) da``.  Propose a chart ``i`` uniformly at random and
``a`` from a :class:`Proposal` of density ``q(a)`` whose support each chart maps
one-to-one (up to a null set) onto a set holding the points where that chart is
the best; keep the proposal with probability ``sqrt(det g_i(a)) / (F q(a))``
and only if ``i`` is the best chart at ``p = p_i(a)`` (:meth:`Atlas.best_chart`).
The kept points then have density ``sum_i [best(p) = i] = 1`` with respect to
the volume: exactly uniform, provided ``F`` bounds ``sqrt(det g_i) / q`` on each
best region; the acceptance rate is ``vol / (n F)`` for ``n`` charts.  Where the
atlas knows its ``quality_floor`` (the best chart's quality is never below it)
a proposal whose chart quality is lower cannot be in that chart's best region
and is dropped before anything else is computed, so ``F`` only has to bound the
ratio where the chart is good.

``F`` comes from a pilot: the largest ratio seen over the pilot proposals of
quality at least the floor, times ``BOUND_MARGIN``.  The bound is checked on
every later proposal that passes the floor; one above ``F`` raises ``F`` to
``BOUND_MARGIN`` times its ratio and restarts the sampling with nothing kept,
so that all returned points were drawn under one bound.

**Velocities** (:func:`sample_velocities`).  The Liouville measure of the
geodesic flow on the energy shell ``1/2 |v|_g^2 = E`` is the volume times the
uniform measure on the sphere of radius ``sqrt(2 E)`` in ``(T_p M, g)``.  With
``C J = Q R`` (:func:`manifold.curvature.tangent_frame`, ``K = C^T C``), a unit
vector ``w`` uniform on ``S^(k-1)`` gives ``v = sqrt(2 E) C^{-1} Q w = sqrt(2 E) J R^{-1} w``:
tangent, of energy ``E``, and uniform on the shell.  It is computed as ``J R^{-1} w``, a chart velocity
pushed forward, which is tangent to the rounding of ``J`` whatever the masses, and then scaled to the energy
``E``: ``C^{-1}`` amplifies the rounding of ``Q w`` by ``cond C``, and with hinge masses 1e-8..1e8 that left
a normal part of 1e-8 of ``|v|``, which the solvers' start checks refused.
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .curvature import tangent_frame
from .metric import InducedMetric
from .validation import check_real, real_array

#: Factor between the largest density seen and the bound ``F`` of the rejection step.
BOUND_MARGIN = 1.25


@dataclass(frozen=True, repr=False)
class VolumeSample:
    """Points uniform in the Riemannian volume (:func:`sample_volume`).

    Attributes
    ----------
    points
        ``(size, N)`` embedded points.
    charts, parameters
        The chart that proposed each point (its best chart) and its parameters there.
    proposals
        Proposals drawn after the last restart.
    acceptance
        Fraction of those proposals kept (before cutting the last round to ``size``).
    density_bound
        The bound ``F`` of ``sqrt(det g) / q`` the returned points were drawn under.
    restarts
        How often a proposal above ``F`` raised it and restarted the sampling.
    """

    points: NDArray
    charts: NDArray
    parameters: NDArray
    proposals: int
    acceptance: float
    density_bound: float
    restarts: int

    def __len__(self) -> int:
        return self.points.shape[0]

    def __repr__(self) -> str:
        return (f"VolumeSample(size={len(self)}, acceptance={self.acceptance:.3g}, "
                f"density_bound={self.density_bound:.4g}, restarts={self.restarts})")


def _check_size(size: object) -> int:
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, numbers.Integral) or int(size) < 1:
        raise ValueError(f"size must be a positive integer, got {size!r}")
    return int(size)


def _check_rng(rng: object) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    return rng


class Proposal(Protocol):
    """How :func:`sample_volume` proposes chart parameters: i.i.d. draws and their probability density in ``da``.

    Every chart must be one-to-one on the support (up to a null set), and the
    support must hold the parameters of every point where that chart is the best.
    """

    def draw(self, size: int, rng: np.random.Generator) -> NDArray:
        """``size`` independent parameter vectors, shape ``(size, dim)``."""

    def density(self, a: NDArray) -> NDArray:
        """Probability density of :meth:`draw` at ``a`` (shape ``(..., dim)``) per ``da``."""


@dataclass(frozen=True)
class BoxProposal:
    """Parameters uniform in the box ``lower <= a <= upper`` (density ``1 / volume``)."""

    lower: NDArray
    upper: NDArray

    def __post_init__(self) -> None:
        lower, upper = (real_array(name, x).reshape(-1) for name, x in (("lower", self.lower), ("upper", self.upper)))
        if lower.shape != upper.shape or np.any(lower >= upper):
            raise ValueError(f"a box needs lower < upper of equal lengths, got lower = {lower}, upper = {upper}")
        object.__setattr__(self, "lower", lower)
        object.__setattr__(self, "upper", upper)

    def draw(self, size: int, rng: np.random.Generator) -> NDArray:
        return rng.uniform(self.lower, self.upper, size=(size, self.lower.size))

    def density(self, a: NDArray) -> NDArray:
        return np.full(np.shape(a)[:-1], 1.0 / np.prod(self.upper - self.lower))


def sample_volume(metric: InducedMetric, size: int, rng: np.random.Generator, proposal: Proposal,
                  *, pilot: int = 4096, batch: int = 4096, max_proposals: int = 10**8) -> VolumeSample:
    """``size`` points uniform in the Riemannian volume of ``metric`` (independent draws; see the module docstring).

    Parameters
    ----------
    metric
        The induced metric on an atlas.
    size
        Number of points, a positive integer.
    rng
        ``numpy.random.Generator``: the only source of randomness.
    proposal
        Draws chart parameters (the same law for every chart), e.g. a
        :class:`BoxProposal`; see :class:`Proposal` for what it must satisfy.
        The closer its density is to ``sqrt(det g)``, the higher the acceptance.
    pilot
        Proposals per chart (on average) that set the bound ``F``.
    batch
        Proposals per chart (on average) and round.
    max_proposals
        Give up (``RuntimeError``) after this many proposals.

    Returns
    -------
    VolumeSample
    """
    size, rng = _check_size(size), _check_rng(rng)
    atlas, k = metric.atlas, metric.atlas.dim
    floor = atlas.quality_floor or 0.0
    n = len(atlas)

    def propose(m: int) -> tuple[NDArray, NDArray, NDArray]:
        """``m`` i.i.d. proposals (chart uniform, ``a`` from ``proposal``) and their ratio ``sqrt(det g) / density``
        (0 below the quality floor)."""
        charts = rng.integers(n, size=m)
        a = np.asarray(proposal.draw(m, rng), dtype=float)
        if a.shape != (m, k):
            raise ValueError(f"proposal.draw({m}, rng) must return shape ({m}, {k}), got {a.shape}")
        ratio = np.zeros(m)
        for i in range(n):
            rows = np.flatnonzero(charts == i)
            if rows.size:
                rows = rows[atlas.charts[i].quality(a[rows]) >= floor]
                ratio[rows] = metric.volume_density(i, a[rows]) / proposal.density(a[rows])
        return charts, a, ratio

    seen = float(propose(n * pilot)[2].max())
    if not seen > 0:
        raise RuntimeError(f"no pilot proposal of quality >= {floor:g} had a positive density: does {proposal!r} "
                           "cover the charts?")
    F, restarts = BOUND_MARGIN * seen, 0
    kept: list[tuple[NDArray, NDArray, NDArray]] = []
    count = proposals = total = 0
    while count < size:
        if total >= max_proposals:
            raise RuntimeError(f"sample_volume kept {count} of {proposals} proposals; gave up after {total} "
                               f"(max_proposals = {max_proposals})")
        charts, a, ratio = propose(n * batch)
        proposals, total = proposals + n * batch, total + n * batch
        if ratio.max() > F:  # the bound failed: nothing drawn under it may be kept
            F, restarts = BOUND_MARGIN * float(ratio.max()), restarts + 1
            kept, count, proposals = [], 0, 0
            continue
        take = np.flatnonzero(rng.random(ratio.size) * F < ratio)
        points = np.empty((take.size, atlas.ambient_dim))
        best = np.zeros(take.size, dtype=bool)
        for i in np.unique(charts[take]):
            rows = charts[take] == i
            points[rows] = atlas.charts[int(i)].get_point(a[take[rows]])
            best[rows] = np.atleast_1d(atlas.get_chart_index(points[rows])) == i
        # Kept in proposal order: the proposals are i.i.d., so the first `size` kept are i.i.d. uniform.
        kept.append((points[best], charts[take[best]], a[take[best]]))
        count += int(best.sum())
    points, charts, parameters = (np.concatenate(x)[:size] for x in zip(*kept))
    return VolumeSample(points, charts, parameters, proposals, count / proposals, F, restarts)


def sample_velocities(metric: InducedMetric, p: ArrayLike, energy: float, rng: np.random.Generator) -> NDArray:
    """Embedded tangent vectors at ``p`` uniform on the energy sphere ``1/2 v^T K v = energy``.

    Parameters
    ----------
    metric
        The induced metric.
    p
        Point(s) of the manifold, shape ``(..., N)``.
    energy
        Kinetic energy ``E > 0``.
    rng
        ``numpy.random.Generator``.

    Returns
    -------
    numpy.ndarray
        ``v`` of shape ``(..., N)``, one independent draw per point:
        ``v = sqrt(2 E) J R^{-1} w``, ``w`` uniform on the unit sphere of ``R^dim``
        (see the module docstring), computed in each point's best chart and scaled to the energy.
    """
    energy, rng = check_real("energy", energy, positive=True), _check_rng(rng)
    atlas, k, N = metric.atlas, metric.atlas.dim, metric.atlas.ambient_dim
    if k == 0:
        raise ValueError("a manifold of dimension 0 has no tangent vectors of positive energy")
    idx, a = atlas.best_chart(p)
    lead = np.shape(idx)
    idx, a = np.ravel(idx), a.reshape(-1, k)
    w = rng.standard_normal((idx.size, k))
    w /= np.linalg.norm(w, axis=-1, keepdims=True)
    v = np.empty((idx.size, N))
    for i in np.unique(idx):
        rows = idx == i
        J = atlas.charts[int(i)].jacobian(a[rows])
        _, R = tangent_frame(J, metric.K_root)
        a_dot = np.linalg.solve(R, w[rows][..., None])[..., 0]  # R a' = w: g-orthonormal in the chart
        v[rows] = np.einsum("...rk,...k->...r", J, a_dot)
    # the energy 1/2 v^T K v of J R^-1 w is 1/2 to the rounding of R, which cond C can spoil: scale it exactly
    v *= np.sqrt(energy / metric.ambient_kinetic_energy(v))[:, None]
    return v.reshape(*lead, N)
