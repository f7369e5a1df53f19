"""Steppers: what advances the state inside one chart, between chart switches.

The atlas loop (:func:`manifold.geodesic_solver.solve_chart_exp_ode`) is
written once; a stepper only integrates the active chart's geodesic equations
from ``(t, y)`` until ``t_final`` or a terminal event, and says which.  Events
are numbered as in :meth:`~manifold.geodesic_system.SymbolicPieces.events`:
first the ``n_quality`` switch events, then two wrap events per periodic
parameter.

To add a stepper, subclass :class:`Stepper` and implement :meth:`Stepper.session`:
a context manager that prepares what the stepper needs for one solve
(compiled code, private mutable state) and yields an ``advance`` function
returning an :class:`Advance`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from .budget import allowance, dense_bytes_per_step, spend
from .compiled import DEFAULT_OPT_LEVEL, CompiledFamily
from .interrupt import propagate_until
from .precision import as_fp, is_double, unit_roundoff
from .progress import step_callback
from .solution import CallableDense, DenseOutput, PointDense, SecondOrderDense, TaylorDense
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
    """

    t: Any
    y: NDArray
    n_steps: int
    event: int | None
    step_times: NDArray
    step_states: NDArray
    dense: DenseOutput | None = None
    failure: str | None = None


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
                switching: bool) -> Any:
        """Context manager yielding an :data:`AdvanceFunction` private to one solve."""


class TaylorStepper(Stepper):
    """heyoka's adaptive Taylor method with event detection (any precision).

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
        Straight-line code steps 3.4x faster at n = 3 but compiled for 185 s
        (n = 4: over 900 s), once per machine with heyoka's disk cache; the
        default ``opt_level`` 1 steps 13-16 % faster than 3 and compiles ~2x
        faster (``benchmarks/taylor_options.py``).
    velocity
        ``None`` (default): the state is ``(a, c)`` (the embedded or Christoffel
        form).  A :class:`manifold.ambient_velocity.ConstrainedVelocity`: the
        state is ``(a, J c)`` and constraints give the acceleration, without
        the chart's second derivatives (a ``form`` other than ``"embedded"`` is then refused).
    """

    name = "taylor"

    def __init__(self, tol: float | None = None, *, compact_mode: bool = True,
                 opt_level: int = DEFAULT_OPT_LEVEL, velocity: Any = None) -> None:
        self.tol = None if tol is None else check_real("tol", tol, positive=True, at_most=MAX_TOLERANCE)
        self.compact_mode = check_bool("compact_mode", compact_mode)
        self.opt_level = check_index("opt_level", opt_level, 4)
        # duck-typed, since manifold.ambient_velocity imports this module
        if velocity is not None and (isinstance(velocity, type) or not all(
                hasattr(velocity, attr) for attr in ("wrap", "check", "key", "pieces", "n_params", "parameters"))):
            raise TypeError(f"velocity must be None or a manifold.ambient_velocity.ConstrainedVelocity instance, "
                            f"got {velocity!r}")
        self.velocity = velocity
        if velocity is not None:
            self.name = f"{type(self).name} (a, J c)"  # the solution's method says which state was integrated

    def relative_tolerance(self, fp_type: Any) -> float:
        # The default tolerance is chosen to be as accurate as the machine epsilon, and is held to that: judged by
        # its own 1e-14, a run at n = 3, L = 1 + 4e-7 returned an energy error of 2.8e-10 as a success
        return taylor_relative_tolerance(self.tol, fp_type)

    def __repr__(self) -> str:
        velocity = "" if self.velocity is None else f", velocity={self.velocity!r}"
        return f"TaylorStepper(tol={self.tol!r}, compact_mode={self.compact_mode}, opt_level={self.opt_level}{velocity})"

    @contextmanager
    def session(self, family: CompiledFamily, fp_type: Any, *, form: str, backward: bool,
                switching: bool) -> Iterator[AdvanceFunction]:
        velocity = self.velocity
        if velocity is not None:
            velocity.check(family, form)
        with family.integrator(fp_type, self.tol, form, backward, self.compact_mode, self.opt_level,
                               velocity=velocity) as ta:
            if velocity is None:
                yield lambda t, y, t_final, pars, dense: taylor_advance(ta, t, y, t_final, pars, dense, fp_type)
                return
            # the constraint system's parameters after the chart's and the (unused in t) span's slot, then what
            # the wrap appends to the chart's (the damping rate of the normal drift)
            tail = np.concatenate([as_fp([0.0], fp_type), velocity.parameters(fp_type)])
            span = family.layout.span_index
            yield velocity.wrap(lambda t, y, t_final, pars, dense: taylor_advance(
                ta, t, y, t_final, np.concatenate([pars[:span], tail, pars[span:]]), dense, fp_type), family, fp_type)


def taylor_relative_tolerance(tol: float | None, fp_type: Any) -> float:
    """The relative accuracy a heyoka run at ``tol`` asks of each step: ``tol``, or the machine epsilon if finer or ``None``."""
    return 2 * unit_roundoff(fp_type) if tol is None else max(tol, 2 * unit_roundoff(fp_type))


def taylor_advance(ta: Any, t: Any, y: NDArray, t_final: Any, pars: NDArray, dense: bool, fp_type: Any,
                   positions: int = 0) -> Advance:
    """Run the heyoka integrator ``ta`` from ``(t, y)`` to ``t_final`` or its first terminal event.

    Shared by every Taylor method (chart geodesics, constrained motion): sets
    state, time and parameters, resets the event cooldowns, propagates, and
    keeps each step's Taylor coefficients in a :class:`TaylorDense` when ``dense``.
    With ``positions = N`` (a system whose whole state is ``(x, v)`` with ``x' = v``, ``N`` positions)
    it keeps only the positions' and a :class:`~manifold.solution.SecondOrderDense`, half the bytes.
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
    step_times, tcs, tops = [ta.time], [], []

    def record(ta: Any) -> bool:
        tcs.append(ta.tc.copy())
        step_times.append(ta.time)
        return progress is None or progress(ta)

    def record_positions(ta: Any) -> bool:
        tc = ta.tc
        tcs.append(tc[:positions].copy())
        tops.append(tc[positions:, -1].copy())  # the whole state is (x, v): these are the velocities'
        step_times.append(ta.time)
        return progress is None or progress(ta)

    # The Taylor coefficients of each step, kept by a step callback: heyoka's c_output gives the same numbers
    # but builds a continuous_output (an LLVM state) on every call, ~2.5 ms per segment.
    callback = (record_positions if positions else record) if dense else progress
    per_step = dense_bytes_per_step(ta, positions) if dense else 0
    outcome, n_steps, stop = propagate_until(ta, t_final, callback=callback, write_tc=dense,
                                             max_steps=allowance(per_step))
    spend(n_steps, per_step)
    y_end = np.array(ta.state)
    event: int | None = None
    failure: str | None = stop  # Ctrl-C or the budget stopped it, else heyoka's outcome says
    if stop is None and outcome != hy.taylor_outcome.time_limit:
        event, failure = terminal_event(outcome, n_events)
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
    return Advance(ta.time, y_end, n_steps, event, times, states, out, failure)


def terminal_event(outcome: Any, n_events: int) -> tuple[int | None, str | None]:
    """``(event, None)`` for heyoka's outcome of terminal event ``event`` (reported as ``-(event + 1)``),
    ``(None, why)`` for any other outcome that is not the time limit."""
    event = -outcome.value - 1
    return (event, None) if 0 <= event < n_events else (None, str(outcome))


class ScipyStepper(Stepper):
    """``scipy.integrate.solve_ivp`` on the family's compiled acceleration (float64 only), for comparisons.

    Parameters
    ----------
    method
        Any ``solve_ivp`` method (``"DOP853"``, ``"RK45"``, ``"Radau"``, ...).
    rtol, atol
        scipy's tolerances.
    """

    def __init__(self, method: str = "DOP853", rtol: float = 1e-12, atol: float = 1e-12) -> None:
        self.method = method
        self.rtol = check_real("rtol", rtol, positive=True, at_most=MAX_TOLERANCE)
        self.atol = check_real("atol", atol, positive=True, at_most=MAX_TOLERANCE)
        self.name = f"scipy-{method}"

    def relative_tolerance(self, fp_type: Any) -> float:
        return max(self.rtol, 2 * unit_roundoff(float))

    def __repr__(self) -> str:
        return f"ScipyStepper({self.method!r}, rtol={self.rtol!r}, atol={self.atol!r})"

    @contextmanager
    def session(self, family: CompiledFamily, fp_type: Any, *, form: str, backward: bool,
                switching: bool) -> Iterator[AdvanceFunction]:
        if not is_double(fp_type):
            raise ValueError(f"the scipy stepper runs in float64 only, got fp_type = {fp_type!r}")
        k = family.family.dim
        acc = family.acceleration(float, form)
        qcf = family.quality(float) if switching else None
        current = {"pars": np.zeros(0)}
        events: list = []  # scipy's events, each with its index in the canonical numbering
        indices: list[int] = []
        if qcf is not None:
            for m in range(family.n_quality):
                def quality(t: float, y: NDArray, m: int = m) -> float:
                    pars = current["pars"]
                    return qcf(y[:k], pars=pars[: qcf.nparams])[m] - pars[family.layout.q_out_index]
                events.append(_terminal(quality, -1))
                indices.append(m)
        for w, p in enumerate(family.family.periodic):
            events += [_terminal(lambda t, y, p=p: y[p] - np.pi, 1), _terminal(lambda t, y, p=p: y[p] + np.pi, -1)]
            indices += [family.n_quality + 2 * w, family.n_quality + 2 * w + 1]
        # scipy's event directions follow the integration (unlike heyoka's): no mirroring when backward

        def rhs(_t: float, y: NDArray) -> NDArray:
            return np.concatenate([y[k:], acc(np.ascontiguousarray(y), pars=current["pars"][: acc.nparams])])

        def advance(t: Any, y: NDArray, t_final: Any, pars: NDArray, dense: bool) -> Advance:
            current["pars"] = np.asarray(pars, dtype=float)
            res = solve_ivp(rhs, (float(t), float(t_final)), np.asarray(y, dtype=float), method=self.method,
                            rtol=self.rtol, atol=self.atol, events=events or None, dense_output=dense)
            n_steps = len(res.t) - 1
            out = CallableDense(res.sol, n_steps, 2 * k) if dense and res.sol is not None else None
            event, failure = None, None
            if res.status == -1:
                failure = f"{self.method} failed at t = {res.t[-1]}: {res.message}"
            elif res.status == 1:
                event = indices[next(m for m, te in enumerate(res.t_events) if len(te))]
            y_end = res.y[:, -1].copy()
            states = res.y[:, 1:].T if dense else y_end[None, :]
            times = res.t[1:] if dense else res.t[-1:]
            return Advance(res.t[-1], y_end, n_steps, event, times, states, out, failure)

        yield advance


def _terminal(f: Callable, direction: int) -> Callable:
    f.terminal, f.direction = True, direction  # type: ignore[attr-defined]
    return f
