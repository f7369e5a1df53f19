"""Random starts for a chain: configurations uniform in the Riemannian volume, velocities on the energy sphere.

The measure is that of the chain's own kinetic metric ``g = J^T K J``
(``K = A (x) I_2``, with its hinge masses and rod densities), so a start drawn
by :func:`sample_starts` is distributed by the Liouville measure of the
geodesic flow on the energy shell ``T = E``: the invariant measure that an
ergodic free motion would fill.  The work is done in :mod:`manifold.sampling`
on the chain's suspension atlas (exact rejection through the best chart); this
module converts to complex hinges.

Chains of any link lengths and masses are also covered by
:meth:`linkage.diagonals.DiagonalSpace.sample` (``chain.diagonal_space()``) with
``measure='riemannian'`` (importance resampling: approximate, with an
effective sample size); the two agree where both apply (``tests/test_sampling.py``).
The functions here need the suspension atlas (:attr:`linkage.Chain.has_atlas`: a sphere, some side of the
polygon ``(l_1, ..., l_n, L)`` dominant; ``n - 2 < L < n`` for unit rods) and refuse other chains by name, saying
what their space is and pointing to that sampler.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from charts import RoundSphereProposal
from manifold import sampling as generic

from .chain import Chain
from .topology import MAX_RODS


def _require_atlas(chain: Chain, what: str) -> None:
    """Unless ``chain`` has a suspension atlas: ``ValueError`` saying what its space is, and the alternative."""
    if not chain.has_atlas:
        space = f" ({chain.topology().summary()})" if chain.n <= MAX_RODS else ""
        raise ValueError(
            f"{what} samples through the suspension atlas, and {chain!r} has none{space}: only a sphere (some side "
            "of the polygon (l_1, ..., l_n, L) dominant) has one; for other generic chains use chain.diagonal_space().sample(size, rng, "
            "measure='riemannian') (configurations, in the chain's kinetic metric) and "
            "HingeConstraints(chain).project_velocity for velocities")


def sample_configurations(chain: Chain, size: int, rng: np.random.Generator) -> NDArray:
    """``size`` independent configurations uniform in the Riemannian volume of the kinetic metric.

    Parameters
    ----------
    chain
        A :class:`~linkage.Chain` with an atlas (``n >= 2``; for ``n = 2`` the two
        points of ``S^0`` with probability 1/2 each).
    size
        Number of configurations, a positive integer.
    rng
        ``numpy.random.Generator``.

    Returns
    -------
    numpy.ndarray
        Complex hinges, shape ``(size, n-1)``: the points of
        :func:`manifold.sampling.sample_volume` on ``chain.metric()`` with a
        :class:`charts.RoundSphereProposal` (which also reports the acceptance).
    """
    _require_atlas(chain, "sample_configurations")
    proposal = RoundSphereProposal(chain.dim)
    return chain.from_point(generic.sample_volume(chain.metric(), size, rng, proposal).points)


def sample_velocities(chain: Chain, hinges: ArrayLike, energy: float, rng: np.random.Generator) -> NDArray:
    """Hinge velocities uniform on the energy sphere ``1/2 v^T K v = energy`` of each configuration.

    Parameters
    ----------
    chain
        The chain (``n >= 3``: ``S^0`` has no velocities).
    hinges
        Complex configurations, shape ``(..., n-1)``, closing to ``1e-9``.
    energy
        Kinetic energy ``E > 0`` of every velocity.
    rng
        ``numpy.random.Generator``.

    Returns
    -------
    numpy.ndarray
        Complex velocities of the shape of ``hinges``, tangent and of energy
        ``E`` to rounding, uniform on the sphere of radius ``sqrt(2 E)`` in
        ``(T_p M, g)`` (independently for each configuration).
    """
    _require_atlas(chain, "sample_velocities")
    points = chain.to_point(chain.check_configuration(hinges))
    return chain.from_point(generic.sample_velocities(chain.metric(), points, energy, rng))


def sample_starts(chain: Chain, size: int, energy: float, rng: np.random.Generator) -> tuple[NDArray, NDArray]:
    """``size`` starts ``(hinges, velocities)`` from the Liouville measure on the energy shell ``T = energy``.

    Configurations uniform in the Riemannian volume, then for each one a
    velocity uniform on its energy sphere; both complex of shape
    ``(size, n-1)``, ready for :func:`linkage.motion.free_motion` one by one.

    Raises
    ------
    ValueError
        For a chain without a suspension atlas (the message says what its space is and names the sampler for
        other generic chains), and for a bad ``size`` or ``energy``.
    """
    _require_atlas(chain, "sample_starts")
    hinges = sample_configurations(chain, size, rng)
    return hinges, sample_velocities(chain, hinges, energy, rng)
