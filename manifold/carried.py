"""Quantities carried along a constrained geodesic: one term, one set of equations, any number of them at once.

A :class:`CarriedTerm` rides on the geodesic ``(x, v)`` of a
:class:`~manifold.constrained.ConstrainedSystem`: it declares how many state
slots it takes, writes its equations on the system's symbolic pieces, completes
its start in the working precision, names the invariants that are checked at
every step, and reads its values back.  :func:`solve_carried` integrates the
geodesic with every term given, in one heyoka Taylor integrator (compiled once
per system and tuple of term keys), and returns a :class:`CarriedSolution`.

The terms of this package are :class:`manifold.transport.ParallelTransport`
and :class:`manifold.jacobi.JacobiField`; a new one is a subclass in a file
of its own, and nothing else changes.

The geodesic part of the state and its checks (energy, constraints) are those
of :func:`manifold.constrained.solve_constrained`; the carried slots are
linear in themselves, so they change the step sizes only through heyoka's
error norm.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .options import DEFAULT_SAVE, PASSED_ON_GROUPS, refuse_moved_options
from .solution import GeodesicSolution, energy_bound

if TYPE_CHECKING:
    from .constrained import ConstrainedGeometry, ConstrainedPieces, ConstrainedSystem

__all__ = ["CARRIED_SAFETY", "CarriedSolution", "CarriedTerm", "carried_violation", "slot_ranges", "solve_carried"]

#: A carried term's invariants may move by this many times the energy bound (:func:`manifold.solution.energy_bound`)
#: before a solve is refused: near the top of a chain's ``L`` range, with rod densities, the transport's Gram
#: matrix moved 1.7-2.4 times as far as the geodesic's energy (n = 3, L = 2.999: 2.6e-11 against 1.5e-11),
#: and with the energy bound itself the transport was refused where the geodesic alone was accepted.
CARRIED_SAFETY = 10.0


class CarriedTerm(ABC):
    """Something carried along a constrained geodesic (see the module docstring).

    A term holds its own start values; its :attr:`key` must depend only on
    what changes the compiled equations (for instance how many vectors are
    carried), so that one integrator serves every start.
    """

    #: What the term is, for messages ("parallel transport", "Jacobi field").
    name: str

    @property
    @abstractmethod
    def key(self) -> Hashable:
        """Identity of the compiled equations: equal keys give equal expressions."""

    @abstractmethod
    def size(self, N: int) -> int:
        """The number of state slots the term takes in ambient dimension ``N``."""

    @abstractmethod
    def equations(self, pieces: ConstrainedPieces, y: list[hy.expression], stabilised: bool) -> list[hy.expression]:
        """The right-hand sides of the term's slots ``y`` (``len(y) == size(N)``), written on ``pieces``.

        ``stabilised`` says whether the geodesic carries Baumgarte's damping
        (the term should damp its own drift off the tangent space with the same
        rate ``alpha = par[0]``).
        """

    @abstractmethod
    def start(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray) -> NDArray:
        """The slots at the start ``(x, v)`` (already on the manifold, in the working precision): the term's
        start values completed and projected in ``geometry``'s precision, flat, ``size(N)`` entries."""

    @abstractmethod
    def invariants(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray,
                   y: NDArray) -> tuple[NDArray, NDArray]:
        """Quantities constant along the exact solution at the states ``(x, v, y)`` (rows ``(B, .)``), in the working
        precision (their changes are taken there: rounded to float64 first, a real128 drift below 1e-16 would
        vanish), and the magnitude each is computed from, as floats (its change is judged relative to the larger
        of that magnitude at the start and now): two arrays of shape ``(B, m)``."""

    @abstractmethod
    def read(self, geometry: ConstrainedGeometry, x: NDArray, v: NDArray, y: NDArray) -> dict[str, NDArray]:
        """The term's values at the states ``(x, v, y)`` (rows ``(B, .)``), by name, each of shape ``(B, ...)``."""


def slot_ranges(terms: Sequence[CarriedTerm], N: int) -> list[slice]:
    """Where each term's slots lie in the state ``(x, v, slots of terms[0], slots of terms[1], ...)``."""
    out, start = [], 2 * N
    for term in terms:
        out.append(slice(start, start + term.size(N)))
        start += term.size(N)
    return out


def carried_violation(term: CarriedTerm, geometry: ConstrainedGeometry, states: NDArray, first: NDArray,
                      slots: slice, times: NDArray, n_steps: int, tol: float) -> str | None:
    """A sentence if ``term``'s invariants at ``states`` (rows ``(x, v, ...)``) moved from their values at the start
    state ``first`` by more than :data:`CARRIED_SAFETY` times the energy bound :func:`manifold.solution.energy_bound`,
    else ``None``."""
    N = geometry.N
    rows = np.concatenate([first[None, :], states])
    values, scales = term.invariants(geometry, rows[:, :N], rows[:, N : 2 * N], rows[:, slots])
    change = np.abs(values[1:] - values[0]).astype(float)  # taken in the working precision, then rounded
    scale = np.maximum(np.asarray(scales[1:], dtype=float), np.asarray(scales[0], dtype=float))
    # an invariant of magnitude 0 (a zero vector carried) stays exactly 0: judge it absolutely, not 0 / 0
    drift = np.max(change / np.where(scale > 0, scale, 1.0), axis=1, initial=0.0)
    bound = CARRIED_SAFETY * energy_bound(n_steps, tol)
    bad = ~(drift <= bound)  # NaN counts as a violation
    if not np.any(bad):
        return None
    k = int(np.argmax(bad))
    return (f"{term.name} check failed at t = {float(times[k]):.6g}: its invariants moved by {drift[k]:.3g} "
            f"(relative), beyond {CARRIED_SAFETY:g} times the energy bound, {bound:.3g}")


@dataclass
class CarriedSolution:
    """A constrained geodesic with quantities carried along it.

    Attributes
    ----------
    solution
        The :class:`~manifold.solution.GeodesicSolution` of the geodesic (dense output kept).
    terms
        The :class:`CarriedTerm` s, in the order of their slots.
    geometry
        The system's :class:`~manifold.constrained.ConstrainedGeometry` in the working precision.
    """

    solution: GeodesicSolution
    terms: tuple[CarriedTerm, ...]
    geometry: ConstrainedGeometry

    def __repr__(self) -> str:
        return f"CarriedSolution({', '.join(t.name for t in self.terms)}; {self.solution!r})"

    def __call__(self, t: ArrayLike) -> tuple[NDArray, NDArray, list[dict[str, NDArray]]]:
        """Point, velocity (shape ``t.shape + (N,)``) and each term's values (:meth:`CarriedTerm.read`, leading
        shape ``t.shape``) at time(s) ``t``, in the working precision."""
        ts = np.asarray(t, dtype=float)
        x, v = self.solution(ts.ravel())
        slots = self.slots(ts.ravel())
        N, values, start = self.geometry.N, [], 0
        for term in self.terms:
            read = term.read(self.geometry, x, v, slots[:, start : start + term.size(N)])
            start += term.size(N)
            values.append({k: a.reshape(*ts.shape, *a.shape[1:]) for k, a in read.items()})
        return x.reshape(*ts.shape, N), v.reshape(*ts.shape, N), values

    def slots(self, t: NDArray) -> NDArray:
        """The carried slots at the 1-d times ``t``, rows ``(len(t), sum of the terms' sizes)``: the last columns
        of the state, after ``(x, v)`` in hinge coordinates and after ``(a, c)`` in a chart."""
        states = self.solution.states(t)
        return states[:, states.shape[1] - sum(term.size(self.geometry.N) for term in self.terms) :]

    def violation(self, tol: float) -> str | None:
        """The first carried term whose invariants moved beyond :data:`CARRIED_SAFETY` times the energy bound at
        relative tolerance ``tol`` over the recorded step times (a sentence), else ``None``: the check that
        :func:`~manifold.constrained.solve_constrained` makes as it goes, for a solve that does not (the chart
        path)."""
        times = np.array([float(s) for s in self.solution.energy_times])
        x, v = self.solution(times)
        rows = np.concatenate([x, v, self.slots(times)], axis=1)
        for term, sl in zip(self.terms, slot_ranges(self.terms, self.geometry.N)):
            message = carried_violation(term, self.geometry, rows[1:], rows[0], sl, times[1:],
                                        self.solution.n_steps, tol)
            if message is not None:
                return message
        return None


def solve_carried(system: ConstrainedSystem, x0: ArrayLike, v0: ArrayLike, t_final: float,
                  terms: Sequence[CarriedTerm], **options: Any) -> CarriedSolution:
    """Integrate the geodesic of ``system`` from ``(x0, v0)`` with ``terms`` carried along it.

    Parameters
    ----------
    system, x0, v0, t_final
        As in :func:`manifold.constrained.solve_constrained`.
    terms
        The :class:`CarriedTerm` s (at least one).
    **options
        Passed on to :func:`~manifold.constrained.solve_constrained` (``precision``, ``stabilisation``
        ``"baumgarte"`` or ``"none"``, ``rate``, ``compact_mode``, ``throw``, ``progress``, ``start``); dense output is
        always kept (``save`` is not taken), since the carried values are read from it.

    Returns
    -------
    CarriedSolution
        Whose every step passed the geodesic's checks and each term's invariant check
        (:attr:`~manifold.solution.SolveStatus.CARRIED_CHECK_FAILED` otherwise, raised by default).
    """
    from .constrained import ConstrainedGeometry, solve_constrained  # constrained integrates CarriedTerms

    terms = tuple(terms)
    if not terms or not all(isinstance(t, CarriedTerm) for t in terms):
        raise TypeError(f"terms must be a non-empty sequence of CarriedTerm, got {terms!r}")
    for name in ("save", "dense", "t_eval", "carry"):
        if name in options:
            raise TypeError(f"solve_carried does not take {name}= (the carried values are read from dense output)")
    refuse_moved_options("solve_carried", options, (*PASSED_ON_GROUPS, "start"))
    solution = solve_constrained(system, x0, v0, t_final, carry=terms, save=DEFAULT_SAVE, **options)
    return CarriedSolution(solution, terms, ConstrainedGeometry(system, solution.fp_type))
