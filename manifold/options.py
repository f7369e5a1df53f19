"""Option groups of the solvers: what to save, and in which precision to integrate.

Options that belong together travel together, in the manner of diffrax's
``SaveAt`` and step-size controllers: a solver takes ``save=SaveAt(...)`` and
``precision=Precision(...)`` instead of four loose keywords, and every group
checks its own fields once, when it is made.  The groups are frozen: one
``SaveAt`` or ``Precision`` can serve many solves.

A keyword that moved into a group (``t_eval=``, ``dense=``, ``fp_type=``,
``tol=``) is refused by :func:`takes_option_groups` with a ``TypeError`` that
names its new home, rather than Python's bare "unexpected keyword argument".
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, ParamSpec, TypeVar

from numpy.typing import NDArray

from .precision import resolve_fp_type
from .steppers import MAX_TOLERANCE
from .validation import check_bool, check_real, check_time_grid, real_array

__all__ = ["DEFAULT_PRECISION", "DEFAULT_SAVE", "MOVED_OPTIONS", "Precision", "SaveAt", "check_group",
           "refuse_moved_options", "takes_option_groups"]

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


#: The groups' defaults, shared by every solver's signature: no grid, dense output as the solver keeps it by
#: default; float64 at the solver's default tolerance.
DEFAULT_SAVE, DEFAULT_PRECISION = SaveAt(), Precision()


#: The solvers' keywords that moved into a group, each with its new home.
MOVED_OPTIONS = {
    "t_eval": "save=SaveAt(t_eval=...)",
    "dense": "save=SaveAt(dense=...)",
    "fp_type": "precision=Precision(fp_type=...)",
    "tol": "precision=Precision(tol=...)",
}


def refuse_moved_options(function: str, given: Iterable[str]) -> None:
    """``TypeError`` if any keyword in ``given`` moved into an option group, naming ``function`` and the group.

    For functions that pass ``**options`` on: call it with the names received.
    """
    moved = [name for name in given if name in MOVED_OPTIONS]
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


def takes_option_groups(solver: Callable[P, R]) -> Callable[P, R]:
    """Decorate a public solver so that a keyword that moved into a group is refused by name
    (:func:`refuse_moved_options`) instead of as an unexpected keyword; the signature is kept."""

    @functools.wraps(solver)
    def checked(*args: P.args, **kwargs: P.kwargs) -> R:
        if kwargs.keys() & MOVED_OPTIONS.keys():
            refuse_moved_options(solver.__name__, kwargs)
        return solver(*args, **kwargs)

    return checked

