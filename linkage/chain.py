"""The physical chain: unit rods, hinge masses and rod densities, configurations.

A :class:`Chain` of ``n`` unit rods is pinned at ``p_0 = 0`` and ``p_n = L``.
Configurations are complex arrays of the interior hinges ``p_1 .. p_{n-1}``
(or, equivalently, rod angles ``theta_1 .. theta_n`` with
``sum_k e^{i theta_k} = L``).  Kinetic energy (dynamics seed, section 1)::

    T = 1/2 sum_j M_j |p_j'|^2 + 1/2 sum_k int_0^1 lambda_k |(1-s) p_{k-1}' + s p_k'|^2 ds
      = 1/2 v^T (A (x) I_2) v,

with ``A`` tridiagonal: ``A_jj = M_j + (lambda_j + lambda_{j+1}) / 3`` and
``A_{j,j+1} = lambda_{j+1} / 6``; ``v`` the interleaved real hinge velocity.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from charts import SuspensionAtlas
from charts.chain_geometry import (
    closure_residual,
    hinges_from_rods,
    rod_vectors,
    to_complex,
    to_real,
    validate_chain,
)
from manifold import InducedMetric


class ConfigurationError(ValueError):
    """A configuration that is not a closed chain of unit rods (or has the wrong shape)."""


def _positive_vector(name: str, value: ArrayLike | float, size: int, allow_zero: bool) -> NDArray:
    v = np.asarray(value, dtype=float)
    if v.ndim == 0:
        v = np.full(size, v)
    if v.shape != (size,):
        raise ValueError(f"{name} must be a scalar or have length {size}, got shape {v.shape}")
    ok = np.isfinite(v) & ((v >= 0) if allow_zero else (v > 0))
    if not np.all(ok):
        bound = ">= 0" if allow_zero else "> 0"
        raise ValueError(f"{name} must be finite and {bound}, got {v[~ok]}")
    return v


class Chain:
    """A planar chain of ``n`` unit rods pinned at ``0`` and ``L``, ``n - 2 < L < n``.

    Parameters
    ----------
    n
        Number of rods, an integer ``>= 2``.
    L
        Distance between the pins, finite with ``n - 2 < L < n`` (where the
        configuration space is the sphere ``S^(n-2)``).
    hinge_masses
        Masses ``M_1 .. M_{n-1}`` of the interior hinges (scalar or length
        ``n - 1``, each ``> 0``); default 1 (the seed's model).
    rod_densities
        Uniform line densities ``lambda_1 .. lambda_n`` of the rods (scalar or
        length ``n``, each ``>= 0``); default 0 (massless rods).
    """

    def __init__(
        self,
        n: int,
        L: float,
        hinge_masses: ArrayLike | float = 1.0,
        rod_densities: ArrayLike | float = 0.0,
    ) -> None:
        self.n, self.L = validate_chain(n, L)
        self.hinge_masses = _positive_vector("hinge_masses", hinge_masses, self.n - 1, allow_zero=False)
        self.rod_densities = _positive_vector("rod_densities", rod_densities, self.n, allow_zero=True)
        self._atlases: dict = {}  # built once: an n = 8 atlas costs ~25 ms

    def __repr__(self) -> str:
        return f"Chain(n={self.n}, L={self.L!r})"

    @property
    def dim(self) -> int:
        """Dimension ``n - 2`` of the configuration space."""
        return self.n - 2

    # -- mass model ---------------------------------------------------------------
    @property
    def mass_matrix(self) -> NDArray:
        """Tridiagonal ``(n-1, n-1)`` matrix ``A`` of the hinge kinetic energy."""
        lam = self.rod_densities
        A = np.diag(self.hinge_masses + (lam[:-1] + lam[1:]) / 3)
        off = lam[1:-1] / 6
        return A + np.diag(off, 1) + np.diag(off, -1)

    @property
    def ambient_metric(self) -> NDArray:
        """``K = A (x) I_2`` on interleaved real hinge vectors."""
        return np.kron(self.mass_matrix, np.eye(2))

    def kinetic_energy(self, velocity: ArrayLike) -> NDArray:
        """``T = 1/2 v^T K v`` for complex hinge velocities ``(..., n-1)``."""
        v = to_real(self.as_hinges(velocity, "velocity"))
        return 0.5 * np.einsum("...i,ij,...j->...", v, self.ambient_metric, v)

    # -- charts -------------------------------------------------------------------
    def atlas(self, switch_threshold: float = 0.25) -> SuspensionAtlas:
        """The atlas of ``n`` cyclically relabeled suspension charts (built once per ``switch_threshold``)."""
        if not isinstance(switch_threshold, (int, float)):  # not a number: the atlas refuses it with its message
            return SuspensionAtlas(self.n, self.L, switch_threshold)
        if switch_threshold not in self._atlases:
            self._atlases[switch_threshold] = SuspensionAtlas(self.n, self.L, switch_threshold)
        return self._atlases[switch_threshold]

    def metric(self, atlas: SuspensionAtlas | None = None) -> InducedMetric:
        """The kinetic-energy metric ``g = J^T K J`` on ``atlas`` (default: :meth:`atlas`)."""
        return InducedMetric(self.atlas() if atlas is None else atlas, self.ambient_metric)

    # -- configurations -----------------------------------------------------------
    def as_hinges(self, values: ArrayLike, what: str = "configuration") -> NDArray:
        """Check complex hinge values (positions or velocities) and return them as complex128.

        Hinge values are complex ``p_j = x_j + i y_j`` of the interior hinges
        ``j = 1 .. n-1``; the interleaved real vector of the same hinges is
        :meth:`to_point`.  Nothing is checked about closure (see
        :meth:`check_configuration`).

        Parameters
        ----------
        values
            Array of complex dtype, shape ``(..., n-1)``, finite.
        what
            What ``values`` are (``"configuration"``, ``"velocity"``, ...), for the messages.

        Returns
        -------
        numpy.ndarray
            ``values`` as a complex128 array of the same shape.

        Raises
        ------
        ConfigurationError
            If the last axis is not ``n - 1`` long, the dtype is not complex (a
            real array is most likely an interleaved point: convert it with
            :meth:`from_point`), or a value is not finite.
        """
        h = np.asarray(values)
        if h.ndim == 0 or h.shape[-1] != self.n - 1:
            raise ConfigurationError(f"a {what} has n - 1 = {self.n - 1} complex hinges, got shape {h.shape}")
        if h.dtype.kind != "c":
            raise ConfigurationError(
                f"a {what} is expected as complex hinges p_j = x_j + i y_j, got an array of dtype {h.dtype} "
                "(for an interleaved real point (x_1, y_1, ...) use Chain.from_point)"
            )
        if not np.all(np.isfinite(h)):
            raise ConfigurationError(f"{what} must be finite, got {h}")
        return h.astype(complex)

    def rods(self, hinges: ArrayLike) -> NDArray:
        """Rod vectors ``e_1 .. e_n`` (complex, ``(..., n)``)."""
        return rod_vectors(self.as_hinges(hinges), self.L)

    def closure_residual(self, hinges: ArrayLike) -> NDArray:
        """``max_k | |e_k| - 1 |``: how far a configuration is from closing (0 if it does)."""
        return closure_residual(self.as_hinges(hinges), self.L)

    def check_configuration(self, hinges: ArrayLike, tol: float = 1e-9) -> NDArray:
        """Return ``hinges`` as a complex array if it closes to ``tol``; raise otherwise."""
        h = self.as_hinges(hinges)
        res = closure_residual(h, self.L)
        if np.any(res > tol):
            raise ConfigurationError(
                f"configuration does not close: max rod-length error {np.max(res):.3g} exceeds tol = {tol:g}"
            )
        return h

    def angles(self, hinges: ArrayLike) -> NDArray:
        """Rod angles ``theta_1 .. theta_n`` in ``(-pi, pi]`` of a configuration."""
        return np.angle(self.rods(hinges))

    def hinges_from_angles(self, angles: ArrayLike, tol: float = 1e-9) -> NDArray:
        """Interior hinges from rod angles; raises unless ``sum e^{i theta_k} = L`` to ``tol``."""
        th = np.asarray(angles, dtype=float)
        if th.ndim == 0 or th.shape[-1] != self.n:
            raise ConfigurationError(f"rod angles have length n = {self.n}, got shape {th.shape}")
        if not np.all(np.isfinite(th)):
            raise ConfigurationError(f"rod angles must be finite, got {th}")
        e = np.exp(1j * th)
        gap = np.abs(e.sum(axis=-1) - self.L)
        if np.any(gap > tol):
            raise ConfigurationError(f"rod angles do not close: |sum e^(i theta) - L| = {np.max(gap):.3g} > tol = {tol:g}")
        return hinges_from_rods(e)

    def to_point(self, hinges: ArrayLike) -> NDArray:
        """Complex hinges ``(..., n-1)`` to the interleaved real point ``(..., 2(n-1))`` used by charts.

        Real input is refused (``ConfigurationError``): it is most likely a point already.
        """
        h = np.asarray(hinges)
        if h.dtype.kind != "c" or h.ndim == 0 or h.shape[-1] != self.n - 1:
            raise ConfigurationError(f"to_point takes complex hinges of shape (..., {self.n - 1}), "
                                     f"got {h.dtype.name} values of shape {h.shape}")
        return to_real(h)

    def from_point(self, point: ArrayLike) -> NDArray:
        """Interleaved real point ``(..., 2(n-1))`` to complex hinges ``(..., n-1)``.

        Complex input is refused (``ConfigurationError``): it is most likely hinges already.
        """
        p = np.asarray(point)
        if p.dtype.kind not in "iuf" or p.ndim == 0 or p.shape[-1] != 2 * (self.n - 1):
            raise ConfigurationError(f"from_point takes real points of shape (..., {2 * (self.n - 1)}), "
                                     f"got {p.dtype.name} values of shape {p.shape}")
        return to_complex(p)
