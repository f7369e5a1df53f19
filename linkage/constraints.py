"""The rod constraints of a chain in hinge space, and the K-orthogonal corrections they define.

The chain moves in the hinge space ``R^(2(n-1))`` of interleaved real hinge
vectors ``x = (x_1, y_1, ..., x_{n-1}, y_{n-1})``, with the constant
kinetic-energy metric ``K = A (x) I_2`` of :attr:`Chain.ambient_metric`.  Its
configurations are the zeros of the ``n`` rod constraints

.. math::

    c_k(x) = \\frac{|e_k|^2}{l_k^2} - 1, \\qquad e_1 = p_1,\\; e_k = p_k - p_{k-1},\\; e_n = L - p_{n-1}

(rod lengths ``l_k``: :attr:`Chain.lengths`), and the tangent space at ``x``
is the null space of ``G = dc/dx``.  The constraints are relative (``|e_k|^2 - l_k^2``
divided by ``l_k^2``; for unit rods the same numbers): the configuration space
and its geodesics do not depend on that scaling, but every tolerance on ``c``
(closure checks, projections, the drift check of the hinge method) does, and
relative constraints make a chain and the same chain scaled by any factor pass
or fail alike.  Every constrained
method in hinge space (the reference integrator of :mod:`linkage.ambient`,
RATTLE, a hinge-coordinate Taylor method) is built from one operation, the
K-smallest solution ``d`` of ``G d = r``:

.. math::

    d = K^{-1} G^T (G K^{-1} G^T)^{-1} r,

which is K-orthogonal to the tangent space ``ker G``.  :class:`HingeConstraints`
holds it and what follows from it: the constrained acceleration, the
K-orthogonal projection of a velocity onto the tangent space, and Gauss-Newton
projection of a position onto ``c = 0``.  Everything is float64.
:class:`ChainSystem` is the same constraints as heyoka expressions for the
hinge Taylor method.  Both evaluate the rods, ``c``, ``G``, ``G v`` and
``(dG/dt) v`` from the one formula of :mod:`linkage.rods`, with the same
``1 / l_k^2`` rounded once.
"""

from __future__ import annotations

import functools
from fractions import Fraction
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

import heyoka as hy

from charts.chain_geometry import closure_tolerances, to_real
from manifold.backends import Cx
from manifold.constrained import ConstrainedSystem, floor_scales
from manifold.options import StartCheck, check_group
from manifold.precision import wider_types
from manifold.validation import check_real

from . import rods
from .chain import START_CLOSURE_TOLERANCE, STRETCHED_GAP, Chain

__all__ = ["ChainSystem", "chain_system", "HingeConstraints", "HingeStart", "start_arguments", "start_state",
           "start_states"]

#: A link shorter than this share of the chain's total length is short: a failed check of the hinge method says so,
#: and how to hold it (:meth:`ChainSystem.rounding_hint`).  Measured (``python -m benchmarks.short_links``): links of
#: 2.4e-4 of the total pass the float64 checks, of 2.4e-5 half of the whips fail them.
SHORT_LINK = 1e-4
#: Below this share of the total, long double at float64's tolerance failed some whips too (2.4e-8: 6 of 8 passed,
#: 2.4e-7: all), and a failed check points to real128.
LONG_DOUBLE_LINK = 1e-7

#: Gauss-Newton steps (at most) when projecting a position back onto the constraints.
_PROJECTION_STEPS = 8
#: Gauss-Newton stops once ``max_k |c_k| <`` this.
_PROJECTION_TOL = 1e-15


def _entries(a: NDArray) -> list:
    """The entries of the last axis of ``a`` for :mod:`linkage.rods`: Python floats of a vector (arithmetic on numpy
    scalars costs ~10x more), arrays of the batch shape otherwise."""
    return a.tolist() if a.ndim == 1 else list(np.moveaxis(a, -1, 0))


def _stacked(values: list) -> NDArray:
    """Per-rod values (numbers or arrays of the batch shape) as an array ``(..., n)``."""
    a = np.asarray(values, dtype=float)
    return a if a.ndim == 1 else np.moveaxis(a, 0, -1)  # one start: already (n,), and moveaxis costs ~5 us


class HingeConstraints:
    """The ``n`` rod constraints of ``chain`` in hinge space, with their K-orthogonal corrections.

    All arrays are real: positions ``x`` and velocities ``v`` are interleaved
    hinge vectors of length ``2(n-1)`` (:meth:`Chain.to_point` of the complex
    hinges), states ``y = (x, v)`` have length ``4(n-1)``.

    Parameters
    ----------
    chain
        The :class:`~linkage.Chain`: its ``n``, ``L``, rod lengths and mass model ``K``.

    Attributes
    ----------
    chain
        The chain.
    n, L, lengths
        Number of rods, pin distance and rod lengths ``l_1 .. l_n`` of the chain.
    ambient_dim
        ``2(n-1)``, the dimension of hinge space.
    K, K_inv
        The kinetic-energy metric ``A (x) I_2`` and its inverse ``A^{-1} (x) I_2``.
    """

    def __init__(self, chain: Chain) -> None:
        self.chain, self.n, self.L, self.lengths = chain, chain.n, chain.L, chain.lengths
        self.ambient_dim = 2 * (self.n - 1)
        self.K, self._mass_matrix = chain.ambient_metric, chain.mass_matrix
        # 1 / l_k^2 rounded once, as the compiled code's parameters (ChainSystem.parameters)
        self._q = list(_inverse_squares(np.asarray(chain.lengths, dtype=float).tobytes()))
        self._lengths = [float(lk) for lk in chain.lengths]

    @functools.cached_property
    def K_inv(self) -> NDArray:
        """``A^{-1} (x) I_2`` (built when first asked for: a start that needs no projection never does)."""
        return np.kron(np.linalg.inv(self._mass_matrix), np.eye(2))

    def __repr__(self) -> str:
        return f"HingeConstraints(n={self.n}, L={self.L!r})"

    def _rods(self, x: NDArray) -> list[Cx]:
        """The rods (:func:`linkage.rods.rod_vectors`) of real hinge vectors ``x`` ``(..., 2(n-1))``: ``n`` pairs of
        numbers or arrays of the batch shape."""
        return rods.rod_vectors(_entries(x), self.L)

    @staticmethod
    def _rod_rates(v: NDArray) -> list[Cx]:
        """The rods' rates ``e_k'`` of real hinge velocities ``v`` ``(..., 2(n-1))``: the pins do not move."""
        return rods.rod_vectors(_entries(v), 0.0)

    def constraints(self, x: NDArray) -> NDArray:
        """The constraint values ``c_k(x) = |e_k|^2 / l_k^2 - 1``, ``k = 1..n``.

        Parameters
        ----------
        x
            Real hinge vector(s), shape ``(..., 2(n-1))``.

        Returns
        -------
        numpy.ndarray
            ``c``, shape ``(..., n)``; zero exactly on the configuration space.
        """
        return _stacked(rods.relative_residuals(self._rods(x), self._q, 1.0))

    def jacobian(self, x: NDArray) -> NDArray:
        """The constraint Jacobian ``G = dc/dx``.

        Since ``e_k = p_k - p_{k-1}`` with fixed pins, ``dc_k = 2 e_k . (dp_k - dp_{k-1}) / l_k^2``:
        row ``k`` holds ``+2 e_k / l_k^2`` in the columns of hinge ``k`` (for ``k <= n-1``)
        and ``-2 e_k / l_k^2`` in those of hinge ``k-1`` (for ``k >= 2``).

        Parameters
        ----------
        x
            Real hinge vector(s), shape ``(..., 2(n-1))``.

        Returns
        -------
        numpy.ndarray
            ``G``, shape ``(..., n, 2(n-1))``.
        """
        E = np.moveaxis(np.asarray([[g.re, g.im] for g in rods.gradients(self._rods(x), self._q)]), (0, 1), (-2, -1))
        j = np.arange(self.n - 1)
        G = np.zeros((*x.shape[:-1], self.n, self.n - 1, 2))
        G[..., j, j, :] = E[..., :-1, :]
        G[..., j + 1, j, :] = -E[..., 1:, :]
        return G.reshape(*x.shape[:-1], self.n, self.ambient_dim)

    def tangency_residual(self, x: NDArray, v: NDArray) -> NDArray:
        """``max_k l_k |(G v)_k|`` of hinge vectors and velocities ``(..., 2(n-1))``: 0 for a tangent ``v``.

        ``l_k (G v)_k = 2 e_k . e_k' / l_k`` is twice the rate of change of rod
        length ``k``, a velocity (for unit rods it is ``(G v)_k`` itself).
        """
        Gv = rods.constraint_rates(self._rods(x), self._rod_rates(v), self._q)
        # per rod on the numbers of one vector (Python floats), one array op fewer per rod on batches
        return _stacked([lk * abs(g) for lk, g in zip(self._lengths, Gv)]).max(axis=-1)

    def min_norm_correction(self, G: NDArray, r: NDArray) -> NDArray:
        """The K-smallest ``d`` with ``G d = r``.

        Minimising ``1/2 d^T K d`` subject to ``G d = r`` gives ``K d = G^T y``
        for a multiplier ``y``, hence

        .. math::

            d = K^{-1} G^T (G K^{-1} G^T)^{-1} r,

        the unique solution that is K-orthogonal to ``ker G``
        (``w^T K d = 0`` for every ``w`` with ``G w = 0``).  ``G`` must have
        full row rank: true on the configuration space for generic lengths
        (:meth:`Chain.check_generic`); it drops at a collinear configuration.

        Parameters
        ----------
        G
            A constraint Jacobian, shape ``(n, 2(n-1))`` (from :meth:`jacobian`).
        r
            Right-hand side, shape ``(n,)``.

        Returns
        -------
        numpy.ndarray
            ``d``, shape ``(2(n-1),)``.
        """
        KiGt = self.K_inv @ G.T
        return KiGt @ np.linalg.solve(G @ KiGt, r)

    def acceleration(self, x: NDArray, v: NDArray) -> NDArray:
        """The acceleration of the free constrained motion at ``(x, v)``.

        The equations of motion ``K x'' = G^T lambda`` together with the
        constraints differentiated twice, ``l_k^2 c_k'' = 2 e_k . e_k'' + 2 |e_k'|^2 = 0``,
        i.e. ``G x'' = -2 |e'|^2 / l^2``, give

        .. math::

            x'' = K^{-1} G^T (G K^{-1} G^T)^{-1} (-2 |e'|^2 / l^2),

        the :meth:`min_norm_correction` for ``r_k = -2 |e_k'|^2 / l_k^2``.  Its solutions
        with tangent start velocities are the constant-speed geodesics of the
        kinetic-energy metric on the configuration space.

        Parameters
        ----------
        x, v
            Real hinge vector and hinge velocity, shape ``(2(n-1),)`` each.

        Returns
        -------
        numpy.ndarray
            ``x''``, shape ``(2(n-1),)``.
        """
        r = -_stacked(rods.velocity_terms(self._rod_rates(v), self._q))
        return self.min_norm_correction(self.jacobian(x), r)

    def project_velocity(self, x: NDArray, v: NDArray) -> NDArray:
        """K-orthogonal projection of ``v`` onto the tangent space ``ker G(x)``.

        .. math::

            v \\mapsto v - K^{-1} G^T (G K^{-1} G^T)^{-1} G v,

        the velocity closest to ``v`` in the K-norm with ``G v = 0``.

        Parameters
        ----------
        x, v
            Real hinge vector and hinge velocity, shape ``(2(n-1),)`` each.

        Returns
        -------
        numpy.ndarray
            The projected velocity, shape ``(2(n-1),)``.
        """
        G = self.jacobian(x)
        # Numerical trap: near the stretched chain (L within 1e-9 of the sum of the lengths) G K^-1 G^T has
        # condition ~1/gap, and one projection leaves a normal part of ~cond eps (2e-8 of |v|, refused by the
        # curvature code); a second, on the residual, takes it to rounding (iterative refinement)
        once = v - self.min_norm_correction(G, G @ v)
        return once - self.min_norm_correction(G, G @ once)

    def project_position(self, x: NDArray) -> NDArray:
        """Gauss-Newton projection of ``x`` onto the configuration space ``c = 0``.

        Repeats

        .. math::

            x \\leftarrow x - K^{-1} G(x)^T (G(x) K^{-1} G(x)^T)^{-1} c(x)

        (the K-smallest step that zeroes the linearised constraints) until
        ``max_k |c_k| < 1e-15``, at most 8 times.  From a point within
        integration error of ``c = 0`` it converges quadratically.

        Parameters
        ----------
        x
            Real hinge vector near the configuration space, shape ``(2(n-1),)``.

        Returns
        -------
        numpy.ndarray
            The projected hinge vector, shape ``(2(n-1),)``.
        """
        for _ in range(_PROJECTION_STEPS):
            c = self.constraints(x)
            if np.max(np.abs(c)) < _PROJECTION_TOL:
                break
            x = x - self.min_norm_correction(self.jacobian(x), c)
        return x

    def project(self, y: NDArray) -> NDArray:
        """Project a state ``y = (x, v)``: :meth:`project_position`, then :meth:`project_velocity` there.

        Parameters
        ----------
        y
            Real state, shape ``(4(n-1),)``.

        Returns
        -------
        numpy.ndarray
            ``(x_p, v_p)`` with ``c(x_p) = 0`` (to the Gauss-Newton tolerance)
            and ``G(x_p) v_p = 0``, shape ``(4(n-1),)``.
        """
        x = self.project_position(y[: self.ambient_dim])
        return np.concatenate([x, self.project_velocity(x, y[self.ambient_dim :])])


class HingeStart(NamedTuple):
    """A start that :func:`start_state` has checked: the functions that integrate from it take it as it is.

    Its fields (a named tuple, whose fields autodoc lists itself): ``constraints``, the chain's
    :class:`HingeConstraints` (``constraints.chain`` the chain); ``x0`` and ``v0``, the real interleaved start
    position (closing to ``1e-9``) and velocity (tangent, finite energy; projected if asked), float64
    ``(2(n-1),)``; ``t_final``, the end time, a finite nonzero float.
    """

    constraints: HingeConstraints
    x0: NDArray
    v0: NDArray
    t_final: float


def start_arguments(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike,
                    t_final: float) -> tuple[NDArray, NDArray, float]:
    """The start of a hinge-space integration with what needs no constraint checked: generic lengths
    (:meth:`Chain.check_generic`), one configuration and one velocity of ``n - 1`` finite complex hinges each, and
    ``t_final`` finite and nonzero (:func:`manifold.validation.check_real`).

    Closure and tangency are left to the caller: :func:`start_state` checks them in numpy, and
    :func:`linkage.free_motion` leaves them to the hinge solver's compiled start check
    (:meth:`manifold.constrained.ConstrainedGeometry.start`), which projects the start in the same call.

    Returns
    -------
    tuple
        ``(hinges0, velocity0, t_final)``: complex128 vectors ``(n-1,)`` (fresh arrays, whose ``view(float)`` is the
        real interleaved vector) and a float.
    """
    chain.check_generic()
    h0 = chain.one_configuration(hinges0, "hinges0", " (for many starts at once: free_motions)")
    w0 = chain.as_hinges(velocity0, "velocity0")
    if w0.shape != (chain.n - 1,):
        raise ValueError(f"velocity0 must have n - 1 = {chain.n - 1} complex entries, got shape {w0.shape}")
    return h0, w0, check_real("t_final", t_final, nonzero=True)


def start_state(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, t_final: float, check: StartCheck) -> HingeStart:
    """Validate the start of a hinge-space integration (shared by every hinge-space method), once per solve.

    Parameters
    ----------
    chain
        The chain; its lengths must be generic (:meth:`Chain.check_generic`, else
        ``ValueError`` naming the collinear configurations).
    hinges0
        Complex initial hinges; must close to ``1e-9`` relative to each rod
        (:meth:`Chain.check_configuration`, else ``ConfigurationError``).
    velocity0
        Complex initial hinge velocities, ``n - 1`` finite entries, tangent:
        ``max_k l_k |(G v)_k| <= check.tangent_tol * max(1, |v|)`` (``l_k |(G v)_k|`` is
        twice the rate of change of rod length ``k``; else ``ValueError``) unless
        ``check.project_velocity``.
    t_final
        End time, finite and nonzero (:func:`manifold.validation.check_real`).
    check
        The :class:`manifold.StartCheck` ``(tangent_tol, project_velocity)``: the relative tolerance of the
        tangency check, and whether a non-tangent ``velocity0`` is replaced by its K-orthogonal projection
        (:meth:`HingeConstraints.project_velocity`) instead of refused.

    Returns
    -------
    HingeStart
        ``(constraints, x0, v0, t_final)``: the chain's :class:`HingeConstraints`,
        the real interleaved start position and velocity, and ``t_final`` as a float.
    """
    check = check_group("start", check, StartCheck)
    h0, w0, t_final = start_arguments(chain, hinges0, velocity0, t_final)
    chain.check_configuration(h0, tol=START_CLOSURE_TOLERANCE)
    system = HingeConstraints(chain)
    x0, v0 = h0.view(float), w0.view(float)  # interleaved (x_1, y_1, ...): to_real of fresh complex128 vectors, no copy
    with np.errstate(over="ignore", invalid="ignore"):
        energy = 0.5 * v0 @ system.K @ v0
    if not np.isfinite(energy):
        raise ValueError(f"velocity0 gives a non-finite kinetic energy (max |velocity0| = {np.max(np.abs(v0)):.3g})")
    residual = float(system.tangency_residual(x0, v0))
    allowed = float(check.allowance(v0))
    if residual > allowed:
        if not check.project_velocity:
            raise ValueError(
                f"velocity0 is not tangent to the configuration space: max_k l_k |(G v)_k| = {residual:.3g} "
                f"exceeds tangent_tol * max(1, |v|) = {allowed:.3g} "
                "(pass start=StartCheck(project_velocity=True) to project it)"
            )
        v0 = system.project_velocity(x0, v0)
    return HingeStart(system, x0, v0, t_final)


def start_states(
    chain: Chain, hinges0: ArrayLike, velocities0: ArrayLike, t_final: float, check: StartCheck
) -> tuple[HingeConstraints, NDArray, NDArray, float]:
    """:func:`start_state` for many starts at once: rows of ``hinges0`` and ``velocities0``, shape ``(N, n-1)``.

    The checks run on all rows together; a row that fails one (or needs its
    velocity projected) goes through :func:`start_state` itself, so it gets
    the same result or the same error, prefixed with ``start k (hinges0[k],
    velocities0[k])``.

    Returns
    -------
    tuple
        ``(constraints, X0, V0, t_final)`` with real interleaved ``X0``, ``V0`` of shape ``(N, 2(n-1))``.
    """
    check = check_group("start", check, StartCheck)
    H = chain.as_hinges(hinges0, "hinges0")
    W = chain.as_hinges(velocities0, "velocities0")
    if H.ndim != 2 or W.shape != H.shape or H.shape[0] == 0:
        raise ValueError(f"hinges0 and velocities0 must both have shape (N, n - 1) = (N, {chain.n - 1}) with N >= 1, "
                         f"got {H.shape} and {W.shape}")
    t_final = check_real("t_final", t_final, nonzero=True)
    system = HingeConstraints(chain)
    X0, V0 = to_real(H).astype(float), to_real(W).astype(float)
    with np.errstate(over="ignore", invalid="ignore"):
        energy = 0.5 * np.einsum("ni,ij,nj->n", V0, system.K, V0)
    chain.check_generic()
    residual = system.tangency_residual(X0, V0)
    ok = (chain.closure_excess(H) <= 1) & np.isfinite(energy)
    ok &= residual <= check.allowance(V0)
    for k in np.nonzero(~ok)[0]:
        try:
            _, X0[k], V0[k], _ = start_state(chain, H[k], W[k], t_final, check)
        except ValueError as e:
            raise type(e)(f"start {k} (hinges0[{k}], velocities0[{k}]): {e}") from None
    return system, X0, V0, t_final


@functools.lru_cache(maxsize=256)
def _inverse_squares(lengths: bytes) -> tuple[float, ...]:
    """``1 / l_k^2`` of the float64 lengths' bytes, each rounded once from its exact value (the float64 values of
    :attr:`ChainSystem.parameters`)."""
    return tuple(float(1 / Fraction(float(l)) ** 2) for l in np.frombuffer(lengths, dtype=float))


@functools.lru_cache(maxsize=256)
def _chain_parameters(L: float, lengths: bytes) -> NDArray:
    """:attr:`ChainSystem.parameters` of the base ``L`` and the float64 lengths' bytes (read-only; the rational
    arithmetic cost ~0.1 ms a solve at n = 4)."""
    inverse_squares = [1 / Fraction(float(l)) ** 2 for l in np.frombuffer(lengths, dtype=float)]
    out = np.array([Fraction(L), *inverse_squares], dtype=object)
    out.flags.writeable = False
    return out


def _rod_rates(v: list) -> list:
    """The rods' rates ``e_k'`` as expressions: the rods of the hinge velocities ``v``, the pins at rest."""
    return rods.rod_vectors(v, hy.expression(0.0))


class ChainSystem(ConstrainedSystem):
    """The chain's configuration space as a :class:`manifold.constrained.ConstrainedSystem`.

    Hinge space ``R^(2(n-1))`` (interleaved real hinges), relative constraints
    ``c_k = |e_k|^2 / l_k^2 - 1`` (``e_1 = p_1``, ``e_k = p_k - p_{k-1}``,
    ``e_n = L - p_{n-1}``) and the kinetic-energy metric ``K = A (x) I_2``.
    ``L`` and the lengths are runtime parameters, so one compiled integrator
    per ``n`` (and sparsity of ``K``) serves every chain of ``n`` rods.
    ``G`` has two nonzero ``1 x 2`` blocks per row, so with hinge masses only
    (diagonal ``K``) the multiplier matrix ``G K^{-1} G^T`` is tridiagonal
    and the generic ``L D L^T`` is the Thomas recursion; rod densities make
    ``K^{-1}`` dense and the solve dense (``n <= 10``: still small).

    Parameters
    ----------
    chain
        The :class:`~linkage.Chain`.
    """

    def __init__(self, chain: Chain) -> None:
        self.chain = chain
        self.ambient_dim, self.n_constraints = 2 * (chain.n - 1), chain.n

    def __repr__(self) -> str:
        return f"ChainSystem({self.chain!r})"

    @property
    def key(self) -> tuple:
        return ("chain", self.chain.n)

    @property
    def parameters(self) -> NDArray:
        """``[L, 1 / l_1^2, ..., 1 / l_n^2]`` (exact rationals of the float64 lengths): one compiled integrator
        serves every base, every set of lengths and every mass model of one sparsity.

        Numerical trap, of cost: heyoka cannot tell a quotient by ``l_k * l_k`` (parameters) from one by a
        variable, and gives both the O(order^2) Taylor recursion of a quotient; a product with the parameter
        ``1 / l_k^2`` costs O(order).  At n = 4 that took 50 of the 135 products and quotients of each step.
        """
        return _chain_parameters(float(self.chain.L), np.asarray(self.chain.lengths, dtype=float).tobytes())

    @property
    def length_scale(self) -> float:
        """The mean rod length (1 for unit rods): the Baumgarte rate is speed / length, an angular rate."""
        return float(np.mean(self.chain.lengths))

    def rounding_hint(self, fp_type: Any, tol: float, remedy: bool = True) -> str | None:
        """Why hinge coordinates may have lost digits on this chain, and (with ``remedy``) what holds them.

        * The shortest link under :data:`SHORT_LINK` of the chain's total length ``R``: hinge coordinates hold its
          direction to about ``u R / l`` (``u`` the unit roundoff; its end hinges are rounded to ``u R``), and where
          it whips round the energy drifts with that (``docs/methods.md``, "Short links").  The remedy: the same
          tolerance ``tol`` in the next wider type (:func:`manifold.precision.wider_types`), real128 for a link
          under :data:`LONG_DOUBLE_LINK` of the total, where long double also failed.
        * The chain nearly stretched (:attr:`Chain.stretch_gap <linkage.chain.Chain.stretch_gap>` below
          :data:`~linkage.chain.STRETCHED_GAP`): the rods' tensions grow like ``1 / gap``.  The remedy, where the
          chain has an atlas: the charts, which ``free_motion``'s default takes there.
        """
        chain = self.chain
        ratio = float(np.min(chain.lengths) / np.sum(chain.lengths))
        hints = []
        if ratio < SHORT_LINK:
            hint = (f"the chain's shortest link is {ratio:.2g} of its total length, and hinge coordinates hold its "
                    f"direction only to about u / {ratio:.2g} (u the unit roundoff)")
            wider = [name for name in wider_types(fp_type) if name != "longdouble" or ratio >= LONG_DOUBLE_LINK]
            if remedy and wider:
                hint += f"; a wider type at the same tolerance holds it: precision=Precision('{wider[0]}', {tol:.3g})"
            hints.append(hint + " (docs/methods.md, 'Short links')")
        if chain.stretch_gap < STRETCHED_GAP:
            hint = (f"the chain is {chain.stretch_gap:.2g} of its perimeter short of full stretch, where the rods' "
                    f"tensions grow like 1 / that and hinge coordinates lose digits")
            if remedy and chain.has_atlas:
                hint += "; the charts hold it: free_motion(method='charts'), its default there"
            hints.append(hint)
        return "; ".join(hints) or None

    @property
    def rounding_scales(self) -> NDArray:
        """``4 R / l_k`` unit roundoffs: ``c_k`` is twice the relative length error, and rounding both of a rod's
        ends moves its length by up to twice :attr:`Chain.rounding_floors` (``u R / l_k`` each); below the common
        floor for rods of comparable lengths up to ``R = 4``, a short link's own.  Near full stretch, where the hinges'
        coordinates approach ``R``, a start of five unit rods rounded from an exact one had ``|c_k| = 17 u``."""
        return 4 * self.chain.rounding_floors / (np.finfo(float).eps / 2)

    @property
    def start_tolerances(self) -> NDArray:
        """``|c_k|`` of a rod whose length is off by the relative error the chain's start check accepts (``t_k``:
        :data:`linkage.chain.START_CLOSURE_TOLERANCE`, or more for a short link,
        :func:`charts.chain_geometry.closure_tolerances`): ``c_k = (1 + d)^2 - 1`` with ``|d| <= t_k`` is at most
        ``t_k (2 + t_k)``, and rounding ``c_k`` adds up to :attr:`rounding_scales` unit roundoffs.  So the solver
        takes every start that :meth:`Chain.check_configuration` takes (with the generic bound on ``c_k``
        itself, a rod 0.6e-9 too long was refused)."""
        t = closure_tolerances(self.chain.lengths, START_CLOSURE_TOLERANCE)
        return t * (2 + t) + floor_scales(self) * (np.finfo(float).eps / 2)

    @property
    def tangency_weights(self) -> NDArray:
        """The rod lengths ``l_k``: ``l_k (G v)_k = 2 e_k . e_k' / l_k`` is twice the rate of change of rod ``k``'s
        length, the measure of :func:`start_state`'s tangency check."""
        return np.asarray(self.chain.lengths, dtype=float)

    @property
    def metric_matrix(self) -> NDArray:
        return self.chain.ambient_metric

    def constraint_expressions(self, x: list, p: list, fp_type) -> list:
        """``|e_k|^2 / l_k^2 - 1`` with the pins ``0`` and ``L = p[0]``, ``1 / l_k^2 = p[k]``
        (:func:`linkage.rods.relative_residuals`)."""
        return rods.relative_residuals(rods.rod_vectors(x, p[0]), p[1:], hy.expression(fp_type(1.0)))

    def constraint_rate_expressions(self, x: list, v: list, p: list, G: list) -> list:
        """``G v = 2 e_k . e_k' / l_k^2`` (:func:`linkage.rods.constraint_rates`)."""
        return rods.constraint_rates(rods.rod_vectors(x, p[0]), _rod_rates(v), p[1:])

    def jacobian_expressions(self, x: list, p: list, c: list) -> list[list[hy.expression | None]]:
        """``G``: row ``k`` is ``g_k = 2 e_k / l_k^2`` on hinge ``k`` and ``-g_k`` on hinge ``k - 1`` (written by
        hand: heyoka's derivative makes ``2 / l_k^2`` a node of its own, and every product with it a full
        Taylor product)."""
        G: list[list[hy.expression | None]] = [[None] * len(x) for _ in c]
        for k, g in enumerate(rods.gradients(rods.rod_vectors(x, p[0]), p[1:])):
            if k < self.chain.n - 1:  # the rod's far end, hinge k (0-based), unless it is the pin L
                G[k][2 * k], G[k][2 * k + 1] = g.re, g.im
            if k > 0:  # its near end, hinge k - 1, unless it is the pin 0
                G[k][2 * k - 2], G[k][2 * k - 1] = -g.re, -g.im
        return G

    def transpose_product_expressions(self, x: list, p: list, G: list, lam: list) -> list:
        """``G^T lambda``: hinge ``j`` feels ``lambda_j g_j - lambda_{j+1} g_{j+1}`` (its rods, 1-based), each
        ``lambda_k g_k`` computed once from the rods (not from ``G``): two products per rod where the entries
        ``+-g_k`` of ``G`` take four (two at the pins)."""
        pulls = [(lk * g.re, lk * g.im) for lk, g in zip(lam, rods.gradients(rods.rod_vectors(x, p[0]), p[1:]))]
        return [c for (ax, ay), (bx, by) in zip(pulls[:-1], pulls[1:]) for c in (ax - bx, ay - by)]

    def velocity_term_expressions(self, x: list, v: list, p: list, G: list) -> list:
        """``(dG/dt) v``: ``2 |e_k'|^2 / l_k^2`` for rod ``k`` (:func:`linkage.rods.velocity_terms`)."""
        return rods.velocity_terms(_rod_rates(v), p[1:])

    def baumgarte_term_expressions(self, x: list, v: list, p: list, c: list, Gv: list, curvature: list,
                                   alpha) -> list:
        r"""``(dG/dt) v + 2 alpha G v + alpha^2 c`` with two products per rod,

        .. math::

            \frac{2 |e_k'|^2 + 4 \alpha\, e_k \cdot e_k'}{l_k^2} + \alpha^2 c_k
            = \frac{2\, e_k' \cdot (e_k' + 2 \alpha e_k)}{l_k^2} + \alpha^2 c_k,

        where the square ``|e_k'|^2`` and the product ``e_k . e_k'`` take three.  Numerical trap: not
        ``2 |e_k' + alpha e_k|^2 / l_k^2 - alpha^2 (c_k + 2)``, one square per rod: it cancels
        ``2 alpha^2 |e_k|^2 / l_k^2`` against ``alpha^2 (c_k + 2)``, a rounding noise of ``eps alpha^2`` that doubled the energy error
        near the top of the range and made rate 10 no better than rate 1 there.
        """
        return [q * (2.0 * (d.re * (d.re + alpha * (2.0 * e.re)) + d.im * (d.im + alpha * (2.0 * e.im))))
                + alpha * (alpha * ck) for e, d, q, ck in zip(rods.rod_vectors(x, p[0]), _rod_rates(v), p[1:], c)]

    def multiplier_pivots(self, x: list, p: list, inverse_metric: list, fp_type) -> list | None:
        r"""The Thomas pivots of ``M = G K^{-1} G^T`` as sums of non-negative terms (hinge masses, ``K = A (x) I_2``
        with ``A`` diagonal; ``None`` with rod densities, whose ``K^{-1}`` is dense).

        Row ``k`` of ``G`` is ``g_k = 2 e_k / l_k^2`` on hinge ``k`` and ``-g_k`` on
        hinge ``k-1``; with hinge weights ``w_k = 1 / m_k`` (``w_0 = w_n = 0``: pins),
        ``M_kk = (w_{k-1} + w_k) |g_k|^2`` and ``M_{k,k-1} = -w_{k-1} g_{k-1} . g_k``.
        Lagrange's identity ``|a|^2 |b|^2 - (a . b)^2 = (a x b)^2`` turns the
        Thomas recursion ``D_k = M_kk - M_{k,k-1}^2 / D_{k-1}`` into

        .. math::

            D_k = w_k |g_k|^2 + E_k, \qquad
            E_k = w_{k-1} \frac{w_{k-1} (g_{k-1} \times g_k)^2 + |g_k|^2 E_{k-1}}{D_{k-1}},
            \qquad E_1 = 0 .

        Numerical trap: the generic recursion cancels where two rods are nearly
        parallel next to a light hinge (with it, hinge masses 1e-3 .. 1e2 lost
        2e-12 of the acceleration there and 1e-11 of the energy over T = 20, and
        a chain 1e-6 from stretched lost 1e-6 of its energy).  Here only the
        cross product of two nearly parallel rods cancels, and absolutely: its
        error ``eps |g|^2`` stays far below the pivot's other terms.
        """
        n = self.chain.n
        N = 2 * (n - 1)
        if any(inverse_metric[i][j] is not None for i in range(N) for j in range(N) if i != j):
            return None
        w = {j + 1: inverse_metric[2 * j][2 * j] for j in range(n - 1)}  # hinge j + 1, the end of rod j + 1
        e = rods.rod_vectors(x, p[0])
        g = rods.gradients(e, p[1:])
        # |g_k|^2 = 4 |e_k|^2 / l_k^4 from the constraints' |e_k|^2: products with parameters, no squares of g
        square = [q * (q * (4.0 * ek.abs2())) for ek, q in zip(e, p[1:])]
        pivots = [w[1] * square[0]]  # E_1 = 0: the first rod hangs from a pin
        E = None
        for k in range(1, n):
            cross = g[k - 1].cross(g[k])
            lagrange = w[k] * (cross * cross)  # a square: half the Taylor recursion of a product
            E = w[k] * (lagrange if E is None else lagrange + square[k] * E) / pivots[k - 1]
            pivots.append(E if k == n - 1 else w[k + 1] * square[k] + E)  # the last rod ends at a pin
        return pivots



def chain_system(chain: Chain) -> ChainSystem:
    """The :class:`ChainSystem` of ``chain``, one per chain object (a chain's lengths and masses are read-only), kept
    in :attr:`Chain.built`, so that what is built on it once (:meth:`manifold.constrained.ConstrainedGeometry.of`)
    serves every solve."""
    system = chain.built.get("chain system")
    if system is None:
        system = chain.built.setdefault("chain system", ChainSystem(chain))
    return system
