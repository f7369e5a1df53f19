"""Free motion of a chain: geodesics of its kinetic-energy metric through the atlas.

Thin layer over :func:`manifold.geodesic_solver.solve_chart_exp_ode` that speaks
in complex hinges instead of interleaved real points.
"""

from __future__ import annotations

from typing import Any

from numpy.typing import ArrayLike, NDArray

from manifold import GeodesicSolution, solve_chart_exp_ode

from .chain import Chain


class ChainMotion:
    """A solved free motion: the geodesic plus complex-hinge accessors.

    Attributes
    ----------
    chain
        The chain.
    solution
        The underlying :class:`~manifold.geodesic_solver.GeodesicSolution`
        (segments, switch log, energies, working-precision evaluation).
    """

    def __init__(self, chain: Chain, solution: GeodesicSolution) -> None:
        self.chain, self.solution = chain, solution

    def __repr__(self) -> str:
        return f"ChainMotion({self.chain!r}, {self.solution!r})"

    def __call__(self, t: ArrayLike) -> tuple[NDArray, NDArray]:
        """Complex hinges and hinge velocities at time(s) ``t`` (rounded to complex128)."""
        p, v = self.solution(t)
        return self.chain.from_point(p.astype(float)), self.chain.from_point(v.astype(float))

    @property
    def n_switches(self) -> int:
        return self.solution.n_switches

    @property
    def relative_energy_error(self) -> float:
        return self.solution.relative_energy_error

    @property
    def chart_ids(self) -> list:
        """Readable ids of the charts used, in order (a chart kept across an angle wrap counts once)."""
        ids = [self.solution.metric.atlas.ids[s.chart] for s in self.solution.segments]
        return [c for k, c in enumerate(ids) if k == 0 or c != ids[k - 1]]


def free_motion(chain: Chain, hinges0: ArrayLike, velocity0: ArrayLike, t_final: float, **kwargs: Any) -> ChainMotion:
    """Integrate the chain's force-free motion from ``hinges0`` with hinge velocity ``velocity0``.

    Parameters
    ----------
    chain
        The chain (its masses define the metric).
    hinges0, velocity0
        Complex interior hinges (must close) and their velocity (must be tangent,
        unless ``project_velocity=True``).
    t_final
        Final time (finite; negative integrates backward).
    **kwargs
        Passed to :func:`~manifold.geodesic_solver.solve_chart_exp_ode`
        (``fp_type``, ``tol``, ``q_out``, ``form``, ``project_velocity``, ``dense``, ...).
    """
    h0 = chain.check_configuration(hinges0)
    v0 = chain._hinge_array(velocity0, "velocity")
    return ChainMotion(chain, solve_chart_exp_ode(chain.metric(), chain.to_point(h0), chain.to_point(v0), t_final, **kwargs))
