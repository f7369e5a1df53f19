"""Option groups of the solvers: what to save, in which precision to integrate, and how to check the start.

Options that belong together travel together, in the manner of diffrax's
``SaveAt`` and step-size controllers: a solver takes ``save=SaveAt(...)``,
``precision=Precision(...)`` and ``start=StartCheck(...)`` instead of six
loose keywords, and every group checks its own fields once, when it is made.
The groups are frozen: one ``SaveAt``, ``Precision`` or ``StartCheck`` can
serve many solves.

A keyword that moved into a group (``t_eval=``, ``dense=``, ``fp_type=``,
``tol=``, ``tangent_tol=``, ``project_velocity=``) is refused by
:func:`takes_option_groups` with a ``TypeError`` that names its new home,
rather than Python's bare "unexpected keyword argument".
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, ParamSpec, TypeVar

import numpy as np
from numpy.typing import NDArray

from .precision import resolve_fp_type
from .steppers import MAX_TOLERANCE
from .validation import check_bool, check_real, check_time_grid, real_array

__all__ = ["DEFAULT_PRECISION", "DEFAULT_SAVE", "DEFAULT_START", "MOVED_OPTIONS", "PASSED_ON_GROUPS", "PROJECTED_START",
           "Precision", "SaveAt", "StartCheck", "TANGENT_TOL", "check_group", "refuse_moved_options",
           "takes_option_groups"]

G = TypeVar("G")


@dataclass(frozen=True, eq=False)
class SaveAt:
    """What a solve keeps: states on a time grid, and the continuous (dense) output.

    Parameters
    ----------
    t_eval
        Times at which points and velocities are recorded (``sol.points``,
        ``sol.velocities``), a 1-d array of finite reals; ``None`` (default)
        records none.  They must lie within ``[0, t_final]`` in integration
        order (increasing for ``t_final > 0``, decreasing for ``t_final < 0``,
        repeats allowed), which the solver checks against its ``t_final``.
        Stored as a read-only float64 array.
    dense
        Keep the continuous output (for a Taylor method, the ``order + 1``
        coefficients of every step), needed to evaluate the solution at any
        ``t``.  ``False`` with ``t_eval`` keeps memory bounded by ``len(t_eval)``.
        ``None`` (default) is the solver's own default (:meth:`keeps_dense`):
        dense output for a single solve, none for an ensemble of them.

    Raises
    ------
    TypeError
        If ``dense`` is not a bool or ``None``, or ``t_eval`` holds complex, string or boolean values.
    ValueError
        If ``t_eval`` is not 1-d or holds ``nan`` or ``inf``.

    Notes
    -----
    Equality is identity (the grid is an array); the group is immutable, so
    one instance can be shared by any number of solves.
    """

    t_eval: NDArray | None = None
    dense: bool | None = None

    def __post_init__(self) -> None:
        if self.dense is not None:
            object.__setattr__(self, "dense", check_bool("dense", self.dense))
        if self.t_eval is not None:
            grid = real_array("t_eval", self.t_eval)
            if grid.ndim != 1:
                raise ValueError(f"t_eval must be a 1-d array of times, got shape {grid.shape}")
            grid.setflags(write=False)  # real_array made a copy: the caller's array may change later, ours may not
            object.__setattr__(self, "t_eval", grid)

    def __reduce__(self) -> tuple:
        return SaveAt, (self.t_eval, self.dense)  # made anew, so that the grid is read-only again

    def keeps_dense(self, default: bool) -> bool:
        """Whether to keep the continuous output: :attr:`dense`, or the solver's ``default`` where it is ``None``."""
        return default if self.dense is None else self.dense

    def grid(self, t_final: float) -> NDArray | None:
        """The ``t_eval`` times checked against ``t_final`` (within ``[0, t_final]``, in integration order), or
        ``None`` if no grid was asked for; ``ValueError`` naming ``t_eval`` otherwise."""
        return None if self.t_eval is None else check_time_grid(self.t_eval, t_final)


@dataclass(frozen=True)
class Precision:
    """The working precision of a solve: the floating type of everything computed, and the integrator's tolerance.

    Parameters
    ----------
    fp_type
        ``float`` (default, float64), ``numpy.longdouble``, ``heyoka.real128``
        or :class:`manifold.precision.MultiPrecision` ``(bits)`` (heyoka's ``real``);
        or by name: ``"float64"``, ``"longdouble"``, ``"real128"``, ``"mp<bits>"``.
        Stored resolved to the type (:func:`manifold.precision.resolve_fp_type`).
    tol
        heyoka's tolerance, a real number in ``(0, 1e-2]``
        (:data:`manifold.steppers.MAX_TOLERANCE`); ``None`` (default) is the
        solver's default for ``fp_type`` (:func:`manifold.compiled.default_tolerance`:
        1e-14 in float64, the machine epsilon of other types).  heyoka uses it
        as its absolute and relative tolerance at once.

    Raises
    ------
    ValueError
        An unknown ``fp_type`` name, or ``tol`` outside ``(0, 1e-2]`` (``nan``, ``inf``, strings and bools included).
    TypeError
        An ``fp_type`` that is not a supported floating type.
    """

    fp_type: Any = float
    tol: float | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "fp_type", resolve_fp_type(self.fp_type))
        if self.tol is not None:
            object.__setattr__(self, "tol", check_real("tol", self.tol, positive=True, at_most=MAX_TOLERANCE))


#: The default relative tolerance of every tangency check of a start velocity (:class:`StartCheck`).
TANGENT_TOL = 1e-9


@dataclass(frozen=True)
class StartCheck:
    """How a solve checks its start velocity: the tangency tolerance, and whether to project instead of refusing.

    A start velocity ``v`` must be tangent to the manifold at the start point.
    Each solver measures the deviation in its own terms, relative to
    ``max(1, |v|)``: the chart solver (:func:`manifold.solve_chart_exp_ode`)
    by the distance of the embedded ``v`` from the chart's tangent space
    (``max_i |(v - J c)_i| <= tangent_tol * max(1, max_i |v_i|)``), the chain's
    hinge-space start (:func:`linkage.constraints.start_state`) by the rates of
    change of the rods (``max_k l_k |(G v)_k| <= tangent_tol * max(1, |v|)``).

    Parameters
    ----------
    tangent_tol
        The relative tolerance of the tangency check, a finite real number ``> 0``
        (default :data:`TANGENT_TOL`, ``1e-9``).  It also bounds the tangency of
        the other tangent vectors a solve starts from (the vectors of a parallel
        transport, a Jacobi field's start values).
    project_velocity
        ``True``: a start velocity that fails the check is replaced by its
        K-orthogonal projection onto the tangent space; ``False`` (default): it
        is refused with a ``ValueError`` that gives the deviation and the
        allowance.  Only the start velocity is projected, never the other
        tangent vectors.

    Raises
    ------
    ValueError
        ``tangent_tol`` not a finite real number ``> 0`` (``nan``, ``inf``, strings and bools included).
    TypeError
        ``project_velocity`` not a bool.
    """

    tangent_tol: float = TANGENT_TOL
    project_velocity: bool = False

    def __post_init__(self) -> None:
        object.__setattr__(self, "tangent_tol", check_real("tangent_tol", self.tangent_tol, positive=True))
        object.__setattr__(self, "project_velocity", check_bool("project_velocity", self.project_velocity))

    def allowance(self, v: NDArray) -> NDArray:
        """``tangent_tol * max(1, |v|)`` over the last axis of real velocities ``v`` (Euclidean norm): how far off the
        tangent space a ``v`` may be, in the check's own measure of the deviation, for the hinge-space checks
        (:func:`linkage.constraints.start_state`, :meth:`manifold.constrained.ConstrainedGeometry.start`)."""
        # sqrt(einsum): np.linalg.norm is 3x slower on the vector of one start
        return self.tangent_tol * np.maximum(1.0, np.sqrt(np.einsum("...i,...i->...", v, v)))


#: The groups' defaults, shared by every solver's signature: no grid, dense output as the solver keeps it by
#: default; float64 at the solver's default tolerance; a start velocity tangent to :data:`TANGENT_TOL`, else refused.
DEFAULT_SAVE, DEFAULT_PRECISION, DEFAULT_START = SaveAt(), Precision(), StartCheck()

#: A start velocity projected onto the tangent space whatever its deviation: for a start already checked by
#: another solver's own test (the projection then only removes rounding).
PROJECTED_START = StartCheck(project_velocity=True)


#: The solvers' keywords that moved into a group, each with its new home (the group's keyword first).
MOVED_OPTIONS = {
    "t_eval": "save=SaveAt(t_eval=...)",
    "dense": "save=SaveAt(dense=...)",
    "fp_type": "precision=Precision(fp_type=...)",
    "tol": "precision=Precision(tol=...)",
    "tangent_tol": "start=StartCheck(tangent_tol=...)",
    "project_velocity": "start=StartCheck(project_velocity=...)",
}


def _group(name: str) -> str:
    """The keyword of the group that the moved keyword ``name`` went into (``"save"`` for ``"t_eval"``)."""
    return MOVED_OPTIONS[name].split("=", 1)[0]


def refuse_moved_options(function: str, given: Iterable[str], groups: Iterable[str] | None = None) -> None:
    """``TypeError`` if any keyword in ``given`` moved into an option group, naming ``function`` and the group.

    For functions that pass ``**options`` on: call it with the names received.  ``groups``: the keywords of the
    groups that ``function`` takes (``("save", "precision")``); a keyword moved into another group is left to the
    function (it does not take that group, so it would be wrong to send the caller there).  ``None``: every group.
    """
    taken = None if groups is None else set(groups)
    moved = [name for name in given if name in MOVED_OPTIONS and (taken is None or _group(name) in taken)]
    if moved:
        homes = "; ".join(f"{name}= is given as {MOVED_OPTIONS[name]}" for name in moved)
        raise TypeError(f"{function}() does not take {', '.join(f'{name}=' for name in moved)}: {homes} "
                        "(manifold.options)")


def check_group(name: str, value: object, group: type[G]) -> G:
    """Return ``value`` if it is an instance of the option group ``group``; ``TypeError`` naming ``name`` otherwise."""
    if not isinstance(value, group):
        raise TypeError(f"{name} must be a manifold.{group.__name__} ({name}={group.__name__}(...)), got {value!r} "
                        f"of type {type(value).__name__}")
    return value


P = ParamSpec("P")
R = TypeVar("R")


#: The groups whose moved keywords are refused by name in a function that passes ``**options`` on, whether or not
#: it takes the group itself: the solvers it passes them to do (or refuse them by name); not ``start``, which only
#: the functions that check a start velocity take.
PASSED_ON_GROUPS = ("save", "precision")


def takes_option_groups(solver: Callable[P, R]) -> Callable[P, R]:
    """Decorate a public solver so that a keyword that moved into a group it takes is refused by name
    (:func:`refuse_moved_options`) instead of as an unexpected keyword; the signature is kept.

    The groups it takes: its keyword parameters ``save``, ``precision`` and ``start``, and where it passes
    ``**options`` on, :data:`PASSED_ON_GROUPS`.  A keyword moved into another group (``tangent_tol=`` to a
    solver without a start check) is left to Python's own error: the caller is not sent to a group that the
    function does not take.
    """
    parameters = inspect.signature(solver).parameters
    groups = set(parameters)
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in parameters.values()):
        groups.update(PASSED_ON_GROUPS)
    moved = frozenset(name for name in MOVED_OPTIONS if _group(name) in groups)

    @functools.wraps(solver)
    def checked(*args: P.args, **kwargs: P.kwargs) -> R:
        if kwargs.keys() & moved:
            refuse_moved_options(solver.__name__, kwargs, (_group(name) for name in moved))
        return solver(*args, **kwargs)

    return checked

