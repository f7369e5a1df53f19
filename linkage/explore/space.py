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
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from charts.suspension import sphere_parameters

from ..chain import Chain
from ..geometry import tangent_basis
from .protocol import as_pairs

__all__ = ["STIFFNESS_DIRECTIONS", "largest_stiffness", "pose_from_sphere", "space_payload"]


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


def _sphere_mesh(chain: Chain, resolution: int) -> dict[str, Any]:
    """Latitude-longitude mesh of chart 0's sphere ``S^2`` (``n = 4``): vertices, triangles, configurations, angles,
    and per vertex the Gaussian curvature, the bending ``|II|^2`` and the largest stiffness."""
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
    return {"vertices": chart0.sphere_point(a).tolist(), "faces": faces, "hinges": as_pairs(hinges),
            "angles": chain.angles(hinges)[:, :3].tolist(), "curvature": np.asarray(curvature).tolist(),
            "bending": np.asarray(bending).tolist(), "stiffness": largest_stiffness(chain, hinges).tolist()}


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
        ``n``, ``topology`` (:meth:`linkage.topology.Topology.summary`), ``hasAtlas``, ``chartIds``;
        ``sphere`` (``n = 4`` with an atlas: the mesh, else ``None``); ``circle`` (``n = 3`` with an atlas:
        points of the unit circle and their rod angles, else ``None``); ``torus``: ``{angles, name}``, rod angles
        of configurations in the cube, and the name of the projection; ``start``: one configuration of the space
        (chart 0's parameters all 0.4 where there is an atlas, else the first sample) to pose the chain in.
    """
    topology = chain.topology()
    out: dict[str, Any] = {"n": chain.n, "lengths": chain.lengths.tolist(), "L": chain.L,
                           "topology": topology.summary(), "hasAtlas": chain.has_atlas,
                           "chartIds": [str(c) for c in chain.atlas().ids] if chain.has_atlas else [],
                           "sphere": None, "circle": None}
    if chain.n == 4 and chain.has_atlas:
        out["sphere"] = _sphere_mesh(chain, resolution)
        angles = np.array(out["sphere"]["angles"])
        name = "the configuration sphere in the cube of rod angles (theta_1, theta_2, theta_3)"
    elif chain.n == 3 and chain.has_atlas:
        points, hinges = _circle(chain, resolution)
        angles = chain.angles(hinges)
        out["circle"] = {"points": points.tolist(), "angles": angles[:, :2].tolist()}
        name = "the configuration circle in the torus of rod angles (theta_1, theta_2)"
    else:
        # hit-and-run in the diagonal polytope takes ~15 (n-2)^2 steps per sample: fewer samples for long chains
        size = max(200, min(samples, samples * 36 // (chain.n - 2) ** 2))
        hinges = chain.diagonal_space().sample(size, np.random.default_rng(seed)).hinges
        angles = chain.angles(hinges)
        name = (f"projection of {size} configurations sampled uniformly in the diagonal coordinates onto the rod "
                f"angles ({'theta_1, theta_2' if chain.n == 3 else 'theta_1, theta_2, theta_3'})")
    out["torus"] = {"angles": np.asarray(angles)[:, :3].tolist(), "name": name}
    start = chain.atlas().charts[0].hinges(np.full(chain.n - 2, 0.4)) if chain.has_atlas else hinges[0]
    out["start"] = as_pairs(start)
    return out


def pose_from_sphere(chain: Chain, point: NDArray) -> NDArray:
    """The configuration at ``point`` of chart 0's round sphere ``S^(n-2)`` (any nonzero scale): the inverse of
    the picture, :func:`charts.suspension.sphere_parameters` then the chart map."""
    if not chain.has_atlas:
        raise ValueError(f"the sphere picture needs an atlas, and this chain has none: {chain.topology().summary()}")
    return chain.atlas().charts[0].hinges(sphere_parameters(point))
