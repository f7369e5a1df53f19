"""Equation terms: what a chart family's compiled geodesic integrator is composed of.

A compiled integrator (:meth:`manifold.compiled.CompiledFamily.integrator`)
is keyed by its tuple of terms and built by applying them in order to an
empty system.  Each term declares

* its **state slots**: the variables its :meth:`Term.equations` add (the
  first term, a :class:`StateTerm`, sets the state the integrator carries;
  a later one may add slots, as Sundman's time adds ``u``, or transform the
  right-hand sides, as it multiplies them by ``s(p)``);
* its **runtime parameters**: :attr:`Term.n_params` values at
  ``par[offset ..]``, the blocks allotted in the order of the terms after the
  chart's own (:attr:`~manifold.geodesic_system.Layout.terms_index`), and their
  values at each segment's start (:meth:`Term.parameter_values` of a
  :class:`SegmentStart`), which the stepper asks of every term of its composition;
* its **events** (:meth:`Term.events`), after the family's switch events (:mod:`manifold.events`; heyoka's
  integrators have no wrap events: :func:`~manifold.steppers.angle_wrap`); the atlas loop acts on each by its kind
  (a :data:`~manifold.events.STOP` ends the solve);
* its **switch map**: how the atlas loop's state ``(a, c)`` maps to the term's
  state at each segment's start (:meth:`StateTerm.enter`) and back at its end
  (:meth:`StateTerm.leave`; the chart switch itself acts on ``(a, c)``); the slots
  of a later term start at :meth:`Term.slots` and the loop carries them through
  switches unchanged; and whether a term's slots change while the geodesic stays at
  rest (:attr:`Term.moves_at_rest`: then a start at rest is integrated all the same).

A term that changes the independent variable, as Sundman's time does, is a
:class:`Clock`: it runs the integrator over a segment itself and reports physical
times.  The terms: :class:`ChartGeodesic` (the state ``(a, c)``, the default),
:class:`manifold.ambient_velocity.ConstrainedVelocity` (the state ``(a, J c)``),
:class:`manifold.ambient_velocity.ChartCarried` (a :mod:`manifold.carried` term, a transported vector or a
Jacobi field, after it) and :class:`manifold.sundman.SundmanTime` (Sundman's time, a :class:`Clock`, last).  A new
term is a subclass in its own file, passed to
:class:`~manifold.steppers.TaylorStepper` (``velocity=`` for a state term,
``terms=`` for the others).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .events import Event
from .geodesic_system import FORMS, SymbolicPieces

if TYPE_CHECKING:
    from .compiled import CompiledFamily, Transfer
    from .steppers import Advance


@dataclass
class SegmentStart:
    """One segment's start, in the atlas loop's terms: what a term's parameter values and switch map may read.

    Attributes
    ----------
    family
        The :class:`~manifold.compiled.CompiledFamily` integrated.
    fp_type
        The working precision.
    t, t_final
        The segment's start time and the solve's final time.
    y
        The loop's state ``(a, c)``, then anything carried after it (ambient slots, unchanged at switches).
    pars
        The active chart's runtime parameters (:attr:`~manifold.compiled.ChartNumerics.pars`).
    """

    family: CompiledFamily
    fp_type: Any
    t: Any
    y: NDArray
    t_final: Any
    pars: NDArray

    @cached_property
    def transfer(self) -> Transfer:
        """The family's transfer at the chart's parameters (:class:`~manifold.compiled.Transfer`)."""
        return self.family.transfer_at(self.fp_type, self.pars)

    @cached_property
    def start(self) -> NDArray:
        """The transfer's outputs at ``(a, c)`` (one column): ``z``, ``J c``, the tangent coefficients of 0 and the
        kinetic energy ``E = 1/2 c^T g c`` (computed once per segment, whoever asks first)."""
        k, N = self.family.family.dim, self.family.family.point_dim
        return self.transfer(self.y[:k, None], self.y[k : 2 * k, None], np.zeros((N, 1)))

    @property
    def energy(self) -> Any:
        """The kinetic energy at the segment's start, in the working precision."""
        return self.start[-1, 0]

    @cached_property
    def ambient(self) -> tuple[NDArray, NDArray]:
        """The point ``p = M z + m`` and velocity ``v = M J c`` at the start, in the ambient frame (the chart's map
        ``M``, ``m`` read from :attr:`pars`)."""
        lay, N = self.family.layout, self.family.family.point_dim
        M = self.pars[lay.map_index : lay.map_index + N * N].reshape(N, N)
        m = self.pars[lay.map_index + N * N : lay.map_index + N * N + N]
        return M @ self.start[:N, 0] + m, M @ self.start[N : 2 * N, 0]

    @property
    def carried(self) -> NDArray:
        """What the loop carries after ``(a, c)``: the terms' slots from the segment before (empty on the first)."""
        k = self.family.family.dim
        return self.y[2 * k :]


class Term(ABC):
    """One piece of a compiled geodesic system (module docstring)."""

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """Identity of the equations it writes (compiled integrators are cached per family and tuple of keys)."""

    @property
    @abstractmethod
    def n_params(self) -> int:
        """Number of its runtime parameters, read at ``par[offset ..]``."""

    @abstractmethod
    def equations(self, pieces: SymbolicPieces, equations: list[tuple], offset: int) -> list[tuple]:
        """The system ``equations`` (pairs ``(variable, right-hand side)``, empty for the first term) with this term
        applied; its parameters are ``par[offset .. offset + n_params - 1]``."""

    def events(self, equations: list[tuple], offset: int) -> list[Event]:
        """Its terminal events, on the composed ``equations`` and its parameters ``par[offset ..]`` (none by
        default), numbered after the family's.

        The atlas loop acts on every event by its :attr:`~manifold.events.Event.kind`, the family's and the
        terms' alike (Sundman's stop, a :data:`~manifold.events.STOP`, ends the solve at ``t_final``).
        """
        return []

    def check(self, family: CompiledFamily, form: str) -> None:
        """Refuse a compiled family or a ``form`` of the state ``(a, c)`` that it cannot be composed with (default:
        none refused)."""

    def requires(self, state: StateTerm) -> None:
        """Refuse a composition whose state term it cannot follow (default: it follows any)."""

    def slots(self, segment: SegmentStart) -> NDArray:
        """The start values of the state slots its :meth:`equations` add, at the solve's first segment, in
        ``segment.fp_type`` (none by default).  The loop carries them after ``(a, c)`` from segment to segment and
        through chart switches unchanged (a term's slots are the same in every chart: ambient, say); a
        :class:`Clock` restarts its own in each segment instead."""
        return np.zeros(0, dtype=segment.y.dtype)

    def parameter_values(self, segment: SegmentStart) -> NDArray:
        """The values of its :attr:`n_params` runtime parameters for the segment starting at ``segment``, in
        ``segment.fp_type`` (none by default).  The stepper asks every term of its composition at each segment's
        start and appends the values, in the order of the terms, to the chart's parameters."""
        return np.zeros(0, dtype=segment.y.dtype)

    @property
    def moves_at_rest(self) -> bool:
        """Whether its slots change while the geodesic stays at its start (a Jacobi field does); if no term of a
        composition does, a start at rest is not integrated (the solution is the start)."""
        return False


class StateTerm(Term):
    """The first term of a composition: it sets the state the integrator carries.

    Attributes
    ----------
    label
        The state's name, e.g. ``"(a, J c)"``: a solution's ``method`` says which state was integrated.
    """

    label: str = "(a, c)"

    @abstractmethod
    def check(self, family: CompiledFamily, form: str) -> None:
        """Refuse a compiled family or a ``form`` it cannot integrate."""

    def enter(self, segment: SegmentStart) -> NDArray:
        """Its switch map on the way in: its state at the segment's start, from the loop's ``(a, c)`` (default: the
        loop's state is its own); the later terms' slots follow it (:meth:`Term.slots`)."""
        return segment.y[: 2 * segment.family.family.dim]

    def leave(self, advance: Advance, segment: SegmentStart) -> Advance:
        """Its switch map on the way out: the stepper's :class:`~manifold.steppers.Advance` in the integrated state,
        read back in the loop's ``(a, c)`` (states, end and dense output; default: unchanged)."""
        return advance

    def rewrapped(self, segment: SegmentStart) -> Callable[[Any], None] | None:
        """What its state needs after a periodic parameter was wrapped by ``2 pi`` between steps
        (:func:`~manifold.steppers.angle_wrap`): a function of the integrator's live state, or ``None`` (default:
        nothing; chart coefficients ``c`` are the same at ``a`` and ``a -+ 2 pi``)."""
        return None


class Clock(Term):
    """A term that changes the independent variable (Sundman's time): it runs the integrator over a segment."""

    @abstractmethod
    def advance(self, ta: Any, segment: SegmentStart, y: NDArray, pars: NDArray, offset: int,
                dense: bool, wrap: Callable[[], int] | None = None) -> Advance:
        """Run heyoka's integrator ``ta`` (its parameters ``pars``, this term's at ``pars[offset ..]``) from the
        integrated state ``y`` at ``segment.t`` to ``segment.t_final`` or the first event, in physical times: an
        :class:`~manifold.steppers.Advance` whose ``event`` indexes the composed events.  ``wrap``
        (:func:`~manifold.steppers.angle_wrap`) runs between every two steps; it returns the wraps it made, whose sum
        is :attr:`Advance.n_wraps`."""


class ChartGeodesic(StateTerm):
    """The chart's geodesic equations in the state ``(a, c)``, ``c = a'``, in the given ``form``
    (:meth:`~manifold.geodesic_system.SymbolicPieces.equations`); no parameters, and the loop's state is its own."""

    def __init__(self, form: str = "embedded") -> None:
        if form not in FORMS:
            raise ValueError(f"form must be one of {FORMS}, got {form!r}")
        self.form = form

    def __repr__(self) -> str:
        return f"ChartGeodesic({self.form!r})"

    @property
    def key(self) -> Hashable:
        return ("chart-geodesic", self.form)

    @property
    def n_params(self) -> int:
        return 0

    def equations(self, pieces: SymbolicPieces, equations: list[tuple], offset: int) -> list[tuple]:
        if equations:
            raise ValueError(f"{self!r} sets the state: it must be the first term")
        return pieces.equations(self.form)

    def check(self, family: CompiledFamily, form: str) -> None:
        if form != self.form:
            raise ValueError(f"form={form!r} asked of {self!r}")
