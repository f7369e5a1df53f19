"""A finite atlas of charts, with transition maps and a chart-switch rule.

Names follow Manifolds.jl's atlas interface (``get_chart_index``,
``get_parameters``, ``get_point``, ``transition_map``, ``transition_map_diff``,
``check_chart_switch``) with the manifold argument dropped: an :class:`Atlas`
knows its manifold through its charts.  Charts are addressed by their integer
index ``i`` in ``atlas.charts``; ``atlas.ids[i]`` is a readable label.
"""

from __future__ import annotations

import functools
from collections.abc import Hashable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chart import Chart, ChartDomainError
from .symbolic import SymbolicChart, chart_ranking
from .validation import check_index, check_real, real_array


#: Charts whose quality at their approximate (unpolished) parameters lies within this of the best chart's are
#: polished and compared again.  The choice equals the argmax of the polished qualities as long as the polish
#: moves no competitive quality by half of this: measured up to 6e-5 for the chain with ``L - (n-2) = 1e-12``,
#: where the fold terms of the quality have gradients ~1/(L - (n-2)), and ~1e-10 elsewhere
#: (``benchmarks/engine_costs.py``, ``tests/test_chart_choice.py``).
QUALITY_MARGIN = 1e-3


class Atlas:
    """A finite set of charts of one embedded manifold.

    Parameters
    ----------
    charts
        Charts with equal ``dim`` and ``ambient_dim``.
    ids
        Optional labels, one per chart (default: ``0 .. k-1``).
    switch_threshold
        ``check_chart_switch(i, a)`` is true where ``charts[i].quality(a)``
        falls below this value.  It must lie below the worst best-chart
        quality of the atlas, so that the chart picked after a switch is
        far from its own threshold (hysteresis: no chattering).
    quality_floor
        A lower bound of the best chart's quality at every point, if known
        (measured or proven); solvers refuse a switch threshold at or above it.
    """

    def __init__(
        self,
        charts: Sequence[Chart],
        ids: Sequence[Hashable] | None = None,
        switch_threshold: float = 0.25,
        quality_floor: float | None = None,
    ) -> None:
        charts = list(charts)
        if not charts:
            raise ValueError("an atlas needs at least one chart, got none")
        dims = {(c.dim, c.ambient_dim) for c in charts}
        if len(dims) != 1:
            raise ValueError(f"charts disagree on (dim, ambient_dim): {sorted(dims)}")
        families = {ch.family.key for ch in charts if hasattr(ch, "family")}
        if len(families) > 1 or (families and not all(hasattr(ch, "family") for ch in charts)):
            raise ValueError(
                f"an atlas takes charts of one chart family (its geodesics compile one system), got {sorted(map(repr, families))}"
            )
        ids = list(range(len(charts))) if ids is None else list(ids)
        if len(ids) != len(charts):
            raise ValueError(f"got {len(ids)} ids for {len(charts)} charts")
        switch_threshold = check_real("switch_threshold", switch_threshold, positive=True)
        if quality_floor is not None:
            quality_floor = check_real("quality_floor", quality_floor, positive=True, at_most=1.0)
        if not switch_threshold < (1.0 if quality_floor is None else quality_floor):
            raise ValueError(f"switch_threshold must lie in (0, {quality_floor or 1.0:g}) (below the atlas's "
                             f"quality floor), got {switch_threshold!r}")
        self.quality_floor = quality_floor
        self.charts: Sequence[Chart] = charts  # read as a sequence: a subclass may narrow the type of its charts
        self.ids = ids
        self.switch_threshold = float(switch_threshold)
        self.dim, self.ambient_dim = dims.pop()

    def __len__(self) -> int:
        return len(self.charts)

    @functools.cached_property
    def chart_quality_floors(self) -> NDArray | None:
        """The floor of each quality expression over every chart and parameter (the least of the charts'
        :meth:`~manifold.family.ChartFamily.quality_floors`), or ``None`` where a chart's family knows none; computed
        once, since it depends on the charts alone."""
        floors = [chart.family.quality_floors(chart.family_parameters) if isinstance(chart, SymbolicChart) else None
                  for chart in self.charts]
        known = [f for f in floors if f is not None]
        return np.min(known, axis=0) if known and len(known) == len(floors) else None

    def _chart(self, i: int) -> Chart:
        return self.charts[check_index("chart index", i, len(self.charts))]

    def _point(self, p: ArrayLike) -> NDArray:
        """``p`` as a real array of shape ``(..., ambient_dim)`` (``TypeError`` for complex input)."""
        p = real_array("p", p, finite=False)
        if p.ndim == 0 or p.shape[-1] != self.ambient_dim:
            raise ValueError(f"a point has shape (..., {self.ambient_dim}), got {p.shape}")
        return p

    def _ranked(self, p: NDArray) -> tuple[NDArray, NDArray]:
        """Every chart's approximate parameters and its quality there for the points ``p`` (``(B, N)``):
        ``(B, C, dim)`` and ``(B, C)``, ``-inf`` where a chart's image does not contain the point.

        Charts of one family with a compiled closed-form inverse are ranked in
        one batched call (:class:`~manifold.symbolic.ChartRanking`); others chart
        by chart through :meth:`~manifold.chart.Chart.approximate_parameters`
        and :meth:`~manifold.chart.Chart.quality`, point by point where a
        chart refuses part of the batch.
        """
        if "_ranking" not in self.__dict__:
            symbolic = [c for c in self.charts if isinstance(c, SymbolicChart) and hasattr(c, "family")]
            self._ranking = chart_ranking(symbolic) if len(symbolic) == len(self.charts) else None
        if self._ranking is not None:
            A, Q = self._ranking(self._ranking.check_point(p))
            for row in np.nonzero(np.all(Q == -np.inf, axis=1))[0]:
                raise ChartDomainError(f"point {p[row]} lies in no chart of the atlas: no chart's inverse is finite there")
            return A, Q
        B, C = len(p), len(self.charts)
        A, Q = np.full((B, C, self.dim), np.nan), np.full((B, C), -np.inf)
        errors: list[list[ChartDomainError]] = [[] for _ in range(B)]
        for c, chart in enumerate(self.charts):
            try:
                A[:, c] = chart.approximate_parameters(p)
                Q[:, c] = chart.quality(A[:, c])
                continue
            except ChartDomainError:  # some point lies outside this chart's image: find which, point by point
                pass
            for b in range(B):
                try:
                    A[b, c] = chart.approximate_parameters(p[b])
                    Q[b, c] = chart.quality(A[b, c])
                except ChartDomainError as e:
                    errors[b].append(e)
        for b in range(B):
            if len(errors[b]) == C:  # e.g. p is not on the manifold: say why, from chart 0
                raise ChartDomainError(f"point {p[b]} lies in no chart of the atlas: {errors[b][0]}") from errors[b][0]
        return A, np.where(np.isnan(Q), -np.inf, Q)  # a NaN quality (0/0 at a chart's pole) never wins

    def _polished(self, p: NDArray, margin: float) -> tuple[NDArray, NDArray]:
        """Parameters and qualities (``(B, C, dim)``, ``(B, C)``) of the points ``p`` (``(B, N)``) in every chart,
        polished where the approximate quality lies within ``margin`` of the point's best; ``-inf`` quality elsewhere."""
        A, Q = self._ranked(p)
        polish = (Q > -np.inf) & (Q >= Q.max(axis=1, keepdims=True) - margin)
        for c, chart in enumerate(self.charts):
            rows = polish[:, c]
            if rows.any():
                A[rows, c] = chart.polish_parameters(A[rows, c], p[rows])
                Q[rows, c] = chart.quality(A[rows, c])
        Q[~polish] = -np.inf
        return A, Q

    def qualities(self, p: ArrayLike) -> NDArray:
        """Quality of every chart at point ``p``: shape ``(len(atlas),)``, or ``p.shape[:-1] + (len(atlas),)``.

        ``-inf`` for a chart whose image does not contain ``p``.
        """
        p = self._point(p)
        flat = p.reshape(-1, self.ambient_dim)
        return self._polished(flat, np.inf)[1].reshape(*p.shape[:-1], len(self.charts))

    def get_chart_index(self, p: ArrayLike) -> int | NDArray:
        """Index of the chart of best quality at ``p`` (lowest index on ties); an int array for a batch."""
        return self.best_chart(p)[0]

    def best_chart(self, p: ArrayLike) -> tuple[int | NDArray, NDArray]:
        """``(i, a)``: the index ``get_chart_index(p)`` and the parameters of ``p`` in that chart.

        A batch of points (shape ``(..., ambient_dim)``) gives arrays of
        indices ``(...)`` and parameters ``(..., dim)``.  See :meth:`chart_choice`.
        """
        return self.chart_choice(p)[:2]

    def chart_choice(self, p: ArrayLike) -> tuple[int | NDArray, NDArray, float | NDArray]:
        """``(i, a, q)``: the chart of best quality at ``p``, the parameters of ``p`` in it and its quality.

        Equal to the argmax over all charts of ``quality(get_parameters(p))``
        (lowest index on ties), computed cheaply: every chart's quality at its
        :meth:`~manifold.chart.Chart.approximate_parameters` (for charts of one
        family with a closed-form inverse, all charts and points in one compiled
        call: :class:`~manifold.symbolic.ChartRanking`), then the polish only for
        the charts within :data:`QUALITY_MARGIN` of the best, compared again.
        """
        p = self._point(p)
        flat = p.reshape(-1, self.ambient_dim)
        A, Q = self._polished(flat, QUALITY_MARGIN)
        idx = np.argmax(Q, axis=1)
        rows = np.arange(len(flat))
        a, q = A[rows, idx], Q[rows, idx]
        if p.ndim == 1:
            return int(idx[0]), a[0], float(q[0])
        return idx.reshape(p.shape[:-1]), a.reshape(*p.shape[:-1], self.dim), q.reshape(p.shape[:-1])

    def get_parameters(self, i: int, p: ArrayLike) -> NDArray:
        """Parameters of point ``p`` in chart ``i``."""
        return self._chart(i).get_parameters(p)

    def get_point(self, i: int, a: ArrayLike) -> NDArray:
        """Point with parameters ``a`` in chart ``i``."""
        return self._chart(i).get_point(a)

    def transition_map(self, i: int, j: int, a: ArrayLike) -> NDArray:
        """Parameters in chart ``j`` of the point with parameters ``a`` in chart ``i``."""
        return self._chart(j).get_parameters(self._chart(i).get_point(a))

    def transition_map_diff(self, i: int, a: ArrayLike, c: ArrayLike, j: int) -> NDArray:
        """Velocity coefficients in chart ``j`` of the tangent vector ``J_i(a) c``.

        The embedded vector ``v = J_i c`` is mapped to ``c_j`` with
        ``J_j(a_j) c_j = v``, ``a_j = transition_map(i, j, a)``.  Because ``v`` is
        the same embedded vector, every quantity defined on the embedding
        (kinetic energy, inner products) is preserved.
        """
        v = self._chart(i).tangent_vector(a, c)
        return self._chart(j).coefficients(self.transition_map(i, j, a), v)

    def check_chart_switch(self, i: int, a: ArrayLike) -> bool | NDArray:
        """True where chart ``i`` at ``a`` is of quality below ``switch_threshold``."""
        q = self._chart(i).quality(a)
        out = q < self.switch_threshold
        return bool(out) if np.ndim(out) == 0 else out
