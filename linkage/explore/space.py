"""The configuration space as the explorer draws it: meshes and point clouds computed by the library.

* Where the chain has an atlas (its space is the sphere ``S^(n-2)``), chart 0's suspension coordinates read it
  as the round sphere (:meth:`charts.SuspensionChart.sphere_point`, the picture of :func:`linkage.draw.sphere_coordinates`):
  for ``n = 4`` a latitude-longitude mesh of ``S^2`` whose vertices are configurations, coloured by the Gaussian
  curvature of the kinetic-energy metric there (:meth:`manifold.InducedMetric.gaussian_curvature`), by the
  bending ``|II|^2`` or by the largest stiffness ``|II(v, v)|`` (:func:`largest_stiffness`); for ``n = 3``
  the circle.
* For every ``n``, the rod angles ``(theta_1, theta_2, theta_3)`` of configurations place the space in the
  cube ``T^3 = [-pi, pi]^3`` (the torus ``T^2`` for ``n = 3``): the sphere's mesh vertices for ``n = 4``, the
  chart-0 circle for ``n = 3``, else configurations sampled uniformly in the diagonal coordinates
  (:meth:`linkage.diagonals.DiagonalSpace.sample`, any lengths), a projection named as such.
* A point dragged in either picture poses the chain: :func:`pose_from_sphere` inverts chart 0's picture, and
  :func:`pose_from_angles` finds the configuration whose first rod angles lie on the pointer's line of sight
  through the cube (or nearest to a point of the torus).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from charts.suspension import sphere_parameters

from ..chain import Chain
from ..geometry import tangent_basis
from .protocol import as_pairs

__all__ = ["STIFFNESS_DIRECTIONS", "largest_stiffness", "pose_from_angles", "pose_from_sphere", "space_payload"]


#: Directions over half a turn of the tangent plane at which the stiffness ``|II(v, v)|`` is read for its largest.
STIFFNESS_DIRECTIONS = 12


def largest_stiffness(chain: Chain, hinges: NDArray) -> NDArray:
    """``max |II(v, v)|_K`` over unit tangent vectors ``v`` at each configuration of a surface (``n = 4``): how hard
    the rods pull on the fastest-turning motion through it (:meth:`manifold.InducedMetric.stiffness` on
    :data:`STIFFNESS_DIRECTIONS` directions of a K-orthonormal frame, :func:`linkage.geometry.tangent_basis`)."""
    frames = np.array([chain.to_point(tangent_basis(chain, h)) for h in hinges])  # (m, 2, N)
    points, metric = chain.to_point(hinges), chain.metric()
    turns = np.linspace(0.0, np.pi, STIFFNESS_DIRECTIONS, endpoint=False)
    return np.max(np.stack([np.asarray(metric.stiffness(points, np.cos(s) * frames[:, 0] + np.sin(s) * frames[:, 1]))
                            for s in turns]), axis=0)


def _sphere_mesh(chain: Chain, resolution: int) -> tuple[dict[str, Any], NDArray]:
    """Latitude-longitude mesh of chart 0's sphere ``S^2`` (``n = 4``): vertices, triangles, and per vertex the
    Gaussian curvature, the bending ``|II|^2`` and the largest stiffness; and the vertices' configurations."""
    chart0 = chain.atlas().charts[0]
    lat = np.linspace(-np.pi / 2, np.pi / 2, resolution + 1)
    lon = np.linspace(-np.pi, np.pi, 2 * resolution + 1)
    a = np.stack(np.meshgrid(lat, lon, indexing="ij"), axis=-1).reshape(-1, 2)
    hinges = chart0.hinges(a)
    metric = chain.metric()
    curvature = metric.gaussian_curvature(chain.to_point(hinges))
    bending = metric.bending(chain.to_point(hinges))
    cols = len(lon)
    quads = [(i * cols + j, (i + 1) * cols + j, (i + 1) * cols + j + 1, i * cols + j + 1)
             for i in range(resolution) for j in range(cols - 1)]
    faces = [[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads]
    mesh = {"vertices": chart0.sphere_point(a).tolist(), "faces": faces, "curvature": np.asarray(curvature).tolist(),
            "bending": np.asarray(bending).tolist(), "stiffness": largest_stiffness(chain, hinges).tolist()}
    return mesh, hinges


def _circle(chain: Chain, resolution: int) -> tuple[NDArray, NDArray]:
    """``n = 3`` with an atlas: chart 0's circle, its points on the unit circle and its configurations."""
    chart0 = chain.atlas().charts[0]
    a = np.linspace(-np.pi, np.pi, 8 * resolution + 1)[:, None]
    return chart0.sphere_point(a), chart0.hinges(a)


def space_payload(chain: Chain, resolution: int = 24, samples: int = 3000, seed: int = 0) -> dict[str, Any]:
    """What the page draws of the configuration space of ``chain`` (see the module's docstring).

    Returns
    -------
    dict
        ``n``, ``lengths``, ``L``, ``topology`` (:meth:`linkage.topology.Topology.summary`), ``hasAtlas``,
        ``chartIds``; ``torus``: ``{angles, hinges, name}``, the configurations of the space that are drawn,
        their rod angles in the cube, and the name of the projection; ``sphere`` (``n = 4`` with an atlas,
        else ``None``): the mesh ``{vertices, faces, curvature, bending, stiffness}`` whose vertex ``k`` is the
        configuration in row ``k`` of ``torus``; ``circle`` (``n = 3`` with an atlas, else ``None``):
        ``{points}`` of the unit circle, point ``k`` the configuration in row ``k`` of ``torus``; ``start``: one
        configuration of the space (chart 0's parameters all 0.4 where there is an atlas, else the first sample)
        to pose the chain in.  Each configuration is sent once, in ``torus``.
    """
    topology = chain.topology()
    out: dict[str, Any] = {"n": chain.n, "lengths": chain.lengths.tolist(), "L": chain.L,
                           "topology": topology.summary(), "hasAtlas": chain.has_atlas,
                           "chartIds": [str(c) for c in chain.atlas().ids] if chain.has_atlas else [],
                           "sphere": None, "circle": None}
    if chain.n == 4 and chain.has_atlas:
        out["sphere"], hinges = _sphere_mesh(chain, resolution)
        name = "the configuration sphere in the cube of rod angles (theta_1, theta_2, theta_3)"
    elif chain.n == 3 and chain.has_atlas:
        points, hinges = _circle(chain, resolution)
        out["circle"] = {"points": points.tolist()}
        name = "the configuration circle in the torus of rod angles (theta_1, theta_2)"
    else:
        # hit-and-run in the diagonal polytope takes ~15 (n-2)^2 steps per sample: fewer samples for long chains
        size = max(200, min(samples, samples * 36 // (chain.n - 2) ** 2))
        hinges = chain.diagonal_space().sample(size, np.random.default_rng(seed)).hinges
        name = (f"projection of {size} configurations sampled uniformly in the diagonal coordinates onto the rod "
                f"angles ({'theta_1, theta_2' if chain.n == 3 else 'theta_1, theta_2, theta_3'})")
    out["torus"] = {"angles": chain.angles(hinges)[:, :3].tolist(), "hinges": as_pairs(hinges), "name": name}
    start = chain.atlas().charts[0].hinges(np.full(chain.n - 2, 0.4)) if chain.has_atlas else hinges[0]
    out["start"] = as_pairs(start)
    return out


def pose_from_sphere(chain: Chain, point: NDArray) -> NDArray:
    """The configuration at ``point`` of chart 0's round sphere ``S^(n-2)`` (any nonzero scale): the inverse of
    the picture, :func:`charts.suspension.sphere_parameters` then the chart map."""
    if not chain.has_atlas:
        raise ValueError(f"the sphere picture needs an atlas, and this chain has none: {chain.topology().summary()}")
    return chain.atlas().charts[0].hinges(sphere_parameters(point))


#: Gauss-Newton iterations of :func:`pose_from_angles`, and the relative decrease of the distance below which it
#: stops.
POSE_ITERATIONS, POSE_TOL = 100, 1e-12


def _close_rods(lengths: NDArray, L: float, theta: NDArray) -> NDArray:
    """Rod angles moved by the smallest steps (Newton, minimum norm) until ``sum_k l_k e^{i theta_k} = L``."""
    for _ in range(8):
        gap = np.sum(lengths * np.exp(1j * theta)) - L
        if abs(gap) <= 1e-15 * L:
            break
        G = np.stack([-lengths * np.sin(theta), lengths * np.cos(theta)])  # d(Re, Im of the sum)/d theta
        theta = theta - np.linalg.lstsq(G, [gap.real, gap.imag], rcond=None)[0]
    return theta


def pose_from_angles(chain: Chain, hinges: NDArray, angles: NDArray, direction: NDArray | None = None) -> NDArray:
    """The configuration near ``hinges`` whose first ``k`` rod angles come nearest to the line through ``angles``
    along ``direction`` in the torus ``T^k`` (to the point ``angles`` itself without a direction).

    In rod angles ``theta`` the configuration space is ``g(theta) = sum_j l_j e^{i theta_j} - L = 0``; with
    ``Q = I - d d^T / |d|^2`` (``Q = I`` without a direction) and ``w`` the wrap to ``(-pi, pi]``, the distance
    ``|r(theta)|``, ``r = Q w(theta_{1..k} - a)``, is minimised over ``g = 0`` by Levenberg-Marquardt steps in
    the tangent space ``ker dg`` from the rod angles of ``hinges``, each step followed by the minimum-norm Newton
    correction back onto ``g = 0`` and taken only where it shortens the distance.  A line of sight through the
    cube of ``(theta_1, theta_2, theta_3)`` meets a surface (``n = 4``) in isolated points, and the pose found
    is the one of them reached from ``hinges``; for ``n > 4`` the steps leave the directions that do not move
    the picture alone.

    Raises
    ------
    ValueError
        If ``angles`` does not have between 1 and ``n`` entries or ``direction`` not as many, or if the result
        does not close to ``1e-12`` (it always does from a configuration).
    """
    a = np.asarray(angles, dtype=float)
    k, n = a.size, chain.n
    if a.ndim != 1 or not 1 <= k <= n:
        raise ValueError(f"angles must be a list of 1 to n = {n} rod angles, got shape {a.shape}")
    Q = np.eye(k)
    if direction is not None:
        d = np.asarray(direction, dtype=float)
        if d.shape != (k,) or not np.any(d):
            raise ValueError(f"direction must be a nonzero vector of {k} entries (as many as angles), got {d}")
        Q -= np.outer(d, d) / (d @ d)
    lengths, L = chain.lengths, chain.L

    def residual(theta: NDArray) -> NDArray:
        return Q @ np.angle(np.exp(1j * (theta[:k] - a)))  # wrapped: the nearest copy of the torus point

    theta = _close_rods(lengths, L, chain.angles(chain.as_hinges(hinges)))
    r, mu = residual(theta), 1e-6
    distance = float(np.linalg.norm(r))
    for _ in range(POSE_ITERATIONS):
        G = np.stack([-lengths * np.sin(theta), lengths * np.cos(theta)])
        _, sv, vt = np.linalg.svd(G)
        N = vt[int(np.sum(sv > 1e-12 * sv[0])):].T  # the tangent space ker dg, shape (n, n - rank)
        B = Q @ N[:k]  # dr/dz for theta = theta + N z
        while True:
            z = -np.linalg.solve(B.T @ B + mu * np.eye(N.shape[1]), B.T @ r)
            trial = _close_rods(lengths, L, theta + N @ z)
            r_trial = residual(trial)
            shorter = float(np.linalg.norm(r_trial))
            if shorter < distance or mu > 1e6:
                break
            mu *= 10.0
        if shorter >= distance:
            break  # no step shortens the distance: a local minimum
        theta, r, mu = trial, r_trial, max(mu / 10.0, 1e-12)
        distance, shrink = shorter, distance - shorter
        if shrink <= POSE_TOL * max(distance, 1.0):
            break
    pose = chain.hinges_from_angles(theta, tol=1e-12 * L)
    residual_max = float(np.max(chain.closure_residual(pose)))
    if residual_max > 1e-12:
        raise ValueError(f"the pose does not close: residual {residual_max:.3g} > 1e-12")
    return pose
