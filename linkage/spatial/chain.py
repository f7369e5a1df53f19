"""Closed revolute chains ``(h_1, ..., h_n)``: closure, configuration curve, bonds.

Notation of Hegedüs, Schicho, Schröcker, "The Theory of Bonds" (cited as [HSS]).
Joints and links are numbered from 1 in every public result; link ``o_i``
carries the axes ``h_i`` and ``h_{i+1}``, and

    F_ij = (t_{i+1} - h_{i+1}) ... (t_j - h_j)          (i < j, indices mod n)

is the relative pose of link ``o_j`` with respect to ``o_i``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Any

import mpmath
import numpy as np
import sympy

from .curve import INF, T, W, ConfigurationCurve, Place, to_mpc
from .coupling import coupling_space, pose_product
from .dualquat import DualQuaternion
from .elimination import (
    ReducibleCurveError,
    RigidLinkageError,
    UnparametrisedComponentError,
    candidate_curves_5r,
    candidate_curves_6r,
)
from .factorization import motion_factorization
from .series import WORKING_DIGITS, PrecisionExhausted, Series

__all__ = [
    "Bond",
    "ReducibleCurveError",
    "RevoluteChain",
    "RigidLinkageError",
    "distances_from_connections",
    "motion_factorization",
]

#: Tolerance of the unit-line test for float axes (exact axes are tested exactly).
AXIS_TOL = 1e-10


@dataclass(frozen=True)
class Bond:
    """A bond: a place of the configuration curve where ``prod (t_k - h_k)`` vanishes.

    Attributes
    ----------
    joints
        ``(t_1, ..., t_n)`` at the bond, complex (``inf`` for the identity).
    parameter, branch
        The place on the configuration curve: ``t = parameter`` (or ``inf``) and the
        sign of ``w`` (``0`` on a rational curve or at a branch point).
    local_distances
        ``D_beta``, ``n x n``, entry ``[i-1, j-1] = d_beta(i, j)``
        ``= 1/2 ord Q(F_ij) - min ord F_ij`` ([HSS] Def. 14 and Lemma 16).
    connection_numbers
        ``{(i, j): k_beta(i, j)}`` for ``i < j`` with nonzero
        ``k_beta(i,j) = d(i,j) + d(i-1,j-1) - d(i,j-1) - d(i-1,j)`` (indices mod n, eq. 20).
    typical
        Exactly two joints have ``t_k^2 + 1 = 0`` ([HSS] Def. 11).
    method
        ``"exact"`` (multiplicities of irreducible factors over Q) or
        ``"mpmath-50"`` (series at 50 digits, threshold in ``linkage.spatial.series``).
    """

    joints: tuple
    parameter: complex
    branch: int
    local_distances: np.ndarray = field(repr=False)
    connection_numbers: dict
    typical: bool
    method: str

    @property
    def joint_lengths(self) -> tuple:
        """``b_beta(i) = d_beta(i-1, i)`` for ``i = 1..n`` (``d(0, 1) = d(n, 1)``)."""
        d, n = self.local_distances, len(self.joints)
        return tuple(float(d[(i - 1) % n, i % n]) for i in range(n))

    @property
    def elementary(self) -> bool:
        """The local joint lengths add up to 1 (two joints of length 1/2).

        [HSS] Def. 20 prints ``sum b_beta / 2 = 1``; with the paper's own elementary
        bonds (eq. 14: two joint lengths 1/2) the sum of the joint lengths is 1.
        """
        return sum(self.joint_lengths) == 1

    def __repr__(self) -> str:
        js = ", ".join("inf" if z == INF else f"{z.real:+.6g}{z.imag:+.6g}I" for z in self.joints)
        kind = "typical" if self.typical else "non-typical"
        return f"Bond(({js}), {kind}, connects {self.connection_numbers}, {self.method})"


def _kind(x: Any) -> str:
    """``"rational"``, ``"algebraic"`` (another exact sympy number) or ``"float"``."""
    if isinstance(x, bool):
        return "float"
    if isinstance(x, (int, Fraction, sympy.Rational)):
        return "rational"
    if isinstance(x, sympy.Basic) and x.is_number and not x.has(sympy.Float):
        return "algebraic"
    return "float"


def _is_zero(x: Any, data: str) -> bool:
    if data == "float":
        return abs(x) <= AXIS_TOL
    e = sympy.expand(x)
    return e == 0 or data == "algebraic" and sympy.simplify(e) == 0


def _as_axis(h: Any, k: int) -> DualQuaternion:
    if not isinstance(h, DualQuaternion):
        try:
            h = DualQuaternion(list(h))
        except (TypeError, ValueError) as err:
            raise ValueError(f"axes[{k}] must be a DualQuaternion or 8 coefficients; got {h!r}") from err
    return h


class RevoluteChain:
    """A closed chain of revolute joints ``(h_1, ..., h_n)``, ``4 <= n <= 7``.

    Parameters
    ----------
    axes
        ``n`` unit lines, as :class:`DualQuaternion` or 8 coefficients each
        (``DualQuaternion.from_line`` builds them from point and direction).  Each
        must satisfy ``h^2 = -1``: zero scalar parts, unit primal vector, primal
        orthogonal to dual.  Consecutive axes (cyclically) must differ (``h_{k+1} != +-h_k``).
        Integer, ``Fraction`` or sympy-rational coefficients are kept exact
        (``data == "rational"``: exact elimination and exact orders); other exact
        sympy numbers such as ``sqrt(2)/2`` too (``"algebraic"``: exact checks,
        orders from 50-digit series); anything else becomes float (``"float"``:
        closure, configuration points and drawings, but no bonds).
    curve
        Optional configuration curve (e.g. a printed one); it is checked to satisfy
        the closure condition identically.

    Notes
    -----
    The closure condition ([HSS] eq. 1) is ``prod (t_k - h_k)`` real and nonzero;
    ``t_k = cot(phi_k / 2)``, ``t_k = inf`` the identity.
    """

    def __init__(self, axes: Sequence[Any], curve: ConfigurationCurve | None = None):
        axes = [_as_axis(h, k) for k, h in enumerate(axes)]
        n = len(axes)
        if not 4 <= n <= 7:
            raise ValueError(f"axes must have 4 to 7 entries (mobility one needs 4 <= n <= 7); got {n}")
        kinds = {_kind(x) for h in axes for x in h}
        self.data = "float" if "float" in kinds else ("algebraic" if "algebraic" in kinds else "rational")
        self.exact = self.data == "rational"
        convert = {"rational": sympy.Rational, "algebraic": sympy.sympify, "float": float}[self.data]
        axes = [h.map(convert) for h in axes]
        for k, h in enumerate(axes):
            sq = h * h
            if not all(_is_zero(e, self.data) for e in [sq[0] + 1, *sq.coefficients[1:]]):
                raise ValueError(
                    f"axes[{k}] = {h} is not a unit line: h^2 = {sq}, expected -1 "
                    "(zero scalar parts, unit primal vector, primal orthogonal to dual)"
                )
        for k in range(n):
            a, b = axes[k], axes[(k + 1) % n]
            if all(_is_zero(x - y, self.data) for x, y in zip(a, b)) or all(
                _is_zero(x + y, self.data) for x, y in zip(a, b)
            ):
                raise ValueError(f"axes[{k}] and axes[{(k + 1) % n}] are the same line; consecutive axes must differ")
        self.axes = tuple(axes)
        self.n = n
        self._curve = None
        if curve is not None:
            if curve.n != n:
                raise ValueError(f"curve has {curve.n} joints, the chain {n}")
            self._check_closure_identically(curve)
            self._curve = curve
        self._bonds: dict[bool, list[Bond]] = {}

    def __repr__(self) -> str:
        return f"RevoluteChain(n={self.n}, {self.data} axes)"

    # closure ----------------------------------------------------------------------
    def closure(self, joints: Sequence[Any]) -> DualQuaternion:
        """``prod_k (t_k - h_k)`` at ``joints = (t_1, ..., t_n)`` (``inf`` -> the factor 1).

        On the configuration curve this is a real scalar: coefficients 1..7 vanish.
        """
        if len(joints) != self.n:
            raise ValueError(f"joints must have n = {self.n} entries; got {len(joints)}")
        r = DualQuaternion.scalar(1)
        for k, (t, h) in enumerate(zip(joints, self.axes)):
            if isinstance(t, (float, complex)) and np.isnan(t):
                raise ValueError(f"joints[{k}] is nan")
            if not (isinstance(t, (float, complex)) and np.isinf(abs(t))):
                r = r * (t - h)
        return r

    def reposed(self, joints: Sequence[Any]) -> RevoluteChain:
        """The same linkage assembled in the real configuration ``joints`` instead of the home pose.

        Link ``o_k`` moves by ``P_k = (t_1 - h_1) ... (t_k - h_k)`` (the pose ``F_0k``), so the
        axis ``h_k``, carried by ``o_{k-1}``, becomes ``h'_k = P_{k-1} h_k P_{k-1}^{-1}``.  As
        ``P_{k-1}^{-1} P_k = t_k - h_k`` and ``(s - h)(t^0 - h) = (t^0 s - 1) - (t^0 + s) h``,

            prod (s_k - h'_k) ~ prod (t_k - h_k) P_n^{-1},   t_k = (t^0_k s_k - 1) / (t^0_k + s_k),

        with ``P_n`` real: the new joint values ``s_k = (1 + t^0_k t_k) / (t^0_k - t_k)`` (the
        cotangent of the angle turned from ``t^0_k``) are real Moebius maps of the old ones.
        They fix ``+-I``, send ``t_k = t^0_k`` to ``s_k = inf``, and keep bonds, local distances
        and connections.  A joint with ``t^0_k = inf`` keeps its value.  The axes ``h_1`` and
        ``h_n`` stay where they are: both lie on the base link ``o_n``.

        Parameters
        ----------
        joints
            A real configuration ``(t_1, ..., t_n)`` (``inf`` allowed); exact numbers keep the
            axes exact.

        Raises
        ------
        ValueError
            If ``joints`` has the wrong length, a non-real entry, or is not a configuration
            (the product is not a nonzero real number).
        """
        if len(joints) != self.n:
            raise ValueError(f"joints must have n = {self.n} entries; got {len(joints)}")
        values = []
        for k, t in enumerate(joints):
            if isinstance(t, complex) and not _joint_inf(t):  # e.g. from configuration_point
                if abs(t.imag) > AXIS_TOL * max(1.0, abs(t)):
                    raise ValueError(f"joints[{k}] = {t} is not real; a pose of the linkage needs real joint values")
                t = t.real
            elif not _joint_inf(t) and sympy.im(sympy.sympify(t)) != 0:
                raise ValueError(f"joints[{k}] = {t} is not real; a pose of the linkage needs real joint values")
            values.append(t)
        joints = values
        data = "float" if any(isinstance(t, float) and not _joint_inf(t) for t in joints) else self.data
        prod = self.closure(joints)
        if not all(_is_zero(e, data) for e in prod.coefficients[1:]) or _is_zero(prod[0], data):
            raise ValueError(f"joints = {tuple(joints)} is not a configuration: prod (t_k - h_k) = {prod} is not real")
        pose = DualQuaternion.scalar(sympy.Integer(1) if data != "float" else 1.0)
        axes = []
        for t, h in zip(joints, self.axes):
            axes.append((pose * h * pose.inverse()).map(sympy.expand if data != "float" else float))
            if not _joint_inf(t):
                pose = pose * (t - h)
        return RevoluteChain(axes)

    def _check_closure_identically(self, curve: ConfigurationCurve) -> None:
        """``prod (a_k + b_k w - c_k h_k)`` has zero vector and dual parts modulo ``w^2 = g``."""
        prod = DualQuaternion.scalar(sympy.Integer(1))
        for a, b, c, h in zip(curve.a, curve.b, curve.c, self.axes):
            num = a.as_expr() + b.as_expr() * W
            prod = (prod * (num - c.as_expr() * h)).map(sympy.expand)
            if curve.g is not None:
                prod = prod.map(lambda e: sympy.expand(e.subs(W**2, curve.g.as_expr())))
        for k, e in enumerate(prod.coefficients[1:], start=1):
            e = sympy.expand(e)
            if curve.g is not None:
                e = sympy.rem(sympy.Poly(e, W), sympy.Poly(W**2 - curve.g.as_expr(), W)).as_expr()
            if self.data != "float" and not _is_zero(e, self.data) or self.data == "float" and _max_abs_coeff(e) > 1e-8:
                raise ValueError(f"curve does not satisfy the closure condition: coefficient {k} of the product is {e}")

    def configuration_point(
        self, value: float, joint: int | None = None, guess: Sequence[float] | None = None
    ) -> tuple:
        """A real configuration with ``t_joint = value``, solved numerically (any ``n``).

        Writes ``t_k = cot(phi_k / 2)`` and each joint as the unit rotation
        ``cos(phi_k/2) - sin(phi_k/2) h_k`` (proportional to ``t_k - h_k``); closure
        means the product is ``+-1``: its primal vector part and its dual part
        vanish.  The other angles are found by ``scipy.optimize.least_squares``
        from ``guess`` (joint values ``t_k``; default: the home pose ``t_k = inf``).

        Parameters
        ----------
        value
            The prescribed real joint value (``inf`` allowed).
        joint
            Which joint is prescribed, 1-based (default ``n``).
        guess
            Starting joint values ``t_1..t_n`` (only the free ones are used).

        Raises
        ------
        ArithmeticError
            If the solver ends with a closure residual above ``1e-10``.
        """
        from scipy.optimize import least_squares

        joint = self.n if joint is None else joint
        self._check_link(joint, "joint")
        hs = [np.array([float(x) for x in h], dtype=float) for h in self.axes]
        angle = _angle_of(value)
        start = [_angle_of(x) for x in guess] if guess is not None else [0.0] * self.n
        if guess is not None and len(guess) != self.n:
            raise ValueError(f"guess must have n = {self.n} entries; got {len(guess)}")
        free = [k for k in range(self.n) if k != joint - 1]

        def product(phis):
            r = DualQuaternion.scalar(1.0)
            for phi, h in zip(phis, hs):
                r = r * (np.cos(phi / 2) - DualQuaternion(np.sin(phi / 2) * h))
            return r

        def residual(x):
            phis = np.empty(self.n)
            phis[free], phis[joint - 1] = x, angle
            r = product(phis)
            return np.array([r[1], r[2], r[3], r[4], r[5], r[6], r[7]], dtype=float)

        sol = least_squares(residual, np.array(start)[free], xtol=1e-15, ftol=1e-15, gtol=1e-15)
        err = float(np.max(np.abs(residual(sol.x))))
        if err > 1e-10:
            raise ArithmeticError(
                f"no configuration with t_{joint} = {value} found near the guess (residual {err:.2e})"
            )
        phis = np.empty(self.n)
        phis[free], phis[joint - 1] = sol.x, angle
        return tuple(_cot_half(phi) for phi in phis)

    # configuration curve ----------------------------------------------------------
    def configuration_curve(self) -> ConfigurationCurve:
        """The configuration curve, by exact elimination for ``n = 4`` and ``n = 5``.

        ``n = 4`` (parameter ``t = t_4``, [HSS] eqs. 7, 12, 13): closure means
        ``Z = (t_1 + h_1)(t_4 + h_4)`` is proportional to
        ``(t_2 - h_2)(t_3 - h_3) = t_2 t_3 - t_3 h_2 - t_2 h_3 + h_2 h_3``.  So ``Z`` lies
        in the coupling space ``L_23 = span(1, h_2, h_3, h_2 h_3)`` (linear in ``Z``)
        and its coordinates ``alpha`` there satisfy ``alpha_0 alpha_3 = alpha_1 alpha_2``.
        The gcd of these polynomials in ``(t_1, t)`` is the curve's equation,
        quadratic in ``t_1`` (``w`` = square root of its discriminant); then
        ``t_2 = -alpha_2 / alpha_3`` and ``t_3 = -alpha_1 / alpha_3``.

        ``n = 5`` (parameter ``t_4`` or ``t_5``, rational where possible) and ``n = 6``
        (parameter ``t_6``, or ``t_5`` when the component is a double cover of the ``t_5``
        line only): the coupling
        equality with ``L_12``, see :mod:`linkage.spatial.elimination`; every
        candidate component is checked against the closure condition exactly.

        Exact (rational) axes are required.  For ``n = 7`` pass ``curve=`` to the
        constructor (e.g. from :func:`motion_factorization`): with one joint fixed, a 7R
        with generic axes has the 16 configurations of a 6R's inverse kinematics
        (``tests/test_spatial_seven.py`` finds them by elimination), so its curve is a
        16-fold cover of each joint's line, not a double cover that the normal form of
        :class:`ConfigurationCurve` could hold.

        Raises
        ------
        RigidLinkageError
            (a ``ValueError``) If the chain is rigid: no curve component (``n = 4, 5``),
            or, for any ``n``, the home pose is an isolated configuration
            (:meth:`is_mobile`).
        ReducibleCurveError
            (a ``ValueError``) If the curve is reducible, including a moving component on which a
            parameter joint is fixed (only components with such a joint at
            ``+-I``, where the product has zero norm, are dropped).
        NotImplementedError
            For ``n = 7`` without a given curve, float axes, or a component that the
            elimination cannot parametrise in any cyclic numbering of the joints (a 6R
            component that is a double cover of the line of neither of the last two joints,
            whichever joint comes first).
        """
        if self._curve is not None:
            return self._curve
        if self.home_is_isolated():
            raise RigidLinkageError(
                f"the chain is rigid: the {self.n} joint screws at the home pose are linearly independent, "
                "so the home pose is an isolated configuration"
            )
        if self.n > 6:
            raise NotImplementedError(
                f"configuration curves by elimination are implemented for n = 4, 5, 6; got n = {self.n}. "
                "A 7R with generic axes takes each value of a joint at 16 configurations (the inverse kinematics "
                "of the 6R left when that joint is fixed), so its curve covers every joint's line 16 times and "
                "has no normal form t_k = (a_k + b_k w)/c_k, w^2 = g(t) in a joint: pass curve= with a "
                "parametrisation (e.g. built by motion polynomial factorisation)"
            )
        if not self.exact:
            raise NotImplementedError(
                f"elimination needs rational axes (these are {self.data}); pass curve= to the constructor"
            )
        if self.n == 4:
            self._curve = self._eliminate_4r()
        else:
            self._curve = self._closing_component(candidate_curves_5r if self.n == 5 else candidate_curves_6r)
        return self._curve

    def _closing_component(self, candidates: Callable[..., list[ConfigurationCurve]]) -> ConfigurationCurve:
        """The one candidate curve that satisfies the closure condition identically.

        The elimination singles out joints (the last two, whose lines the curve must cover
        at most twice).  When it finds no component with the axes as numbered, or cannot
        parametrise one (``NotImplementedError``), the chain is numbered cyclically from
        joint ``2, 3, ..., n`` in turn: ``prod (t_k - h_k)`` is real exactly when its
        cyclic shifts are (they are conjugate to it), so a curve of the shifted chain is
        one of this chain with its joints renumbered back.  A component on which one of the
        last two joints stays at the identity (``t_k = inf``) or that covers their lines more
        than twice is then parametrised by other joints.  A component refused in one
        numbering must lie on a curve found in another (its equation is checked there);
        otherwise the refusal stands.
        """
        refusals: list[tuple[int, UnparametrisedComponentError]] = []
        comps: list[ConfigurationCurve] = []
        for shift in range(self.n):
            try:
                found = candidates(self.axes[shift:] + self.axes[:shift])
            except UnparametrisedComponentError as err:
                refusals.append((shift, err))
                continue
            comps = []
            for curve in (_renumbered(c, shift) for c in found):
                try:
                    self._check_closure_identically(curve)
                except ValueError:
                    continue
                comps.append(curve)
            if comps:
                break
        if not comps and refusals:
            raise NotImplementedError(f"{refusals[0][1]} (in each of the {self.n} cyclic numberings of the joints)")
        for shift, refused in refusals:  # a component refused in another numbering must be among those found
            if not any(_contains_component(c, refused, shift) for c in comps):
                raise NotImplementedError(
                    f"{refused} (numbered from joint {shift + 1}); the curve found in another numbering of the "
                    "joints does not contain that component"
                )
        if not comps:
            raise RigidLinkageError(
                "the chain is rigid: the closure equations have no common curve component "
                f"(in each of the {self.n} cyclic numberings of the joints)"
            )
        if len(comps) > 1:
            raise ReducibleCurveError(
                f"the configuration curve is reducible ({len(comps)} components): "
                f"{[c.expressions() for c in comps]}; pass curve= with one component to analyse it alone"
            )
        return comps[0]

    def joint_screws(self) -> np.ndarray | sympy.Matrix:
        """The ``6 x n`` Jacobian of the closure map at the home pose (all ``t_k = inf``).

        Column ``k`` is the screw of axis ``h_k``: its primal and dual vector parts
        (direction and negative moment).  Near the home pose a joint turned by a small
        angle ``phi`` moves the last link by ``-phi/2 h_k`` to first order; so the chain
        can leave the home pose only along the kernel of this matrix.  Exact for exact
        axes (a sympy ``Matrix``), float otherwise.
        """
        rows = [[h[c] for h in self.axes] for c in (1, 2, 3, 5, 6, 7)]
        return np.array(rows, dtype=float) if self.data == "float" else sympy.Matrix(rows)

    def home_is_isolated(self) -> bool:
        """The home pose is an isolated configuration: the joint screws are independent.

        Then ``rank J = n`` (``n <= 6``), the closure map is an immersion at the home
        pose, and no curve of configurations passes through it.  Exact rank for exact
        axes; for float axes the smallest singular value must exceed ``1e-8`` times the
        largest, and an ambiguous one raises ``ArithmeticError``.
        """
        j = self.joint_screws()
        if self.n > 6:
            return False
        if isinstance(j, np.ndarray):
            s = np.linalg.svd(j, compute_uv=False)
            if 1e-12 * s[0] < s[-1] <= 1e-8 * s[0]:
                raise ArithmeticError(
                    f"the joint screws are nearly dependent (singular values {s}): rounded axes cannot "
                    "tell an isolated home pose from a mobile one; give exact axes"
                )
            return bool(s[-1] > 1e-8 * s[0])
        return j.rank(simplify=True) == self.n

    def is_mobile(self) -> bool:
        """The chain moves: its configuration set contains a curve.

        Decided, in this order: a given or computed curve means mobile; independent
        joint screws at the home pose (:meth:`home_is_isolated`) mean that the assembled
        chain cannot move (``False``); six independent screws and ``n = 7`` mean a smooth
        curve through the home pose (``True``); for ``n = 4, 5`` with rational axes the
        exact elimination of :meth:`configuration_curve` decides for ``n = 4, 5, 6`` with
        rational axes (a reducible curve is mobile too).

        Raises
        ------
        NotImplementedError
            When none of these applies (float axes with dependent screws, or an
            elimination that cannot represent the curve).
        """
        if self._curve is not None:
            return True
        if self.home_is_isolated():
            return False
        screws = self.joint_screws()
        rank = int(np.linalg.matrix_rank(screws)) if isinstance(screws, np.ndarray) else screws.rank(simplify=True)
        if self.n == 7 and rank == 6:
            return True
        if self.n in (4, 5, 6) and self.exact:
            try:
                self.configuration_curve()
            except RigidLinkageError:
                return False
            except ReducibleCurveError:
                return True
            return True
        raise NotImplementedError(
            f"mobility of this {self.n}R chain ({self.data} axes, dependent joint screws at the home pose) "
            "is decided only by a configuration curve: pass curve= or give a 4R/5R chain rational axes"
        )

    def _eliminate_4r(self) -> ConfigurationCurve:
        h1, h2, h3, h4 = self.axes
        x = sympy.Symbol("x")  # t_1
        basis = sympy.Matrix([list(v) for v in (DualQuaternion.scalar(sympy.Integer(1)), h2, h3, h2 * h3)]).T
        if basis.rank() != 4:
            raise ValueError("axes 2 and 3 span less than a 4-dimensional coupling space (equal lines?)")
        z = sympy.Matrix(list(((x + h1) * (T + h4)).map(sympy.expand)))
        alpha = ((basis.T * basis).inv() * basis.T * z).applyfunc(sympy.expand)
        residual = (z - basis * alpha).applyfunc(sympy.expand)
        equations = [e for e in list(residual) + [sympy.expand(alpha[0] * alpha[3] - alpha[1] * alpha[2])] if e != 0]
        p = equations[0]
        for e in equations[1:]:
            p = sympy.gcd(p, e)
        _, factors = sympy.factor_list(p, x, T)
        comps = [f for f, _ in factors if sympy.degree(f, x) > 0 and sympy.degree(f, T) > 0]
        # A factor free of t or of t_1 is a component on which joint 1 or joint n is
        # fixed.  Only t_k = +-I (a factor of t_k^2 + 1) is spurious: there the product
        # has zero norm, it cannot be real and nonzero.  Any other such factor is a
        # component along which the other joints can move (e.g. a folded kite,
        # t_1 = -1): dropping it silently would report the bonds and distances of
        # part of the curve as those of the linkage (issue 11, review finding B).
        fixed = []
        for f, _ in factors:
            v = T if sympy.degree(f, x) == 0 else (x if sympy.degree(f, T) == 0 else None)
            if v is not None and sympy.rem(v**2 + 1, f, v) != 0:
                fixed.append(f)
        if fixed:
            t_1 = sympy.Symbol("t_1")
            described = ", ".join(
                f"{f.subs(x, t_1)} = 0 (joint {1 if sympy.degree(f, T) == 0 else self.n} fixed)" for f in fixed
            )
            raise ReducibleCurveError(
                f"the configuration curve (t = t_{self.n}) is reducible: besides "
                f"{[str(c.subs(x, t_1)) for c in comps]} "
                f"it has component(s) {described} along which the other joints can move; bonds and "
                "distances of the whole linkage need every component, and a fixed joint cannot serve as "
                "the parameter t = t_n.  Pass curve= with one component to analyse that component alone"
            )
        if not comps:
            raise RigidLinkageError("the chain is rigid: the closure equations have no common curve component")
        if len(comps) > 1:
            raise ReducibleCurveError(f"the configuration curve is reducible ({len(comps)} components): {comps}")
        poly = sympy.Poly(comps[0], x)
        if poly.degree() == 1:
            c1, c0 = poly.all_coeffs()
            t1 = -c0 / c1
            g = None
        else:
            ca, cb, cc = poly.all_coeffs()
            g = sympy.expand(cb**2 - 4 * ca * cc)
            t1 = (-cb + W) / (2 * ca)
        a = [sympy.together(e.subs(x, t1)) for e in alpha]
        joints = [t1, -a[2] / a[3], -a[1] / a[3], T]
        if g is None:
            return ConfigurationCurve.rational([sympy.cancel(e) for e in joints])
        return ConfigurationCurve.hyperelliptic(joints, g)

    # bonds ------------------------------------------------------------------------
    def bonds(self, numeric: bool = False) -> list[Bond]:
        """All bonds, with local distance matrices and connection numbers.

        Candidates are the places over the roots of ``t_k^2 + 1`` (all joints) and
        over ``t = inf``; a place is a bond when every coordinate of
        ``F_0n = prod (t_k - h_k)`` vanishes there (joint coordinates taken as limits
        along the curve, so 0/0 base points do not count).

        With exact (rational) axes the orders are exact: on a rational curve as
        multiplicities of the irreducible factors over Q of ``prod (a_k^2 + c_k^2)``
        (all roots of a factor share one local structure); on a hyperelliptic curve
        by series over the number field ``Q(I, t0, sqrt(...))`` of the place, when
        ``t0`` has degree at most ``EXACT_ROOT_DEGREE`` over Q.  Everything else uses
        series at 50 digits with the documented zero threshold (``Bond.method``
        says which).

        Parameters
        ----------
        numeric
            Force the 50-digit series everywhere (a cross-check of the exact results).
        """
        if self.data == "float":
            raise ValueError(
                "bonds need exact axes (rationals or sympy numbers): float axes satisfy the closure of an "
                "overconstrained linkage only to rounding, far above the 50-digit zero threshold; "
                "convert them, e.g. with sympy.nsimplify"
            )
        if numeric not in self._bonds:
            curve = self.configuration_curve()
            if curve.is_rational and self.exact and not numeric:
                bonds = self._bonds_exact(curve)
            else:
                bonds = self._bonds_series(curve, exact=self.exact and not numeric)
            self._bonds[numeric] = sorted(bonds, key=_bond_order)
        return list(self._bonds[numeric])

    def _pairs(self):
        return [(i, j) for i in range(1, self.n + 1) for j in range(i + 1, self.n + 1)]

    def _finish(self, joints, t0, branch, dist: dict, typical: bool, method: str) -> Bond:
        n = self.n
        d = np.zeros((n, n))
        for (i, j), v in dist.items():
            d[i - 1, j - 1] = d[j - 1, i - 1] = v
        return Bond(tuple(joints), t0, branch, d, connection_numbers(d), typical, method)

    # -- series path
    def _bonds_series(self, curve: ConfigurationCurve, exact: bool) -> list[Bond]:
        """Bonds found on 50-digit places, then re-analysed exactly where a cheap exact field exists."""
        out = []
        with mpmath.workdps(WORKING_DIGITS):
            numeric_axes = [h.map(to_mpc) for h in self.axes]
            for t0, factor in curve.bond_candidate_factors():
                for place in curve.places(t0):
                    # With exact data the exact place decides, before any numeric screen: a
                    # thresholded test must never be able to drop a bond that exact
                    # arithmetic would find (issue 11, review finding A).
                    exact_place = curve.exact_place(place, factor) if exact else None
                    if exact_place is not None:
                        place = exact_place
                        field = place.joints[0][1].field
                        axes = [h.map(field.convert) for h in self.axes]
                    else:
                        place = _normalized_place(place)
                        axes = numeric_axes
                    if not self._vanishes_at(place, axes):
                        continue
                    dist = {}
                    for i in range(1, self.n):
                        f = self._product_series(place, axes, i, i)
                        for j in range(i + 1, self.n + 1):  # F_ij = F_i,j-1 (t_j - h_j)
                            f = f * self._product_series(place, axes, j - 1, j)
                            dist[(i, j)] = Fraction(f.quadratic_form().order(), 2) - _min_order(f)
                    hits = sum(1 for num, den in place.joints if (num * num + den * den).order() > 0)
                    method = "exact" if place.exact else "mpmath-50"
                    out.append(self._finish(place.joint_values(), place.t0, place.branch, dist, hits == 2, method))
        return out

    def _vanishes_at(self, place: Place, axes) -> bool:
        """``F_0n`` vanishes at the place: all coordinates have order >= 1.

        Only the ``u^0`` coefficients matter, so the joints are truncated to ``O(u)``.
        On a numeric place the joint pairs must be normalised first
        (:func:`_normalized_place`): the zero threshold is relative to a scale of at
        least 1, so it is scale-invariant only for terms of modulus about 1.
        """
        first = Place(place.t0, place.branch, tuple((a.truncated(1), b.truncated(1)) for a, b in place.joints))
        try:
            _min_order(self._product_series(first, axes, 0, self.n))
        except PrecisionExhausted:
            return True
        return False

    @staticmethod
    def _product_series(place: Place, axes, i: int, j: int) -> DualQuaternion:
        """``F_ij`` at a place: ``prod_{k=i+1..j} (num_k - den_k h_k)`` (1-based joints)."""
        field = place.joints[0][1].field
        zero = Series.exact([], 0, field)
        r = DualQuaternion.scalar(Series.exact([1], 0, field), zero)
        for k in range(i, j):
            num, den = place.joints[k]
            r = r * (DualQuaternion.scalar(num, zero) - axes[k] * den)
        return r

    # -- exact path (rational curve, rational axes)
    def _bonds_exact(self, curve: ConfigurationCurve) -> list[Bond]:
        n = self.n
        a, c = list(curve.a), list(curve.c)
        e = [max(p.degree(), q.degree(), 0) for p, q in zip(a, c)]
        one = sympy.Poly(1, T, domain="QQ")
        # F_ij as dual quaternions with polynomial coefficients, homogeneous degree sum e_k
        prods = {}
        for i in range(n):
            r = DualQuaternion.scalar(one, 0 * one)
            for j in range(i, n):
                r = r * (DualQuaternion.scalar(a[j], 0 * one) - self.axes[j] * c[j])
                prods[(i, j + 1)] = (r, sum(e[i : j + 1]))
        bond_poly = one
        for ak, ck in zip(a, c):
            bond_poly = bond_poly * (ak * ak + ck * ck)
        factors = [f for f, _ in bond_poly.factor_list()[1]]
        out = []
        for m in factors + [None]:  # None: t = inf
            full, deg = prods[(0, n)]
            if _exact_min_order(full, deg, m) <= 0:
                continue
            dist = {}
            for i, j in self._pairs():
                f, deg = prods[(i, j)]
                q = _exact_order(f.quadratic_form(), 2 * deg, m)
                dist[(i, j)] = Fraction(q, 2) - _exact_min_order(f, deg, m)
            # joints with t_k^2 + 1 = 0 here: (a_k^2 + c_k^2) vanishes (homogeneous degree 2 e_k)
            hits = sum(_exact_order(ak * ak + ck * ck, 2 * ek, m) > 0 for ak, ck, ek in zip(a, c, e))
            roots = [INF] if m is None else [complex(sympy.N(r, 30)) for r in m.all_roots()]
            for t0 in roots:
                joints = curve.places(t0)[0].joint_values()
                out.append(self._finish(joints, t0, 0, dist, hits == 2, "exact"))
        return out

    # totals -------------------------------------------------------------------------
    def distance_matrix(self) -> np.ndarray:
        """``D = sum_beta D_beta`` ([HSS] Theorem 19: ``d(i,j) = deg C_ij * deg f_ij``)."""
        return sum((b.local_distances for b in self.bonds()), np.zeros((self.n, self.n)))

    def connections(self) -> dict[tuple[int, int], int]:
        """``{(i, j): number of lines}`` of the bond diagram, ``i < j`` 1-based.

        One line per unit of ``k_beta(i, j)`` per pair of conjugate bonds (the two
        bonds of a pair have equal connection numbers), negative for dashed lines.
        """
        total: dict = {}
        for b in self.bonds():
            for key, k in b.connection_numbers.items():
                total[key] = total.get(key, 0) + k
        out = {}
        for key, k in sorted(total.items()):
            if k % 2:
                raise ArithmeticError(
                    f"connection number sum {k} for joints {key} is odd: bonds are not in conjugate pairs"
                )
            if k:
                out[key] = k // 2
        return out

    # coupling ---------------------------------------------------------------------
    def coupling_map(self, i: int, j: int) -> Callable[..., DualQuaternion]:
        """The coupling map ``f_ij``: a function of a curve point returning ``F_ij`` (eq. 3).

        The returned function takes the curve parameter ``t`` and ``branch`` (sign
        of ``w``) and gives the dual quaternion ``F_ij``, replaced by its limit
        direction (the leading coefficient along the curve) where it vanishes; the
        result is determined up to a nonzero scalar (joint pairs are scaled to
        modulus 1 before the leading order is read).
        Links are 1-based; for ``i > j`` the product runs over ``i+1, ..., n, 1, ..., j``.
        """
        self._check_link(i, "i")
        self._check_link(j, "j")
        if i == j:
            raise ValueError(f"i and j must be different links; got i = j = {i}")
        curve = self.configuration_curve()
        order = [k % self.n for k in range(i, j if j > i else j + self.n)]

        def f(t: Any, branch: int = 1) -> DualQuaternion:
            with mpmath.workdps(WORKING_DIGITS):
                places = curve.places(t)
                place = places[0] if len(places) == 1 else places[0 if branch == 1 else 1]
                place = _normalized_place(place)  # scale-invariant choice of the leading order
                zero = Series.exact([0])
                r = DualQuaternion.scalar(Series.exact([1]), zero)
                for k in order:
                    num, den = place.joints[k]
                    r = r * (DualQuaternion.scalar(num, zero) - self.axes[k].map(to_mpc) * den)
                v = _min_order(r)
                return DualQuaternion([complex(s.coefficient(v)) for s in r])

        return f

    def relative_pose(self, i: int, j: int, joints: Sequence[Any]) -> DualQuaternion:
        """``F_ij = (t_{i+1} - h_{i+1}) ... (t_j - h_j)`` at ``joints`` ([HSS] eq. 2).

        The pose of link ``o_j`` relative to ``o_i``; links 1-based, for ``i >= j`` the
        product runs cyclically over ``i+1, ..., n, 1, ..., j`` (``i = j``: the full loop
        starting after joint ``i``).  A joint value ``inf`` is the factor ``1``.
        """
        return pose_product(*self._forward(i, j, joints))

    def relative_pose_backward(self, i: int, j: int, joints: Sequence[Any]) -> DualQuaternion:
        """``G_ij = (t_i + h_i)(t_{i-1} + h_{i-1}) ... (t_{j+1} + h_{j+1})`` ([HSS] eq. 4).

        The conjugate of the rest of the loop: on a configuration, ``F_ij G_ij^-1`` is
        real, so ``G_ij`` is another representative of the same pose ``f_ij``
        (``G_ij = (-1)^m (-t_i - h_i) ... (-t_{j+1} - h_{j+1})``, ``m`` factors, a point of
        the coupling variety of the backward axes, see :meth:`coupling_varieties`).
        """
        self._check_link(i, "i")
        self._check_link(j, "j")
        if len(joints) != self.n:
            raise ValueError(f"joints must have n = {self.n} entries; got {len(joints)}")
        m = (i - j) % self.n or self.n
        ks = [(i - 1 - s) % self.n for s in range(m)]
        neg = [t if _joint_inf(t) else -joints[k] for k, t in zip(ks, (joints[k] for k in ks))]
        return pose_product([self.axes[k] for k in ks], neg) * (-1) ** sum(not _joint_inf(t) for t in neg)

    def coupling_varieties(self, i: int, j: int) -> tuple[tuple[DualQuaternion, ...], tuple[DualQuaternion, ...]]:
        """The two axis sequences whose coupling varieties meet in the coupling curve ``C_ij``.

        The coupling equality ([HSS] Section 2): ``C_ij = X_{i+1..j} cap X_{i, i-1, ..., j+1}``,
        with ``X`` as in :func:`linkage.spatial.coupling.coupling_variety_parameters`.
        Returns ``((h_{i+1}, ..., h_j), (h_i, h_{i-1}, ..., h_{j+1}))``.
        """
        self._check_link(i, "i")
        self._check_link(j, "j")
        forward = self._forward(i, j, [INF] * self.n)[0]
        m = (i - j) % self.n or self.n
        backward = [self.axes[(i - 1 - s) % self.n] for s in range(m)]
        return tuple(forward), tuple(backward)

    def _forward(self, i: int, j: int, joints: Sequence[Any]) -> tuple[list, list]:
        self._check_link(i, "i")
        self._check_link(j, "j")
        if len(joints) != self.n:
            raise ValueError(f"joints must have n = {self.n} entries; got {len(joints)}")
        m = (j - i) % self.n or self.n
        ks = [(i + s) % self.n for s in range(m)]
        return [self.axes[k] for k in ks], [joints[k] for k in ks]

    def coupling_space_dimension(self, i: int, j: int) -> int:
        """``dim L_{i, i+1, ..., j}``: span of all products ``h_k1 ... h_ks``, ``i <= k1 < ... < ks <= j``.

        Joints are 1-based and taken cyclically from ``i`` up to ``j``.  [HSS]
        Theorem 7: for three consecutive axes the dimension is 4 iff they are
        concurrent (parallel or through one point), 6 iff they are Bennett axes.
        """
        self._check_link(i, "i")
        self._check_link(j, "j")
        idx = [k % self.n for k in range(i - 1, (j if j >= i else j + self.n))]
        vectors = [list(p) for p in coupling_space([self.axes[k] for k in idx])]
        if self.data != "float":
            return sympy.Matrix(vectors).rank(simplify=True)
        return int(np.linalg.matrix_rank(np.array(vectors, dtype=float), tol=1e-9))

    def _check_link(self, i: Any, name: str) -> None:
        if not isinstance(i, (int, np.integer)) or not 1 <= i <= self.n:
            raise ValueError(f"{name} must be a link/joint number in 1..{self.n}; got {i!r}")

    def draw_bond_diagram(self, ax: Any, **kwargs: Any) -> Any:
        """Draw the bond diagram on a matplotlib ``Axes`` (see :func:`linkage.spatial.draw.draw_bond_diagram`)."""
        from .draw import draw_bond_diagram

        return draw_bond_diagram(ax, self.n, self.connections(), **kwargs)


def connection_numbers(d: np.ndarray) -> dict[tuple[int, int], int]:
    """``{(i, j): k(i, j)}``, nonzero entries, ``k(i,j) = d(i,j) + d(i-1,j-1) - d(i,j-1) - d(i-1,j)``.

    ``d`` is a (local or total) distance matrix, ``d[i-1, j-1] = d(i, j)``, indices mod n
    ([HSS] eq. 20).
    """
    n = d.shape[0]

    def dd(i, j):
        return d[(i - 1) % n, (j - 1) % n]

    out = {}
    for i in range(1, n + 1):
        for j in range(i + 1, n + 1):
            k = dd(i, j) + dd(i - 1, j - 1) - dd(i, j - 1) - dd(i - 1, j)
            if k != int(k):
                raise ArithmeticError(f"connection number k({i},{j}) = {k} is not an integer (Lemma 22)")
            if k:
                out[(i, j)] = int(k)
    return out


def distances_from_connections(n: int, connections: dict[tuple[int, int], int]) -> np.ndarray:
    """The distance matrix read off a bond diagram ([HSS] Theorem 23).

    Cutting the diagram at the links ``o_i`` and ``o_j`` leaves the joints
    ``h_{i+1}, ..., h_j`` on one side and the others on the other; ``d(i, j)`` is the
    number of connections drawn between the two sides (dashed ones, negative
    entries of ``connections``, counted negatively).  ``connections`` is keyed
    ``(i, j)``, ``1 <= i < j <= n``, as :meth:`RevoluteChain.connections` returns it.
    """
    if not isinstance(n, (int, np.integer)) or n < 3:
        raise ValueError(f"n must be an integer >= 3; got {n!r}")
    for (a, b), k in connections.items():
        if not (1 <= a < b <= n) or not isinstance(k, (int, np.integer)):
            raise ValueError(f"connections must map pairs 1 <= i < j <= {n} to integers; got {(a, b)}: {k!r}")
    d = np.zeros((n, n), dtype=int)
    for i in range(1, n + 1):
        for j in range(i + 1, n + 1):
            side = set(range(i + 1, j + 1))
            d[i - 1, j - 1] = d[j - 1, i - 1] = sum(k for (a, b), k in connections.items() if (a in side) != (b in side))
    return d


def _renumbered(curve: ConfigurationCurve, shift: int) -> ConfigurationCurve:
    """A curve of the chain numbered from joint ``shift + 1`` as a curve of the chain itself."""
    back = [(k - shift) % curve.n for k in range(curve.n)]
    a, b, c = ([p[k].as_expr() for k in back] for p in (curve.a, curve.b, curve.c))
    return ConfigurationCurve(a, b, c, None if curve.g is None else curve.g.as_expr())


def _contains_component(curve: ConfigurationCurve, err: UnparametrisedComponentError, shift: int) -> bool:
    """The refused component's equation holds along ``curve`` (at real and complex sample points).

    The equation is in the last two joints of the chain numbered from joint ``shift + 1``;
    it must vanish to ``1e-8`` of the size of its terms at three points or more of ``curve``
    where those joints are finite.
    """
    n = curve.n
    i, j = (n - 2 + shift) % n, (n - 1 + shift) % n
    poly = sympy.Poly(err.factor, *err.variables)
    checked = 0
    for t in (0.37, -1.21, 2.3, 0.83 + 0.41j, -0.55 - 1.7j):
        for branch in (1, -1):
            p = curve(t, branch)
            a, b = p[i], p[j]
            if not (np.isfinite(a) and np.isfinite(b)):
                continue
            value = sum(complex(c) * a**k * b**m for (k, m), c in poly.terms())
            size = sum(abs(complex(c)) * abs(a) ** k * abs(b) ** m for (k, m), c in poly.terms())
            if abs(value) > 1e-8 * size:
                return False
            checked += 1
    return checked >= 3


def _joint_inf(t: Any) -> bool:
    return isinstance(t, (float, complex)) and bool(np.isinf(abs(t)))


def _angle_of(t: float) -> float:
    """``phi`` with ``t = cot(phi/2)`` (``inf -> 0``)."""
    t = float(np.real(t))
    return 0.0 if np.isinf(t) else 2 * np.arctan2(1.0, t)


def _cot_half(phi: float) -> complex:
    s = np.sin(phi / 2)
    return complex("inf") if s == 0 else complex(np.cos(phi / 2) / s)


def _bond_order(b: Bond) -> tuple:
    """Sort key: the joints connected, then the joint values (a conjugate pair stays together)."""
    finite = [complex(0) if z == INF else z for z in b.joints]
    pair = [(z == INF, round(f.real, 9), abs(round(f.imag, 9))) for z, f in zip(b.joints, finite)]
    return (sorted(b.connection_numbers.items()), pair, [round(f.imag, 9) for f in finite])


def _normalized_place(place: Place) -> Place:
    """The place with each joint pair ``(num_k, den_k)`` divided by ``max(|num_k(0)|, |den_k(0)|)``.

    ``F_ij`` is homogeneous of degree one in each pair, so orders (bonds, local
    distances) do not change; but the 50-digit zero threshold (``1e-30`` times a
    scale of at least 1) is then applied to terms of modulus at most about 1.
    Unnormalised pairs reach ``1e23`` for ordinary rational axes, and rounding
    residuals of ``1e6`` in the product would count as nonzero: bonds were lost.
    """
    if place.exact:
        return place
    joints = []
    for num, den in place.joints:
        scale = max(abs(num.coefficient(0)), abs(den.coefficient(0)))
        if scale == 0:
            raise PrecisionExhausted(f"joint pair vanishes at the place t = {place.t0}")
        inv = 1 / scale
        joints.append((num * inv, den * inv))
    return Place(place.t0, place.branch, tuple(joints))


def _min_order(h: DualQuaternion) -> int:
    orders = []
    for s in h:
        try:
            orders.append(s.order())
        except PrecisionExhausted:
            continue
    if not orders:
        raise PrecisionExhausted("every coordinate vanishes to the computed order")
    return min(orders)


def _exact_order(p: sympy.Poly, degree: int, m: sympy.Poly | None) -> int:
    """Order of the homogeneous form of ``p`` (degree ``degree``) at the roots of ``m`` (``None``: inf)."""
    if p.is_zero:
        raise ArithmeticError("order of the zero polynomial")
    if m is None:
        return degree - p.degree()
    k = 0
    while True:
        q, r = sympy.div(p, m)
        if not r.is_zero:
            return k
        p, k = q, k + 1


def _exact_min_order(h: DualQuaternion, degree: int, m) -> int:
    return min(_exact_order(p, degree, m) for p in h if not p.is_zero)


def _max_abs_coeff(e: Any) -> float:
    poly = sympy.Poly(e, T, W) if e != 0 else None
    return 0.0 if poly is None else max(abs(complex(c)) for c in poly.coeffs())
