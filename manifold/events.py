"""Terminal events of a chart geodesic: declared once, located by heyoka or on a stepper's dense output.

An :class:`Event` is a function ``g`` of the state (a heyoka expression) and a
direction: the motion stops where ``g`` crosses zero that way.  The chart
family's events (:func:`chart_events`, numbered in this order everywhere) are

* one switch event per quality expression, ``quality_m(a) - q_out``, falling
  (the chart's quality sinks to the threshold before its singular set), except for the
  qualities whose floor lies above ``q_out`` (they can never fire:
  :meth:`~manifold.family.ChartFamily.quality_floors`);
* two wrap events per periodic parameter ``a_p``: ``a_p - pi`` rising and
  ``a_p + pi`` falling (the loop wraps ``a_p`` by ``-+ 2 pi`` and stays in the chart), for the
  steppers that locate events on dense output only: heyoka's Taylor steppers wrap between steps
  instead (:func:`manifold.steppers.angle_wrap`), which ends no segment;

and Sundman's time adds a stop event, last (:func:`stop_event`).

**Direction convention** (the one place it is fixed): a direction is the sign
of ``dg/dt`` *along the motion*, in the order the integration visits the
times; a backward run (``t_final < 0``) meets the same events in the same
directions.  heyoka's directions refer to increasing time, so
:func:`heyoka_events` mirrors them for a backward integrator; the locator
below works in the order of the steps and needs no mirroring.

Two ways to locate them:

* heyoka's Taylor steppers compile them as terminal events
  (:func:`heyoka_events`): heyoka isolates the roots of each step's Taylor
  polynomial of ``g``, so no crossing inside a step is missed.
* Any other stepper only steps; :func:`first_crossing` finds an event on each
  step's dense interpolant, as ``scipy.integrate.solve_ivp`` does for its own
  events (a sign change of ``g`` between the step's ends, then Brent's method
  on the interpolant), and also a dip through zero and back inside one step
  (a grazing event: ``g`` heads for zero at the step's start and away at its
  end; the extremum is found on the interpolant, and the crossing before it).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq, minimize_scalar

from .precision import event_fp_kwargs

#: Directions of :attr:`Event.direction`: the sign of ``dg/dt`` along the motion at the crossing (0: either).
FALLING, EITHER, RISING = -1, 0, 1
#: Kinds of :attr:`Event.kind`: what the atlas loop does when it fires.
SWITCH, WRAP, STOP = "switch", "wrap", "stop"


@dataclass(frozen=True)
class Event:
    """A terminal event: the motion stops where ``expression`` crosses zero in ``direction``.

    Attributes
    ----------
    expression
        ``g``, a heyoka expression of the state variables and runtime parameters.
    direction
        :data:`FALLING`, :data:`RISING` or :data:`EITHER`: the sign of ``dg/dt`` along the motion (module docstring).
    kind
        :data:`SWITCH` (change chart), :data:`WRAP` (add ``shift * 2 pi`` to the periodic parameter
        ``parameter``, same chart) or :data:`STOP` (the solve ends there, successfully: Sundman's time reaching
        ``t_final``, or any term's own end of the motion; the message says where if before ``t_final``).
    parameter, shift
        For a wrap: the index of the periodic parameter and the sign of the ``2 pi`` added.
    """

    expression: Any
    direction: int
    kind: str
    parameter: int | None = None
    shift: int = 0


def chart_events(pieces: Any, switches: Sequence[int] | None = None, wraps: bool = True) -> list[Event]:
    """The chart family's events, in their canonical order: the switch events, then two wraps per periodic parameter
    (unless ``wraps`` is false: the Taylor integrators wrap between steps).

    ``pieces`` is the family's :class:`~manifold.geodesic_system.SymbolicPieces`; ``q_out`` is its runtime parameter
    (:attr:`~manifold.geodesic_system.Layout.q_out_index`), so one compiled system serves every threshold.
    ``switches``: the indices of the qualities whose switch events are kept (``None``: all; see
    :meth:`~manifold.family.ChartFamily.quality_floors` for the ones that can never fire).
    """
    q_out = hy.par[pieces.layout.q_out_index]
    kept = range(len(pieces.quality)) if switches is None else switches
    events = [Event(pieces.quality[m] - q_out, FALLING, SWITCH) for m in kept]
    for p in pieces.family.periodic if wraps else ():
        events += [Event(pieces.a[p] - hy.pi, RISING, WRAP, p, -1), Event(pieces.a[p] + hy.pi, FALLING, WRAP, p, 1)]
    return events


def stop_event(u: hy.expression) -> Event:
    """Sundman's stop: the segment's time ``u`` (from 0 at its start) reaching 1."""
    return Event(u - 1.0, EITHER, STOP)


def heyoka_events(events: Sequence[Event], backward: bool, fp_type: Any) -> list[hy.t_event]:
    """heyoka's terminal events for ``events``: its directions refer to increasing time, so mirrored when ``backward``."""
    sense = -1 if backward else 1
    directions = {1: hy.event_direction.positive, -1: hy.event_direction.negative, 0: hy.event_direction.any}
    fp = event_fp_kwargs(fp_type)
    return [hy.t_event(e.expression, direction=directions[sense * e.direction], **fp) for e in events]


def event_slopes(events: Sequence[Event], a: Sequence[hy.expression], c: Sequence[hy.expression]) -> list:
    """``dg/dt = sum_i (dg/da_i) c_i`` of each event along a chart geodesic ``a' = c``.

    The chart's events are functions of the parameters ``a`` (and runtime parameters) only; an event that
    reads any other state variable is refused: its slope would need the equations of that variable.
    """
    names = {str(x) for x in a}
    for e in events:
        other = set(hy.get_variables(e.expression)) - names
        if other:
            raise ValueError(f"an event located on dense output must be a function of the chart parameters; "
                             f"{e.expression} also reads {sorted(other)}")
    jac = hy.diff_tensors([e.expression for e in events], list(a), diff_order=1).jacobian
    return [hy.sum([jac[m, i] * c[i] for i in range(len(a))]) for m in range(len(events))]


def first_crossing(directions: NDArray, g: Callable[[float], NDArray], t0: float, t1: float,
                   start: tuple[NDArray, NDArray], end: tuple[NDArray, NDArray]) -> tuple[int, float] | None:
    """The first event crossed in the step from ``t0`` to ``t1`` (either order), as ``(index, time)``; ``None`` if none.

    An event fires in the step where ``h = d g`` (``d`` its direction, both signs for :data:`EITHER`) goes from
    ``h(t0) <= 0`` to ``h(t1) > 0``, or from ``h(t0) < 0`` to ``h(t1) = 0``: one that lands exactly on a step's end
    fires there, and a start exactly on an event heading across it (an angle at ``-pi`` moving down) fires at
    the start, so the loop acts on it instead of running past.  Where ``h`` stays negative at both ends but
    heads up at ``t0`` and down at ``t1`` (a dip toward zero inside the step), its maximum on the interpolant is
    found, and if it reaches zero, the crossing before it.  Of the events that fire, the earliest along the motion
    wins (ties: the lowest index).  Roots are found by Brent's method to a few units of rounding in ``t``.

    Parameters
    ----------
    directions
        Each event's direction (:data:`FALLING`, :data:`RISING`, :data:`EITHER`), along the motion.
    g
        The events' values at a time inside the step, read on the stepper's dense interpolant.
    start, end
        ``(values, slopes)`` of the events at ``t0`` and ``t1``: ``g`` and ``dg/dt``.
    """
    (g0, s0), (g1, s1) = start, end
    forward = 1.0 if t1 >= t0 else -1.0
    best: tuple[int, float] | None = None
    for m, direction in enumerate(directions):
        for d in ((1, -1) if direction == EITHER else (direction,)):
            t = _crossing(lambda t: d * g(t)[m], t0, t1, d * g0[m], d * g1[m], forward * d * s0[m],
                          forward * d * s1[m])
            if t is not None and (best is None or forward * (t - best[1]) < 0):
                best = (m, t)
    return best


def _crossing(h: Callable[[float], float], t0: float, t1: float, h0: float, h1: float, rise0: float,
              rise1: float) -> float | None:
    """Where ``h`` first reaches zero from below in the step (``rise``: ``dh`` per step of the motion at each end)."""
    if h0 <= 0 < h1 or h0 < 0 == h1:
        return t1 if h1 == 0 else (t0 if h0 == 0 else _root(h, t0, t1))
    if not (h0 < 0 and h1 < 0 and rise0 > 0 and rise1 < 0):
        return None
    # a dip toward zero inside the step: the maximum of h on the interpolant, then the crossing before it
    lo, hi = min(t0, t1), max(t0, t1)
    peak = minimize_scalar(lambda t: -h(t), bounds=(lo, hi), method="bounded",
                           options={"xatol": 4 * np.finfo(float).eps * max(abs(lo), abs(hi), 1.0)})
    t_peak = float(peak.x)
    if h(t_peak) < 0:
        return None
    return _root(h, t0, t_peak)


def _root(h: Callable[[float], float], t0: float, t1: float) -> float:
    """The root of ``h`` between ``t0`` (``h < 0``) and ``t1`` (``h >= 0``) by Brent's method.

    The interpolant may round differently from the step's own end values: where it shows no sign change, the
    crossing is at the end that it puts on zero's far side.
    """
    if h(t0) >= 0:
        return t0
    if h(t1) <= 0:
        return t1
    lo, hi = min(t0, t1), max(t0, t1)
    # numerical trap: brentq's default xtol (2e-12, absolute) is far coarser than the times of a long run resolve
    xtol = 2 * np.finfo(float).eps * max(abs(lo), abs(hi), np.finfo(float).tiny)
    return float(brentq(h, lo, hi, xtol=xtol, rtol=4 * np.finfo(float).eps))
