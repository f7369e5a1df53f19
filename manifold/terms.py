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
  chart's own (:attr:`~manifold.geodesic_system.Layout.terms_index`);
* its **events** (:meth:`Term.events`), after the family's switch and wrap
  events (:mod:`manifold.events`);
* its **switch map**: how the atlas loop's state ``(a, c)`` maps to the term's
  state at each segment's start and back at its end
  (:meth:`StateTerm.wrap`; the chart switch itself acts on ``(a, c)``).

The terms: :class:`ChartGeodesic` (the state ``(a, c)``, the default),
:class:`manifold.ambient_velocity.ConstrainedVelocity` (the state ``(a, J c)``,
with :mod:`manifold.carried` terms after it) and
:class:`manifold.sundman.SundmanTime` (Sundman's time).  A new term is a
subclass in its own file, passed by the stepper that integrates it.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable
from typing import Any

from .events import Event
from .geodesic_system import FORMS, SymbolicPieces


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

    def events(self, equations: list[tuple]) -> list[Event]:
        """Its terminal events, on the composed ``equations`` (none by default), numbered after the family's.

        The atlas loop acts on the family's switch and wrap events; a term's own are acted on by the stepper
        that integrates it (Sundman's stop ends the segment at ``t_final``: :func:`manifold.sundman.sundman_advance`).
        """
        return []


class StateTerm(Term):
    """The first term of a composition: it sets the state the integrator carries."""

    @abstractmethod
    def check(self, family: Any, form: str) -> None:
        """Refuse a compiled family (:class:`~manifold.compiled.CompiledFamily`) or a ``form`` it cannot integrate."""

    @abstractmethod
    def wrap(self, advance: Callable, family: Any, fp_type: Any) -> Callable:
        """Its switch map: an :data:`~manifold.steppers.AdvanceFunction` in the loop's ``(a, c)`` around ``advance``,
        which integrates this term's state, its parameters' values appended to the chart's."""


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

    def check(self, family: Any, form: str) -> None:
        if form != self.form:
            raise ValueError(f"form={form!r} asked of {self!r}")

    def wrap(self, advance: Callable, family: Any, fp_type: Any) -> Callable:
        return advance
