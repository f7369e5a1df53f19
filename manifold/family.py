"""Chart families: chart maps written as heyoka expressions, so that they can be compiled.

A :class:`ChartFamily` is a parametrised map ``a -> z(a; theta)`` written as
heyoka expressions, with the family parameters ``theta`` as runtime
parameters ``par[0 .. n_params-1]``.  Everything compiled from it (geodesic
integrator, transfer, acceleration, quality and Jacobian functions) lives in
:class:`manifold.compiled.CompiledFamily`, one per ``family.key``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Hashable, Sequence
from typing import Any

import heyoka as hy
from numpy.typing import NDArray


class ChartFamily(ABC):
    """A family of chart maps ``z(a; theta)`` as heyoka expressions.

    A subclass implements :attr:`key`, :meth:`point_expressions` and
    :meth:`quality_expressions`, and may implement :meth:`point_jets`,
    :meth:`inverse_expressions`, :meth:`velocity_solve` and :meth:`quality_floors`.
    Equality of families is equality of keys: compiled code is cached per key.

    Attributes
    ----------
    dim
        Number of chart parameters ``a``.
    point_dim
        Number of coordinates of ``z``.
    block
        ``z`` is made of ``point_dim / block`` points of ``R^block`` (2 for planar
        hinges, 1 for plain coordinates); the ambient metric must be ``B (x) I_block``.
    n_params
        Number of family parameters ``theta``.
    periodic
        Indices of ``2 pi``-periodic parameters.  The steppers wrap them into
        ``[-pi, pi]`` (heyoka's between steps, :func:`manifold.steppers.angle_wrap`, so that within a step, and in
        the dense output there, the angle can be one step's turn past ``+-pi``): heyoka's error control is
        relative to the state's size, so an angle left to grow to ``O(1000)`` would cost three digits.
    """

    dim: int
    point_dim: int
    block: int
    n_params: int
    periodic: tuple[int, ...] = ()

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """Identity of the family: two families with equal keys compile to the same code."""

    @abstractmethod
    def point_expressions(self, a: Sequence[hy.expression], fp_type: Any) -> list[hy.expression]:
        """``z(a; theta)`` with ``theta = par[0 .. n_params-1]``, constants exact in ``fp_type``."""

    def point_jets(self, a: Sequence[hy.expression], c: Sequence[hy.expression], fp_type: Any) -> list | None:
        """``z`` as :class:`~manifold.jets.Jet` s along velocity ``c``, or ``None`` (the default).

        A family that can run its formula on jets gets the geodesic equations
        from one forward sweep instead of symbolic differentiation of the
        expanded ``z``: much smaller for deep formulas.
        """
        return None

    def inverse_expressions(self, z: Sequence[hy.expression], fp_type: Any) -> list[hy.expression] | None:
        """The closed-form inverse ``a(z; theta)`` as expressions in the variables ``z``, or ``None`` (the default).

        With it, :class:`~manifold.atlas.Atlas` ranks all the charts of an
        atlas by one compiled evaluation (inverse and quality together) and
        polishes only the charts that can win.  It need only be accurate
        enough to rank: charts polish their parameters afterwards.
        """
        return None

    @abstractmethod
    def quality_expressions(self, a: Sequence[hy.expression]) -> list[hy.expression]:
        """Expressions whose minimum is the chart quality (empty: the chart is global).

        Each one is also a switch event of the geodesic integrator
        (``expression - q_out``, decreasing), so the numpy quality and the
        events come from this one formula.
        """

    def velocity_solve(self, a: Sequence[hy.expression], V: Sequence[hy.expression],
                       fp_type: Any) -> tuple[list, list] | None:
        """``(a', J a')`` for an ambient velocity ``V`` (expressions) by the family's own recursion, or ``None``
        (the default: :meth:`~manifold.geodesic_system.SymbolicPieces.velocity_coefficients` and the jets).

        It must be the same arithmetic as the generic forward substitution (the same least-squares fit per
        block of the Jacobian, so the same oblique projection off the tangent space), only cheaper, with the
        chart's values built as :meth:`point_jets` builds them so that the two share them.
        """
        return None

    def quality_floors(self, theta: NDArray) -> NDArray | None:
        """Lower bounds of the :meth:`quality_expressions` at parameters ``theta``, over every ``a``; or ``None``
        (the default: none known).

        A quality whose floor lies above the switch threshold ``q_out`` never falls to it, so its switch event can
        never fire: the geodesic solver compiles its integrator without that event (each event costs its Taylor
        coefficients and a root search at every step).  A floor must hold for every real ``a``, not only on the
        chart's domain, and must not be rounded up.
        """
        return None

    def __eq__(self, other: object) -> bool:
        return isinstance(other, ChartFamily) and other.key == self.key

    def __hash__(self) -> int:
        return hash(self.key)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(key={self.key!r})"
