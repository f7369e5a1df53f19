"""Floating types of the compiled solvers, heyoka's multiprecision ``real`` included.

An ``fp_type`` is ``float``, ``numpy.longdouble``, ``heyoka.real128`` or a
:class:`MultiPrecision` (heyoka's ``real`` at a fixed number of bits).  Every
``fp_type`` converts a scalar by a call, ``fp_type(x)``; arrays go through
:func:`as_fp`, and heyoka's constructors take :func:`heyoka_fp_kwargs`.
heyoka rejects a ``real`` whose precision differs from its integrator's, so
multiprecision arrays are built element by element at exactly ``bits``.
"""

from __future__ import annotations

from typing import Any

import heyoka as hy
import numpy as np
from numpy.typing import ArrayLike, NDArray


class MultiPrecision:
    """heyoka's arbitrary-precision ``real`` with ``bits`` bits of significand.

    Usable wherever the solvers take an ``fp_type``:
    ``solve_chart_exp_ode(..., precision=Precision(fp_type=MultiPrecision(256)))``.  Its
    ``numpy`` dtype is ``heyoka.real``; its unit roundoff is ``2**-bits``.
    """

    def __init__(self, bits: int) -> None:
        if not isinstance(bits, (int, np.integer)) or isinstance(bits, bool) or not 24 <= bits <= 1000:
            raise ValueError(f"bits must be an integer in [24, 1000], got {bits!r}")
        self.bits = int(bits)

    def __call__(self, x) -> hy.real:
        if isinstance(x, (np.integer, np.bool_)):  # heyoka.real takes Python ints, not numpy's
            x = int(x)
        return hy.real(x, self.bits)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, MultiPrecision) and other.bits == self.bits

    def __hash__(self) -> int:
        return hash(("MultiPrecision", self.bits))

    def __repr__(self) -> str:
        return f"MultiPrecision({self.bits})"


def as_fp(x: ArrayLike, fp_type) -> NDArray:
    """``x`` as an array of ``fp_type`` (multiprecision: every element at exactly ``bits``)."""
    if isinstance(fp_type, MultiPrecision):
        x = np.asarray(x)
        out = np.empty(x.shape, dtype=hy.real)
        for idx in np.ndindex(x.shape):
            out[idx] = fp_type(x[idx])
        return out
    return np.asarray(x).astype(fp_type)


def heyoka_fp_kwargs(fp_type) -> dict:
    """Keyword arguments selecting ``fp_type`` in heyoka's integrators, events and cfuncs."""
    if isinstance(fp_type, MultiPrecision):
        return {"fp_type": hy.real, "prec": fp_type.bits}
    return {"fp_type": fp_type}


def event_fp_kwargs(fp_type) -> dict:
    """Keyword arguments selecting ``fp_type`` in ``heyoka.t_event`` (which takes no precision)."""
    return {"fp_type": heyoka_fp_kwargs(fp_type)["fp_type"]}


#: Names accepted wherever an ``fp_type`` is (besides the types themselves and ``"mp<bits>"``).
FP_NAMES = {"float64": float, "longdouble": np.longdouble, "real128": getattr(hy, "real128", None)}


def resolve_fp_type(fp_type):
    """The floating type named by ``fp_type``: a type itself, or ``"float64"``, ``"longdouble"``,
    ``"real128"``, ``"mp<bits>"`` (heyoka's ``real`` at ``bits`` bits, 24..1000).

    Raises ``ValueError`` listing the names for an unknown string, ``TypeError`` for other objects.
    """
    if isinstance(fp_type, str):
        if fp_type in FP_NAMES and FP_NAMES[fp_type] is not None:
            return FP_NAMES[fp_type]
        if fp_type.startswith("mp") and fp_type[2:].isdigit():
            return MultiPrecision(int(fp_type[2:]))
        raise ValueError(f"fp_type must be one of 'float64', 'longdouble', 'real128' or 'mp<bits>' "
                         f"(e.g. 'mp256'), got {fp_type!r}")
    unit_roundoff(fp_type)  # raises TypeError for anything that is not a supported type
    return fp_type


def fp_name(fp_type) -> str:
    """The name of a floating type, as :func:`resolve_fp_type` reads it: ``"float64"``, ``"mp256"``, ...

    Raises ``TypeError`` for an unsupported type.
    """
    if isinstance(fp_type, MultiPrecision):
        return f"mp{fp_type.bits}"
    unit_roundoff(fp_type)  # raises TypeError for anything that is not a supported type
    if is_double(fp_type):
        return "float64"
    return next(name for name, t in FP_NAMES.items() if t is fp_type)


#: ``eps / 2`` of the hardware types, read once (``numpy.finfo`` costs microseconds per call, a solve asks several times).
_HARDWARE_ROUNDOFF = {t: float(np.finfo(t).eps) / 2 for t in (float, np.float64, np.longdouble)}


def unit_roundoff(fp_type) -> float:
    """``2**-p`` for a ``p``-bit significand: 2**-53 (float), 2**-64 (x86 long double), 2**-113, 2**-bits."""
    if isinstance(fp_type, MultiPrecision):
        return 2.0**-fp_type.bits
    if fp_type in _HARDWARE_ROUNDOFF:
        return _HARDWARE_ROUNDOFF[fp_type]
    if fp_type is getattr(hy, "real128", None):
        return 2.0**-113
    raise TypeError(
        f"fp_type must be float, numpy.longdouble, heyoka.real128 or MultiPrecision(bits), got {fp_type!r}"
    )


def wider_types(fp_type) -> list[str]:
    """The names (:func:`fp_name`) of the supported hardware and quad types with more significant bits than
    ``fp_type``, narrowest first: from float64 ``["longdouble", "real128"]`` where long double is wider than float64
    (x86), else ``["real128"]``; none from real128 (:class:`MultiPrecision` goes further, at a cost)."""
    bits = -np.log2(unit_roundoff(fp_type))
    return [name for name, t in FP_NAMES.items() if t is not None and -np.log2(unit_roundoff(t)) > bits]


def two_pi(fp_type) -> Any:
    """``2 pi`` rounded once to ``fp_type`` (``8 atan(1)`` in it): the shift of every wrap of a periodic parameter,
    so that the stepper's wraps between steps and the loop's at events round alike."""
    return 8 * np.arctan(as_fp(1.0, fp_type))


def is_double(fp_type) -> bool:
    """True for IEEE double (``float`` or ``numpy.float64``)."""
    return fp_type in (float, np.float64)
