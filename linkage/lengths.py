"""Validation of a chain of arbitrary link lengths, shared by its topology and diagonals.

A chain has rods of lengths ``l_1 .. l_n > 0``, pinned at ``p_0 = 0`` and
``p_n = L > 0``.  Its closed polygon has the ``n + 1`` sides
``(l_1, ..., l_n, L)``: index ``k - 1`` is rod ``l_k`` and index ``n`` is the base.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.validation import ArgumentError, check_real


def validate_lengths(lengths: ArrayLike, L: object) -> tuple[NDArray, float]:
    """Check link lengths and base; return ``(lengths as float array, float(L))``.

    Raises
    ------
    manifold.validation.ArgumentError
        A ``ValueError`` naming the argument (``argument``: ``"lengths"`` or ``"L"``), the bad value and the valid
        range: ``lengths`` a 1-D sequence of at least two finite numbers ``> 0``, ``L`` a finite number ``> 0``.
    """
    try:
        raw = np.asarray(lengths)
    except ValueError:  # a ragged nested sequence
        raw = np.asarray(None)
    if raw.dtype.kind not in "iuf":  # strings, booleans, complex or ragged input are not lengths
        raise ArgumentError("lengths", f"lengths must be a sequence of finite numbers > 0, got {lengths!r}")
    ls = raw.astype(float)
    if ls.ndim != 1 or ls.size < 2:
        raise ArgumentError("lengths", f"lengths must be a 1-D sequence of at least 2 link lengths, got shape "
                            f"{ls.shape}")
    bad = ~(np.isfinite(ls) & (ls > 0))
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ArgumentError("lengths", f"lengths must be finite and > 0, got lengths[{k}] = {float(ls[k])!r}")
    try:
        Lf = check_real("L", L, positive=True)  # refuses strings and booleans, which float() would take
    except ValueError:
        raise ArgumentError("L", f"L (base length) must be a finite number > 0, got L = {L!r}") from None
    return ls, Lf


def sides(lengths: NDArray, L: float) -> NDArray:
    """The ``n + 1`` sides ``(l_1, ..., l_n, L)`` of the closed polygon (base last, index ``n``)."""
    return np.append(lengths, L)
