r"""Chart geodesics with the mass-weighted ambient velocity as state: every component on the scale of the energy.

:class:`~manifold.ambient_velocity.ConstrainedVelocity` integrates ``(a, V)`` with ``V = J c`` the chart frame's
ambient velocity.  With unequal masses ``V`` mixes fast light coordinates and slow heavy ones, and heyoka's error
norm is relative to the state's largest component, so a heavy coordinate's velocity is kept only to the light ones'
scale.  Here the state is ``(a, w)`` with

.. math::

    w = (R \otimes I_b) V, \qquad R^T R = B, \qquad |w|^2 = V^T (B \otimes I_b) V = 2 E,

``B`` the chart's metric block (``M^T K M = B \otimes I_b``, :class:`~manifold.geodesic_system.Layout`), ``R`` its
upper triangular Cholesky factor (``sqrt(m_k)`` on the diagonal for unrelabelled hinge masses), so every component
of ``w`` carries kinetic energy on one scale.  The equations are those of ``(a, V)`` with ``V`` read from ``w``:

.. math::

    J a' = (R^{-1} \otimes I_b) w, \qquad
    w' = (R \otimes I_b) \big(M^{-1} f(M z + m, M J a') - \gamma ((R^{-1} \otimes I_b) w - J a')\big),

the same damping of the normal drift at the same rate ``gamma``.  ``R`` and ``R^{-1}`` are runtime parameters
(their upper triangles, computed in the working precision from each chart's ``B`` at the segment's start), so the
step adds only products with parameters (``O(p)`` each at Taylor order ``p``) to the ``(a, V)`` equations.

The term is a :class:`~manifold.terms.StateTerm`: its switch map converts ``(a, c) -> (a, w)`` at a segment's start
(``w = R V``, ``V = J c``) and ``(a, w) -> (a, V) -> (a, c)`` at its end, dense output included, through the
``(a, V)`` term's own read-back.  Carried quantities (:class:`~manifold.ambient_velocity.ChartCarried`) ride on
``(a, V)`` only.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from .ambient_velocity import DEFAULT_RATE, ConstrainedVelocity
from .compiled import CompiledFamily
from .constrained import ConstrainedSystem
from .geodesic_system import SymbolicPieces
from .solution import DenseOutput
from .steppers import Advance
from .terms import SegmentStart, StateTerm
from .validation import check_positive_int


class WeightedVelocity(StateTerm):
    """Integrate a chart family's geodesics in ``(a, w)``, ``w = (R (x) I_b) J c`` with ``R^T R = B`` (module
    docstring), the normal acceleration from ``system``.

    Its parameters: those of :class:`~manifold.ambient_velocity.ConstrainedVelocity` (the system's, then ``gamma`` and ``1 / (2 E)``),
    then the upper triangles of ``R`` and of ``R^{-1}``, row by row.

    Parameters
    ----------
    system
        Constraints whose zero set, with the metric ``system.metric_matrix``, is the manifold that the atlas charts
        (as for :class:`~manifold.ambient_velocity.ConstrainedVelocity`).
    block
        The chart family's block size ``b`` (``M^T K M = B (x) I_b``: 2 for planar hinges); the family's is
        checked.  A term's parameter count is fixed before it meets a family, and ``R`` has ``N / b`` rows.
    rate
        Damping rate of the normal drift, as for :class:`~manifold.ambient_velocity.ConstrainedVelocity`.
    """

    label = "(a, w)"

    def __init__(self, system: ConstrainedSystem, block: int, rate: float = DEFAULT_RATE) -> None:
        self.velocity = ConstrainedVelocity(system, rate)  # checks system and rate
        self.block = check_positive_int("block", block)
        if system.ambient_dim % self.block:
            raise ValueError(f"block must divide the system's ambient dimension {system.ambient_dim}, got {block!r}")
        self.size = system.ambient_dim // self.block  # rows of R
        self._upper = np.triu_indices(self.size)
        self._factors: dict[tuple, tuple[NDArray, NDArray]] = {}  # (fp_type, B) -> (R, R^-1): one per chart

    def __repr__(self) -> str:
        return f"WeightedVelocity({self.velocity.system!r}, block={self.block}, rate={self.velocity.rate!r})"

    def __getstate__(self) -> dict:
        """Pickle the system, block and rate (the compiled store of the inner term holds a lock)."""
        return {"system": self.velocity.system, "block": self.block, "rate": self.velocity.rate}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["system"], state["block"], state["rate"])  # type: ignore[misc]

    @property
    def key(self) -> Hashable:
        return ("weighted-velocity", self.block, self.velocity.key)

    @property
    def n_params(self) -> int:
        """The ``(a, V)`` term's parameters, then the upper triangles of ``R`` and ``R^{-1}``."""
        return self.velocity.n_params + 2 * len(self._upper[0])

    def check(self, family: CompiledFamily, form: str) -> None:
        """As :meth:`~manifold.ambient_velocity.ConstrainedVelocity.check`, and refuse a family of another block size."""
        self.velocity.check(family, form)
        if family.family.block != self.block:
            raise ValueError(f"block: {self!r} weighs blocks of {self.block}, the charts of {family.family!r} have "
                             f"blocks of {family.family.block}")

    def _triangle(self, offset: int) -> list[list[Any]]:
        """The upper triangular matrix of parameters ``par[offset ..]`` (row by row), zeros below."""
        out: list[list[Any]] = [[None] * self.size for _ in range(self.size)]
        for k, (r, s) in enumerate(zip(*self._upper)):
            out[r][s] = hy.par[offset + k]
        return out

    def _apply(self, T: list[list[Any]], x: list[Any]) -> list[Any]:
        """``(T (x) I_b) x`` for an upper triangular ``T`` of expressions (points interleaved by blocks)."""
        b = self.block
        return [hy.sum([T[i][j] * x[j * b + d] for j in range(i, self.size)])
                for i in range(self.size) for d in range(b)]

    def equations(self, pieces: SymbolicPieces, equations: list[tuple], offset: int) -> list[tuple]:
        """The ``(a, V)`` equations with ``V = (R^{-1} (x) I_b) w`` substituted and ``w' = (R (x) I_b) V'``."""
        if equations:
            raise ValueError(f"{self!r} sets the state: it must be the first term")
        k = pieces.k
        inner = self.velocity.equations(pieces, [], offset)
        R_offset = offset + self.velocity.n_params
        R, R_inv = self._triangle(R_offset), self._triangle(R_offset + len(self._upper[0]))
        w = [hy.expression(f"w{r}") for r in range(pieces.N)]
        V = [lhs for lhs, _ in inner[k:]]
        rhs = hy.subs([f for _, f in inner], dict(zip(V, self._apply(R_inv, w))))
        return list(zip([a for a, _ in inner[:k]], rhs[:k])) + list(zip(w, self._apply(R, rhs[k:])))

    def factors(self, segment: SegmentStart) -> tuple[NDArray, NDArray]:
        """``R`` (upper triangular, ``R^T R = B``) and ``R^{-1}`` of the segment's chart, in its working precision
        (``B`` read from the chart's parameters; computed once per chart and type)."""
        lay = segment.family.layout
        packed = segment.pars[lay.n_theta : lay.n_theta + lay.n_metric]
        key = (segment.fp_type, tuple(float(x) for x in packed))  # B is packed through float64: exact
        if key not in self._factors:
            self._factors[key] = self._cholesky(packed)
        return self._factors[key]

    def _cholesky(self, packed: NDArray) -> tuple[NDArray, NDArray]:
        """``R`` and ``R^{-1}`` of ``B`` given by its upper triangle ``packed``, in its floating type: Cholesky, then
        back substitution, element by element, so that every floating type takes it (heyoka's ``real128`` and
        ``real`` included)."""
        n = self.size
        B = np.zeros((n, n), dtype=packed.dtype)
        B[self._upper] = packed
        R, R_inv = np.zeros_like(B), np.zeros_like(B)
        for i in range(n):
            pivot = B[i, i] - sum((R[j, i] * R[j, i] for j in range(i)), B[i, i] * 0)
            if not pivot > 0:
                raise ValueError(f"the chart's metric block B is not positive definite (pivot {i}: {pivot})")
            R[i, i] = np.sqrt(pivot)
            for s in range(i + 1, n):
                R[i, s] = (B[i, s] - sum((R[j, i] * R[j, s] for j in range(i)), B[i, s] * 0)) / R[i, i]
        for i in reversed(range(n)):
            R_inv[i, i] = 1 / R[i, i]
            for s in range(i + 1, n):
                R_inv[i, s] = -sum((R[i, j] * R_inv[j, s] for j in range(i + 1, s + 1)), B[i, s] * 0) / R[i, i]
        return R, R_inv

    def parameter_values(self, segment: SegmentStart) -> NDArray:
        """The ``(a, V)`` term's values, then ``R`` and ``R^{-1}`` of the segment's chart."""
        R, R_inv = self.factors(segment)
        return np.concatenate([self.velocity.parameter_values(segment), R[self._upper], R_inv[self._upper]])

    def _weigh(self, T: NDArray, states: NDArray, k: int) -> NDArray:
        """States stacked as rows ``(m, k + N + ...)`` with their velocity block multiplied by ``T (x) I_b``."""
        N, b = self.size * self.block, self.block
        weighed = (T @ states[:, k : k + N].reshape(len(states), self.size, b)).reshape(len(states), N)
        return np.concatenate([states[:, :k], weighed, states[:, k + N :]], axis=1)

    def enter(self, segment: SegmentStart) -> NDArray:
        """``(a, w)`` with ``w = (R (x) I_b) J c`` at the segment's start."""
        R, _ = self.factors(segment)
        return self._weigh(R, self.velocity.enter(segment)[None, :], segment.family.family.dim)[0]

    def rewrapped(self, segment: SegmentStart) -> Callable[[Any], None]:
        """``w = (R (x) I_b) V`` with ``V`` projected as :meth:`ConstrainedVelocity.rewrapped
        <manifold.ambient_velocity.ConstrainedVelocity.rewrapped>` projects it, in the live state ``(a, w, ...)``."""
        R, R_inv = self.factors(segment)
        k, N, project = segment.family.family.dim, self.size * self.block, self.velocity.rewrapped(segment)

        def reweigh(state: Any) -> None:
            av = self._weigh(R_inv, np.array(state[: k + N])[None, :], k)[0]
            project(av)
            state[k : k + N] = self._weigh(R, av[None, :], k)[0, k:]

        return reweigh

    def leave(self, advance: Advance, segment: SegmentStart) -> Advance:
        """The integrated ``(a, w)`` read back as ``(a, V)``, then as ``(a, c)`` by the ``(a, V)`` term's
        :meth:`~manifold.ambient_velocity.ConstrainedVelocity.leave`, dense output included."""
        _, R_inv = self.factors(segment)
        k, adv = segment.family.family.dim, advance
        out = None if adv.dense is None else _UnweighedDense(adv.dense, self, R_inv, k)
        unweighed = Advance(adv.t, self._weigh(R_inv, adv.y[None, :], k)[0], adv.n_steps, adv.event,
                            adv.step_times, self._weigh(R_inv, adv.step_states, k), out, adv.failure,
                            n_wraps=adv.n_wraps)
        return self.velocity.leave(unweighed, segment)


class _UnweighedDense:
    """Dense output of an ``(a, w)`` segment, read as ``(a, V)``."""

    def __init__(self, inner: DenseOutput, term: WeightedVelocity, R_inv: NDArray, k: int) -> None:
        self.inner, self.term, self.R_inv, self.k = inner, term, R_inv, k

    @property
    def nbytes(self) -> int:
        """Bytes held: the inner output's."""
        return self.inner.nbytes

    def __call__(self, ts: NDArray) -> NDArray:
        return self.term._weigh(self.R_inv, self.inner(ts), self.k)
