"""Sundman's time for the chart path: integrate in ``tau`` with ``dt = s(p) dtau``.

A Taylor step is limited by the nearest singularity of the solution in complex
time.  For a submanifold given by constraints ``c(p) = 0`` with a constant
ambient metric ``K``, the motion is singular where ``M = G K^-1 G^T`` is (``G``
the constraints' Jacobian), and these are the singularities that limit the
chart path's steps (``benchmarks/sundman_time.py``).  With ``s = det M`` (or any
positive multiple), the system

    dy/dtau = s(p) f(y),        dt/dtau = s(p)

has the same orbits with those singularities moved away, and takes fewer steps;
``s`` must be that of the real motion's ``K``: a factor for the wrong metric
gains little.  The factor is a :class:`TimeFactor` of the ambient point
``p = M z(a) + m`` (each chart's own map, passed as runtime parameters), so
nothing here knows what the constraints are.

:class:`SundmanTime` is an equation term (:mod:`manifold.terms`) and a clock: composed after the state's in
a :class:`~manifold.steppers.TaylorStepper` (:class:`SundmanStepper` is that stepper), each
segment runs in ``tau`` from 0 until the segment's time
``u = (t - t_start) / (t_final - t_start)`` reaches 1 (its stop event, on which the loop ends the solve) or a
switch event fires, and reports physical times (``u`` restarts from the time reached every
:data:`RESTART_STEPS` steps: ``t = origin + (t_final - origin) u``).  Its dense
output (:class:`SundmanDense`) finds ``tau`` for a requested ``t`` by Newton's
method on the step's polynomial ``u(tau)``, monotone in ``tau``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Sequence
from types import SimpleNamespace
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray

from .budget import allowance, dense_bytes_per_step, spend
from .compiled import CompiledFamily
from .events import Event, stop_event
from .geodesic_system import SymbolicPieces
from .interrupt import propagate_until
from .precision import as_fp, unit_roundoff
from .progress import step_callback
from .solution import DenseOutput, PointDense, TaylorDense, polynomial_values
from .steppers import Advance, TaylorStepper, terminal_event
from .terms import Clock, SegmentStart, Term

#: Bound on ``|tau|`` of one segment; the segment ends by its ``u = 1`` event long before (``tau`` is about
#: ``t / s``, and ``s`` stays positive on the manifold).
TAU_LIMIT = 1e30
#: Newton iterations allowed for ``tau(t)`` in a step (from the chord's guess, 3-6 are used).
NEWTON_ITERATIONS = 30
#: Steps after which the segment's time ``u`` restarts at 0 (:func:`sundman_advance`).
RESTART_STEPS = 16


class TimeFactor(ABC):
    """A positive function ``s(p; kappa)`` of the ambient point whose complex zeros are the motion's singularities.

    It should be dimensionless, of order 1 on ordinary configurations: the Taylor coefficients in
    ``tau`` scale like its powers, and a factor of 1e20 overflows them at order 15.

    Attributes
    ----------
    ambient_dim
        Dimension ``N`` of the ambient points ``p`` it takes.
    n_params
        Number of its parameters ``kappa``.
    """

    ambient_dim: int
    n_params: int

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """Identity of the expression (compiled code is cached per chart family and key)."""

    @abstractmethod
    def expression(self, p: Sequence[hy.expression], pars: Sequence[hy.expression]) -> hy.expression:
        """``s`` at the ambient point ``p`` (expressions) with parameters ``pars`` (``n_params`` expressions)."""

    @abstractmethod
    def parameters(self) -> NDArray:
        """The values of ``kappa`` (float64, ``n_params``)."""


class SundmanTime(Clock):
    """Sundman's time as an equation term (:mod:`manifold.terms`): the right-hand sides times ``s(p)``, the segment's
    time ``u`` as one more state slot, and its stop event ``u = 1`` (:func:`manifold.events.stop_event`).

    Its parameters: ``1 / (t_final - origin)``, then the factor's (:meth:`~manifold.geodesic_system.SymbolicPieces.sundman_equations`),
    their values given at each segment's start (:meth:`parameter_values`).  A :class:`~manifold.terms.Clock`: it runs
    each segment in ``tau`` (:func:`sundman_advance`: ``u`` starts at 0 and restarts every :data:`RESTART_STEPS`
    steps), reporting physical times.
    """

    def __init__(self, factor: TimeFactor) -> None:
        if not isinstance(factor, TimeFactor):
            raise TypeError(f"factor must be a manifold.sundman.TimeFactor, got {type(factor).__name__}")
        self.factor = factor
        self._kappa: dict[Any, NDArray] = {}  # fp_type -> the factor's parameter values

    def __repr__(self) -> str:
        return f"SundmanTime({self.factor!r})"

    @property
    def key(self) -> Hashable:
        return ("sundman", self.factor.key)

    @property
    def n_params(self) -> int:
        return 1 + self.factor.n_params

    def equations(self, pieces: SymbolicPieces, equations: list[tuple], offset: int) -> list[tuple]:
        return pieces.sundman_equations(self.factor, equations, offset)

    def events(self, equations: list[tuple], offset: int) -> list[Event]:
        return [stop_event(equations[-1][0])]

    def check(self, family: CompiledFamily, form: str) -> None:
        """Refuse a factor of points of another dimension than the family's."""
        if self.factor.ambient_dim != family.family.point_dim:
            raise ValueError(f"factor: {self.factor!r} takes points of R^{self.factor.ambient_dim}, the charts of "
                             f"{family.family!r} give points of R^{family.family.point_dim}")

    def parameter_values(self, segment: SegmentStart) -> NDArray:
        """``1 / (t_final - t)`` (the segment's span, from its start) and the factor's ``kappa``."""
        fp = segment.fp_type
        if fp not in self._kappa:
            self._kappa[fp] = as_fp(self.factor.parameters(), fp)
        return np.concatenate([as_fp([1.0], fp) / (segment.t_final - segment.t), self._kappa[fp]])

    def advance(self, ta: Any, segment: SegmentStart, y: NDArray, pars: NDArray, offset: int,
                dense: bool, wrap: Callable[[], int] | None = None) -> Advance:
        return sundman_advance(ta, segment.t, y, segment.t_final, pars, dense, segment.fp_type, offset, wrap)

    def __getstate__(self) -> dict:
        """Pickle the factor only (the cached values are rebuilt)."""
        return {"factor": self.factor}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["factor"])  # type: ignore[misc]


class SundmanDense:
    """Dense output of a segment integrated in Sundman's time, evaluated at physical times.

    Parameters
    ----------
    tau_dense
        The Taylor polynomials in ``tau`` of the state ``(y, u)`` (:class:`~manifold.solution.TaylorDense`).
    origins, spans
        Per step, ``t = origin + span u`` (the run restarts ``u`` at 0 every few steps, :func:`sundman_advance`).
    u_ends
        Per step, ``u`` at its end.
    """

    def __init__(self, tau_dense: TaylorDense, origins: NDArray, spans: NDArray, u_ends: NDArray) -> None:
        self.tau_dense, self.origins, self.spans, self.u_ends = tau_dense, origins, spans, u_ends
        self._t_ends = (origins + spans * u_ends).astype(float)
        self._sign = 1.0 if float(spans[0]) > 0 else -1.0

    @property
    def nbytes(self) -> int:
        """Bytes held: the polynomials and the steps' time maps."""
        return self.tau_dense.nbytes + int(self.origins.nbytes + self.spans.nbytes + self.u_ends.nbytes)

    def __call__(self, ts: NDArray) -> NDArray:
        """States ``(len(ts), 2k)`` at the physical times ``ts`` (inside the segment)."""
        fp = self.tau_dense.fp_type
        ts = as_fp(ts, fp)
        s = np.searchsorted(self._t_ends[:-1] * self._sign, ts.astype(float) * self._sign, side="left")
        target = (ts - self.origins[s]) / self.spans[s]
        times, coeffs = self.tau_dense.times, self.tau_dense.tcs[s, -1, :]  # u(tau) of each point's step
        width, u_start = times[s + 1] - times[s], coeffs[:, 0]
        h = width * (target - u_start) / (self.u_ends[s] - u_start)  # the chord's guess
        slope = coeffs[:, 1:] * np.arange(1, coeffs.shape[1])
        eps = 8 * unit_roundoff(fp)
        for _ in range(NEWTON_ITERATIONS):
            rate = polynomial_values(slope, h)  # du/dtau: of the sign of tau's direction, never 0
            step = (polynomial_values(coeffs, h) - target) / rate
            h = h - step
            # converged to what u's own rounding (eps |u| <= eps, u in [0, 1]) leaves of tau: eps / |rate|
            if np.all(np.abs(step.astype(float)) <= eps * np.abs((width + 1 / rate).astype(float))):
                break
        else:
            raise ArithmeticError(f"Sundman time: tau(t) did not converge in {NEWTON_ITERATIONS} Newton steps "
                                  f"(largest step {np.max(np.abs(step.astype(float))):.3g})")
        return self.tau_dense.at(s, h)[:, :-1]


def sundman_advance(ta: Any, t: Any, y: NDArray, t_final: Any, pars: NDArray, dense: bool, fp_type: Any,
                    span_index: int, wrap: Callable[[], int] | None = None) -> Advance:
    """Run the Sundman integrator ``ta`` of the chart from ``(t, y)`` (``t != t_final``) to ``t_final`` or its first
    switch event.

    ``pars`` are every parameter of the composition (the chart's, each term's), :class:`SundmanTime`'s first,
    the span ``1 / (t_final - t)``, at ``span_index``.  Times in the result are physical; a segment that reaches
    ``t_final`` ends exactly there, reporting its stop event (``u = 1``, located by heyoka to a rounding; the last of
    the composition's), on which the atlas loop ends the solve.

    Numerical trap: ``u`` is a state variable, so each step rounds it by ``eps |u|``, and ``t`` by
    ``eps |u (t_final - t_start)|``; over a long segment that would pile up to ``eps`` times the
    segment's length per step.  So every :data:`RESTART_STEPS` steps ``u`` restarts at 0 from the time
    reached, which bounds the loss by about ``(RESTART_STEPS + steps / RESTART_STEPS) eps |t_final|`` over
    the whole run (each restart rounds ``origin + span u`` once; heyoka keeps its own time in double-length
    arithmetic, so ``t`` in the plain stepper has no such loss).  A restart, in the step callback, falls
    between steps, so it costs no step (heyoka reads state and parameters afresh at each step).  A factor
    that vanishes on the path would stop ``t``: a restart that finds the time unmoved ends the segment as
    a failure instead of looping.  The same callback runs ``wrap`` (:func:`~manifold.steppers.angle_wrap`).
    """
    ta.state[:] = np.append(y, fp_type(0.0))
    ta.time = fp_type(0.0)
    ta.pars[:] = pars[: len(ta.pars)]
    ta.reset_cooldowns()
    progress = step_callback()
    n_events, forward = len(ta.t_events), float(t_final - t) > 0  # dt/dtau > 0: tau runs with t
    taus, tcs, origins, spans = [ta.time], [], [], []
    clock = {"origin": t, "span": t_final - t, "steps": 0, "now": t, "stalled": False}  # t = origin + span u
    # views of the integrator's coefficients and state, which heyoka updates in place and never moves (every
    # precision): taken once, not per step (~0.5 us each a step)
    tc, live = ta.tc, ta.state
    wraps = [0]

    def record(ta: Any) -> bool:
        origin, span = clock["origin"], clock["span"]
        clock["steps"] += 1
        if dense:
            tcs.append(tc.copy())
            taus.append(ta.time)
            origins.append(origin)
            spans.append(span)
        now = clock["now"] = origin + span * live[-1]
        if progress is not None:
            progress(SimpleNamespace(time=now))
        if clock["steps"] % RESTART_STEPS == 0 and now != t_final:  # between steps (1 / 0 if t_final is hit exactly)
            if abs(float(now - origin)) <= RESTART_STEPS * unit_roundoff(fp_type) * abs(float(span)):
                # s(p) has vanished on the path: t no longer moves
                clock["stalled"] = True
                return False
            clock["origin"], clock["span"] = now, t_final - now
            live[-1] = fp_type(0.0)
            ta.pars[span_index] = 1 / clock["span"]
        if wrap is not None:
            wraps[0] += wrap()
        return True

    per_step = dense_bytes_per_step(ta) if dense else 0
    outcome, n_steps, stop = propagate_until(ta, fp_type(TAU_LIMIT if forward else -TAU_LIMIT), callback=record,
                                             write_tc=dense, max_steps=allowance(per_step))
    spend(n_steps, per_step)
    state = np.array(live)
    y_end = state[:-1]
    event, failure, t_end = None, None, clock["origin"] + clock["span"] * state[-1]
    if stop is not None:  # Ctrl-C or the budget: the callback recorded the last step whole before it stopped
        failure = stop
    elif outcome == hy.taylor_outcome.time_limit:
        failure = f"Sundman time reached |tau| = {TAU_LIMIT:g} before t_final"
    elif clock["stalled"]:
        failure = f"Sundman time stalled at t = {clock['now']}: the time factor vanished on the path"
    else:
        event, failure = terminal_event(outcome, n_events)
        if event == n_events - 1:  # u = 1: t_final reached, exactly
            t_end = t_final
    if failure is not None:
        t_end = clock["now"]  # the last step's end, not a failed step's (heyoka keeps the state before it)
    out: DenseOutput | None = None
    if dense and n_steps > 0:
        tau_dense = TaylorDense(np.array(taus), np.array(tcs), fp_type)
        widths = tau_dense.times[1:] - tau_dense.times[:-1]
        u_ends = polynomial_values(tau_dense.tcs[:, -1, :], widths)
        out = SundmanDense(tau_dense, np.array(origins), np.array(spans), u_ends)
        times = out.origins + out.spans * u_ends
        times[-1] = t_end
        states = np.concatenate([tau_dense.tcs[1:, :-1, 0], y_end[None, :]])
    else:
        out = PointDense(y_end) if dense else None
        times, states = np.array([t_end]), y_end[None, :]
    return Advance(t_end, y_end, n_steps, event, times, states, out, failure, n_wraps=wraps[0])


class SundmanStepper(TaylorStepper):
    """heyoka's Taylor method in Sundman's time ``dt = s(p) dtau`` (see the module docstring): a
    :class:`~manifold.steppers.TaylorStepper` with the term :class:`SundmanTime` composed after the state's.

    Parameters
    ----------
    factor
        The :class:`TimeFactor` (for a chain: :class:`linkage.time_factor.ChainTimeFactor`).
    tol, compact_mode, opt_level, velocity
        As for :class:`~manifold.steppers.TaylorStepper`.
    terms
        Further terms, composed before Sundman's time (which multiplies their equations too): for instance
        :class:`manifold.ambient_velocity.ChartCarried` s.
    """

    name = "taylor-sundman"

    def __init__(self, factor: TimeFactor, tol: float | None = None, *, terms: Sequence[Term] = (),
                 **options: Any) -> None:
        # SundmanTime refuses anything but a TimeFactor
        super().__init__(tol, terms=(*terms, SundmanTime(factor)), **options)
        self.factor = factor

    def __repr__(self) -> str:
        velocity = "" if self.velocity is None else f", velocity={self.velocity!r}"
        terms = f", terms={self.terms[:-1]!r}" if self.terms[:-1] else ""
        return (f"SundmanStepper({self.factor!r}, tol={self.tol!r}, compact_mode={self.compact_mode}, "
                f"opt_level={self.opt_level}{velocity}{terms})")
