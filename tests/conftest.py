"""Shared hypothesis strategies, leaning toward the hard regions of the charts.

Hard regions: latitudes near the poles ``+-pi/2``, the circle angle near
``t = +-pi/2`` (where the elbow height changes sign), and ``L`` within 1e-3 of
both ends of ``(n-2, n)``.
"""

from __future__ import annotations

import os

import heyoka as hy
import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from charts.suspension_symbolic import SuspensionFamily

# The strategies lean on purpose toward poles and range ends, where many draws are filtered (``assume``
# of a chart's quality, of a generic topology): hypothesis's filter_too_much check then fails a run by the
# seed's luck (seed 25 filtered 50 draws of 58 in one test), which says nothing about the code.
settings.register_profile(
    "default", deadline=None, max_examples=60,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
# ``pytest --hypothesis-profile=stress`` draws ten times as many cases; run it
# after touching a chart or the solver (the default run is sized for CI).
settings.register_profile("stress", parent=settings.get_profile("default"), max_examples=600)
settings.load_profile("default")

HALF_PI = np.pi / 2

#: ``LINKAGE_TEST_SIMD_WIDTH=8 python -m pytest`` runs the suite as on a machine whose SIMD width heyoka reports as 8
#: (AVX-512); the library reads the width at each call, and no test may assume one.
SIMD_WIDTH_VARIABLE = "LINKAGE_TEST_SIMD_WIDTH"


@pytest.fixture(autouse=True)
def forced_simd_width(monkeypatch):
    """heyoka's recommended SIMD width as :data:`SIMD_WIDTH_VARIABLE` says, if set."""
    width = os.environ.get(SIMD_WIDTH_VARIABLE)
    if width:
        monkeypatch.setattr(hy, "recommended_simd_size", lambda *args, **kwargs: int(width))


@st.composite
def base_lengths(draw, n: int) -> float:
    """``L`` in ``(n-2, n)``: uniform, or within 1e-3 (down to 1e-7) of either end."""
    kind = draw(st.sampled_from(["uniform", "low", "high"]))
    if kind == "uniform":
        return draw(st.floats(n - 2 + 1e-3, n - 1e-3))
    gap = 10.0 ** draw(st.floats(-7, -3))
    return n - 2 + gap if kind == "low" else n - gap


@st.composite
def latitudes(draw) -> float:
    """A latitude in ``[-pi/2, pi/2]``: uniform, near a pole, or exactly at one."""
    kind = draw(st.sampled_from(["uniform", "near-pole", "pole"]))
    sign = draw(st.sampled_from([-1.0, 1.0]))
    if kind == "uniform":
        return draw(st.floats(-HALF_PI, HALF_PI))
    if kind == "pole":
        return sign * HALF_PI
    return sign * (HALF_PI - 10.0 ** draw(st.floats(-8, -0.5)))


@st.composite
def circle_angles(draw) -> float:
    """``t``: uniform on ``[-pi, pi]``, or within ``1e-12 .. 1e-2`` of ``+-pi/2``, or exactly there."""
    kind = draw(st.sampled_from(["uniform", "near", "exact"]))
    sign = draw(st.sampled_from([-1.0, 1.0]))
    if kind == "uniform":
        return draw(st.floats(-np.pi, np.pi))
    if kind == "exact":
        return sign * HALF_PI
    return sign * HALF_PI + draw(st.sampled_from([-1.0, 1.0])) * 10.0 ** draw(st.floats(-12, -2))


@st.composite
def chart_parameters(draw, n: int) -> np.ndarray:
    """Parameters ``(phi_n, ..., phi_4, t)`` of an ``n``-rod suspension chart."""
    lat = [draw(latitudes()) for _ in range(n - 3)]
    return np.array(lat + [draw(circle_angles())])


@st.composite
def rod_orders(draw, n: int) -> np.ndarray:
    return np.array(draw(st.permutations(range(n))))


def folded_conditioning(n: int, L: float) -> float:
    """Error growth ``max(1, 1e-3 / (L - (n-2)))`` of chart derivatives near ``L = n - 2``.

    There the first two rods of a chart can fold back onto each other, the
    circle level's ``p_2`` passes within ``L - (n-2)`` of the origin, and the
    elbow direction ``p_2 / |p_2|`` amplifies rounding by ``1 / |p_2|``.  Within
    1e-3 of the end the plain tolerances hold; closer, they scale with this.
    """
    return max(1.0, 1e-3 / (L - (n - 2)))


def parameter_rounding_floor(chart, a: np.ndarray) -> float:
    """``eps |p| / sigma_min(J(a))``: how far one ulp of ``p = chart(a)`` can move ``a``, at worst.

    The worst-direction amplification of rounding in ``p``, an upper estimate
    of what a backward-stable inverse loses (observed errors stay below 1% of
    it).  It exceeds 1e-12 only where the chart is ill-conditioned although every
    latitude has ``q >= 0.05`` (e.g. four nested latitudes at ``q = 0.1``:
    ``sigma_min = 5e-5``).
    """
    sigma_min = np.linalg.svd(chart.jacobian(a), compute_uv=False)[-1]
    return float(np.finfo(float).eps * np.abs(chart.get_point(a)).max() / sigma_min)


def unit_speed_start(chain, a, c):
    """Configuration at chart-0 parameters ``a`` and the tangent velocity ``J(a) c`` scaled to unit kinetic speed."""
    from charts import SuspensionChart

    chart = SuspensionChart(chain.n, chain.L)
    a = np.asarray(a, dtype=float)
    h0 = chart.hinges(a)
    v0 = chain.from_point(chart.jacobian(a) @ np.asarray(c, dtype=float))
    return h0, v0 / np.sqrt(2 * chain.kinetic_energy(v0))


def assert_same_motion(got, ref, T: float) -> None:
    """``got`` and ``ref`` solve one motion over ``T``: the same status, points at 51 times and at the end to 1e-10,
    the same switch log (charts, and times to 1e-9), and ``got``'s recorded energy constant to 1e-13."""
    assert got.t_reached == T and got.status == ref.status
    ts = np.linspace(0.0, T, 51)
    assert np.max(np.abs(got(ts)[0] - ref(ts)[0])) <= 1e-10
    assert np.max(np.abs(got.end_state()[0] - ref.end_state()[0])) <= 1e-10
    assert [(s.from_chart, s.to_chart) for s in got.switches] == [(s.from_chart, s.to_chart) for s in ref.switches]
    assert np.allclose([s.time for s in got.switches], [s.time for s in ref.switches], atol=1e-9, rtol=0)
    E = np.asarray(got.energies, dtype=float)
    assert np.max(np.abs(E / E[0] - 1)) <= 1e-13


class DifferentiatedFamily(SuspensionFamily):
    """A suspension family without jets: its derivatives come from heyoka's symbolic differentiation of the
    expanded ``z``, the independent route the jets are checked against (any ``SuspensionFamily`` options)."""

    @property
    def key(self):
        return ("differentiated", *super().key)

    def point_jets(self, a, c, fp_type):
        return None


def atlas_start(chain, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A generic start of unit kinetic energy, in the chain's best chart: ambient point and velocity."""
    rng = np.random.default_rng(seed)
    atlas = chain.atlas()
    p0 = atlas.get_point(0, rng.uniform(-1.0, 1.0, chain.n - 2))
    i = atlas.get_chart_index(p0)
    v0 = atlas.charts[i].tangent_vector(atlas.get_parameters(i, p0), rng.normal(size=chain.n - 2))
    return p0, v0 / np.sqrt(2 * chain.metric().ambient_kinetic_energy(v0))
