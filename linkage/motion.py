"""Free motion of a chain: geodesics of its kinetic-energy metric through the atlas.

:func:`free_motion` is a thin layer over :func:`manifold.solve_chart_exp_ode`
(``method="charts"``) and :func:`manifold.constrained.solve_constrained`
(``method="hinges"``);
:class:`ChainMotion` shows any method's solution in complex hinges instead of
interleaved real points.  :func:`free_motions` (many starts at once, on every
core or a Dask cluster; :mod:`linkage.ensemble`) and :func:`lyapunov_exponent`
(:mod:`linkage.lyapunov`) are re-exported here.
"""

from __future__ import annotations

import dataclasses
import inspect
from collections.abc import Sequence
from functools import cache, cached_property
from pathlib import Path
from typing import Any

import numpy as np

from numpy.typing import ArrayLike, NDArray

from manifold import GeodesicSolution, InducedMetric, solve_chart_exp_ode
from manifold.ambient_velocity import ConstrainedVelocity
from manifold.constrained import StartRefused, solve_constrained
from manifold.options import (DEFAULT_PRECISION, DEFAULT_SAVE, DEFAULT_START, PROJECTED_START, Precision, SaveAt,
                              StartCheck, check_group, takes_option_groups)
from manifold.progress import ProgressArgument
from manifold.sundman import SundmanStepper
from manifold.terms import Term

from .chain import STRETCHED_GAP, Chain
from .constraints import ChainSystem, chain_system, start_arguments, start_state
from .ensemble import EnsembleMotion, free_motions
from .lyapunov import lyapunov_exponent, lyapunov_exponents
from .time_factor import ChainTimeFactor

__all__ = ["AUTO", "CHART_STEPPER_OPTIONS", "METHODS", "ChainMotion", "EnsembleMotion", "check_method_options",
           "choose_method", "default_chart_stepper", "free_motion", "free_motions", "lyapunov_exponent",
           "lyapunov_exponents"]


class ChainMotion:
    """A solved free motion of a chain: any method's :class:`~manifold.GeodesicSolution`, in complex hinges.

    ``motion(t)`` evaluates complex hinges and velocities at any times of the
    dense output; ``times``, ``hinges``, ``velocities`` are the recorded
    states (the ``t_eval`` grid if one was asked for, else every step, read from the dense output);
    ``end_hinges``, ``end_velocities`` where the solve stopped, with or without dense output.

    Attributes
    ----------
    chain
        The chain.
    solution
        The underlying :class:`~manifold.GeodesicSolution` (status, stats,
        segments, switch log, energies, working-precision evaluation).
    """

    def __init__(self, chain: Chain, solution: GeodesicSolution) -> None:
        self.chain, self.solution = chain, solution

    def __repr__(self) -> str:
        rounded = "" if self.solution.fp_type is float else "; motion(t) rounds to complex128, motion.solution(t) keeps it"
        return f"ChainMotion({self.chain!r}, {self.solution!r}{rounded})"

    def __call__(self, t: ArrayLike) -> tuple[NDArray, NDArray]:
        """Complex hinges and hinge velocities at time(s) ``t``, rounded to complex128 (numpy has no complex type of
        long double's or quad's width); ``motion.solution(t)`` gives the interleaved real points and velocities in
        the working precision."""
        p, v = self.solution(t)
        return self.chain.from_point(p.astype(float)), self.chain.from_point(v.astype(float))

    @cached_property
    def _end(self) -> tuple[NDArray, NDArray]:
        # end_state() maps a chart state to the hinges in a compiled call: once for both properties
        p, v = self.solution.end_state()
        return self.chain.from_point(p.astype(float)), self.chain.from_point(v.astype(float))

    @property
    def end_hinges(self) -> NDArray:
        """Complex hinges where the solve stopped (at ``t_final``, or where it failed), rounded to complex128; kept
        with any :class:`~manifold.SaveAt`, ``SaveAt(dense=False)`` included (as
        :attr:`~linkage.ensemble.EnsembleMotion.end_hinges`)."""
        return self._end[0]

    @property
    def end_velocities(self) -> NDArray:
        """Complex hinge velocities where the solve stopped (as :attr:`end_hinges`)."""
        return self._end[1]

    @cached_property
    def _recorded(self) -> tuple[NDArray, NDArray, NDArray]:
        sol = self.solution
        if sol.t_eval is not None and sol.points is not None and sol.velocities is not None:
            return sol.t_eval, sol.points.astype(float), sol.velocities.astype(float)
        t = np.array([float(x) for x in sol.energy_times])
        p, v = sol(t)
        return t, p.astype(float), v.astype(float)

    @property
    def times(self) -> NDArray:
        """Times of the recorded states: the ``t_eval`` grid, else every step (from the dense output: without it and
        without a grid, ``ValueError``; :attr:`end_hinges` needs neither)."""
        return self._recorded[0]

    @property
    def hinges(self) -> NDArray:
        """Complex hinges at :attr:`times`, shape ``(len(times), n-1)``."""
        return self.chain.from_point(self._recorded[1])

    @property
    def velocities(self) -> NDArray:
        """Complex hinge velocities at :attr:`times`."""
        return self.chain.from_point(self._recorded[2])

    @property
    def energies(self) -> NDArray:
        """Kinetic energy ``1/2 v^T K v`` at :attr:`times` (float64)."""
        return self.chain.kinetic_energy(self.velocities)

    @property
    def closure_residuals(self) -> NDArray:
        """``max_k | |e_k| - l_k | / l_k`` at :attr:`times` (0 for an exact configuration)."""
        return self.chain.closure_residual(self.hinges)

    @property
    def success(self) -> bool:
        """True if the solve reached ``t_final``."""
        return self.solution.success

    @property
    def n_steps(self) -> int:
        """Accepted integration steps."""
        return self.solution.n_steps

    @property
    def n_switches(self) -> int:
        """Number of chart switches."""
        return self.solution.n_switches

    @property
    def relative_energy_error(self) -> float:
        """``max |E(t) - E(0)| / E(0)`` over the solver's own energy record."""
        return self.solution.relative_energy_error

    def to_html(self, path: str | Path, samples: int = 600, title: str | None = None) -> Path:
        """Write a self-contained HTML replay of the motion (three.js inside, no server, nothing from the network):
        the chain with a trail, the path on chart 0's sphere coloured by chart with the switches, the relative
        energy error.  :func:`linkage.explore.replay.write_replay`; needs dense output."""
        from .explore.replay import write_replay
        return write_replay(self, path, samples, title)

    @property
    def chart_ids(self) -> list:
        """Readable ids of the charts used, in order (a chart kept across an angle wrap counts once)."""
        metric = self.solution.metric
        if metric is None:  # a method given no atlas integrates in no chart
            return []
        ids = [metric.atlas.ids[s.chart] for s in self.solution.segments if s.chart is not None]
        return [c for k, c in enumerate(ids) if k == 0 or c != ids[k - 1]]


def chart_metric(chain: Chain) -> InducedMetric | None:
    """The kinetic-energy metric on the chain's atlas, or ``None`` where it has none (:attr:`Chain.has_atlas`).

    A hinge-space solution carrying it reads chart parameters on demand
    (``solution.parameters(t)``); without it, it has none.
    """
    return chain.metric() if chain.has_atlas else None


#: The free-motion methods: in the atlas of suspension charts, or in hinge coordinates with rod constraints.
METHODS = ("charts", "hinges")
#: ``free_motion``'s default: :func:`choose_method` picks one of :data:`METHODS` by measurement.
AUTO = "auto"


def _default_velocity(chain: Chain, kwargs: dict) -> ConstrainedVelocity | None:
    """The chart method's default state: ``(a, J c)`` with the rods' acceleration (0.6x the Taylor recursions of
    ``(a, c)``), except with rod densities, whose dense ``K^-1`` leaves the multiplier system's pivots generic:
    near the top of the range they lose digits (energy error 2.6e-11 against 1.4e-14 in ``(a, c)`` at
    ``L = R - 1e-3``, docs/methods.md), and where a ``form`` (embedded, christoffel) is asked for by name."""
    if "form" in kwargs or np.any(chain.rod_densities > 0):
        return None
    return ConstrainedVelocity(ChainSystem(chain))


def _hinge_solve(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, t_final: float, start: StartCheck,
                 **options: Any) -> GeodesicSolution:
    """:func:`free_motion`'s hinge method: the start checked once, in the compiled call that projects it
    (:func:`~linkage.constraints.start_arguments` in numpy before it), a refusal reported by
    :func:`~linkage.constraints.start_state` in the chain's terms."""
    h0, w0, t_final = start_arguments(chain, hinges0, velocity0, t_final)
    try:
        return solve_constrained(chain_system(chain), h0.view(float), w0.view(float), t_final,
                                 metric=chart_metric(chain), start=start, **options)
    except StartRefused as refused:
        start_state(chain, hinges0, velocity0, t_final, start)  # the refusal in the chain's terms, naming hinges0
        raise ValueError(f"the start lies within rounding of a tolerance of the start check, which the hinge "
                         f"solver's compiled check refuses: {refused}") from None


#: Options often written for the tolerance, ``precision=Precision(tol=...)`` (scipy's names).
_TOLERANCE_ALIASES = ("rtol", "atol", "tolerance")


#: The options of the charts' default stepper that ``free_motion`` takes for ``method="charts"`` (a ``stepper`` given
#: holds its own): its compile option, which the hinge solver takes too.
CHART_STEPPER_OPTIONS = ("compact_mode",)


@cache
def _method_options(method: str) -> tuple[str, ...]:
    """The options ``free_motion`` takes for the method: its solver's keyword options, passed on, and for the charts
    :data:`CHART_STEPPER_OPTIONS` (read once: ``inspect`` costs tens of microseconds, and a short call's fixed cost
    is counted)."""
    solver = solve_constrained if method == "hinges" else solve_chart_exp_ode
    parameters = inspect.signature(solver).parameters
    own = CHART_STEPPER_OPTIONS if method == "charts" else ()
    return tuple(sorted([name for name, p in parameters.items() if p.kind is inspect.Parameter.KEYWORD_ONLY
                         and name not in ("metric", "progress", "carry", "start", "save", "precision")] + list(own)))


def default_chart_stepper(chain: Chain, tol: float | None, velocity: ConstrainedVelocity | None,
                          compact_mode: bool | None = None, terms: Sequence[Term] = ()) -> SundmanStepper:
    """The chart method's default stepper: Sundman's time ``dt = det M dtau`` (13-44 % fewer steps).

    Parameters
    ----------
    chain
        The chain, whose :class:`~linkage.time_factor.ChainTimeFactor` sets the time.
    tol
        heyoka's tolerance (``None``: the default of the working precision).
    velocity
        The state term: a :class:`~manifold.ambient_velocity.ConstrainedVelocity`, the state ``(a, J c)``, or
        ``None``, the state ``(a, c)``.
    compact_mode
        heyoka's compile option; ``None`` (default) or ``True``: compact code; ``False``: straight-line code, which
        steps 1.2-2.5x faster in the state ``(a, J c)`` and compiles for 4-82 s at n = 3..8, once per machine,
        tolerance and direction (``docs/methods.md``, "Compile options").
    terms
        Further equation terms (carried quantities), as :class:`~manifold.steppers.TaylorStepper` takes them.

    Raises
    ------
    ValueError
        ``compact_mode=False`` in the state ``(a, c)``, whose unrolled code, with the chart's second derivatives,
        compiled for 185 s at n = 3 and had not finished after 900 s at n = 4.
    """
    if compact_mode is False and velocity is None:
        raise ValueError("compact_mode=False would compile the chart state (a, c), which free_motion takes with rod "
                         "densities or a form= given, unrolled: 185 s at n = 3 and over 900 s at n = 4; leave "
                         "compact_mode at its default, or give stepper=SundmanStepper(ChainTimeFactor(chain), "
                         "compact_mode=False) to pay that")
    compile_options = {} if compact_mode is None else {"compact_mode": compact_mode}
    return SundmanStepper(ChainTimeFactor(chain), tol=tol, velocity=velocity, terms=terms, **compile_options)


def choose_method(chain: Chain, options: dict[str, Any]) -> str:
    """The method that ``method="auto"`` stands for, for ``chain`` and ``free_motion``'s other options.

    The method that alone takes an option given (``stepper``, ``form``, ``q_out``: the charts;
    ``stabilisation``, ``rate``, ...: the hinges; both take ``compact_mode``); else ``"charts"``
    where the chain has an atlas and is nearly stretched (:attr:`Chain.stretch_gap
    <linkage.chain.Chain.stretch_gap>` below :data:`~linkage.chain.STRETCHED_GAP`: the top of a sphere range,
    where the hinge method's velocities collect errors that no check sees); otherwise ``"hinges"``, the faster at every size and precision measured (7-15x
    at equal error 1e-10 in float64 for n = 4..10 in the last two runs of ``benchmarks.peers``, 4.8-4.9x in
    real128 at n = 4: ``docs/methods.md``, "which method when").
    """
    charts, hinges, given = set(_method_options("charts")), set(_method_options("hinges")), set(options)
    if given & (charts - hinges):
        return "charts"
    if given & (hinges - charts):
        return "hinges"
    return "charts" if chain.stretch_gap < STRETCHED_GAP and chain.has_atlas else "hinges"


def check_method_options(method: str, options: dict[str, Any], function: str, also: tuple[str, ...] = ()) -> None:
    """``TypeError`` naming an option given to ``function`` that ``method`` does not take, with the options it does
    take: those ``free_motion`` passes on for the method (its solver's keyword options, and for the charts
    :data:`CHART_STEPPER_OPTIONS`) and ``also``."""
    taken = tuple(sorted((*_method_options(method), *also)))
    for name in options:
        if name not in taken:
            hint = "; the tolerance is precision=Precision(tol=...)" if name in _TOLERANCE_ALIASES else ""
            raise TypeError(f"{function}(method={method!r}) does not take {name}={options[name]!r}{hint} "
                            f"(its options: {', '.join(taken)})")


@takes_option_groups
def free_motion(
    chain: Chain,
    hinges0: ArrayLike,
    velocity0: ArrayLike,
    t_final: float,
    *,
    method: str = AUTO,
    save: SaveAt = DEFAULT_SAVE,
    precision: Precision = DEFAULT_PRECISION,
    start: StartCheck = DEFAULT_START,
    progress: ProgressArgument = None,
    **kwargs: Any,
) -> ChainMotion:
    """Integrate the chain's force-free motion from ``hinges0`` with hinge velocity ``velocity0``.

    The start is checked once, in hinge space, where the rod constraints give an
    exact tangency test independent of any chart: in numpy for the charts
    (:func:`linkage.constraints.start_state`), and for the hinges with the same bounds in the compiled call that
    also projects the start (:meth:`manifold.constrained.ConstrainedGeometry.start`; a refusal is reported in the
    chain's terms, by :func:`~linkage.constraints.start_state`).
    Both methods integrate the same geodesic of the kinetic-energy metric with
    heyoka's Taylor method and return the same :class:`ChainMotion`:

    * ``method="charts"``: in the atlas of suspension charts, switching chart
      at events (:func:`manifold.solve_chart_exp_ode`); gives chart
      parameters and the switch log; by default in Sundman's time
      ``dt = det M dtau`` (:class:`manifold.sundman.SundmanStepper` with
      :class:`linkage.time_factor.ChainTimeFactor`: the same motion in 13-44 %
      fewer steps; a ``stepper`` given is taken as it is: ``stepper=TaylorStepper()`` integrates in ``t``
      with the state ``(a, c)``) with the state
      ``(a, J c)`` and the rod constraints' acceleration
      (:class:`manifold.ambient_velocity.ConstrainedVelocity`: no second derivatives of the chart,
      0.6x the Taylor recursions; not with rod densities, nor when ``form`` is given: then ``(a, c)``);
      only where the chain has an atlas
      (:attr:`Chain.has_atlas`: the sphere with ``L`` its dominant side,
      ``R - 2 mu < L < R``; ``n - 2 < L < n`` for unit rods), else ``ValueError``
      naming ``method="hinges"``;
    * ``method="hinges"``: in hinge coordinates with the rod constraints and
      their multipliers (:func:`manifold.constrained.solve_constrained` on
      :class:`linkage.constraints.ChainSystem`); no chart, nothing singular,
      any generic lengths whatever the topology (spheres, tori, higher
      genus); chart parameters read on demand from the atlas where there is one.

    Parameters
    ----------
    chain
        The chain (its masses define the metric).  Its lengths must be generic
        (:meth:`Chain.check_generic`): ``ValueError`` naming the collinear
        configurations otherwise.
    hinges0, velocity0
        Complex interior hinges (must close to ``1e-9``) and their velocity
        (tangent: ``max_k l_k |(G v)_k| <= tangent_tol * max(1, |v|)``,
        :func:`linkage.constraints.start_state`, with ``start.tangent_tol``).
    t_final
        Final time (finite, nonzero; negative integrates backward).
    method
        ``"hinges"``, ``"charts"`` or ``"auto"`` (default): :func:`choose_method`, the hinges (the faster by
        measurement at every size and precision) except for a nearly stretched chain with an atlas, or where an
        option only the charts take is given.
    save
        :class:`manifold.SaveAt` ``(t_eval, dense)``: the times at which states are recorded, and whether to keep
        the continuous output (default) for ``motion(t)`` at any time.
    precision
        :class:`manifold.Precision` ``(fp_type, tol)``: the working precision (float64 by default; long
        double, real128, :class:`manifold.precision.MultiPrecision`) and heyoka's tolerance (``None``: the
        method's default for ``fp_type``).
    start
        :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the tolerance of the tangency check
        (default ``1e-9``), and whether a non-tangent ``velocity0`` is projected K-orthogonally instead of refused.
    progress
        ``True`` draws a tqdm bar of the time reached and prints a line per
        compile (what is compiled, and that heyoka caches it on disk); a
        callable receives each :class:`manifold.progress.ProgressUpdate`
        instead.  See :mod:`manifold.progress`.
    **kwargs
        The method's own options, passed on: to :func:`manifold.solve_chart_exp_ode` for ``"charts"``
        (``stepper``, ``q_out``, ``switching``, ``form``, ``max_switches``, ``throw``, ``budget``, ...; a
        ``stepper`` given takes its own tolerance, not ``precision.tol``), to
        :func:`manifold.constrained.solve_constrained` for ``"hinges"`` (``stabilisation``, ``rate``,
        ``projection_interval``, ``compact_mode``, ``throw``, ``budget``).  ``compact_mode`` is both methods'
        compile option (``None``, the default: compact for the charts, :func:`~linkage.motion.default_chart_stepper`;
        for the hinges :func:`manifold.constrained.default_compact_mode`); ``compact_mode=False`` makes the charts'
        default stepper straight-line code, which steps 1.2-2.5x faster and compiles once per machine, tolerance
        and direction for 4-82 s at n = 3..8 (not in the state ``(a, c)``: ``ValueError``).
    """
    if method not in (*METHODS, AUTO):
        raise ValueError(f"method must be one of {(*METHODS, AUTO)}, got {method!r}")
    precision, save = check_group("precision", precision, Precision), check_group("save", save, SaveAt)
    if method == AUTO:
        method = choose_method(chain, kwargs)
    check_method_options(method, kwargs, "free_motion")
    if method == "hinges":
        return ChainMotion(chain, _hinge_solve(chain, hinges0, velocity0, t_final, start, precision=precision,
                                               save=save, progress=progress, **kwargs))
    _, x0, v0, t_final = start_state(chain, hinges0, velocity0, t_final, start)
    # velocity0 is tangent to start.tangent_tol (checked above): the chart solver's projection only removes rounding
    compact_mode, stepper = kwargs.pop("compact_mode", None), kwargs.get("stepper")
    if stepper is None:  # Sundman's time: 13-44 % fewer steps (docs/methods.md)
        kwargs["stepper"] = default_chart_stepper(chain, precision.tol, _default_velocity(chain, kwargs), compact_mode)
        precision = dataclasses.replace(precision, tol=None)  # the stepper holds it
    elif compact_mode is not None:
        raise TypeError(f"free_motion(method='charts') takes compact_mode={compact_mode!r} for its default stepper "
                        f"only: the stepper given holds its own compile options ({type(stepper).__name__}(..., "
                        f"compact_mode=...))")
    solution = solve_chart_exp_ode(chain.metric(), x0, v0, t_final, precision=precision, save=save,
                                   start=PROJECTED_START, progress=progress, **kwargs)
    return ChainMotion(chain, solution)
