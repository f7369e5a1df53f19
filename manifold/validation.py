"""Validation of scalar arguments, shared by every package.

One path for checking a real scalar argument (a time, a step size, a
tolerance), so that every public function refuses the same inputs with the same
kind of message: the argument's name, the bad value and the valid range.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

__all__ = ["check_real"]


def check_real(name: str, value: object, *, positive: bool = False, nonzero: bool = False) -> float:
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

    Returns
    -------
    float
        ``float(value)`` (a numpy long double is rounded to float64).

    Raises
    ------
    ValueError
        If ``value`` is not a real number in the valid range.
    """
    if positive:
        valid = "a real number in (0, inf)"
    elif nonzero:
        valid = "a finite nonzero real number"
    else:
        valid = "a finite real number"
    scalar = value
    if isinstance(value, np.ndarray) and value.ndim == 0:
        scalar = value[()]  # the numpy scalar of the same dtype
    is_real = isinstance(scalar, numbers.Real) and not isinstance(scalar, (bool, np.bool_))
    if not is_real:
        raise ValueError(f"{name} must be {valid}, got {value!r} of type {type(value).__name__}")
    try:
        x = float(scalar)
    except OverflowError:  # an int beyond the float range
        x = math.inf
    if not math.isfinite(x) or (positive and x <= 0) or (nonzero and x == 0):
        raise ValueError(f"{name} must be {valid}, got {value!r}")
    return x
