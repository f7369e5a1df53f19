"""Steppers: what advances the state inside one chart, between chart switches.

The atlas loop (:func:`manifold.geodesic_solver.solve_chart_exp_ode`) is
written once; a stepper only integrates the active chart's geodesic equations
from ``(t, y)`` until ``t_final`` or a terminal event, and says which.  The
events are declared once (:mod:`manifold.events`), numbered as in
:func:`~manifold.events.chart_events`: first the switch events (those the solve
needs: a quality whose floor lies above the threshold gets none), then two wrap
events per periodic parameter, which only a :class:`DenseStepper` meets: heyoka's steppers wrap the periodic
parameters between steps instead (:func:`angle_wrap`), so a wrap ends no segment there.

Two kinds of stepper:

* a :class:`DenseStepper` only steps: subclass it and implement
  :meth:`DenseStepper.stepping`, which yields the accepted steps with their
  dense interpolants; the events are located on them by the shared
  :func:`locate_events` (:class:`ScipyStepper` is one);
* a :class:`Stepper` that locates the events itself implements
  :meth:`Stepper.session` ``(family, fp_type, *, form, backward, switches)``, a context manager that prepares
  what it needs for one solve (compiled code, private mutable state) and yields an ``advance``
  function returning an :class:`Advance`, and, if it leaves out the switch events
  that cannot fire (``switches``), :meth:`Stepper.events` with the same list: :class:`TaylorStepper` compiles the
  events into heyoka's integrator (:func:`manifold.events.heyoka_events`), whose
  root finding on the Taylor polynomials misses no crossing inside a step.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray
import scipy.integrate
from scipy.integrate import OdeSolution

from .budget import allowance, dense_bytes_per_step, spend
from .compiled import DEFAULT_OPT_LEVEL, CompiledFamily
from .events import Event, first_crossing
from .interrupt import propagate_grid, propagate_until
from .precision import is_double, two_pi, unit_roundoff
from .progress import step_callback
from .solution import CallableDense, DenseOutput, PointDense, SecondOrderDense, TaylorDense
from .terms import ChartGeodesic, Clock, SegmentStart, StateTerm, Term
from .validation import check_bool, check_index, check_real

#: Largest accepted tolerance: looser runs are not geodesics (``tol = 1`` gave a 21 % energy error).
MAX_TOLERANCE = 1e-2


@dataclass
class Advance:
    """Where a stepper stopped and why.

    Attributes
    ----------
    t, y
        Time and state ``(a, c)`` reached, in the working precision.
    n_steps
        Accepted steps.
    event
        Index of the terminal event that stopped it; ``None`` if it reached ``t_final``.
    step_times, step_states
        Times after the start and states there (shape ``(m, 2k)``) at which the
        energy is recorded: every step with ``dense``, else only the end.
    dense
        Continuous output of the segment (``None`` unless asked for).
    failure
        Why the stepper broke down (``None`` if it did not).
    samples
        States at the times of the grid the stepper was given, in order, as many as it reached (``None``
        unless it sampled a grid itself: :func:`taylor_advance` with ``grid``).
    n_wraps
        Periodic parameters moved by ``2 pi`` between steps (:func:`angle_wrap`) inside the segment.
    """

    t: Any
    y: NDArray
    n_steps: int
    event: int | None
    step_times: NDArray
    step_states: NDArray
    dense: DenseOutput | None = None
    failure: str | None = None
    samples: NDArray | None = None
    n_wraps: int = 0


#: ``advance(t, y, t_final, pars, dense) -> Advance``
AdvanceFunction = Callable[[Any, NDArray, Any, NDArray, bool], Advance]


class Stepper(ABC):
    """Integrates one chart's geodesic equations between events (see the module docstring)."""

    name: str

    @abstractmethod
    def relative_tolerance(self, fp_type: Any) -> float:
        """The relative accuracy asked of each step, which scales the solver's energy check."""

    @abstractmethod
    def session(self, family: CompiledFamily, fp_type: Any, *, form: str, backward: bool,
                switches: tuple[int, ...] | None) -> Any:
        """Context manager yielding an :data:`AdvanceFunction` private to one solve, whose events are
        :meth:`events` ``(family, fp_type, form, switches)``."""

    def events(self, family: CompiledFamily, fp_type: Any, form: str,
               switches: tuple[int, ...] | None = None) -> list[Event]:
        """The terminal events that its :attr:`Advance.event` indexes (default: the family's switch events, those of
        its compiled integrators, :meth:`~manifold.compiled.CompiledFamily.composition`: a stepper that runs them
        wraps the periodic parameters between steps, :func:`angle_wrap`); the atlas loop acts on each by its kind.

        ``switches`` names the qualities whose switch events the solve needs (``None``: all); the others can never
        fire (:meth:`~manifold.family.ChartFamily.quality_floors`), and a stepper may leave them out.
        """
        return family.events(wraps=False)

    def moves_at_rest(self, form: str) -> bool:
        """Whether anything it integrates changes while the geodesic stays at its start (default: no; then the loop
        does not integrate a start at rest)."""
        return False


class TaylorStepper(Stepper):
    """heyoka's adaptive Taylor method with event detection (any precision), on a composition of equation terms.

    Parameters
    ----------
    tol
        heyoka's tolerance; ``None`` is :func:`~manifold.compiled.default_tolerance`:
        1e-14 in float64 (as accurate as the machine epsilon there, and 16-29 %
        cheaper), the machine epsilon of other types.  The energy check holds
        the default to the machine epsilon's bound, a given ``tol`` to its own.
    compact_mode, opt_level
        heyoka's compile options: compact mode (a loop over the decomposition
        instead of straight-line code) and LLVM's optimisation level, 0 to 3.
        Compact by default: unrolled code makes the default chart path (the state ``(a, J c)`` in Sundman's time)
        1.2-2.2x faster at n = 3..6 and 2.3-2.5x at n = 8, but compiles for 4-7 s at n = 3, 14-20 s at n = 4 and
        75-82 s at n = 8 (compact: 2-9 s), once per machine, tolerance and direction; the state ``(a, c)``, with
        the chart's second derivatives, compiled unrolled for 185 s at n = 3 (docs/methods.md, "Compile
        options").  ``compact_mode=False`` pays that once for long runs.  The default ``opt_level`` 1 steps 13-16 %
        faster than 3 and compiles ~2x faster (``benchmarks/taylor_options.py``).
    velocity
        ``None`` (default): the state is ``(a, c)`` (the embedded or Christoffel
        form, :class:`~manifold.terms.ChartGeodesic`).  A :class:`manifold.ambient_velocity.ConstrainedVelocity`: the
        state is ``(a, J c)`` and constraints give the acceleration, without
        the chart's second derivatives (a ``form`` other than ``"embedded"`` is then refused).  Any other
        :class:`~manifold.terms.StateTerm` sets the state the same way.
    terms
        The further equation terms (:class:`~manifold.terms.Term`, not state terms), composed after the state's in
        this order; at most one :class:`~manifold.terms.Clock` (:class:`manifold.sundman.SundmanTime`), which then
        runs each segment, and last.  Every term's parameter values are asked of it at each segment's start
        (:meth:`~manifold.terms.Term.parameter_values`), its slots' start values at the first
        (:meth:`~manifold.terms.Term.slots`), its events acted on by the loop.
    """

    name = "taylor"

    def __init__(self, tol: float | None = None, *, compact_mode: bool = True,
                 opt_level: int = DEFAULT_OPT_LEVEL, velocity: Any = None, terms: Sequence[Term] = ()) -> None:
        self.tol = None if tol is None else check_real("tol", tol, positive=True, at_most=MAX_TOLERANCE)
        self.compact_mode = check_bool("compact_mode", compact_mode)
        self.opt_level = check_index("opt_level", opt_level, 4)
        if velocity is not None and not isinstance(velocity, StateTerm):
            raise TypeError(f"velocity must be None or a manifold.ambient_velocity.ConstrainedVelocity instance "
                            f"(a manifold.terms.StateTerm), got {velocity!r}")
        self.velocity = velocity
        self.terms = tuple(terms)
        if not all(isinstance(term, Term) and not isinstance(term, StateTerm) for term in self.terms):
            raise TypeError(f"terms must hold manifold.terms.Term objects that are not state terms (give a state term "
                            f"as velocity=), got {self.terms!r}")
        clocks = [term for term in self.terms if isinstance(term, Clock)]
        if len(clocks) > 1 or (clocks and self.terms[-1] is not clocks[0]):
            raise ValueError(f"terms may hold at most one Clock (one independent variable), and last (it transforms "
                             f"every equation before it), got {self.terms!r}")
        self.clock: Clock | None = clocks[0] if clocks else None
        if velocity is not None:
            self.name = f"{self.name} {velocity.label}"  # the solution's method says which state was integrated

    def relative_tolerance(self, fp_type: Any) -> float:
        # The default tolerance is chosen to be as accurate as the machine epsilon, and is held to that: judged by
        # its own 1e-14, a run at n = 3, L = 1 + 4e-7 returned an energy error of 2.8e-10 as a success
        return taylor_relative_tolerance(self.tol, fp_type)

    def __repr__(self) -> str:
        velocity = "" if self.velocity is None else f", velocity={self.velocity!r}"
        terms = f", terms={self.terms!r}" if self.terms else ""
        return (f"TaylorStepper(tol={self.tol!r}, compact_mode={self.compact_mode}, opt_level={self.opt_level}"
                f"{velocity}{terms})")

    def state(self, family: CompiledFamily, form: str) -> StateTerm:
        """The term that sets the integrated state: ``velocity``, or the chart geodesic in ``form``; checked."""
        state = self._state(form)
        state.check(family, form)
        return state

    def _state(self, form: str) -> StateTerm:
        return ChartGeodesic(form) if self.velocity is None else self.velocity

    def composition(self, family: CompiledFamily, form: str) -> tuple[Term, ...]:
        """The terms it integrates: the state's, then :attr:`terms`, each checked against ``family`` and the state."""
        for term in self.terms:
            term.check(family, form)
        state = self.state(family, form)
        for term in self.terms:
            term.requires(state)
        return (state, *self.terms)

    def events(self, family: CompiledFamily, fp_type: Any, form: str,
               switches: tuple[int, ...] | None = None) -> list[Event]:
        """The composition's events, with the switch events of ``switches`` only: one that cannot fire would still
        cost its Taylor coefficients and a root search at every step."""
        return family.composition(fp_type, self.composition(family, form), switches)[1]

    def moves_at_rest(self, form: str) -> bool:
        return any(term.moves_at_rest for term in (self._state(form), *self.terms))

    @contextmanager
    def session(self, family: CompiledFamily, fp_type: Any, *, form: str, backward: bool,
                switches: tuple[int, ...] | None) -> Iterator[AdvanceFunction]:
        terms = self.composition(family, form)
        state, clock = self.state(family, form), self.clock
        offsets = np.cumsum([family.layout.terms_index] + [term.n_params for term in terms])
        with family.integrator(fp_type, self.tol, terms, backward, self.compact_mode, self.opt_level,
                               switches) as ta:
            def advance(t: Any, y: NDArray, t_final: Any, pars: NDArray, dense: bool) -> Advance:
                segment = SegmentStart(family, fp_type, t, y, t_final, pars)
                carried = segment.carried if segment.carried.size else np.concatenate(
                    [segment.carried] + [term.slots(segment) for term in self.terms])  # the first segment: starts
                y_in = np.concatenate([state.enter(segment), carried])
                if t_final == t:  # nothing to integrate (a switch event can end a segment exactly at t_final)
                    return state.leave(Advance(t, y_in, 0, None, np.array([t]), y_in[None, :],
                                               PointDense(y_in) if dense else None), segment)
                values = np.concatenate([pars] + [parameter_values(term, segment) for term in terms])
                wrap = angle_wrap(ta.state, family.family.periodic, fp_type, state.rewrapped(segment))
                if clock is None:
                    adv = taylor_advance(ta, t, y_in, t_final, values, dense, fp_type, wrap=wrap)
                else:
                    adv = clock.advance(ta, segment, y_in, values, int(offsets[terms.index(clock)]), dense, wrap)
                return state.leave(adv, segment)

            yield advance


def parameter_values(term: Term, segment: SegmentStart) -> NDArray:
    """``term``'s parameter values at ``segment``, refused unless there are as many as it declares."""
    values = term.parameter_values(segment)
    if len(values) != term.n_params:
        raise ValueError(f"{term!r} declares n_params = {term.n_params} but its parameter_values gave {len(values)}")
    return values


def taylor_relative_tolerance(tol: float | None, fp_type: Any) -> float:
    """The relative accuracy a heyoka run at ``tol`` asks of each step: ``tol``, or the machine epsilon if finer or ``None``."""
    return 2 * unit_roundoff(fp_type) if tol is None else max(tol, 2 * unit_roundoff(fp_type))


def angle_wrap(state: Any, periodic: Sequence[int], fp_type: Any,
               after: Callable[[Any], None] | None = None) -> Callable[[], int] | None:
    """Between two steps, move each periodic parameter ``state[p]`` that has left ``[-pi, pi]`` back by ``2 pi``,
    then call ``after(state)`` if it moved one (the state term's :meth:`~manifold.terms.StateTerm.rewrapped`); the
    function returns how many it moved (``None`` without periodic parameters).

    heyoka reads the state afresh at each step, so a wrap between steps costs neither a step nor a segment
    (terminal events at ``+-pi`` ended a segment at each wrap, and with it the conversions, the parameter packing and
    the grid's Newton solves around it: 8.7-9.0 ms against 7.4 ms of CPU for a T = 20 run at n = 4 with three wraps).
    The angle is at most one step's change past ``+-pi`` when it is wrapped (a start outside the range: after the
    first step); the chart map is periodic in it, and the dense output may read such a value inside a step.
    ``x -+ 2 pi`` is exact for ``x`` in ``[pi, 4 pi]`` (Sterbenz): a wrap rounds only through the constant ``2 pi``.

    Numerical trap: that rounding moves the point by 2.4e-16 in ``t``, forward along the motion at every wrap.  An
    ambient velocity ``V`` left as it was is then off the tangent space by as much, the constraint force does work
    on that part until the damping removes it, and the energy drifted one way: -1.9e-13 over T = 2e4 at n = 4 (six
    of six starts, 6.1 standard errors), -1.2e-12 over T = 1.2e5 (eight of eight).  So ``(a, J c)`` projects ``V``
    onto the tangent space at the wrapped point (``after``), as a segment's start did when a wrap ended one
    (+5.9e-14 over T = 2e4, 2.6 standard errors, against +7.7e-14 and 1.8 then).  Chart coefficients ``c`` need
    nothing.
    """
    if not periodic:
        return None
    turn = two_pi(fp_type)
    pi = turn / 2

    def wrap() -> int:
        moved = 0
        for p in periodic:
            x = state[p]
            if x > pi:
                state[p], moved = x - turn, moved + 1
            elif x < -pi:
                state[p], moved = x + turn, moved + 1
        if moved and after is not None:
            after(state)
        return moved

    return wrap


def taylor_advance(ta: Any, t: Any, y: NDArray, t_final: Any, pars: NDArray, dense: bool, fp_type: Any,
                   positions: int = 0, grid: NDArray | None = None, wrap: Callable[[], int] | None = None) -> Advance:
    """Run the heyoka integrator ``ta`` from ``(t, y)`` to ``t_final`` or its first terminal event.

    Shared by every Taylor method (chart geodesics, constrained motion): sets
    state, time and parameters, resets the event cooldowns, propagates, and
    keeps each step's Taylor coefficients in a :class:`TaylorDense` when ``dense``.
    With ``positions = N`` (a system whose whole state is ``(x, v)`` with ``x' = v``, ``N`` positions)
    it keeps only the positions' and a :class:`~manifold.solution.SecondOrderDense`, half the bytes.

    With a ``grid`` of times in ``[t, t_final]`` (integration order, in the working precision) and no ``dense``,
    heyoka evaluates the states there on each step's Taylor polynomials as it goes
    (:func:`manifold.interrupt.propagate_grid`, the same steps; no Python per step) into
    :attr:`Advance.samples`, and the states kept for the checks (:attr:`Advance.step_states`) are those at the
    grid's times after ``t`` and at the end.

    ``wrap`` (:func:`angle_wrap` on ``ta``'s state: a chart's periodic parameters) runs between every two steps, in
    a step callback.
    """
    if positions and len(y) != 2 * positions:
        raise ValueError(f"positions = {positions} needs a state (x, v) of {2 * positions} components, got {len(y)}")
    ta.state[:] = y
    ta.time = t
    ta.pars[:] = pars[: len(ta.pars)]
    n_events = len(ta.t_events) if ta.with_events else 0
    if n_events:
        ta.reset_cooldowns()
    progress = step_callback()  # None unless asked; it only reads the integrator: results are the same without it
    wraps = [0]

    def between(ta: Any) -> bool:
        if wrap is not None:
            wraps[0] += wrap()
        return progress is None or progress(ta)

    plain = between if wrap or progress else None  # the callback without dense output: none, unless needed
    if grid is not None and not dense:
        return replace(_sampled_advance(ta, t, t_final, grid, n_events, plain), n_wraps=wraps[0])
    step_times, tcs, tops = [ta.time], [], []
    # ta.tc is a view of the integrator's coefficient buffer, which heyoka fills in place at every step and never
    # moves (every precision): taken once here, not per step (~0.7 us a step), and only to keep it (~3 us a call)
    tc: Any = ta.tc if dense else None
    head: Any = tc[:positions] if dense else None  # the whole state is (x, v): the positions', the velocities' last
    top: Any = tc[positions:, -1] if dense else None

    def record(ta: Any) -> bool:
        tcs.append(tc.copy())
        step_times.append(ta.time)
        return between(ta)

    def record_positions(ta: Any) -> bool:
        tcs.append(head.copy())
        tops.append(top.copy())
        step_times.append(ta.time)
        return between(ta)

    # The Taylor coefficients of each step, kept by a step callback: heyoka's c_output gives the same numbers
    # but builds a continuous_output (an LLVM state) on every call, ~2.5 ms per segment.
    callback = (record_positions if positions else record) if dense else plain
    per_step = dense_bytes_per_step(ta, positions) if dense else 0
    outcome, n_steps, stop = propagate_until(ta, t_final, callback=callback, write_tc=dense,
                                             max_steps=allowance(per_step))
    spend(n_steps, per_step)
    y_end = np.array(ta.state)
    event, failure = _ending(outcome, stop, n_events)
    out: DenseOutput | None = None
    if dense and n_steps > 0 and positions:
        out = SecondOrderDense(np.array(step_times), np.array(tcs), np.array(tops), fp_type)
        times = out.times[1:]
        starts = np.concatenate([out.tcs[1:, :, 0], out.step_velocities[1:]], axis=1)  # v_0 = x_1 exactly
        states = np.concatenate([starts, y_end[None, :]])
    elif dense and n_steps > 0:
        out = TaylorDense(np.array(step_times), np.array(tcs), fp_type)
        times = out.times[1:]
        states = np.concatenate([out.tcs[1:, :, 0], y_end[None, :]])  # a step's order-0 term is its start
    else:
        out = PointDense(y_end) if dense else None
        times, states = np.array([ta.time]), y_end[None, :]
    return Advance(ta.time, y_end, n_steps, event, times, states, out, failure, n_wraps=wraps[0])


def _sampled_advance(ta: Any, t: Any, t_final: Any, grid: NDArray, n_events: int,
                     progress: Callable[[Any], bool] | None) -> Advance:
    """:func:`taylor_advance` of ``ta`` (state, time and parameters set) to ``t_final`` sampling ``grid`` in heyoka."""
    times = grid if len(grid) and grid[-1] == t_final else np.append(grid, t_final)  # the run ends at t_final
    outcome, n_steps, stop, states = propagate_grid(ta, times, callback=progress, max_steps=allowance(0))
    spend(n_steps, 0)
    y_end = np.array(ta.state)
    event, failure = _ending(outcome, stop, n_events)
    times = times[: len(states)]
    kept = (times != t) & np.concatenate([[True], times[1:] != times[:-1]])  # each time after the start once
    kept_times, kept_states = times[kept], states[kept]
    if not len(kept_times) or kept_times[-1] != ta.time:
        kept_times, kept_states = np.append(kept_times, ta.time), np.concatenate([kept_states, y_end[None, :]])
    return Advance(ta.time, y_end, n_steps, event, kept_times, kept_states, None, failure, states[: len(grid)])


def _ending(outcome: Any, stop: str | None, n_events: int) -> tuple[int | None, str | None]:
    """``(event, failure)`` of a propagation that ended with heyoka's ``outcome``: Ctrl-C or the budget (``stop``),
    a terminal event, heyoka's failure, or neither (it reached its time)."""
    if stop is None and outcome != hy.taylor_outcome.time_limit:
        return terminal_event(outcome, n_events)
    return None, stop


def terminal_event(outcome: Any, n_events: int) -> tuple[int | None, str | None]:
    """``(event, None)`` for heyoka's outcome of terminal event ``event`` (reported as ``-(event + 1)``),
    ``(None, why)`` for any other outcome that is not the time limit."""
    event = -outcome.value - 1
    return (event, None) if 0 <= event < n_events else (None, str(outcome))


@dataclass
class Step:
    """One accepted step of a :class:`DenseStepper`, from ``t_old`` to ``t``.

    ``y`` is the state at ``t``; ``interpolant`` the step's dense output, called as scipy's
    ``DenseOutput``: at a time inside the step it gives the state (shape ``(n,)``), at an array of
    times the states as columns (``(n, len(ts))``).
    """

    t_old: float
    t: float
    y: NDArray
    interpolant: Callable[[Any], NDArray]


class StepperFailure(Exception):
    """A :class:`DenseStepper` could not take its next step; the message says why."""


#: ``steps(t, y, t_final, pars) -> Iterator[Step]``: the accepted steps from ``(t, y)`` toward ``t_final``.
StepsFunction = Callable[[float, NDArray, float, NDArray], Iterator[Step]]


class DenseStepper(Stepper):
    """A stepper that only steps: the events are located on its dense output, by the shared locator.

    A subclass implements :meth:`stepping`; its :meth:`session` runs the steps
    and stops them at the family's first event (:func:`locate_events`), so the
    chart switches and wraps come with it.  float64 only (the locator finds
    roots in float64).
    """

    @abstractmethod
    def stepping(self, family: CompiledFamily, *, form: str, backward: bool) -> Any:
        """Context manager yielding a :data:`StepsFunction` for one solve.

        ``steps(t, y, t_final, pars)`` integrates the active chart's geodesic
        equations in the state ``(a, c)`` (``family.acceleration(float, form)``
        with the chart's parameters ``pars``) from ``(t, y)`` toward
        ``t_final`` and yields each accepted :class:`Step`, ending at
        ``t_final``; it raises :class:`StepperFailure` where it breaks down.
        """

    def events(self, family: CompiledFamily, fp_type: Any, form: str,
               switches: tuple[int, ...] | None = None) -> list[Event]:
        """All of the family's events, the wraps included: the locator ends a segment at each wrap."""
        return family.events()

    @contextmanager
    def session(self, family: CompiledFamily, fp_type: Any, *, form: str, backward: bool,
                switches: tuple[int, ...] | None) -> Iterator[AdvanceFunction]:
        """Steps with all of the family's events (:meth:`Stepper.events`: ``switches`` is not used; the locator
        evaluates every event in one compiled call per step)."""
        if not is_double(fp_type):
            raise ValueError(f"the {self.name} stepper runs in float64 only, got fp_type = {fp_type!r}")
        values = family.event_values(float)
        directions = np.array([e.direction for e in family.events()])
        with self.stepping(family, form=form, backward=backward) as steps:
            def advance(t: Any, y: NDArray, t_final: Any, pars: NDArray, dense: bool) -> Advance:
                pars = np.asarray(pars, dtype=float)

                def at(state: NDArray) -> NDArray:
                    return values(np.ascontiguousarray(state, dtype=float), pars=pars[: values.nparams])

                y = np.asarray(y, dtype=float)
                return locate_events(steps(float(t), y, float(t_final), pars), float(t), y, at, directions, dense)

            yield advance


def locate_events(steps: Iterator[Step], t: float, y: NDArray, values: Callable[[NDArray], NDArray],
                  directions: NDArray, dense: bool) -> Advance:
    """Run ``steps`` from ``(t, y)`` until the first event (:func:`manifold.events.first_crossing`) or their end.

    ``values(state)`` gives the events' values, then their rates ``dg/dt``
    (:meth:`~manifold.compiled.CompiledFamily.event_values`).  The step in
    which an event fires is cut at the event, and the state there read on its
    interpolant (as ``solve_ivp`` does).
    """
    m = len(directions)
    before = values(y)
    kept: list[Step] = []
    n_steps, event, failure = 0, None, None
    try:
        for step in steps:
            if step.t == step.t_old:
                continue
            n_steps += 1
            after = values(step.y)

            def on_step(s: float, interpolant: Callable[[Any], NDArray] = step.interpolant) -> NDArray:
                return values(interpolant(s))[:m]

            hit = first_crossing(directions, on_step, step.t_old, step.t, (before[:m], before[m:]),
                                 (after[:m], after[m:])) if m else None
            if hit is not None:
                event, t_event = hit
                if t_event != step.t_old:
                    y_event = step.y if t_event == step.t else np.asarray(step.interpolant(t_event))
                    kept.append(Step(step.t_old, t_event, y_event, step.interpolant))
                break
            if not dense:
                kept.clear()  # only the end state is needed
            kept.append(step)
            before = after
    except StepperFailure as e:
        failure = str(e)
    t_end, y_end = (kept[-1].t, kept[-1].y.copy()) if kept else (t, y.copy())
    out: DenseOutput | None = None
    if dense and kept:
        times = np.array([kept[0].t_old] + [s.t for s in kept])
        out = CallableDense(OdeSolution(times, [s.interpolant for s in kept]), len(kept), len(y))
        step_times, states = times[1:], np.array([s.y for s in kept])
    else:
        out = PointDense(y_end) if dense else None
        step_times, states = np.array([t_end]), y_end[None, :]
    return Advance(t_end, y_end, n_steps, event, step_times, states, out, failure)


#: The ``solve_ivp`` methods :class:`ScipyStepper` takes by name.
SCIPY_METHODS = ("RK23", "RK45", "DOP853", "Radau", "BDF", "LSODA")


class ScipyStepper(DenseStepper):
    """A ``scipy.integrate`` solver, step by step, on the family's compiled acceleration (float64 only), for comparisons.

    It only steps (``OdeSolver.step``); the chart switches and wraps are located on
    each step's dense output (:class:`DenseStepper`).

    Parameters
    ----------
    method
        One of :data:`SCIPY_METHODS` (``"DOP853"``, ``"RK45"``, ``"Radau"``, ...).
    rtol, atol
        scipy's tolerances.
    """

    def __init__(self, method: str = "DOP853", rtol: float = 1e-12, atol: float = 1e-12) -> None:
        if method not in SCIPY_METHODS:
            raise ValueError(f"method must be one of {SCIPY_METHODS}, got {method!r}")
        self.method = method
        self.rtol = check_real("rtol", rtol, positive=True, at_most=MAX_TOLERANCE)
        self.atol = check_real("atol", atol, positive=True, at_most=MAX_TOLERANCE)
        self.name = f"scipy-{method}"

    def relative_tolerance(self, fp_type: Any) -> float:
        return max(self.rtol, 2 * unit_roundoff(float))

    def __repr__(self) -> str:
        return f"ScipyStepper({self.method!r}, rtol={self.rtol!r}, atol={self.atol!r})"

    @contextmanager
    def stepping(self, family: CompiledFamily, *, form: str, backward: bool) -> Iterator[StepsFunction]:
        k = family.family.dim
        acc = family.acceleration(float, form)
        solver_class = getattr(scipy.integrate, self.method)

        def steps(t: float, y: NDArray, t_final: float, pars: NDArray) -> Iterator[Step]:
            acc_pars = pars[: acc.nparams]

            def rhs(_t: float, y: NDArray) -> NDArray:
                return np.concatenate([y[k:], acc(np.ascontiguousarray(y), pars=acc_pars)])

            if t == t_final:
                return
            solver = solver_class(rhs, t, y, t_final, rtol=self.rtol, atol=self.atol)
            while solver.status == "running":
                message = solver.step()
                if solver.status == "failed":
                    raise StepperFailure(f"{self.method} failed at t = {solver.t}: {message}")
                yield Step(solver.t_old, solver.t, solver.y.copy(), solver.dense_output())

        yield steps
