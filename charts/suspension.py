"""Suspension charts of the closed chain and the atlas of its cyclic relabelings.

A :class:`SuspensionChart` is the iterated-suspension parametrisation
(:mod:`charts.suspension_formula`) of the chain whose k-th rod is rod
``order[k]``, with the hinges put back in the chain's own rod order.  Points
are interleaved real vectors of the ``2(n-1)`` hinge coordinates
(:mod:`charts.chain_geometry`); parameters are ``(phi_n, ..., phi_4, t)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.atlas import Atlas
from manifold.chart import ChartDomainError
from manifold.precision import as_fp
from manifold.symbolic import SymbolicChart
from manifold.validation import first_entry, real_array

from . import suspension_formula as formula
from manifold.backends import NUMPY
from .chain_geometry import (
    closure_excess,
    closure_residual,
    relabel_hinges,
    relabel_matrix,
    to_complex,
    to_real,
    unlabel_hinges,
    side_orders,
    validate_side_order,
    validate_sphere_chain,
)
from .suspension_symbolic import SuspensionFamily

#: Largest closure residual (max rod-length error) accepted by ``get_parameters`` (a rod much shorter than the chain:
#: its float64 rounding floor, ``chain_geometry.closure_tolerances``).
CLOSURE_TOLERANCE = 1e-9
#: Slack beyond ``|phi| = pi/2`` accepted as rounding in ``get_point``.
LATITUDE_SLACK = 1e-12
#: Worst best-chart quality of the cyclic atlas (poles and folds), rounded down from
#: ``benchmarks/atlas_quality.py`` over ``L - (n-2)`` from 1e-12 to ``2 - 1e-12`` (``docs/atlas_quality.md``).
QUALITY_FLOOR = {2: 1.0, 3: 0.8, 4: 0.6, 5: 0.6, 6: 0.6, 7: 0.6, 8: 0.6}


class SuspensionChart(SymbolicChart):
    """Iterated-suspension chart of a chain of ``n`` links pinned at ``0`` and ``L`` whose space is a sphere.

    Parameters
    ----------
    lengths
        An integer ``n >= 2`` (``n`` unit rods) or the link lengths ``l_1 .. l_n``
        (``n >= 2``, each ``> 0``), in the chain's own order.
    L
        Base length.  Some side of the polygon ``(l_1, ..., l_n, L)`` must be
        dominant (``s_j < P/2 < s_j + s_i`` for all others): the configuration
        space is then the sphere ``S^(n-2)``
        (:func:`charts.chain_geometry.validate_sphere_chain`).  The dominant side
        is the chart's base: ``L`` itself for ``R - 2 mu < L < R`` (``R`` the sum
        of the lengths, ``mu`` the shortest; ``n-2 < L < n`` for unit rods), or a
        link ``l_j``, the polygon then turned so that ``l_j`` lies on the real
        axis and turned back to pin ``L`` (:func:`charts.suspension_formula.pinned_hinges`).
    order
        Side order: the chart's k-th link is side ``order[k]`` (``0 .. n-1`` the
        links, ``n`` the pinned base ``L``), a permutation of the sides other than
        the chart's base; default the sides that follow the base around the
        polygon (the identity for base ``L``).  The chart is singular where sides
        ``order[0], order[1], order[2]`` point the same way.
    sheet
        For ``n = 2`` only: which of the two points of ``S^0`` (``+1``: elbow up).

    Notes
    -----
    ``dim = n - 2`` parameters ``(phi_n, ..., phi_4, t)`` with
    ``phi_m in [-pi/2, pi/2]`` and ``t`` any real (period ``2 pi``).
    ``quality(a) = min(cos(phi_n), ..., cos(phi_4), q_A, q_B)``: 0 at the poles (three rods of
    the order stretched in a line), at the fold of the first two rods (``q_A``) and at the
    folded triple (``q_B``), see :func:`charts.suspension_formula.fold_qualities`.
    Unit rods compile :class:`SuspensionFamily` ``(n)`` (``theta = (L,)``); other
    lengths ``SuspensionFamily(n, lengths=True)`` (or ``link_base=True``), whose
    runtime parameters carry the lengths in chart order: one compiled family for
    every length vector.
    """

    def __init__(self, lengths: int | ArrayLike, L: float, order: ArrayLike | None = None, sheet: int = 1) -> None:
        ls, self.L, self.base = validate_sphere_chain(lengths, L)
        ls.flags.writeable = False
        self.lengths, self.n = ls, ls.size
        self.unit_rods = bool(np.all(ls == 1.0))
        n, base = self.n, self.base
        self.order = validate_side_order(side_orders(n, base)[0] if order is None else order, n, base)
        #: The chain's own links in chart order: ``order`` with the base's slot held by the dominant link.
        self.links = np.where(self.order == n, base, self.order)
        if sheet not in (1, -1):
            raise ValueError(f"sheet must be +1 or -1, got {sheet!r}")
        self.sheet = sheet
        self.dim = n - 2
        self.ambient_dim = 2 * (n - 1)
        #: ``M`` of ``p = M z + m``: chart-order hinges ``z`` to own-order hinges ``p`` (interleaved real).
        self.linear_map = np.kron(relabel_matrix(self.links), np.eye(2))
        sides_lengths = np.append(ls, self.L)[self.order]  # the chart's links: the sides other than its base
        D = float(np.append(ls, self.L)[base])
        if self.unit_rods:
            self.rods = formula.Rods.unit(n)
            theta = [self.L]
        else:
            slacks = formula.top_slacks(sides_lengths, D)
            self.rods = formula.Rods([float(x) for x in sides_lengths], NUMPY, slacks)
            theta = [D, *sides_lengths, *slacks]
            if base != n:
                theta += [self.L, *(self.order == n).astype(float)]
        if n >= 3:
            self.family = SuspensionFamily(n, lengths=not self.unit_rods, link_base=base != n)
            self.family_parameters = np.array(theta)

    def offset(self, fp_type: type = float) -> NDArray:
        """``m = p(z = 0)``: the relabeling's constant part, a multiple of ``L`` (exact in ``fp_type``)."""
        unit = to_real(relabel_hinges(np.zeros(self.n - 1), self.links, 1.0)).real
        return as_fp(unit, fp_type) * as_fp(self.L, fp_type)

    def __repr__(self) -> str:
        chain = f"n={self.n}" if self.unit_rods else f"lengths={tuple(float(x) for x in self.lengths)}"
        return f"SuspensionChart({chain}, L={self.L!r}, order={self.order.tolist()})"

    # -- parameters -----------------------------------------------------------
    def check_parameters(self, a: ArrayLike) -> NDArray:
        """``a`` as floats of shape ``(..., n-2)``, finite, latitudes in ``[-pi/2, pi/2]`` (``ChartDomainError``)."""
        a = real_array("chart parameters", a, finite=False)
        if a.ndim == 0 or a.shape[-1] != self.dim:
            names = [f"phi_{m}" for m in range(self.n, 3, -1)] + ["t"]  # dim = n - 2 names: phi_n..phi_4, t
            raise ChartDomainError(
                f"chart parameters must have shape (..., {self.dim}) = ({', '.join(names[: self.dim])}), "
                f"got shape {a.shape}"
            )
        finite = np.isfinite(a)
        if not finite.all():
            raise ChartDomainError(f"chart parameters must be finite, got {first_entry('a', a, ~finite)}")
        lat = a[..., :-1]
        if np.any(np.abs(lat) > np.pi / 2 + LATITUDE_SLACK):
            bad = lat[np.abs(lat) > np.pi / 2 + LATITUDE_SLACK]
            raise ChartDomainError(f"latitudes phi_m must lie in [-pi/2, pi/2], got {bad}")
        return a

    def _columns(self, a: NDArray) -> list[NDArray]:
        return [a[..., k] for k in range(self.dim)]

    # -- the map and its inverse -------------------------------------------------
    def hinges(self, a: ArrayLike) -> NDArray:
        """Complex interior hinges ``(..., n-1)`` in the chain's own rod order."""
        return to_complex(self.get_point(a))

    def get_point(self, a: ArrayLike) -> NDArray:
        if self.n > 2:
            return super().get_point(a)
        a = self.check_parameters(a)  # S^0: the elbow of the given sheet
        z = formula.hinges([], self.L, NUMPY, self.sheet, self.rods)[0]
        return np.broadcast_to(to_real(np.array([z.re + 1j * z.im])), (*a.shape[:-1], 2)).copy()

    def get_parameters(self, p: ArrayLike) -> NDArray:
        return self.polish_parameters(self.approximate_parameters(p), p)

    def check_point(self, p: ArrayLike) -> NDArray:
        """``p`` as floats of shape ``(..., 2(n-1))``, finite, closing to :data:`CLOSURE_TOLERANCE` (``ChartDomainError``)."""
        p = super().check_point(p)
        if not np.all(np.isfinite(p)):
            raise ChartDomainError(f"point must be finite, got {p}")
        h = to_complex(p)
        if np.any(~(closure_excess(h, self.L, self.lengths, CLOSURE_TOLERANCE) <= 1)):
            raise ChartDomainError(
                f"configuration does not close: relative rod-length error {np.max(closure_residual(h, self.L, self.lengths)):.3g} "
                f"> {CLOSURE_TOLERANCE:g} (or a short rod's float64 rounding floor, chain_geometry.closure_tolerances) "
                f"({self!r})"
            )
        return p

    def approximate_parameters(self, p: ArrayLike) -> NDArray:
        """The closed-form inverse (:func:`charts.suspension_formula.parameters`, compiled), before the polish."""
        if self.n > 2:
            return super().approximate_parameters(p)
        z = unlabel_hinges(to_complex(self.check_point(p)), self.links, self.L)
        if np.any(np.sign(z.imag) == -self.sheet):
            raise ChartDomainError(f"point is on the other sheet than this S^0 chart (sheet {self.sheet})")
        return np.zeros((*z.shape[:-1], 0))

    def polish_parameters(self, a: ArrayLike, p: ArrayLike) -> NDArray:
        """Two Gauss-Newton steps (:meth:`~manifold.chart.Chart.refine_parameters`): the closed form goes
        through ill-conditioned intermediates near the chart's singular set."""
        if self.n == 2:
            return np.asarray(a, dtype=float)
        return self.refine_parameters(a, p)

    def clamp_parameters(self, a: NDArray) -> NDArray:
        """Latitudes clipped to ``[-pi/2, pi/2]``, ``t`` wrapped to ``[-pi, pi)``."""
        out = np.array(a, dtype=float)
        out[..., :-1] = np.clip(out[..., :-1], -np.pi / 2, np.pi / 2)
        t = out[..., -1]
        # only angles outside [-pi, pi): (t + pi) % 2pi - pi rounds a small t to a multiple of ulp(pi) = 4.4e-16,
        # which undid the Gauss-Newton polish wherever J is large (t = 1e-9, |J| = 1.5e8: a 3.7e-11 point error)
        out[..., -1] = np.where((t < -np.pi) | (t >= np.pi), (t + np.pi) % (2 * np.pi) - np.pi, t)
        return out

    # -- derivatives and quality (from the compiled family; S^0 has no parameters) ----
    def raw_jacobian(self, a: ArrayLike) -> NDArray:
        if self.n > 2:
            return super().raw_jacobian(a)
        return np.zeros((*self.check_parameters(a).shape[:-1], self.ambient_dim, 0))

    def raw_hessian(self, a: ArrayLike) -> NDArray:
        if self.n > 2:
            return super().raw_hessian(a)
        return np.zeros((*self.check_parameters(a).shape[:-1], self.ambient_dim, 0, 0))

    def quality(self, a: ArrayLike) -> NDArray:
        if self.n > 2:
            return super().quality(a)
        return np.ones(self.check_parameters(a).shape[:-1])

    def sphere_point(self, a: ArrayLike) -> NDArray:
        """The point of the unit sphere ``S^(n-2)`` in ``R^(n-1)`` with these suspension coordinates.

        ``(phi_m, rest) -> (sin phi_m, cos phi_m * sphere(rest))``, ending with
        ``t -> (cos t, sin t)``: the chart read as latitudes and longitude, a
        homeomorphism of the configuration space onto the round sphere (used for
        pictures; continuous through the poles, where ``cos phi_m = 0``).
        """
        a = self.check_parameters(a)
        out = np.stack([np.cos(a[..., -1]), np.sin(a[..., -1])], axis=-1)
        for k in range(self.dim - 2, -1, -1):
            phi = a[..., k : k + 1]
            out = np.concatenate([np.sin(phi), np.cos(phi) * out], axis=-1)
        return out

    def rod_angles(self, a: ArrayLike) -> NDArray:
        """Rod angles ``theta_1 .. theta_n`` from the seed's angle form (own rod order).

        With a dominant link ``l_j`` as base the form gives the angles ``f_k`` of the chart's sides in the
        turned polygon; turning back by ``pi - f_{k0}`` (``k0`` the slot of ``L``) puts ``L`` on the real axis,
        and ``l_j``, the chart's closing side ``-l_j``, gets ``-f_{k0}``.
        """
        a = self.check_parameters(a)
        D = self.L if self.base == self.n else float(self.lengths[self.base])
        f = np.stack(np.broadcast_arrays(*formula.rod_angles(self._columns(a), D, NUMPY, self.sheet, self.rods)), axis=-1)
        if self.base != self.n:
            k0 = int(np.flatnonzero(self.order == self.n)[0])
            turned = f[..., k0 : k0 + 1]
            f = np.where(self.order == self.n, -turned, f + np.pi - turned)
        out = np.empty_like(f)
        out[..., self.links] = f
        return out


def sphere_parameters(x: ArrayLike) -> NDArray:
    """Inverse of :meth:`SuspensionChart.sphere_point`: latitudes and longitude ``(phi_n, ..., phi_4, t)`` of
    points ``x`` of the round sphere ``S^k`` (shape ``(..., k+1)``, ``k >= 1``; any positive scale)."""
    x = real_array("x", x)
    if x.ndim == 0 or x.shape[-1] < 2:
        raise ValueError(f"x must have shape (..., k+1) with k >= 1, got {x.shape}")
    cols = []
    for j in range(x.shape[-1] - 2):
        cols.append(np.arctan2(x[..., j], np.linalg.norm(x[..., j + 1 :], axis=-1)))
    cols.append(np.arctan2(x[..., -1], x[..., -2]))
    return np.stack(cols, axis=-1)


class RoundSphereProposal:
    """Suspension parameters of points uniform on the round sphere ``S^k``: a proposal for
    :func:`manifold.sampling.sample_volume`.

    :meth:`SuspensionChart.sphere_point` reads the parameters as latitudes and
    longitude, so their density per ``da`` is
    ``q(a) = prod_j cos(a_j)^(k-1-j) / |S^k|`` (latitude ``a_j``, ``j = 0..k-2``;
    ``|S^k| = 2 pi^((k+1)/2) / Gamma((k+1)/2)``).  Each level of a suspension
    chart collapses its inner sphere at the poles in the same way, so
    ``sqrt(det g) / q`` stays of order one where a uniform box proposal would
    waste a factor ``prod_j E[cos^(k-1-j)]`` (7 at ``k = 4``, 58 at ``k = 6``).

    Parameters
    ----------
    dim
        ``k = n - 2 >= 0`` (``k = 0``: the empty parameter vector of ``S^0``).
    """

    def __init__(self, dim: int) -> None:
        if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 0:
            raise ValueError(f"dim must be an integer >= 0, got {dim!r}")
        self.dim = int(dim)
        self.exponents = np.arange(self.dim - 1, 0, -1)  # of cos(phi_n), ..., cos(phi_4)
        self.area = 2 * np.pi ** ((self.dim + 1) / 2) / math.gamma((self.dim + 1) / 2)

    def __repr__(self) -> str:
        return f"RoundSphereProposal(dim={self.dim})"

    def draw(self, size: int, rng: np.random.Generator) -> NDArray:
        if self.dim == 0:
            return np.zeros((size, 0))
        return sphere_parameters(rng.standard_normal((size, self.dim + 1)))  # a Gaussian's direction is uniform

    def density(self, a: NDArray) -> NDArray:
        a = np.asarray(a, dtype=float)
        lat = a[..., : self.exponents.size]
        return np.prod(np.cos(lat) ** self.exponents, axis=-1) / self.area


def cyclic_orders(n: int) -> list[NDArray]:
    """The ``n`` cyclic shifts ``(s, s+1, ..., s-1)`` of the rod order (:func:`~charts.chain_geometry.side_orders`
    with the base ``L``)."""
    return side_orders(n, n)


class SuspensionAtlas(Atlas):
    """Atlas of the ``n`` cyclic relabelings of the suspension chart.

    The charts' base is the dominant side of the polygon.  With the base ``L``,
    chart ``s`` starts its suspension at rod ``s``; it is singular where rods
    ``s, s+1, s+2`` (mod ``n``) point the same way.  With a dominant link ``l_j``,
    chart ``s`` takes the sides after ``l_j`` around the polygon (``L`` among
    them) from the ``s``-th on (:func:`~charts.chain_geometry.side_orders`).
    For ``n = 2`` the atlas is the two one-point charts of ``S^0``; for ``n = 3``
    every chart is global.  With links of other lengths a relabeling permutes
    the lengths too (they are the charts' runtime parameters).

    Parameters
    ----------
    lengths, L
        The chain: an integer ``n`` (unit rods) or the link lengths, and the
        base ``L``; some side must be dominant (see :class:`SuspensionChart`).
    switch_threshold
        Quality below which the active chart should be left (default 0.25,
        well below the worst best-chart quality, 0.60 for n = 4..8 and 0.80
        for n = 3 in ``benchmarks/atlas_quality.py``).

    Attributes
    ----------
    quality_floor
        The measured worst best-chart quality, rounded down
        (:data:`QUALITY_FLOOR`, unit rods; ``None`` for other lengths, where it
        depends on the lengths: ``docs/atlas_quality.md``).
    base
        The dominant side (``n``: ``L``; ``j``: the link ``l_{j+1}``).
    parameter_box
        ``(lower, upper)`` of the chart parameters: latitudes in ``[-pi/2, pi/2]``,
        ``t`` over one period ``[-pi, pi]``.
    """

    charts: Sequence[SuspensionChart]  # narrower than Atlas.charts: sphere_point, hinges, rod_angles are there

    def __init__(self, lengths: int | ArrayLike, L: float, switch_threshold: float = 0.25) -> None:
        ls, L, base = validate_sphere_chain(lengths, L)
        n = ls.size
        if n == 2:
            charts = [SuspensionChart(ls, L, sheet=s) for s in (1, -1)]
            ids = ["sheet+", "sheet-"]
        else:
            charts = [SuspensionChart(ls, L, o) for o in side_orders(n, base)]
            ids = [f"shift{s}" for s in range(n)]
        super().__init__(charts, ids, switch_threshold, QUALITY_FLOOR.get(n) if charts[0].unit_rods else None)
        self.n, self.L, self.lengths, self.base = n, L, charts[0].lengths, base
        # Every chart maps this box onto the whole configuration space, one-to-one off its singular set (empty for n = 2).
        half = np.full(max(n - 3, 0), np.pi / 2)
        self.parameter_box = (np.append(-half, -np.pi), np.append(half, np.pi)) if n > 2 else (np.zeros(0), np.zeros(0))
