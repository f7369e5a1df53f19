"""Validation of scalar arguments, shared by every package.

One path for checking a real scalar argument (a time, a step size, a
tolerance), so that every public function refuses the same inputs with the same
kind of message: the argument's name, the bad value and the valid range.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["ArgumentError", "check_bool", "check_index", "check_positive_int", "check_real", "check_time_grid",
           "first_entry", "real_array"]


class ArgumentError(ValueError):
    """A refused argument: a ``ValueError`` whose message names the argument, the bad value and the valid range, and
    which also says which argument it was, for a caller that maps the arguments to its own fields (a form, a
    request) without reading the message.

    Parameters
    ----------
    argument
        The refused argument's name, as the refusing function's signature spells it.
    message
        The whole message.

    Attributes
    ----------
    argument
        As given.
    """

    def __init__(self, argument: str, message: str) -> None:
        super().__init__(message)
        self.argument = argument


def check_real(name: str, value: object, *, positive: bool = False, nonzero: bool = False,
               at_most: float | None = None) -> float:
    """Return ``value`` as a finite Python ``float``, or raise ``ValueError``.

    Accepted are real numbers: Python ``int`` and ``float``, numpy integer and
    floating scalars, and 0-d arrays of an integer or floating dtype.  Refused,
    with a ``ValueError`` naming ``name``, the value and the valid range:

    * anything that is not a real number, in particular strings (``'1'`` is not
      converted), ``bool`` and ``numpy.bool_``, complex numbers (even with a zero
      imaginary part) and arrays of any other shape or dtype;
    * ``nan`` and ``+-inf``;
    * with ``positive``, every ``x <= 0`` (valid range ``(0, inf)``);
    * with ``nonzero``, ``x == 0`` (valid range ``(-inf, 0) U (0, inf)``).

    Parameters
    ----------
    name
        The argument's name, as the caller's signature spells it.
    value
        The value to check.
    positive
        Require ``x > 0``.
    nonzero
        Require ``x != 0`` (implied by ``positive``).
    at_most
        Require ``x <= at_most``.

    Returns
    -------
    float
        ``float(value)`` (a numpy long double is rounded to float64).

    Raises
    ------
    ValueError
        If ``value`` is not a real number in the valid range.
    """
    if type(value) is float:  # the common case, without the abstract-class checks below (~0.5 us a call)
        x = value
    else:
        scalar = value
        if isinstance(value, np.ndarray) and value.ndim == 0:
            scalar = value[()]  # the numpy scalar of the same dtype
        if not isinstance(scalar, numbers.Real) or isinstance(scalar, (bool, np.bool_)):
            raise ValueError(f"{name} must be {_valid_range(positive, nonzero, at_most)}, got {value!r} of type "
                             f"{type(value).__name__}")
        try:
            x = float(scalar)
        except OverflowError:  # an int beyond the float range
            x = math.inf
    too_large = at_most is not None and x > at_most
    if not math.isfinite(x) or (positive and x <= 0) or (nonzero and x == 0) or too_large:
        raise ValueError(f"{name} must be {_valid_range(positive, nonzero, at_most)}, got {value!r}")
    return x


def _valid_range(positive: bool, nonzero: bool, at_most: float | None) -> str:
    """What :func:`check_real` accepts, for its messages."""
    if positive:
        return f"a real number in (0, {'inf)' if at_most is None else f'{at_most:g}]'}"
    if at_most is not None:
        return f"a finite real number <= {at_most:g}"
    if nonzero:
        return "a finite nonzero real number"
    return "a finite real number"


def check_bool(name: str, value: object) -> bool:
    """Return ``value`` if it is a ``bool`` (or ``numpy.bool_``); raise ``TypeError`` naming ``name`` otherwise.

    Strings such as ``'no'`` and numbers are refused: a flag that silently
    reads ``'no'`` as true is a wrong answer.
    """
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {value!r} of type {type(value).__name__}")
    return bool(value)


def check_index(name: str, value: object, size: int) -> int:
    """Return ``value`` as an ``int`` in ``[0, size)``.

    Raises ``TypeError`` for anything but an integer (``bool`` included) and
    ``ValueError`` for an integer out of range, both naming ``name`` and the range.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer in [0, {size - 1}], got {value!r} of type {type(value).__name__}")
    if not 0 <= int(value) < size:
        raise ValueError(f"{name} must be an integer in [0, {size - 1}], got {value!r}")
    return int(value)


def check_positive_int(name: str, value: object) -> int:
    """Return ``value`` as an ``int >= 1``; ``ValueError`` naming ``name`` for anything else (``bool`` included)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def first_entry(name: str, values: np.ndarray, bad: np.ndarray) -> str:
    """``name[i, j] = value`` for the first ``True`` of the mask ``bad`` over the array ``values`` (at least one):
    a message names the entry at fault instead of printing an array of many."""
    at = tuple(int(i) for i in np.argwhere(bad)[0])
    return f"{name}[{', '.join(map(str, at))}] = {values[at].item()!r}"


def real_array(name: str, value: object, *, finite: bool = True,
               expected: str = "a real array (interleaved real coordinates)") -> np.ndarray:
    """``value`` as a float64 array; ``TypeError`` for complex, string, boolean or object input.

    numpy would drop an imaginary part with only a warning, and read a string
    array as text (``'1'`` would be taken as the time 1): both are refused here,
    naming ``name`` and what was ``expected``.  With ``finite``, ``nan`` and
    ``inf`` raise ``ValueError``.
    """
    arr = np.asarray(value)
    if arr.dtype.kind not in "iuf":
        what = "complex" if arr.dtype.kind == "c" else arr.dtype.name
        raise TypeError(f"{name} must be {expected}, got {what} values")
    arr = arr.astype(float)
    if finite and not np.isfinite(arr).all():  # the method: no dispatch through np.all (~2 us a call)
        raise ValueError(f"{name} must be finite, got {value!r}")
    return arr


def check_time_grid(t_eval: object, t_final: float) -> np.ndarray:
    """``t_eval`` as a 1-d float64 array of times within ``[0, t_final]`` in integration order, or ``ValueError``.

    Integration order is increasing for ``t_final > 0`` and decreasing for
    ``t_final < 0``; repeated times are allowed.
    """
    grid = real_array("t_eval", t_eval)
    lo, hi = sorted((0.0, t_final))
    ordered = np.all(np.diff(grid) * (1.0 if t_final >= 0 else -1.0) >= 0)
    if grid.ndim != 1 or not np.all((grid >= lo) & (grid <= hi)) or not ordered:
        raise ValueError(f"t_eval must be a 1-d array of times within [0, {t_final:g}] in integration order, "
                         f"got {t_eval!r}")
    return grid
