"""A finite atlas of charts, with transition maps and a chart-switch rule.

Names follow Manifolds.jl's atlas interface (``get_chart_index``,
``get_parameters``, ``get_point``, ``transition_map``, ``transition_map_diff``,
``check_chart_switch``) with the manifold argument dropped: an :class:`Atlas`
knows its manifold through its charts.  Charts are addressed by their integer
index ``i`` in ``atlas.charts``; ``atlas.ids[i]`` is a readable label.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chart import Chart, ChartDomainError
from .validation import check_index, check_real, real_array


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

    def _chart(self, i: int) -> Chart:
        return self.charts[check_index("chart index", i, len(self.charts))]

    def _point(self, p: ArrayLike) -> NDArray:
        """``p`` as a real array of shape ``(..., ambient_dim)`` (``TypeError`` for complex input)."""
        p = real_array("p", p, finite=False)
        if p.ndim == 0 or p.shape[-1] != self.ambient_dim:
            raise ValueError(f"a point has shape (..., {self.ambient_dim}), got {p.shape}")
        return p

    def _all_parameters(self, p: NDArray) -> tuple[list[NDArray | None], NDArray]:
        """Parameters and quality of the single point ``p`` in every chart."""
        params, q, errors = [], [], []
        for c in self.charts:
            try:
                a = c.get_parameters(p)
            except ChartDomainError as e:  # p lies outside this chart's image
                a = None
                errors.append(e)
            params.append(a)
            q.append(-np.inf if a is None else c.quality(a))
        if len(errors) == len(self.charts):  # e.g. p is not on the manifold: say why, from chart 0
            raise ChartDomainError(f"point {np.asarray(p)} lies in no chart of the atlas: {errors[0]}") from errors[0]
        return params, np.array(q)

    def _batch_parameters(self, p: NDArray) -> tuple[NDArray, NDArray]:
        """Parameters ``(B, len(atlas), dim)`` (NaN outside a chart) and qualities ``(B, len(atlas))`` of points ``(B, N)``.

        One batched inverse per chart; only if some point lies outside some
        chart's image (a :class:`ChartDomainError` for the batch) is the batch
        decided point by point.
        """
        try:
            per_chart = [c.get_parameters(p) for c in self.charts]
            q = np.stack([c.quality(a) for c, a in zip(self.charts, per_chart)], axis=-1)
            return np.stack(per_chart, axis=1), q
        except ChartDomainError:
            pass
        out_a = np.full((p.shape[0], len(self.charts), self.dim), np.nan)
        out_q = np.empty((p.shape[0], len(self.charts)))
        for b, x in enumerate(p):
            in_charts, out_q[b] = self._all_parameters(x)
            for i, a in enumerate(in_charts):
                if a is not None:
                    out_a[b, i] = a
        return out_a, out_q

    def qualities(self, p: ArrayLike) -> NDArray:
        """Quality of every chart at point ``p``: shape ``(len(atlas),)``, or ``p.shape[:-1] + (len(atlas),)``.

        ``-inf`` for a chart whose image does not contain ``p``.
        """
        p = self._point(p)
        if p.ndim == 1:
            return self._all_parameters(p)[1]
        return self._batch_parameters(p.reshape(-1, p.shape[-1]))[1].reshape(*p.shape[:-1], len(self.charts))

    def get_chart_index(self, p: ArrayLike) -> int | NDArray:
        """Index of the chart of best quality at ``p`` (lowest index on ties); an int array for a batch."""
        return self.best_chart(p)[0]

    def best_chart(self, p: ArrayLike) -> tuple[int | NDArray, NDArray]:
        """``(i, a)``: the index ``get_chart_index(p)`` and the parameters of ``p`` in that chart.

        One inverse per chart, where ``get_chart_index`` followed by
        ``get_parameters`` would invert the chosen chart twice.  A batch of
        points (shape ``(..., ambient_dim)``) gives arrays of indices ``(...)``
        and parameters ``(..., dim)``, with one batched inverse per chart.
        """
        p = self._point(p)
        if p.ndim > 1:
            all_a, all_q = self._batch_parameters(p.reshape(-1, p.shape[-1]))
            idx = np.argmax(all_q, axis=-1)
            a = all_a[np.arange(idx.size), idx]
            return idx.reshape(p.shape[:-1]), a.reshape(*p.shape[:-1], self.dim)
        params, q = self._all_parameters(p)
        i = int(np.argmax(q))
        a = params[i]
        assert a is not None  # a chart without parameters has quality -inf, and some chart has them
        return i, a

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
