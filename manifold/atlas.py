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
    """

    def __init__(
        self,
        charts: Sequence[Chart],
        ids: Sequence[Hashable] | None = None,
        switch_threshold: float = 0.25,
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
        if not 0.0 < switch_threshold < 1.0:
            raise ValueError(f"switch_threshold must lie in (0, 1), got {switch_threshold!r}")
        self.charts = charts
        self.ids = ids
        self.switch_threshold = float(switch_threshold)
        self.dim, self.ambient_dim = dims.pop()

    def __len__(self) -> int:
        return len(self.charts)

    def _chart(self, i: int) -> Chart:
        if not (isinstance(i, (int, np.integer)) and 0 <= i < len(self.charts)):
            raise IndexError(f"chart index must be an integer in [0, {len(self.charts) - 1}], got {i!r}")
        return self.charts[i]

    def _all_parameters(self, p: ArrayLike) -> tuple[list[NDArray | None], NDArray]:
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

    def qualities(self, p: ArrayLike) -> NDArray:
        """Quality of every chart at point ``p``: array of shape ``(len(atlas),)``.

        ``-inf`` for a chart whose image does not contain ``p``.
        """
        return self._all_parameters(p)[1]

    def get_chart_index(self, p: ArrayLike) -> int:
        """Index of the chart of best quality at ``p`` (lowest index on ties)."""
        return self.best_chart(p)[0]

    def best_chart(self, p: ArrayLike) -> tuple[int, NDArray]:
        """``(i, a)``: the index ``get_chart_index(p)`` and the parameters of ``p`` in that chart.

        One inverse per chart, where ``get_chart_index`` followed by
        ``get_parameters`` would invert the chosen chart twice.
        """
        params, q = self._all_parameters(p)
        i = int(np.argmax(q))
        return i, params[i]

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
