"""The physical chain: rods of any lengths, hinge masses and rod densities, configurations.

A :class:`Chain` of ``n`` rods of lengths ``l_1 .. l_n`` (unit rods if given as
an integer ``n``) is pinned at ``p_0 = 0`` and ``p_n = L``.  Configurations are
complex arrays of the interior hinges ``p_1 .. p_{n-1}`` with ``|p_k - p_{k-1}| = l_k``
(or, equivalently, rod angles ``theta_1 .. theta_n`` with
``sum_k l_k e^{i theta_k} = L``).  A rod of uniform line density ``lambda_k`` has
mass ``lambda_k l_k``; its point at ``s in [0, 1]`` is ``(1-s) p_{k-1} + s p_k``,
so the kinetic energy (dynamics seed, section 1) is::

    T = 1/2 sum_j M_j |p_j'|^2 + 1/2 sum_k lambda_k l_k int_0^1 |(1-s) p_{k-1}' + s p_k'|^2 ds
      = 1/2 v^T (A (x) I_2) v,

with ``A`` tridiagonal: ``A_jj = M_j + (lambda_j l_j + lambda_{j+1} l_{j+1}) / 3`` and
``A_{j,j+1} = lambda_{j+1} l_{j+1} / 6``; ``v`` the interleaved real hinge velocity.

The configuration space (:meth:`Chain.topology`) is a sphere ``S^(n-2)`` where
a side of the polygon ``(l_1, ..., l_n, L)`` dominates: the base ``L`` for
``R - 2 mu < L < R`` (``R`` the sum of the lengths, ``mu`` the shortest;
``n - 2 < L < n`` for unit rods), or a link.  There the suspension charts of
``charts/``, built on the dominant side, give an atlas (:meth:`Chain.atlas`).
Elsewhere it may be a pair of tori, a surface of higher genus, singular, or
empty (refused); its free motion is integrated in hinge coordinates
(``free_motion(..., method="hinges")``, which also serves every chain with an
atlas), and :meth:`Chain.diagonal_space` parameterises it by the diagonals ``|p_k|``.
"""

from __future__ import annotations

import numbers
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from charts import SuspensionAtlas
from charts.chain_geometry import (
    closure_excess,
    closure_residual,
    closure_scales,
    hinges_from_rods,
    rod_vectors,
    rounding_floors,
    sphere_range,
    to_complex,
    to_real,
    validate_chain,
)
from manifold import InducedMetric
from manifold.constrained import START_ROUNDING_MARGIN
from manifold.validation import ArgumentError, first_entry

from .diagonal_path import DiagonalPath, diagonal_path
from .diagonals import DiagonalSpace, diagonals, from_diagonals
from .lengths import validate_lengths
from .topology import MAX_RODS, RTOL, Topology, longest_side, topology


class ConfigurationError(ValueError):
    """A configuration that is not a closed chain of the chain's rods (or has the wrong shape)."""


#: Hinge masses are taken in this range, rod densities in ``[0, 1e100]``: beyond it the kinetic metric's products of
#: masses overflow or underflow float64 (hinge masses 1e-150: the chart method's first energy was NaN; 1e200: both
#: methods'); a tiny density beside the hinge masses is harmless.  Scaling every mass by one factor changes no
#: geodesic, so a model can always be brought into it.
MASS_RANGE = (1e-100, 1e100)
#: A start must close to this, relative to each rod (:meth:`Chain.check_configuration`), or to what float64 rounding
#: allows where that is larger; every solver of the chain takes what this check takes.
START_CLOSURE_TOLERANCE = 1e-9
#: A chain whose :attr:`Chain.stretch_gap` is below this is nearly stretched: there the hinge method's rods carry
#: tensions ``~ E / gap`` and it loses digits (``docs/methods.md``); ``free_motion``'s default takes the charts.
STRETCHED_GAP = 1e-3


def _read_only(a: NDArray) -> NDArray:
    a.flags.writeable = False
    return a


def _positive_vector(name: str, value: ArrayLike | float, size: int, allow_zero: bool) -> NDArray:
    v = np.asarray(value, dtype=float)
    if v.ndim == 0:
        v = np.full(size, v)
    if v.shape != (size,):
        raise ArgumentError(name, f"{name} must be a scalar or have length {size}, got shape {v.shape}")
    lo, hi = MASS_RANGE
    lo = 0.0 if allow_zero else lo
    ok = (v >= lo) & (v <= hi)
    if not np.all(ok):
        bad = v[~ok]
        unphysical = np.isnan(bad) | ((bad < 0) if allow_zero else (bad <= 0))  # not a mass at all, at any scale
        reasons = []
        if unphysical.any():
            reasons.append("a density is a number >= 0" if allow_zero else "a mass is a number > 0")
        if (~unphysical).any():
            reasons.append("beyond the range, the kinetic metric overflows or underflows float64; scale all masses "
                           "together to bring them in: the geodesics do not change")
        raise ArgumentError(name, f"{name} must be in [{lo:g}, {hi:g}] ({'; '.join(reasons)}), got {bad}")
    return v


def _nonempty_chain(lengths: int | ArrayLike, L: object) -> tuple[NDArray, float]:
    """Validated ``(lengths, L)``: an integer ``n >= 2`` means ``n`` unit rods; an empty space is refused."""
    if np.ndim(lengths) == 0:
        if isinstance(lengths, (bool, np.bool_)) or not isinstance(lengths, numbers.Integral) or lengths < 2:
            raise ArgumentError("lengths", f"lengths must be an integer n >= 2 (n unit rods) or a sequence of at "
                                           f"least 2 link lengths, got {lengths!r}")
        lengths = np.ones(int(lengths))
    ls, L = validate_lengths(lengths, L)
    j, excess = longest_side(ls, L)
    P = float(ls.sum()) + L
    if excess > RTOL * P:
        name = "L" if j == ls.size else f"lengths[{j}]"
        side = L if j == ls.size else float(ls[j])
        n = ls.size
        unit = ""
        if np.all(ls == 1):
            unit = f"; {n} unit rods close for 0 < L <= {n}, a sphere S^{n - 2} for {n - 2} < L < {n}"
        raise ArgumentError(
            "L" if j == ls.size else "lengths",
            f"the configuration space is empty: {name} = {side!r} exceeds the sum {P - side:.15g} of the other "
            f"sides of the polygon (l_1, ..., l_n, L), so no configuration closes; every side must be at most "
            f"half the perimeter, here {P / 2:.15g}{unit}")
    return ls, L


class Chain:
    """A planar chain of rods of lengths ``l_1 .. l_n`` pinned at ``0`` and ``L``.

    Parameters
    ----------
    lengths
        Either an integer ``n >= 2`` (``n`` unit rods: ``Chain(n, L)``) or a
        sequence of ``n >= 2`` finite lengths ``l_1 .. l_n > 0``.
    L
        Distance between the pins, finite and ``> 0``.  Refused if the
        configuration space is empty (some side of the polygon
        ``(l_1, ..., l_n, L)`` longer than the sum of the others); any other
        ``L`` is a chain (:meth:`topology` says what its space is).
    hinge_masses
        Masses ``M_1 .. M_{n-1}`` of the interior hinges (scalar or length
        ``n - 1``, each ``> 0``); default 1 (the seed's model).
    rod_densities
        Uniform line densities ``lambda_1 .. lambda_n`` of the rods (scalar or
        length ``n``, each ``>= 0``; rod ``k`` has mass ``lambda_k l_k``);
        default 0 (massless rods).

    Attributes
    ----------
    lengths
        ``l_1 .. l_n`` (read-only float array).
    n, L
        Number of rods and pin distance.
    unit_rods
        Whether every ``l_k == 1`` (given as an integer ``n`` or as lengths).
    built
        What other modules build once from the chain, by name (:func:`linkage.constraints.chain_system`).
    """

    def __init__(
        self,
        lengths: int | ArrayLike,
        L: float,
        hinge_masses: ArrayLike | float = 1.0,
        rod_densities: ArrayLike | float = 0.0,
    ) -> None:
        self.lengths, self.L = _nonempty_chain(lengths, L)
        self.lengths.flags.writeable = False
        self.n = self.lengths.size
        self.unit_rods = bool(np.all(self.lengths == 1.0))
        self.hinge_masses = _positive_vector("hinge_masses", hinge_masses, self.n - 1, allow_zero=False)
        self.rod_densities = _positive_vector("rod_densities", rod_densities, self.n, allow_zero=True)
        # read-only like the lengths: the mass matrices and the metric below are built once from them
        self.hinge_masses.flags.writeable = self.rod_densities.flags.writeable = False
        self._topology: Topology | None = None
        self._atlases: dict = {}  # built once: an n = 8 atlas costs ~25 ms
        self._refusal: tuple[str | None] | None = None  # (why there is no atlas, or None), decided once
        self._metric: InducedMetric | None = None  # of the default atlas (its checks of K cost ~0.1 ms a call)
        self._closure_scales: dict[float, NDArray] = {}  # per tolerance (charts.chain_geometry.closure_scales)
        # what other modules build once from the chain (read-only lengths and masses), by name: the
        # linkage.constraints.chain_system under "chain system" (documented in the class's Attributes)
        self.built: dict[str, Any] = {}

    def __repr__(self) -> str:
        if self.unit_rods:
            return f"Chain(n={self.n}, L={self.L!r})"
        return f"Chain(lengths={tuple(float(v) for v in self.lengths)}, L={self.L!r})"

    @property
    def dim(self) -> int:
        """Dimension ``n - 2`` of the configuration space (where it is a manifold)."""
        return self.n - 2

    # -- topology and diagonals ---------------------------------------------------
    def topology(self) -> Topology:
        """What the configuration space is (:func:`linkage.topology.topology`; ``n <= 20``)."""
        if self._topology is None:
            self._topology = topology(self.lengths, self.L)
        return self._topology

    def check_generic(self) -> None:
        """Raise ``ValueError`` unless the configuration space is a smooth manifold (generic lengths).

        Generic means no signed sum ``sum_k eps_k l_k`` equals ``L``; otherwise
        the collinear configurations ``e_k = eps_k l_k`` are singular points
        (the constraint Jacobian loses rank there), and the message names them.
        A chain with an atlas (:attr:`has_atlas`: a sphere) is generic: unit rods with ``n - 2 < L < n``
        without enumerating subsets (every signed sum is ``n`` or at most ``n - 2``), other lengths by
        :meth:`topology`, which reports a sphere only where no signed sum equals ``L``.
        """
        if self.has_atlas:
            return
        if self.n > MAX_RODS:
            raise ValueError(f"deciding whether lengths are generic enumerates 2^n signed sums: n must be <= "
                             f"{MAX_RODS}, got n = {self.n}")
        t = self.topology()
        if not t.generic:
            tol = RTOL * (float(np.sum(self.lengths)) + float(self.L))  # topology's: RTOL times the perimeter
            raise ValueError(
                f"free motion needs a smooth configuration space, and this one is not: {t.summary()} "
                f"(there sum_k eps_k l_k = L = {float(self.L)!r} to within {tol:.3g}, RTOL = {RTOL:g} times the "
                "perimeter; move L or a length off every such signed sum by more than that)")

    def diagonal_space(self) -> DiagonalSpace:
        """The diagonal polytope ``D`` of free diagonals ``(|p_2|, ..., |p_{n-1}|)`` (``n >= 3``)."""
        return DiagonalSpace(self.lengths, self.L, self.mass_matrix)

    def from_diagonals(self, x: ArrayLike, flips: ArrayLike) -> NDArray:
        """Complex hinges ``(..., n-1)`` with free diagonals ``x`` ``(..., n-2)`` and flips ``(..., n-1)``.

        See :func:`linkage.diagonals.from_diagonals`.
        """
        return from_diagonals(self.lengths, self.L, x, flips)

    def diagonals(self, hinges: ArrayLike) -> tuple[NDArray, NDArray]:
        """``(x, flips)`` of closed configurations (:func:`linkage.diagonals.diagonals`)."""
        return diagonals(self.lengths, self.L, self.as_hinges(hinges))

    def path(self, hinges0: ArrayLike, hinges1: ArrayLike) -> DiagonalPath:
        """A continuous path of closed configurations from ``hinges0`` to ``hinges1`` (each ``(n-1,)``, closing to
        1e-9): straight in the diagonals with the flips fixed, a flip changed where its fan triangle is flat
        (:func:`linkage.diagonal_path.diagonal_path`); ``path(s)`` gives the hinges at ``s`` in ``[0, 1]``.
        Raises :class:`~linkage.diagonal_path.DifferentComponentsError` (a ``ValueError``) if they lie in
        different connected components."""
        return diagonal_path(self.diagonal_space(), self.check_one_configuration(hinges0, "hinges0"),
                             self.check_one_configuration(hinges1, "hinges1"))

    # -- mass model ---------------------------------------------------------------
    @cached_property
    def mass_matrix(self) -> NDArray:
        """Tridiagonal ``(n-1, n-1)`` matrix ``A`` of the hinge kinetic energy (module docstring); read-only, built
        once (a solve reads it several times: ~0.1 ms each time at n = 4)."""
        w = self.rod_densities * self.lengths  # rod masses lambda_k l_k
        A = np.diag(self.hinge_masses + (w[:-1] + w[1:]) / 3)
        off = w[1:-1] / 6
        return _read_only(A + np.diag(off, 1) + np.diag(off, -1))

    @cached_property
    def ambient_metric(self) -> NDArray:
        """``K = A (x) I_2`` on interleaved real hinge vectors; read-only, built once."""
        return _read_only(np.kron(self.mass_matrix, np.eye(2)))

    def kinetic_energy(self, velocity: ArrayLike) -> NDArray:
        """``T = 1/2 v^T K v`` for complex hinge velocities ``(..., n-1)``."""
        v = to_real(self.as_hinges(velocity, "velocity"))
        return 0.5 * np.einsum("...i,ij,...j->...", v, self.ambient_metric, v)

    # -- charts -------------------------------------------------------------------
    def _chart_refusal(self) -> str | None:
        """Why this chain has no suspension atlas, or ``None`` if it has one (decided once: every solve asks)."""
        if self._refusal is None:
            self._refusal = (self._find_chart_refusal(),)
        return self._refusal[0]

    def _find_chart_refusal(self) -> str | None:
        hint = "; integrate its free motion with free_motion(..., method='hinges') instead (any generic lengths)"
        if self.unit_rods:
            try:
                validate_chain(self.n, self.L)
            except ValueError as err:
                return f"{err}; suspension charts (atlas, metric, method='charts') exist only there" + hint
            return None
        if self.n > MAX_RODS:
            return (f"deciding whether the configuration space is a sphere enumerates 2^n signed sums: suspension "
                    f"charts of links of other lengths need n <= {MAX_RODS}, got n = {self.n}" + hint)
        t = self.topology()
        if t.kind == "sphere":
            return None
        lo, hi = sphere_range(self.lengths)
        return (f"suspension charts (atlas, metric, free_motion(..., method='charts')) exist only where the "
                f"configuration space is a sphere, a side of the polygon (l_1, ..., l_n, L) dominant (the base L "
                f"for {lo!r} < L < {hi!r}; away from the ends by more than topology()'s tolerance); here it is "
                f"{t.summary()}" + hint)

    @property
    def stretch_gap(self) -> float:
        """How far the chain is from full stretch, as a share of the perimeter ``P`` of the polygon
        ``(l_1, ..., l_n, L)``: ``(P - 2 s) / P`` with ``s`` its longest side, the amount by which that side falls short
        of the others' sum (``-2`` times :func:`~linkage.topology.longest_side`'s excess).  Below
        :data:`STRETCHED_GAP` the chain is nearly stretched."""
        _, excess = longest_side(self.lengths, self.L)
        return -2 * excess / (float(np.sum(self.lengths)) + self.L)

    @property
    def has_atlas(self) -> bool:
        """Whether :meth:`atlas` exists: where the configuration space is the sphere ``S^(n-2)``, some side of
        the polygon ``(l_1, ..., l_n, L)`` dominant (the charts' base: ``L`` for ``R - 2 mu < L < R``, ``R`` the
        sum of the lengths, ``mu`` the shortest; else a link).

        For unit rods ``n - 2 < L < n`` exactly (as :func:`charts.chain_geometry.validate_chain`); for lengths
        given as a sequence as :meth:`topology` decides, which counts ``L`` within ``RTOL * P`` of an end as
        that end (singular or a point: ``L = 8.2`` for the lengths ``(1, 2, 1.5, 2.5, 1.2)`` is their
        stretched configuration, although ``8.2`` rounds below their exact sum).
        """
        return self._chart_refusal() is None

    def atlas(self, switch_threshold: float = 0.25) -> SuspensionAtlas:
        """The atlas of ``n`` cyclically relabeled suspension charts (built once per ``switch_threshold``;
        ``ValueError`` unless :attr:`has_atlas`)."""
        refusal = self._chart_refusal()
        if refusal is not None:
            raise ValueError(refusal)
        lengths = self.n if self.unit_rods else self.lengths
        if not isinstance(switch_threshold, (int, float)):  # not a number: the atlas refuses it with its message
            return SuspensionAtlas(lengths, self.L, switch_threshold)
        if switch_threshold not in self._atlases:
            self._atlases[switch_threshold] = SuspensionAtlas(lengths, self.L, switch_threshold)
        return self._atlases[switch_threshold]

    def metric(self, atlas: SuspensionAtlas | None = None) -> InducedMetric:
        """The kinetic-energy metric ``g = J^T K J`` on ``atlas`` (default: :meth:`atlas`, whose metric is built once)."""
        if atlas is not None:
            return InducedMetric(atlas, self.ambient_metric)
        if self._metric is None:
            self._metric = InducedMetric(self.atlas(), self.ambient_metric)
        return self._metric

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
            interleaved = h.ndim > 0 and h.shape[-1] == 2 * (self.n - 1) and h.dtype.kind in "fiu"
            hint = (" (a real array of 2 (n - 1) entries is an interleaved point: use Chain.from_point)"
                    if interleaved else "")
            raise ConfigurationError(f"{what}: expected n - 1 = {self.n - 1} complex hinges along its last axis, "
                                     f"got shape {h.shape}{hint}")
        if h.dtype.kind != "c":
            raise ConfigurationError(
                f"{what} must hold complex hinges p_j = x_j + i y_j, got an array of dtype {h.dtype} "
                "(for an interleaved real point (x_1, y_1, ...) use Chain.from_point)"
            )
        finite = np.isfinite(h)
        if not finite.all():
            raise ConfigurationError(f"{what} must be finite, got {first_entry(what, h, ~finite)}")
        return h.astype(complex)

    def rods(self, hinges: ArrayLike) -> NDArray:
        """Rod vectors ``e_1 .. e_n`` (complex, ``(..., n)``)."""
        return rod_vectors(self.as_hinges(hinges), self.L)

    def closure_residual(self, hinges: ArrayLike) -> NDArray:
        """``max_k | |e_k| - l_k | / l_k``: how far a configuration is from closing, relative to each rod (0 if it does)."""
        return closure_residual(self.as_hinges(hinges), self.L, self.lengths)

    @cached_property
    def rounding_floors(self) -> NDArray:
        """Per rod, the relative closure error that rounding the hinges to float64 alone leaves
        (:func:`charts.chain_geometry.rounding_floors`: ``u R / l_k``, 1.1e-7 for a 6e-9 link among unit rods)."""
        return rounding_floors(self.lengths)

    def closure_excess(self, hinges: ArrayLike, tol: float = 1e-9) -> NDArray:
        """``max_k | |e_k| - l_k | / (l_k tol_k)``, ``tol_k`` the larger of ``tol`` and
        :data:`manifold.constrained.START_ROUNDING_MARGIN` times the rod's :attr:`rounding_floors`
        (:func:`charts.chain_geometry.closure_excess`): at most 1 where :meth:`check_configuration` accepts."""
        return self._closure_excess(self.as_hinges(hinges), tol)

    def _closure_excess(self, h: NDArray, tol: float) -> NDArray:
        """:meth:`closure_excess` of hinges ``h`` that :meth:`as_hinges` has checked, the rods' scales kept per ``tol``."""
        scales = self._closure_scales.get(tol)
        if scales is None:
            scales = self._closure_scales.setdefault(tol, closure_scales(self.lengths, tol))
        return closure_excess(h, self.L, self.lengths, tol, scales)

    def check_configuration(self, hinges: ArrayLike, tol: float = 1e-9) -> NDArray:
        """Return ``hinges`` as a complex array if each rod closes to ``tol`` relative to its length, or to what
        float64 rounding allows where that is larger (:meth:`closure_tolerances`); raise ``ConfigurationError``
        otherwise."""
        h = self.as_hinges(hinges)
        excess = self._closure_excess(h, tol)
        if (~(excess <= 1)).any():  # the method: no dispatch through np.any
            res = closure_residual(h, self.L, self.lengths)
            raise ConfigurationError(
                f"configuration does not close: max relative rod-length error {np.max(res):.3g} exceeds tol = {tol:g} "
                f"(or {START_ROUNDING_MARGIN} times the rod's float64 rounding floor, Chain.rounding_floors, where "
                "larger)"
            )
        return h

    def one_configuration(self, hinges: ArrayLike, name: str, hint: str = "") -> NDArray:
        """:meth:`as_hinges` of one configuration: ``ValueError`` naming ``name`` for any other shape than ``(n-1,)``
        (``hint`` appended to the message).  Closure is not checked (:meth:`check_one_configuration`)."""
        h = self.as_hinges(hinges, name)
        if h.shape != (self.n - 1,):
            raise ValueError(f"{name} must be one configuration, shape (n - 1,) = ({self.n - 1},), got {h.shape}{hint}")
        return h

    def check_one_configuration(self, hinges: ArrayLike, name: str, hint: str = "") -> NDArray:
        """:meth:`one_configuration`, closing to :data:`START_CLOSURE_TOLERANCE` (:meth:`check_configuration`)."""
        return self.check_configuration(self.one_configuration(hinges, name, hint), tol=START_CLOSURE_TOLERANCE)

    def angles(self, hinges: ArrayLike) -> NDArray:
        """Rod angles ``theta_1 .. theta_n`` in ``(-pi, pi]`` of a configuration."""
        return np.angle(self.rods(hinges))

    def hinges_from_angles(self, angles: ArrayLike, tol: float = 1e-9) -> NDArray:
        """Interior hinges from rod angles; raises unless ``sum_k l_k e^{i theta_k} = L`` to ``tol``."""
        th = np.asarray(angles, dtype=float)
        if th.ndim == 0 or th.shape[-1] != self.n:
            raise ConfigurationError(f"rod angles have length n = {self.n}, got shape {th.shape}")
        if not np.all(np.isfinite(th)):
            raise ConfigurationError(f"rod angles must be finite, got {th}")
        e = self.lengths * np.exp(1j * th)
        gap = np.abs(e.sum(axis=-1) - self.L)
        if np.any(gap > tol):
            raise ConfigurationError(f"rod angles do not close: |sum_k l_k e^(i theta_k) - L| = {np.max(gap):.3g} "
                                     f"> tol = {tol:g}")
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
