r"""Chart geodesics with the ambient velocity as state: the chart gives the point, constraints the acceleration.

The embedded form integrates ``(a, c)`` and needs the chart's second derivatives
``h = z_ab c^a c^b`` along the velocity; pushing second-order jets through a chart
formula costs about ten products of series per product of the formula (suspension
charts, n = 4, float64: of 491.5 full Taylor recursions per step, 57.5 are the formula's
values, 137 their gradient ``J`` and 286 the derivatives along the velocity).
Where the image of the charts is also the zero set of constraints
``C(x) = 0`` with the same constant metric ``K`` (a
:class:`~manifold.constrained.ConstrainedSystem`), the normal acceleration is
known without any chart: ``x'' = K^{-1} G^T lambda`` with
``G K^{-1} G^T lambda = -(dG/dt) x'``.  So the state can be ``(a, V)`` with
``V = J c`` the chart frame's ambient velocity:

.. math::

    J a' = V, \qquad V' = M^{-1} f(M z(a) + m, M J a') - \gamma \big(\delta
        - \tfrac{\langle \delta, J a' \rangle_W}{2 E} J a'\big), \qquad \delta = V - J a',

(``p = M z + m`` the chart's map, :meth:`~manifold.geodesic_system.SymbolicPieces.ambient_velocity_equations`),
``a'`` read from ``V`` by forward substitution where ``J`` is block triangular, as an iterated suspension's
is: ``O(n)`` nodes instead of the normal equations' ``O(n^3)``
(:meth:`~manifold.geodesic_system.SymbolicPieces.velocity_coefficients`, ``docs/math.md`` §7b).
Only the Jacobian ``J`` is needed: 307 full recursions at n = 4 with the switch
events, against 511 in ``t`` (float64; 1,850 against 2,616 at n = 8; in Sundman's
time 323.5 against 531.5 and 1,892.5 against 2,674.5).  The point
stays on the manifold by construction (it is the chart's), so no constraint
stabilisation is needed.  ``V`` drifts off the tangent space by rounding;
``f``'s velocity is ``J a'``, not ``V``, and each segment's end removes the drift
``V - J a'`` (its state is read back as ``c = g^{-1} J^T W V``, K-orthogonally).
Within a segment, though, the drift turns into tangent velocity as the tangent
space turns (planted at 1e-6, it changed the energy by 6.6e-7 over t = 3), and the
forward substitution, an oblique projection, lets some of it into ``a'``; over
long runs the energy error grew like ``t^0.6..0.9`` instead of ``sqrt(t)``
undamped.  The last term damps the drift at the rate ``gamma`` of
:func:`~manifold.constrained.damping_rate` (the hinge method's Baumgarte rate,
scale-free), and vanishes on the exact solution.  It leaves out the drift's part along ``J a'`` (``W`` the
chart's metric, ``|J a'|_W^2 = 2 E``): rounding makes ``J a'`` longer or shorter than ``V``'s tangent part by a
few hundredths of an eps on average, and damping that part pumped the bias into the energy.

It is an equation term (:mod:`manifold.terms`): steppers take it as ``velocity=``
(:class:`~manifold.steppers.TaylorStepper`, :class:`~manifold.sundman.SundmanStepper`).  Segments start and end in
``(a, c)`` as every stepper's do: its switch map converts on the way in (``V = J c``,
:meth:`ConstrainedVelocity.enter`) and on the way out (:meth:`ConstrainedVelocity.leave`), dense output included, so
the engine, switches, energy checks and solutions are unchanged; its parameter values (the system's, and ``gamma``
at each segment's energy) it gives itself (:meth:`ConstrainedVelocity.parameter_values`).

The same state carries :mod:`manifold.carried` terms along the chart geodesic,
each an equation term of the composition after it (:class:`ChartCarried`): their slots are ambient (a transported
vector ``W``, a Jacobi field's ``(J, U)``), their equations the constraint system's with ``x = M z(a) + m``
and ``v = M J a'``, so a chart switch leaves them as they are: the
transition's differential acts on chart coefficients, and these have none.
They follow ``(a, V)`` in the state, and the solver's loop passes them through
every segment, wrap and switch.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any

import heyoka as hy

import numpy as np
from numpy.typing import NDArray

from .compiled import CompiledFamily, Transfer
from .carried import CarriedTerm
from .constrained import (ConstrainedGeometry, ConstrainedPieces, ConstrainedSystem, compiled_constrained,
                          damping_rate, speed_scale)
from .geodesic_system import SymbolicPieces
from .precision import as_fp
from .solution import DenseOutput
from .steppers import Advance
from .terms import SegmentStart, StateTerm, Term
from .validation import check_bool, check_real

#: Damping rate of ``V``'s normal drift (:class:`ConstrainedVelocity`), chosen by measurement in ``docs/methods.md``.
DEFAULT_RATE = 3.0
#: How :class:`ConstrainedVelocity` reads ``a'`` and ``J a'`` from ``V``: the chart family's own recursion (where it
#: has one; else the jets), or forward substitution on the jets (``docs/math.md`` §7b).
SOLVES = ("recursion", "jets")


class ConstrainedVelocity(StateTerm):
    """Integrate a chart family's geodesics in ``(a, V)``, the normal acceleration from ``system``.

    An equation term (:mod:`manifold.terms`) that sets the state: its parameters are the system's
    runtime parameters, then the damping rate ``gamma`` and ``1 / (2 E)`` of the segment; its switch map (:meth:`enter`, :meth:`leave`) converts
    ``(a, c) <-> (a, V)`` at each segment's ends.

    Parameters
    ----------
    system
        Constraints whose zero set, with the metric ``system.metric_matrix``, is
        the manifold that the atlas charts (for a chain:
        :class:`linkage.constraints.ChainSystem`); the caller vouches for that.
        The solver's energy check, which reads the chart's metric, catches a
        system of another manifold or metric (a base ``L`` of 2.6 against the
        atlas's 2.7: energy error 0.10; 2.7001: 1.2e-4, both refused).
    rate
        Damping rate of ``V``'s normal drift ``V - J a'``, in units of the
        motion's speed scale over the system's length (as the hinge method's
        Baumgarte rate: :func:`manifold.constrained.damping_rate`); 0 leaves the
        drift alone.  The default is chosen by measurement (``docs/methods.md``).
    solve
        How ``a'`` and ``J a'`` are read from ``V`` (:data:`SOLVES`): ``"recursion"`` (default), the chart family's
        own recursion where it has one (the suspension charts' levels: 1.35-1.58x faster a step than the jets), or
        ``"jets"``, forward substitution on the chart's jets.  The two give the same numbers, rounded differently:
        the recursion's ``a'`` and ``J a'`` are longer or shorter than the point's own jets give, by a few hundredths
        of an eps on average, which makes the energy drift upwards over long float64 runs (n = 4, L = 2.5,
        T = 1.2e5, eight starts: +2.3e-13 to +1.1e-12, mean +6.0e-13), where the jets' drifts a third as much
        (-0.03e-13 to +5.4e-13, mean +2.4e-13; ``docs/methods.md``).  For float64 runs beyond T of about 1e4,
        choose ``conserving`` (below), or ``"jets"``.
    conserving
        Take the normal acceleration's part along ``V`` out of ``V'`` (:meth:`SymbolicPieces.ambient_velocity_equations`):
        0 on the exact solution, so the motion is the same, but the energy's rate becomes of second order in the
        drift and in the acceleration's rounding.  Over T = 1.2e5 (n = 4, L = 2.5, eight starts) the energy then
        shows no drift of one sign, where the default drifts by +0.0016 eps a step (``docs/methods.md``, "Long
        runs"); near a whip of a light hinge (hinge masses 1e-3, 1, 1e2) the larger acceleration's rounding costs
        it more: energy error 5.2e-12 against 1.5e-13 over a backward T = 12 through two such whips.  Off by
        default; for long float64 runs of comparable masses, turn it on.

    Raises
    ------
    TypeError
        If ``system`` is not a :class:`~manifold.constrained.ConstrainedSystem`.
    ValueError
        If ``rate`` is negative or not finite, or ``solve`` is not one of :data:`SOLVES`.
    """

    label = "(a, J c)"

    def __init__(self, system: ConstrainedSystem, rate: float = DEFAULT_RATE, solve: str = "recursion",
                 conserving: bool = False) -> None:
        if not isinstance(system, ConstrainedSystem):
            raise TypeError(f"system must be a manifold.constrained.ConstrainedSystem, got {type(system).__name__}")
        self.system = system
        self.rate = check_real("rate", rate)
        if self.rate < 0:
            raise ValueError(f"rate must be a finite real number >= 0, got {rate!r}")
        if solve not in SOLVES:
            raise ValueError(f"solve must be one of {SOLVES}, got {solve!r}")
        self.solve = solve
        self.conserving = check_bool("conserving", conserving)
        self._compiled = compiled_constrained(system)
        self._values: dict[Any, NDArray] = {}  # fp_type -> parameter values
        self._speed_scale = speed_scale(system)  # once: each segment's damping rate needs it
        self._acceleration = self._compiled.acceleration(float, stabilised=False)  # the turning rate's, in float64

    def __repr__(self) -> str:
        return (f"ConstrainedVelocity({self.system!r}, rate={self.rate!r}, solve={self.solve!r}, "
                f"conserving={self.conserving!r})")

    @property
    def key(self) -> Hashable:
        """Identity of the compiled equations: the system's key, its metric's sparsity, the velocity solve and
        whether the equations are conserving."""
        return ("constrained-velocity", self.system.key, self._compiled.layout, self.solve, self.conserving)

    @property
    def n_constraint_pars(self) -> int:
        """Number of the system's runtime parameters (they come first)."""
        return len(self.parameters(float))

    @property
    def n_params(self) -> int:
        """Number of its runtime parameters: the system's, then ``gamma`` and ``1 / (2 E)``."""
        return self.n_constraint_pars + 2

    def equations(self, pieces: SymbolicPieces, equations: list[tuple], offset: int) -> list[tuple]:
        """:meth:`~manifold.geodesic_system.SymbolicPieces.ambient_velocity_equations`, the system's parameters at
        ``par[offset ..]``, ``gamma`` and ``1 / (2 E)`` after them, ``a'`` read as ``solve`` says."""
        if equations:
            raise ValueError(f"{self!r} sets the state: it must be the first term")
        return pieces.ambient_velocity_equations(self.pieces(pieces.fp_type), self.n_constraint_pars, offset,
                                                 self.solve == "recursion", self.conserving)

    def pieces(self, fp_type: Any) -> ConstrainedPieces:
        """The system's symbolic equations in ``fp_type``."""
        return self._compiled.pieces(fp_type)

    def parameters(self, fp_type: Any) -> NDArray:
        """The system's runtime parameter values in ``fp_type`` (no stabilisation: ``alpha = 0``)."""
        if fp_type not in self._values:
            self._values[fp_type] = self._compiled.layout.pack(self.system, 0.0, fp_type)
        return self._values[fp_type]

    def __getstate__(self) -> dict:
        """Pickle the system and the options only (for ensembles on other processes): the compiled store holds a
        lock."""
        return {"system": self.system, "rate": self.rate, "solve": self.solve, "conserving": self.conserving}

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["system"], state["rate"], state["solve"], state["conserving"])  # type: ignore[misc]

    def check(self, family: CompiledFamily, form: str) -> None:
        """Refuse a system of another ambient dimension than the family's points, and a ``form`` other than the
        default ``"embedded"`` (the forms are those of the state ``(a, c)``; this state has none)."""
        N = family.family.point_dim
        if self.system.ambient_dim != N:
            raise ValueError(f"velocity: the constraint system lives in R^{self.system.ambient_dim}, the charts of "
                             f"{family.family!r} in R^{N}")
        if form != "embedded":
            raise ValueError(f"form={form!r} is a form of the state (a, c); a stepper with velocity= integrates "
                             f"(a, J c) and has none: drop velocity= or form=")

    def parameter_values(self, segment: SegmentStart) -> NDArray:
        """The system's parameters, then the damping rate ``gamma`` of the segment (:meth:`damping`) and
        ``1 / (2 E)`` (0 at rest) with ``E`` its energy."""
        two_E = 2 * segment.energy
        inverse = np.array([1 / two_E if two_E > 0 else 0 * two_E], dtype=segment.y.dtype)
        return np.concatenate([self.parameters(segment.fp_type), as_fp([self.damping(segment)], segment.fp_type),
                               inverse])

    def damping(self, segment: SegmentStart) -> float:
        r"""``gamma = sign(t_final - t) rate max(sqrt(2 E) s, omega)`` at the segment's start.

        ``sqrt(2 E) s`` is the hinge method's Baumgarte rate (:func:`~manifold.constrained.damping_rate`, the speed
        over the system's length) and

        .. math::

            \omega = \frac{|f(x, v)|}{|v|},

        ``f`` the normal acceleration, the rate at which the tangent space turns along the motion: the drift
        ``V - J a'`` turns into tangent velocity at about that rate, so it must be damped at least as fast.  Where
        the manifold is small, ``omega`` is the larger: near the top of its range of ``L`` a chain's configuration
        space is a sphere of radius about ``sqrt(n - L)`` (unit rods), whose tangent space turns thousands of times
        faster than the speed over the rod length at ``n - L = 5e-8``; damped at that slower rate, the drift fed
        the energy 3.8e-11 in ``t = 0.9`` (26,917 steps), against 1.9e-12 at ``omega`` (``docs/methods.md``).
        Numerical trap: the norms are Euclidean, not ``K``'s, so that the light masses' fast motion sets the rate
        (as ``tr K^-1`` does in ``s``); with hinge masses 0.013..31 the K-norms' rate left 3.1e-11 where this
        leaves 1.9e-12.
        """
        x, v = (np.asarray(u, dtype=float) for u in segment.ambient)
        direction = float(segment.t_final - segment.t)
        speed = damping_rate(self._speed_scale, self.rate, float(segment.energy), direction)
        f = self._acceleration(np.concatenate([x, v]), pars=self.parameters(float)[: self._acceleration.nparams])
        vv = float(v @ v)
        turning = np.sqrt(float(f @ f) / vv) if vv > 0 else 0.0
        return float(np.sign(direction)) * max(abs(speed), self.rate * turning)

    def enter(self, segment: SegmentStart) -> NDArray:
        """``(a, V)`` with ``V = J c`` at the segment's start (the conversion once per segment: switches go through
        the ambient velocity anyway)."""
        k, N = segment.family.family.dim, segment.family.family.point_dim
        return np.concatenate([segment.y[:k], segment.start[N : 2 * N, 0]])

    def rewrapped(self, segment: SegmentStart) -> Callable[[Any], None]:
        """``V`` projected onto the tangent space at the wrapped point, ``V <- J c`` with ``c`` its tangent
        coefficients there (:meth:`~manifold.compiled.Transfer.coefficients`), in the live state ``(a, V, ...)``:
        the wrap's rounding of ``2 pi`` moved the point by 2.4e-16 (:func:`~manifold.steppers.angle_wrap`)."""
        k, N, transfer = segment.family.family.dim, segment.family.family.point_dim, segment.transfer
        zero = np.zeros((N, 1))

        def project(state: Any) -> None:
            a = np.array(state[:k])[:, None]
            c = transfer.coefficients(a, np.array(state[k : k + N])[:, None])
            state[k : k + N] = transfer(a, c, zero)[N : 2 * N, 0]

        return project

    def leave(self, advance: Advance, segment: SegmentStart) -> Advance:
        """The integrated ``(a, V)`` read back as ``(a, c)`` (:func:`_chart_states`), dense output included."""
        transfer, adv = segment.transfer, advance
        out = None if adv.dense is None else _ChartDense(adv.dense, transfer)
        return Advance(adv.t, _chart_states(adv.y[None, :], transfer)[0], adv.n_steps, adv.event, adv.step_times,
                       _chart_states(adv.step_states, transfer), out, adv.failure, n_wraps=adv.n_wraps)


class ChartCarried(Term):
    """A :class:`~manifold.carried.CarriedTerm` (a transported vector, a Jacobi field) as an equation term of the chart
    path: its ambient slots after the state ``(a, V)`` of ``velocity``.

    Its equations are the term's own, written on the constraint system's symbolic pieces, with the system's point
    and velocity read from the chart state (``x = M z(a) + m``, ``v = M J a'``:
    :meth:`~manifold.geodesic_system.SymbolicPieces.ambient_frame`) and its damping of drift off the tangent space
    at ``velocity``'s ``gamma``.  It has no parameters of its own; its slots start at the term's
    :meth:`~manifold.carried.CarriedTerm.start` (the start point and velocity in the ambient frame, completed in
    the working precision) and, being ambient, pass every chart switch unchanged (the transition's differential acts
    on chart coefficients, and these have none).  Read them back with :class:`~manifold.carried.CarriedSolution`.

    Parameters
    ----------
    term
        The carried term.
    velocity
        The state term it rides on: the composition's must be of the same system (key and parameters).
    """

    n_params = 0

    def __init__(self, term: CarriedTerm, velocity: ConstrainedVelocity) -> None:
        if not isinstance(term, CarriedTerm):
            raise TypeError(f"term must be a manifold.carried.CarriedTerm, got {term!r}")
        if not isinstance(velocity, ConstrainedVelocity):
            raise TypeError(f"velocity must be a manifold.ambient_velocity.ConstrainedVelocity, got {velocity!r}")
        self.term, self.velocity = term, velocity

    def __repr__(self) -> str:
        return f"ChartCarried({self.term!r}, {self.velocity!r})"

    @property
    def key(self) -> Hashable:
        return ("chart-carried", self.term.key)

    @property
    def moves_at_rest(self) -> bool:
        """A carried quantity may move while the geodesic stays at rest (a Jacobi field does): integrated."""
        return True

    def requires(self, state: StateTerm) -> None:
        """Refuse a state other than ``velocity``'s: another system's equations, or the same with other parameters
        (the term's start would be projected on another manifold)."""
        if not (isinstance(state, ConstrainedVelocity) and state.key == self.velocity.key
                and np.array_equal(state.parameters(float), self.velocity.parameters(float))):
            raise ValueError(f"{self!r} rides on the state (a, V) of {self.velocity!r}, the composition's state is "
                             f"{state!r}")

    def equations(self, pieces: SymbolicPieces, equations: list[tuple], offset: int) -> list[tuple]:
        """``equations`` with the term's slots appended (variables named after their place in the state)."""
        constrained, N = self.velocity.pieces(pieces.fp_type), pieces.N
        n_constraint_pars = self.velocity.n_constraint_pars
        moves = pieces.ambient_frame(constrained, n_constraint_pars, pieces.layout.terms_index,
                                     self.velocity.solve == "recursion")
        # the term damps its own drift at the rate its stabilised form reads at par[0]: the velocity's gamma
        moves[hy.par[0]] = hy.par[pieces.layout.terms_index + n_constraint_pars]
        y = [hy.expression(f"carried{len(equations)}_{i}") for i in range(self.term.size(N))]
        return equations + list(zip(y, hy.subs(self.term.equations(constrained, y, True), moves)))

    def slots(self, segment: SegmentStart) -> NDArray:
        """The term's start values at the start point and velocity, in the ambient frame."""
        p, v = segment.ambient
        return self.term.start(ConstrainedGeometry(self.velocity.system, segment.fp_type), p, v)


def _chart_states(states: NDArray, transfer: Transfer) -> NDArray:
    """``(a, c)`` of states ``(a, V)`` stacked as rows ``(m, k + N)``: ``c = g^{-1} J^T W V``, refined once by the
    residual ``V - J c`` (:meth:`~manifold.compiled.Transfer.coefficients`).

    Numerical trap: the normal equations carry ``V``'s rounding back with ``cond(J)`` (a review measured the round
    trip ``c -> V -> c`` toward a pole: 5.1e-15, 2.6e-12, 3.3e-10 at ``cond(J)`` 14, 1.2e4, 1.2e6; refined 2.6e-15,
    1.3e-12, 1.3e-10), and the energies recorded from these states see it: n = 4, T = 20, 1.7e-14 unrefined
    against 3.7e-15 refined (``tests/test_ambient_velocity.py``).
    """
    k, N = transfer.k, transfer.N
    a = states[:, :k].T
    # anything carried after (a, V) is ambient: it passes as it is
    return np.concatenate([a, transfer.coefficients(a, states[:, k : k + N].T), states[:, k + N :].T]).T


class _ChartDense:
    """Dense output of an ``(a, V)`` segment, read as ``(a, c)``."""

    def __init__(self, inner: DenseOutput, transfer: Transfer) -> None:
        self.inner, self.transfer = inner, transfer

    @property
    def nbytes(self) -> int:
        """Bytes held: the inner output's."""
        return self.inner.nbytes

    def __call__(self, ts: NDArray) -> NDArray:
        return _chart_states(self.inner(ts), self.transfer)
