"""Diagonal parameterization of a planar closed chain of any link lengths.

Rods ``l_1 .. l_n`` are pinned at ``p_0 = 0`` and ``p_n = L``.  The diagonals are
``d_k = |p_k|``; the ends are fixed, ``d_1 = l_1`` and ``d_n = L``, so the free
diagonals are ``x = (d_2, ..., d_{n-1})``.  Fan triangle ``T_k = (0, p_{k-1}, p_k)``,
``k = 2..n``, has sides ``(d_{k-1}, l_k, d_k)`` and flip
``sigma_k = sign Im(conj(p_{k-1}) p_k)`` (``+1`` where the triangle is flat).

* **Diagonal space** ``D = { x : |d_{k-1} - l_k| <= d_k <= d_{k-1} + l_k }``, a
  convex polytope of ``3(n-1)`` half-spaces ``A x <= b``, inside the cuboid
  ``r_k <= d_k <= R_k`` (``R_k = l_1 + .. + l_k``,
  ``r_k = max(0, 2 max_{j<=k} l_j - R_k)``).
* **Triangle slacks** of ``T_k`` (``a = d_{k-1}``, ``c = d_k``, ``l = l_k``), the
  rows ``3(k-2) + 0, 1, 2`` of ``b - A x``::

      u_k = a + l - c,    v_k = c + l - a,    w_k = a + c - l.

* **Configuration** from ``(x, sigma)``, backwards from the base: ``phi_n = 0``,
  ``phi_{k-1} = phi_k - sigma_k gamma_k``, ``p_{k-1} = d_{k-1} e^{i phi_{k-1}}``,
  with ``gamma_k`` the angle of ``T_k`` at the origin, by the half-angle formula
  ``tan(gamma_k / 2) = sqrt(u_k v_k / (w_k (a + c + l)))``.

The configuration space is ``2^(n-1)`` copies of ``D`` (one per flip vector) glued
along the facets where a triangle is flat.  See ``docs/diagonals.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

from charts.chain_geometry import rod_vectors
from manifold.validation import check_positive_int, first_entry, real_array

from .lengths import validate_lengths

# Points of D may lie this far (times the perimeter) outside a wall, as rounding
# of a point computed on the wall leaves them; their slacks are clipped to 0.
WALL_RTOL = 16 * np.finfo(float).eps
# |sin gamma_k| (per rod) below which :func:`diagonals` calls a fan triangle flat.
FLAT_SIN = 8 * np.finfo(float).eps
# Closure tolerance (times the perimeter) accepted by :func:`diagonals`.
CLOSURE_RTOL = 1e-9


# -- the three slacks and the fan angle ---------------------------------------------
def triangle_slacks(a: ArrayLike, l: ArrayLike, c: ArrayLike) -> tuple[NDArray, NDArray, NDArray]:
    """Slacks ``(u, v, w) = (a + l - c, c + l - a, a + c - l)`` of a triangle with sides ``a, l, c``.

    Numerical trap: written as printed, each is a sum of ``O(1)`` numbers that
    nearly cancel on its wall, and the rounding of the partial sum (``eps * l``)
    swamps a slack of ``1e-12``.  Each is instead evaluated in the order in which
    both subtractions are exact near the wall (Sterbenz: ``y - z`` is exact for
    ``z/2 <= y <= 2z``), e.g. ``u = l - (c - a)`` when ``a >= l`` (then
    ``c ~ a + l <= 2a``) and ``u = a - (c - l)`` otherwise.  So a slack is as
    accurate as the floats ``a, l, c`` allow, relative to itself.
    """
    a, l, c = np.asarray(a, dtype=float), np.asarray(l, dtype=float), np.asarray(c, dtype=float)
    u = np.where(a >= l, l - (c - a), a - (c - l))
    v = np.where(c >= l, l - (a - c), c - (a - l))
    w = np.where(a >= c, c - (l - a), a - (l - c))
    return u, v, w


def fan_rotation(a: NDArray, l: NDArray, c: NDArray, u: NDArray, v: NDArray, w: NDArray) -> NDArray:
    """``e^{i gamma}``, ``gamma in [0, pi]`` the angle between sides ``a`` and ``c``, from the slacks.

    Half-angle formula: ``tan(gamma/2) = h / g`` with ``h^2 = u v`` and
    ``g^2 = w (a + c + l)``, so ``cos gamma = (g^2 - h^2) / (g^2 + h^2)`` and
    ``sin gamma = 2 g h / (g^2 + h^2)`` (``g^2 + h^2 = 4 a c``).  The slacks enter
    as products, never as differences.  Numerical trap avoided: ``acos`` of the
    law of cosines has an infinite derivative at ``gamma = 0, pi`` and loses half
    the digits there, exactly near the walls.  On a wall ``sin gamma`` is exactly
    0, so both flips give bit-identical rotations.  Where ``a = 0`` or ``c = 0``
    (a hinge on the origin) the angle is free and ``gamma = 0`` is returned.
    """
    g2, h2 = w * (a + c + l), u * v
    norm = g2 + h2
    free = norm == 0
    norm = np.where(free, 1.0, norm)
    # sqrt(g2) sqrt(h2), not sqrt(g2 h2), and real divisions, not a complex one: with a diagonal of 1e-323 the
    # product underflowed to 0 and numpy's complex division by the subnormal norm overflowed (NaN hinges)
    return np.where(free, 1.0 + 0j, (g2 - h2) / norm + 2j * (np.sqrt(g2) * np.sqrt(h2) / norm))


# -- validation ---------------------------------------------------------------------
def _full_diagonals(lengths: NDArray, L: float, x: NDArray) -> NDArray:
    """``(d_1, ..., d_n)`` with the fixed ends ``d_1 = l_1``, ``d_n = L``; shape ``(..., n)``."""
    lead = x.shape[:-1]
    return np.concatenate([np.full((*lead, 1), lengths[0]), x, np.full((*lead, 1), L)], axis=-1)


def _all_slacks(lengths: NDArray, d: NDArray) -> NDArray:
    """Slacks ``(u_k, v_k, w_k)``, ``k = 2..n``, of full diagonals ``d``; shape ``(..., n-1, 3)``."""
    return np.stack(triangle_slacks(d[..., :-1], lengths[1:], d[..., 1:]), axis=-1)


def _check_x(lengths: NDArray, L: float, x: ArrayLike) -> NDArray:
    n = lengths.size
    xs = real_array("x", x, finite=False, expected="an array of real diagonals")  # finite: checked below, by entry
    if xs.ndim == 0 or xs.shape[-1] != n - 2:
        raise ValueError(f"x holds the n - 2 = {n - 2} free diagonals (d_2..d_{n-1}) on its last axis, got shape {xs.shape}")
    finite = np.isfinite(xs)
    if not finite.all():
        raise ValueError(f"x must be finite, got {first_entry('x', xs, ~finite)}")
    return xs


def _checked_slacks(lengths: NDArray, L: float, xs: NDArray) -> tuple[NDArray, NDArray]:
    """Full diagonals and slacks of ``xs``, clipped at 0; ``ValueError`` naming the first point outside ``D``."""
    d = _full_diagonals(lengths, L, xs)
    s = _all_slacks(lengths, d)
    tol = WALL_RTOL * (lengths.sum() + L)
    bad = s < -tol
    if np.any(bad):
        *lead, t, _ = (int(i) for i in np.argwhere(bad)[0])
        k, a, c, l = t + 2, d[tuple(lead) + (t,)], d[tuple(lead) + (t + 1,)], lengths[t + 1]
        where = f"x[{tuple(lead)}]" if lead else "x"
        raise ValueError(
            f"{where} is outside the diagonal space: triangle T_{k} needs |d_{k-1} - l_{k}| <= d_{k} <= d_{k-1} + l_{k}, "
            f"i.e. d_{k} in [{abs(a - l):.17g}, {a + l:.17g}] given d_{k-1} = {a:.17g}, l_{k} = {l:.17g}; got d_{k} = {c:.17g}"
        )
    return d, np.maximum(s, 0.0)


def _check_flips(n: int, flips: ArrayLike) -> NDArray:
    f = np.asarray(flips)
    if f.ndim == 0 or f.shape[-1] != n - 1:
        raise ValueError(f"flips holds n - 1 = {n - 1} signs (sigma_2..sigma_n) on its last axis, got shape {f.shape}")
    ok = (f == 1) | (f == -1)
    if not np.all(ok):
        idx = tuple(int(i) for i in np.argwhere(~ok)[0])
        raise ValueError(f"flips must be +1 or -1, got flips[{idx}] = {f[idx].item()!r}")
    return f.astype(int)


# -- the map and its inverse --------------------------------------------------------
def _prepared(lengths: ArrayLike, L: float, x: ArrayLike, flips: ArrayLike) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Validated lengths, full diagonals, clipped slacks and flips, broadcast over the leading axes."""
    ls, L = validate_lengths(lengths, L)
    xs, fs = _check_x(ls, L, x), _check_flips(ls.size, flips)
    lead = np.broadcast_shapes(xs.shape[:-1], fs.shape[:-1])
    xs = np.broadcast_to(xs, (*lead, xs.shape[-1]))
    fs = np.broadcast_to(fs, (*lead, fs.shape[-1]))
    d, s = _checked_slacks(ls, L, xs)
    return ls, d, s, fs


def _hinges(lengths: NDArray, d: NDArray, s: NDArray, flips: NDArray) -> tuple[NDArray, NDArray]:
    """Hinges ``p_1..p_{n-1}`` and the fan rotations ``e^{i gamma_k}`` from checked inputs."""
    rot = fan_rotation(d[..., :-1], lengths[1:], d[..., 1:], s[..., 0], s[..., 1], s[..., 2])
    turn = np.where(flips > 0, np.conj(rot), rot)  # e^{-i sigma_k gamma_k}
    units = np.cumprod(turn[..., ::-1], axis=-1)[..., ::-1]  # e^{i phi_{k-1}}, k = 2..n
    return d[..., :-1] * units, rot


def from_diagonals(lengths: ArrayLike, L: float, x: ArrayLike, flips: ArrayLike) -> NDArray:
    """Complex hinges ``p_1 .. p_{n-1}`` of the configuration with diagonals ``x`` and flips ``flips``.

    Parameters
    ----------
    lengths, L
        The chain: ``l_1 .. l_n > 0``, base ``L > 0``.
    x
        Free diagonals ``(d_2, ..., d_{n-1})``, shape ``(..., n-2)``, in ``D``
        (points up to ``WALL_RTOL * P`` outside a wall are put on it).
    flips
        ``sigma_2 .. sigma_n`` in ``{+1, -1}``, shape ``(..., n-1)``; leading
        axes broadcast against those of ``x``.

    Returns
    -------
    ndarray
        Complex ``(..., n-1)``: ``phi_n = 0``,
        ``phi_{k-1} = phi_k - sigma_k gamma_k``, ``p_{k-1} = d_{k-1} e^{i phi_{k-1}}``.
        Closure ``|p_k - p_{k-1}| = l_k`` holds by construction.
    """
    ls, d, s, fs = _prepared(lengths, L, x, flips)
    return _hinges(ls, d, s, fs)[0]


def diagonals(lengths: ArrayLike, L: float, hinges: ArrayLike) -> tuple[NDArray, NDArray]:
    """``(x, flips)`` of closed configurations: ``x = (|p_2|, ..., |p_{n-1}|)``, ``sigma_k = sign Im(conj(p_{k-1}) p_k)``.

    ``hinges`` is complex ``(..., n-1)`` and must close to ``CLOSURE_RTOL * P``
    (``ValueError`` otherwise).  A flat triangle gets ``sigma_k = +1``; flat means
    ``|sin gamma_k| <= FLAT_SIN * n``, so flips are recovered wherever the
    triangle's slacks exceed about ``(FLAT_SIN * n)^2 * d``, i.e. ``1e-28``.
    """
    ls, L = validate_lengths(lengths, L)
    n = ls.size
    h = np.asarray(hinges)
    if h.ndim == 0 or h.shape[-1] != n - 1:
        raise ValueError(f"hinges holds the n - 1 = {n - 1} interior hinges p_1..p_{n-1} on its last axis, got shape {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ValueError("hinges must be finite")
    gap = np.abs(np.abs(rod_vectors(h, L)) - ls)
    if gap.size and gap.max() > CLOSURE_RTOL * (ls.sum() + L):
        raise ValueError(
            f"hinges is not a closed chain of lengths {tuple(ls)} and base {L}: max ||p_k - p_(k-1)| - l_k| = "
            f"{gap.max():.3g} > {CLOSURE_RTOL:g} * perimeter"
        )
    p = np.concatenate([h, np.full((*h.shape[:-1], 1), L, dtype=complex)], axis=-1)
    cross = np.imag(np.conj(p[..., :-1]) * p[..., 1:])
    # On a flat triangle the cross product is rounding noise of either sign:
    # |sin gamma_k| <= FLAT_SIN * n counts as flat (there both flips agree to rounding).
    flat = np.abs(cross) <= FLAT_SIN * n * np.abs(p[..., :-1]) * np.abs(p[..., 1:])
    return np.abs(h[..., 1:]), np.where(flat | (cross > 0), 1, -1)


def hinge_jacobian(lengths: ArrayLike, L: float, x: ArrayLike, flips: ArrayLike) -> NDArray:
    """``dp_j / dd_m`` of :func:`from_diagonals` at fixed flips; complex ``(..., n-1, n-2)``.

    ``p_j = d_j e^{i phi_j}``, ``phi_j = -sum_{k>j} sigma_k gamma_k``;
    ``dgamma_k/dd_{k-1} = -(a^2 + l^2 - c^2) / (a Q)`` and
    ``dgamma_k/dd_k = -(c^2 + l^2 - a^2) / (c Q)`` with ``Q = sqrt(u v w (a+c+l))``
    (four times the area).  Infinite on a wall (``Q = 0``): ``ValueError`` there.
    """
    ls, d, s, fs = _prepared(lengths, L, x, flips)
    n = ls.size
    Q = np.sqrt(s[..., 0] * s[..., 1] * s[..., 2] * (d[..., :-1] + d[..., 1:] + ls[1:]))
    if np.any(Q == 0):
        raise ValueError("hinge_jacobian is infinite on a wall of D (a flat fan triangle); x must be interior")
    p, _ = _hinges(ls, d, s, fs)
    a, c, l = d[..., :-1], d[..., 1:], ls[1:]
    dg_da = -fs * (a * a + l * l - c * c) / (a * Q)  # sigma_k dgamma_k / dd_{k-1}
    dg_dc = -fs * (c * c + l * l - a * a) / (c * Q)  # sigma_k dgamma_k / dd_k
    j = np.arange(1, n)[:, None]  # hinge index 1..n-1
    m = np.arange(2, n)[None, :]  # free diagonal index 2..n-1
    # dphi_j/dd_m = -(sigma_m dgamma_m/dd_m [m > j] + sigma_{m+1} dgamma_{m+1}/dd_m [m >= j])
    dphi = -((m > j) * dg_dc[..., None, :-1] + (m >= j) * dg_da[..., None, 1:])
    return (j == m) * (p / np.abs(p))[..., :, None] + 1j * p[..., :, None] * dphi


def _hinge_mass_matrix(mass_matrix: ArrayLike | None, hinges: int) -> NDArray | None:
    """``mass_matrix`` as a float ``(hinges, hinges)`` array (``None`` stays ``None``); ``ValueError`` on another shape."""
    if mass_matrix is None:
        return None
    A = np.asarray(mass_matrix, dtype=float)
    if A.shape != (hinges, hinges):
        raise ValueError(f"mass_matrix must have shape {(hinges, hinges)} (one row per hinge), got {A.shape}")
    return A


def riemannian_density(lengths: ArrayLike, L: float, x: ArrayLike, flips: ArrayLike,
                       mass_matrix: ArrayLike | None = None) -> NDArray:
    """``sqrt(det(J^T K J))``: Riemannian volume of the kinetic metric per ``dx``, at fixed flips.

    ``J`` is :func:`hinge_jacobian`, ``K = A (x) I_2`` the kinetic metric on
    interleaved hinge coordinates for the ``(n-1, n-1)`` hinge ``mass_matrix``
    ``A`` (``Chain.mass_matrix``; ``None``: unit hinge masses, ``A = I``).  The
    density grows like ``slack^(-1/2)`` at a wall.
    """
    J = hinge_jacobian(lengths, L, x, flips)
    A = _hinge_mass_matrix(mass_matrix, J.shape[-2])
    A = np.eye(J.shape[-2]) if A is None else A
    # Re(J^H A J) = J_r^T (A (x) I_2) J_r for a real symmetric A
    G = np.real(np.einsum("...jm,jl,...lk->...mk", np.conj(J), A, J))
    return np.sqrt(np.linalg.det(G))


# -- the polytope -------------------------------------------------------------------
@dataclass(frozen=True, repr=False)
class DiagonalSample:
    """Samples ``(x, flips)`` and their configurations ``hinges`` (complex ``(N, n-1)``).

    ``measure`` says what they are distributed by: 'lebesgue' -- ``x`` uniform in
    ``D`` (Lebesgue ``dx``) and ``flips`` uniform on ``{+-1}^(n-1)``, independent;
    'riemannian' -- configurations uniform in the Riemannian volume of the
    kinetic metric (approximately: importance resampling,
    see :meth:`DiagonalSpace.sample`).  ``acceptance`` is the rejection
    sampler's acceptance rate, ``ess`` the effective size of the weighted pool.
    """

    x: NDArray
    flips: NDArray
    hinges: NDArray
    method: str
    measure: str
    acceptance: float | None = None
    ess: float | None = None

    def __len__(self) -> int:
        return self.x.shape[0]

    def __repr__(self) -> str:
        info = "".join(
            f", {k}={v:.3g}" for k, v in (("acceptance", self.acceptance), ("ess", self.ess)) if v is not None
        )
        return f"DiagonalSample(N={len(self)}, measure={self.measure!r}, method={self.method!r}{info})"


class DiagonalSpace:
    """The diagonal polytope ``D`` of rods ``lengths`` pinned ``L`` apart (``n >= 3``).

    Attributes
    ----------
    lengths, L, n, dim
        The chain and ``dim = n - 2``, the dimension of ``D``.
    A, b
        ``D = { x : A x <= b }``; row ``3(k-2) + j`` is slack ``j`` (``u, v, w``)
        of fan triangle ``T_k``, ``k = 2..n``.
    lower, upper
        The cuboid ``r_k <= d_k <= R_k`` (``k = 2..n-1``) that contains ``D``.
    mass_matrix
        The hinge mass matrix of the kinetic metric for the 'riemannian'
        samples (``None``: unit hinge masses); ``Chain.diagonal_space`` passes the chain's.
    """

    def __init__(self, lengths: ArrayLike, L: float, mass_matrix: ArrayLike | None = None) -> None:
        self.lengths, self.L = validate_lengths(lengths, L)
        self.n = self.lengths.size
        if self.n < 3:
            raise ValueError(f"a diagonal space needs n >= 3 rods (n = 2 has no free diagonal), got n = {self.n}")
        self.mass_matrix = _hinge_mass_matrix(mass_matrix, self.n - 1)
        self.dim = self.n - 2
        self.A, self.b = self._half_spaces()
        R = np.cumsum(self.lengths)
        r = np.maximum(0.0, 2 * np.maximum.accumulate(self.lengths) - R)
        self.lower, self.upper = r[1:-1], R[1:-1]
        for arr in (self.A, self.b, self.lower, self.upper):
            arr.flags.writeable = False

    def __repr__(self) -> str:
        return f"DiagonalSpace(lengths={tuple(float(v) for v in self.lengths)}, L={self.L!r})"

    def _half_spaces(self) -> tuple[NDArray, NDArray]:
        """Rows ``u: c - a <= l``, ``v: a - c <= l``, ``w: -a - c <= -l`` per triangle; fixed ends moved to ``b``."""
        n, ls = self.n, self.lengths
        coef = np.array([[-1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])  # coefficients of (a, c) = (d_{k-1}, d_k)
        rhs = np.array([1.0, 1.0, -1.0])
        fixed = {1: ls[0], n: self.L}
        A, b = np.zeros((3 * (n - 1), n - 2)), np.zeros(3 * (n - 1))
        for k in range(2, n + 1):
            rows = slice(3 * (k - 2), 3 * (k - 1))
            b[rows] = rhs * ls[k - 1]
            for col, diag in ((0, k - 1), (1, k)):
                if diag in fixed:
                    b[rows] -= coef[:, col] * fixed[diag]
                else:
                    A[rows, diag - 2] = coef[:, col]
        return A, b

    # -- membership ----------------------------------------------------------------
    def slacks(self, x: ArrayLike) -> NDArray:
        """``b - A x`` (shape ``(..., 3(n-1))``), each slack accurate near its wall (:func:`triangle_slacks`)."""
        xs = _check_x(self.lengths, self.L, x)
        s = _all_slacks(self.lengths, _full_diagonals(self.lengths, self.L, xs))
        return s.reshape(*xs.shape[:-1], -1)

    def contains(self, x: ArrayLike, tol: float = 0.0) -> NDArray:
        """Whether ``x`` (shape ``(..., n-2)``) is in ``D``: every slack ``>= -tol``."""
        return np.all(self.slacks(x) >= -tol, axis=-1)

    def interior_point(self) -> tuple[NDArray, float]:
        """Chebyshev centre and radius of ``D`` (linear program); radius 0 if ``D`` is flat, ``ValueError`` if empty."""
        norms = np.linalg.norm(self.A, axis=1)
        c = np.zeros(self.dim + 1)
        c[-1] = -1.0
        res = linprog(c, A_ub=np.column_stack([self.A, norms]), b_ub=self.b, bounds=[(None, None)] * self.dim + [(0, None)])
        if res.status == 2:
            raise ValueError(f"the diagonal space of {self!r} is empty (some side exceeds half the perimeter)")
        if not res.success:
            raise RuntimeError(f"linprog failed on {self!r}: {res.message}")
        return res.x[:-1], float(res.x[-1])

    def vertices(self) -> NDArray:
        """The vertices of ``D``, shape ``(V, n-2)`` (qhull half-space intersection; an interval for ``n = 3``)."""
        centre, radius = self.interior_point()
        if radius <= WALL_RTOL * (self.lengths.sum() + self.L):
            raise ValueError(f"the diagonal space of {self!r} has no interior (non-generic lengths); its vertices are not computed")
        if self.dim == 1:
            col = self.A[:, 0]
            return np.array([[np.max(self.b[col < 0] / col[col < 0])], [np.min(self.b[col > 0] / col[col > 0])]])
        hs = HalfspaceIntersection(np.column_stack([self.A, -self.b]), centre)
        pts = hs.intersections
        scale = self.lengths.sum() + self.L
        _, keep = np.unique(np.round(pts / (1e-9 * scale)), axis=0, return_index=True)
        return pts[np.sort(keep)]

    def volume(self) -> float:
        """Lebesgue volume of ``D`` (exact up to rounding: convex hull of :meth:`vertices`); 0 if ``D`` has no interior."""
        _, radius = self.interior_point()
        if radius <= WALL_RTOL * (self.lengths.sum() + self.L):
            return 0.0
        v = self.vertices()
        return float(v[1, 0] - v[0, 0]) if self.dim == 1 else float(ConvexHull(v).volume)

    # -- sampling ------------------------------------------------------------------
    def sample(
        self,
        N: int,
        rng: np.random.Generator,
        method: str = "auto",
        measure: str = "lebesgue",
        steps: int | None = None,
        pool: int = 20,
        max_draws: int = 10**7,
    ) -> DiagonalSample:
        """``N`` samples of ``(x, flips)`` and their configurations.

        Parameters
        ----------
        N
            Number of samples.
        rng
            ``numpy.random.Generator``.
        method
            How ``x`` uniform in ``D`` is drawn.  'rejection': uniform in the
            cuboid, kept if in ``D`` (exact; cost ``1 / acceptance``, refused past
            ``max_draws`` draws).  'hit-and-run': ``N`` independent chains started
            at the Chebyshev centre; each step picks a direction and moves to a
            uniform point of the chord of ``D`` through ``x`` (uniform measure is
            invariant for any symmetric direction law; after ``steps // 3``
            isotropic steps the directions follow the ensemble covariance,
            if there are at least ``10 (n-1)`` chains to estimate it).
            Approximately uniform after ``steps`` steps (default
            ``40 + 15 (n-2)^2``, about five times what the moments need in the
            tests).  'auto': rejection if a pilot of 4096 cuboid draws accepts
            at least 5%, hit-and-run otherwise.
        measure
            'lebesgue': ``x`` uniform in ``D`` and ``flips`` uniform, i.e. the
            configurations have density ``1 / sqrt(det J^T J)`` with respect to
            the Riemannian volume.  'riemannian': configurations uniform in the
            Riemannian volume of the kinetic metric (of :attr:`mass_matrix`;
            unit hinge masses if it is ``None``): a
            pool of ``pool * N`` 'lebesgue' samples weighted by
            :func:`riemannian_density` and resampled with replacement.  Exact
            only as ``pool -> oo``; the weights grow like ``slack^(-1/2)`` at the
            walls (integrable, heavy-tailed), so check ``ess``.
        steps, pool, max_draws
            See ``method`` and ``measure``.
        """
        if measure not in ("lebesgue", "riemannian"):
            raise ValueError(f"measure must be 'lebesgue' or 'riemannian', got {measure!r}")
        if method not in ("auto", "rejection", "hit-and-run"):
            raise ValueError(f"method must be 'auto', 'rejection' or 'hit-and-run', got {method!r}")
        N = check_positive_int("N", N)
        max_draws, pool = check_positive_int("max_draws", max_draws), check_positive_int("pool", pool)
        if steps is not None:
            steps = check_positive_int("steps", steps)
        M = int(N) * (pool if measure == "riemannian" else 1)
        acceptance = None
        if method == "auto":
            pilot = self.contains(rng.uniform(self.lower, self.upper, size=(4096, self.dim)))
            method = "rejection" if pilot.mean() >= 0.05 else "hit-and-run"
        if method == "rejection":
            x, acceptance = self._rejection(M, rng, max_draws)
        else:
            x = self._hit_and_run(M, rng, 40 + 15 * self.dim**2 if steps is None else int(steps))
        flips = rng.choice(np.array([-1, 1]), size=(M, self.n - 1))
        d, s = _checked_slacks(self.lengths, self.L, x)
        hinges = _hinges(self.lengths, d, s, flips)[0]
        if measure == "lebesgue":
            return DiagonalSample(x, flips, hinges, method, measure, acceptance)
        w = riemannian_density(self.lengths, self.L, x, flips, self.mass_matrix)
        ess = float(w.sum() ** 2 / (w * w).sum())
        pick = rng.choice(M, size=int(N), replace=True, p=w / w.sum())
        return DiagonalSample(x[pick], flips[pick], hinges[pick], method, measure, acceptance, ess)

    def _rejection(self, N: int, rng: np.random.Generator, max_draws: int) -> tuple[NDArray, float]:
        kept, drawn, count = [], 0, 0
        batch = min(2**20, max(1024, 2 * N))  # 2^20 draws at a time bounds the memory
        while count < N:
            if drawn >= max_draws:
                raise RuntimeError(
                    f"rejection sampling accepted {count} of {drawn} cuboid draws (rate {count / drawn:.2g}); "
                    "use method='hit-and-run'"
                )
            cand = rng.uniform(self.lower, self.upper, size=(batch, self.dim))
            ok = cand[self.contains(cand)]
            kept.append(ok)
            drawn, count = drawn + batch, count + ok.shape[0]
            rate = max(count, 1) / drawn
            batch = int(min(2**20, max(1024, 1.2 * (N - count) / rate)))
        return np.concatenate(kept)[:N], count / drawn

    def _hit_and_run(self, N: int, rng: np.random.Generator, steps: int) -> NDArray:
        centre, radius = self.interior_point()
        if radius <= WALL_RTOL * (self.lengths.sum() + self.L):
            raise ValueError(f"the diagonal space of {self!r} has no interior; hit-and-run needs one")
        # Chains along the last axis: (dim, N) and (rows, N) arrays, so that the
        # reductions over rows run across contiguous memory; einsum, not BLAS,
        # for these skinny products (threads only contend on shared cores).
        x = np.repeat(centre[:, None], N, axis=1)
        chol: NDArray = np.eye(self.dim)
        for step in range(steps):
            # fewer chains than that give a singular or meaningless covariance (N = 1: NaN)
            if step == steps // 3 and N >= 10 * (self.dim + 1):
                cov = np.atleast_2d(np.cov(x)) + 1e-12 * np.eye(self.dim)
                chol = np.linalg.cholesky(cov)
            u = np.einsum("ij,jn->in", chol, rng.standard_normal((self.dim, N)))
            slack = np.maximum(self.b[:, None] - np.einsum("ij,jn->in", self.A, x), 0.0)
            rate = np.einsum("ij,jn->in", self.A, u)  # d slack / dt = -rate
            with np.errstate(divide="ignore", invalid="ignore"):
                t = slack / rate
            t_hi = np.where(rate > 0, t, np.inf).min(axis=0)
            t_lo = np.where(rate < 0, t, -np.inf).max(axis=0)
            x += (t_lo + (t_hi - t_lo) * rng.random(N)) * u
        return x.T.copy()
