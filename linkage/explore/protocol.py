"""The explorer's requests and answers, without any web framework: validation, solves and JSON payloads.

Every request is a JSON object with a fixed set of fields; anything else is refused with a
:class:`RequestError` that names the field, the bad value and what is valid (the server answers it with
status 400, or 413 for work over the budget).  Complex numbers travel as ``[re, im]`` pairs, so a
configuration of ``n - 1`` hinges is a list of ``n - 1`` pairs.

The numbers come from the library only: :func:`solve_motion` is :func:`linkage.motion.free_motion` with a
``t_eval`` grid, and :func:`motion_payload` reads the recorded samples of its :class:`~linkage.motion.ChainMotion`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from manifold.budget import Budget
from manifold.options import DEFAULT_START, Precision, SaveAt
from manifold.progress import ProgressUpdate
from manifold.solution import SolveStatus
from manifold.validation import ArgumentError

from ..chain import Chain
from ..constraints import HingeConstraints, start_state
from ..draw import sphere_coordinates
from ..motion import METHODS, ChainMotion, free_motion

__all__ = ["CHAIN_FIELDS", "MOTION_FIELDS", "PRECISIONS", "Cancelled", "Limits", "MotionRequest", "RequestError",
           "as_pairs", "check_fields", "drag_hinge", "motion_payload", "motion_request", "parse_chain",
           "parse_complex", "parse_configuration", "read_choice", "read_integer", "read_number", "read_numbers",
           "solve_motion", "tangent_velocity"]

#: The precisions a client may ask for: the library's ``fp_type`` names, with the relative cost of a step in each
#: (measured: a T = 10 solve at n = 4 takes about 4x as long in long double and 60x in real128 as in float64).
PRECISIONS = {"float64": 1.0, "longdouble": 4.0, "real128": 60.0}

#: Fields that describe the chain (every request that needs one).
CHAIN_FIELDS = ("lengths", "L", "masses")
#: The request field of each argument of :class:`~linkage.chain.Chain` that a request sets (and a refusal can name).
CHAIN_ARGUMENT_FIELDS = {"lengths": "lengths", "L": "L", "hinge_masses": "masses"}
#: Fields of a motion request (``POST /api/motion``).
MOTION_FIELDS = (*CHAIN_FIELDS, "hinges", "velocity", "T", "method", "precision", "samples")

#: A drag is projected from the configuration with the dragged hinge this many times heavier than the heaviest
#: other hinge: the K-smallest correction then leaves it (nearly) where the pointer put it.
DRAG_WEIGHT = 1e6


class RequestError(ValueError):
    """A request the server refuses: ``field`` names what is wrong, ``status`` is the HTTP status to answer with."""

    def __init__(self, field: str, message: str, status: int = 400) -> None:
        super().__init__(f"{field}: {message}")
        self.field, self.message, self.status = field, message, status

    def as_json(self) -> dict[str, Any]:
        """The JSON body of the error answer."""
        return {"error": self.message, "field": self.field, "status": self.status}


@dataclass(frozen=True)
class Limits:
    """The work one request may ask for.

    The estimated cost of a motion is ``|T| (n - 1) w`` with ``w`` the precision's weight
    (:data:`PRECISIONS`); a request above ``max_cost`` is refused before anything runs.  The solve itself then
    spends at most ``max_steps`` Taylor steps (:class:`manifold.budget.Budget`), which catches the chains whose
    motion needs far more steps per unit time than the estimate assumes (a light hinge that whips).

    Attributes
    ----------
    max_cost
        Largest estimated cost (default 3000: T = 1000 at n = 4 in float64, T = 16 in real128).
    max_samples
        Most samples of a motion returned at once.
    max_n
        Most rods.
    max_steps
        Taylor steps one solve may take.
    """

    max_cost: float = 3000.0
    max_samples: int = 20001
    max_n: int = 16
    max_steps: int = 2_000_000

    def cost(self, n: int, T: float, precision: str) -> float:
        """Estimated cost ``|T| (n - 1) w`` of a motion."""
        return abs(T) * (n - 1) * PRECISIONS[precision]

    def check_cost(self, n: int, T: float, precision: str) -> None:
        """:class:`RequestError` with status 413 if the motion's estimated cost is over ``max_cost``."""
        cost = self.cost(n, T, precision)
        if cost > self.max_cost:
            raise RequestError(
                "T", f"the estimated cost |T| (n - 1) w = {abs(T):g} * {n - 1} * {PRECISIONS[precision]:g} "
                f"({precision}) = {cost:g} exceeds this server's budget of {self.max_cost:g}: ask for a shorter T "
                f"or a cheaper precision, or start the server with a larger --budget", status=413)


def check_fields(body: object, allowed: tuple[str, ...], required: tuple[str, ...]) -> dict[str, Any]:
    """``body`` if it is a JSON object with only ``allowed`` fields and every ``required`` one."""
    if not isinstance(body, dict):
        raise RequestError("body", f"the request must be a JSON object with the fields {', '.join(allowed)}, "
                                   f"got {type(body).__name__}")
    unknown = sorted(set(body) - set(allowed))
    if unknown:
        raise RequestError(unknown[0], f"unknown field {unknown[0]!r}; the fields are {', '.join(allowed)}")
    for name in required:
        if name not in body:
            raise RequestError(name, f"missing field {name!r} (required: {', '.join(required)})")
    return body


def read_number(field: str, value: object, *, positive: bool = False, nonzero: bool = False) -> float:
    """A finite JSON number (not a boolean, not a string)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise RequestError(field, f"must be a number, got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise RequestError(field, f"must be finite, got {value!r}")
    if positive and x <= 0:
        raise RequestError(field, f"must be > 0, got {value!r}")
    if nonzero and x == 0:
        raise RequestError(field, f"must be nonzero, got {value!r}")
    return x


def read_integer(field: str, value: object, low: int, high: int) -> int:
    """A JSON integer in ``[low, high]``."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise RequestError(field, f"must be an integer in [{low}, {high}], got {value!r}")
    return value


def read_choice(field: str, value: object, choices: tuple[str, ...]) -> str:
    """One of the strings ``choices``."""
    if not isinstance(value, str) or value not in choices:
        raise RequestError(field, f"must be one of {', '.join(repr(c) for c in choices)}, got {value!r}")
    return value


def read_numbers(field: str, value: object, size: int | None = None) -> NDArray:
    """A JSON list of finite numbers (of ``size`` entries if given)."""
    if not isinstance(value, list) or (size is not None and len(value) != size):
        expected = "a list of numbers" if size is None else f"a list of {size} numbers"
        raise RequestError(field, f"must be {expected}, got {value!r}")
    return np.array([read_number(f"{field}[{k}]", x) for k, x in enumerate(value)])


def parse_complex(field: str, value: object, size: int) -> NDArray:
    """A JSON list of ``size`` pairs ``[re, im]`` of finite numbers, as a complex array."""
    if not isinstance(value, list) or len(value) != size:
        raise RequestError(field, f"must be a list of {size} complex numbers as [re, im] pairs (n - 1 = {size} "
                                  f"hinges), got {value!r}")
    out = np.empty(size, dtype=complex)
    for k, pair in enumerate(value):
        re, im = read_numbers(f"{field}[{k}]", pair, 2)
        out[k] = complex(re, im)
    return out


def as_pairs(z: NDArray) -> list:
    """Complex array of any shape as nested lists with ``[re, im]`` pairs in place of the numbers."""
    return np.stack([z.real, z.imag], axis=-1).tolist()


def parse_chain(body: dict[str, Any], limits: Limits) -> Chain:
    """The chain of a request: ``lengths`` (an integer ``n``: unit rods, or a list of rod lengths), ``L``, and
    ``masses`` (optional: a number, or a list of ``n - 1`` hinge masses; default 1)."""
    lengths = body.get("lengths")
    if isinstance(lengths, bool) or not isinstance(lengths, (int, list)):
        raise RequestError("lengths", f"must be an integer n (n unit rods) or a list of rod lengths, got {lengths!r}")
    if isinstance(lengths, int):
        n = read_integer("lengths", lengths, 2, limits.max_n)
        rods: int | NDArray = n
    else:
        rods = read_numbers("lengths", lengths)
        n = len(rods)
        if not 2 <= n <= limits.max_n:
            raise RequestError("lengths", f"must have between 2 and {limits.max_n} rods, got {n}")
        if np.any(rods <= 0):
            raise RequestError("lengths", f"rod lengths must be > 0, got {lengths!r}")
    L = read_number("L", body.get("L"), positive=True)
    masses = body.get("masses", 1.0)
    weights = read_numbers("masses", masses, n - 1) if isinstance(masses, list) else read_number("masses", masses)
    if np.any(np.asarray(weights) <= 0):
        raise RequestError("masses", f"hinge masses must be > 0, got {masses!r}")
    try:
        chain = Chain(rods, L, hinge_masses=weights)
    except ArgumentError as err:  # masses out of range, or an empty space (the side too long: L or a rod)
        raise RequestError(CHAIN_ARGUMENT_FIELDS[err.argument], str(err)) from None
    return chain


def parse_configuration(chain: Chain, field: str, value: object) -> NDArray:
    """Complex hinges that close (to 1e-9 relative to each rod, :meth:`Chain.check_configuration`)."""
    h = parse_complex(field, value, chain.n - 1)
    try:
        return chain.check_one_configuration(h, field)
    except ValueError as err:
        raise RequestError(field, f"is off the constraints: {err}") from None


@dataclass(frozen=True)
class MotionRequest:
    """A validated motion request."""

    chain: Chain
    hinges: NDArray
    velocity: NDArray
    T: float
    method: str
    precision: str
    samples: int

    @property
    def times(self) -> NDArray:
        """The sample times ``linspace(0, T, samples)``."""
        return np.linspace(0.0, self.T, self.samples)


def motion_request(body: object, limits: Limits, *, fields: tuple[str, ...] = MOTION_FIELDS) -> MotionRequest:
    """Validate a motion request: the chain, a start on its constraints, a tangent velocity, ``T`` within the budget.

    ``method`` defaults to ``"charts"`` where the chain has an atlas, else ``"hinges"``; ``precision`` to
    ``"float64"``; ``samples`` to 201.
    """
    body = check_fields(body, fields, ("lengths", "L", "hinges", "velocity", "T"))
    chain = parse_chain(body, limits)
    T = read_number("T", body["T"], nonzero=True)
    method = read_choice("method", body.get("method", "charts" if chain.has_atlas else "hinges"), METHODS)
    precision = read_choice("precision", body.get("precision", "float64"), tuple(PRECISIONS))
    samples = read_integer("samples", body.get("samples", 201), 2, limits.max_samples)
    try:
        chain.check_generic()
    except ValueError as err:
        raise RequestError("L", str(err)) from None
    if method == "charts" and not chain.has_atlas:
        raise RequestError("method", f"'charts' needs an atlas, and this chain has none ({chain.topology().summary()}); "
                                     "use 'hinges'")
    hinges = parse_configuration(chain, "hinges", body["hinges"])
    velocity = parse_complex("velocity", body["velocity"], chain.n - 1)
    try:
        start_state(chain, hinges, velocity, T, DEFAULT_START)
    except ValueError as err:
        raise RequestError("velocity", f"is not tangent to the constraints at hinges: {err}") from None
    if not np.any(velocity):
        raise RequestError("velocity", "must be nonzero (a chain at rest does not move)")
    limits.check_cost(chain.n, T, precision)
    return MotionRequest(chain, hinges, velocity, T, method, precision, samples)


class Cancelled(Exception):
    """The client went away: the solve was stopped."""


def solve_motion(request: MotionRequest, limits: Limits, cancelled: Callable[[], bool] | None = None) -> ChainMotion:
    """:func:`linkage.motion.free_motion` of the request on its sample grid, within ``limits.max_steps`` steps.

    ``cancelled`` is asked at every progress report of the solve (every segment, and at most every 0.2 s inside
    one); when it returns true the solve stops with :class:`Cancelled`.  A solve that ends short of ``T`` (its
    budget of steps spent, a failed check) raises :class:`RequestError` with status 422 and the solver's message.
    """
    def report(update: ProgressUpdate) -> None:
        if cancelled is not None and cancelled():
            raise Cancelled(f"cancelled at t = {update.t:g}")

    motion = free_motion(request.chain, request.hinges, request.velocity, request.T, method=request.method,
                         precision=Precision(request.precision), save=SaveAt(request.times),
                         budget=Budget(steps=limits.max_steps),
                         throw=False, progress=report if cancelled is not None else False)
    if motion.solution.status is not SolveStatus.SUCCESS:
        raise RequestError("T", f"the solve stopped at t = {float(motion.solution.t_reached):g} of T = "
                                f"{request.T:g}: {motion.solution.message}", status=422)
    return motion


def motion_payload(motion: ChainMotion, *, times: NDArray | None = None, energy0: float | None = None,
                   t0: float = 0.0) -> dict[str, Any]:
    """The JSON answer of a solved motion: its samples, their relative energy error, charts and switches.

    Parameters
    ----------
    motion
        A solve with a ``t_eval`` grid, or with dense output if ``times`` are given.
    times
        Times to sample the motion at (its dense output); default: its recorded times.
    energy0
        The energy that the errors are relative to (default: the motion's own energy at its first sample).
    t0
        Added to every time (a motion that continues an earlier one).

    Returns
    -------
    dict
        ``times``; ``hinges`` and ``velocities`` (``[re, im]`` pairs); ``energyError`` ``|E(t) - E0| / E0`` per
        sample from the float64 samples, and ``maxEnergyError`` the solver's own record in the working precision;
        ``chart`` the integrating chart of each sample (``-1`` for ``method="hinges"``, which integrates in no
        chart) and ``chartIds`` the atlas's chart names; ``switches`` ``{t, from, to}`` of the solve;
        ``angles`` the rod angles of each sample and ``sphere`` its point of the round sphere in chart-0
        coordinates (:func:`linkage.draw.sphere_coordinates`; ``None`` without an atlas).
    """
    chain, solution = motion.chain, motion.solution
    if times is None:
        times, hinges, velocities = motion.times, motion.hinges, motion.velocities
    else:
        hinges, velocities = motion(times)
    energies = chain.kinetic_energy(velocities)
    E0 = float(energies[0]) if energy0 is None else energy0
    has_charts = chain.has_atlas
    # the integrating chart; a hinge-space solve has none (reading the best chart per sample would cost ~2 ms each)
    in_charts = any(segment.chart is not None for segment in solution.segments)
    charts = np.asarray(solution.parameters(times)[0]) if in_charts else np.full(len(times), -1)
    return {
        "times": (times + t0).tolist(),
        "hinges": as_pairs(hinges),
        "velocities": as_pairs(velocities),
        "energyError": (np.abs(energies - E0) / E0).tolist(),
        "maxEnergyError": motion.relative_energy_error,
        "chart": charts.tolist(),
        "chartIds": [str(c) for c in chain.atlas().ids] if has_charts else [],
        "switches": [{"t": float(s.time) + t0, "from": s.from_chart, "to": s.to_chart} for s in solution.switches],
        "angles": chain.angles(hinges).tolist(),
        "sphere": sphere_coordinates(motion, times).tolist() if has_charts else None,
        "nSteps": motion.n_steps,
    }


def tangent_velocity(chain: Chain, hinges: NDArray, velocity: NDArray) -> NDArray:
    """The K-orthogonal projection of a hinge velocity onto the tangent space at ``hinges``
    (:meth:`HingeConstraints.project_velocity`): what a flick of the pointer launches."""
    x = chain.to_point(hinges)
    return chain.from_point(HingeConstraints(chain).project_velocity(x, chain.to_point(velocity)))


def drag_hinge(chain: Chain, hinges: NDArray, index: int, target: complex) -> NDArray:
    """The configuration near ``hinges`` with hinge ``index`` (0-based: ``p_{index+1}``) moved towards ``target``.

    The hinge is put at the target and the configuration projected back onto the constraints
    (:meth:`HingeConstraints.project_position`, Gauss-Newton with the K-smallest correction) in the metric of the
    same chain with the dragged hinge :data:`DRAG_WEIGHT` times heavier, so the other hinges make the correction.
    A target too far for the projection to converge is approached by halves; where even 1/64 of the way does not
    converge the configuration stays as it was.
    """
    masses = np.full(chain.n - 1, float(np.max(chain.hinge_masses)))
    masses[index] *= DRAG_WEIGHT
    heavy = HingeConstraints(Chain(chain.lengths, chain.L, hinge_masses=masses))
    x = chain.to_point(hinges)
    step = np.zeros_like(x)
    step[2 * index: 2 * index + 2] = [target.real - hinges[index].real, target.imag - hinges[index].imag]
    for halvings in range(7):
        # twice: from a pointer's distance, Gauss-Newton's 8 steps of one call leave ~1e-11 of closure
        y = heavy.project_position(heavy.project_position(x + step / 2**halvings))
        h = chain.from_point(y)
        if np.all(np.isfinite(y)) and float(np.max(chain.closure_residual(h))) <= 1e-12:
            return h
    return hinges
