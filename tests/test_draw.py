"""Drawings and animations draw what they should: the chain's joints, the path on the sphere, the switches.

They work on a plain matplotlib ``Figure`` (no pyplot, no display).  The
sphere coordinates are checked against the chain's geometry directly: in chart
0 of ``n = 4`` the first coordinate is ``sin(phi_4) = theta / alpha_4`` with
``theta = arg(L - p_3)`` the angle of the last rod and
``cos(alpha_4) = (L^2 - 8) / (2 L)`` (``docs/math.md``, section 1).
"""

import numpy as np
import pytest
from matplotlib import animation as mpl_animation
from matplotlib.figure import Figure
from PIL import Image

from linkage import (
    Chain,
    animate,
    animation,
    draw_chain_at,
    draw_chart_timeline,
    draw_configuration,
    draw_configurations,
    draw_energy_error,
    draw_sphere_path,
)
from linkage.demo import pole_start
from linkage.constraints import HingeConstraints
from linkage.draw import SWITCH_GID, sphere_coordinates
from linkage.motion import free_motion

T = 30.0


@pytest.fixture(scope="module")
def motion():
    chain = Chain(4, 3.5)  # near the top of (2, 4): the path meets the charts' poles often
    h0, v0 = pole_start(chain)
    m = free_motion(chain, h0, v0, T, method="charts")
    assert m.n_switches >= 3  # the pictures below have switches to mark
    return m


def _latitude_from_geometry(chain, hinges):
    """``sin(phi_4)`` of chart 0 from the hinges alone: the last rod's angle over its arc ``alpha_4``."""
    L = chain.L
    alpha = np.arccos((L**2 - 8) / (2 * L))
    return np.angle(L - hinges[..., -1]) / alpha


def test_draw_configurations_puts_rods_hinges_and_pins_on_the_axes():
    chain = Chain(3, 2.0)
    h = np.array([np.exp(1j * np.pi / 3), 1 + np.exp(1j * np.pi / 3)])
    ax = Figure().add_subplot()
    assert draw_configurations(ax, [h, h.conj()], chain.L, labels=["up", "down"]) is ax
    assert len(ax.lines) == 2 * 3  # per configuration: rods, hinges, pins
    np.testing.assert_allclose(ax.lines[0].get_xydata(), [[0, 0], [h[0].real, h[0].imag], [h[1].real, h[1].imag], [2, 0]])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["up", "down"]
    assert draw_configuration(Figure().add_subplot(), h, chain.L) is not None


def test_the_chain_at_a_time_is_the_motions_joints_with_unit_rods(motion):
    t = 7.3
    ax = draw_chain_at(Figure().add_subplot(), motion, t)
    xy = ax.lines[0].get_xydata()
    joints = xy[:, 0] + 1j * xy[:, 1]
    np.testing.assert_array_equal(joints[1:-1], motion(t)[0])
    assert joints[0] == 0 and joints[-1] == motion.chain.L
    np.testing.assert_allclose(np.abs(np.diff(joints)), 1.0, atol=1e-12)  # every rod has unit length
    i = int(motion.solution.parameters(t)[0])
    assert ax.get_title() == f"t = {t:.4g}, chart {motion.solution.metric.atlas.ids[i]}"


def test_the_sphere_path_is_chart_0s_latitude_coloured_by_chart_with_the_switches_marked(motion):
    ts = np.linspace(0, T, 801)
    ax = draw_sphere_path(Figure().add_subplot(projection="3d"), motion, ts)
    path = [line for line in ax.lines if line.get_linestyle() == "-"]
    (marks,) = [line for line in ax.lines if line.get_gid() == SWITCH_GID]
    # the stretches join end to start and together are the sampled path
    stretches = [np.array(line.get_data_3d()).T for line in path]
    for a, b in zip(stretches, stretches[1:]):
        np.testing.assert_array_equal(a[-1], b[0])
    points = np.concatenate([stretches[0]] + [s[1:] for s in stretches[1:]])
    assert len(points) == len(ts)
    np.testing.assert_allclose(np.linalg.norm(points, axis=1), 1.0, atol=1e-12)  # n = 4: the whole S^2
    np.testing.assert_allclose(points[:, 0], _latitude_from_geometry(motion.chain, motion(ts)[0]), atol=1e-12)
    # each stretch in the colour of the chart active at its first time
    starts = np.cumsum([0] + [len(s) - 1 for s in stretches[:-1]])
    charts = motion.solution.parameters(ts[starts])[0]
    assert [line.get_color() for line in path] == [f"C{c}" for c in charts]
    assert len(path) == motion.n_switches + 1  # 801 samples see every stretch of this run
    # a cross at every switch, where the sphere point of the motion is at that time
    switch_times = np.array([s.time for s in motion.solution.switches])
    crosses = np.array(marks.get_data_3d()).T
    assert len(crosses) == motion.n_switches
    np.testing.assert_allclose(crosses[:, 0], _latitude_from_geometry(motion.chain, motion(switch_times)[0]), atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(crosses, axis=1), 1.0, atol=1e-12)


def test_the_energy_error_plot_is_the_solvers_record_and_marks_the_switches(motion):
    ax = draw_energy_error(Figure().add_subplot(), motion)
    (curve,) = [line for line in ax.lines if line.get_gid() != SWITCH_GID]
    t, err = curve.get_xydata().T
    assert err.max() == motion.relative_energy_error > 0
    assert 0 <= t[0] and t[-1] <= T and np.all(np.diff(t) > 0)
    vertical = [line.get_xdata()[0] for line in ax.lines if line.get_gid() == SWITCH_GID]
    assert vertical == [s.time for s in motion.solution.switches]
    assert ax.get_yscale() == "log"


def test_the_chart_timeline_covers_the_run_and_switches_where_the_log_says(motion):
    ax = draw_chart_timeline(Figure().add_subplot(), motion)
    bars = [line.get_xydata() for line in ax.lines if line.get_gid() != SWITCH_GID]
    starts, ends, rows = (np.array([b[0, 0] for b in bars]), np.array([b[1, 0] for b in bars]),
                          np.array([b[0, 1] for b in bars]))
    assert starts[0] == 0 and ends[-1] == T and np.array_equal(starts[1:], ends[:-1])  # no gap, no overlap
    assert len(bars) == motion.n_switches + 1  # one bar per stay in a chart
    for s in motion.solution.switches:
        before, after = np.flatnonzero(ends == s.time), np.flatnonzero(starts == s.time)
        assert rows[before[0]] == s.from_chart and rows[after[0]] == s.to_chart
    arrows = [line.get_xydata() for line in ax.lines if line.get_gid() == SWITCH_GID]
    assert [(a[0, 0], a[0, 1], a[1, 1]) for a in arrows] == [(s.time, s.from_chart, s.to_chart)
                                                            for s in motion.solution.switches]
    assert [t.get_text() for t in ax.get_yticklabels()] == list(motion.solution.metric.atlas.ids)


def test_an_animation_frame_is_the_chain_at_its_time(motion, tmp_path):
    times = [0.0, 3.0, 11.5]
    fig = Figure()
    anim = animation(motion, times, fig=fig)
    anim.save(tmp_path / "m.gif", writer=mpl_animation.PillowWriter(fps=5), dpi=30)
    with Image.open(tmp_path / "m.gif") as gif:
        assert gif.n_frames == len(times)
    # after saving, the artists show the last frame
    chain_ax, sphere_ax = fig.axes
    (rods,) = [line for line in chain_ax.lines if line.get_marker() == "o"]
    xy = rods.get_xydata()
    np.testing.assert_array_equal(xy[1:-1, 0] + 1j * xy[1:-1, 1], motion(times[-1])[0])
    assert rods.get_color() == f"C{motion.solution.parameters(times[-1])[0]}"
    dot = [line for line in sphere_ax.lines if line.get_marker() == "o"][-1]
    np.testing.assert_allclose(np.array(dot.get_data_3d())[:, 0], sphere_coordinates(motion, [times[-1]])[0])


def test_animate_writes_a_gif_in_one_call(motion, tmp_path):
    path = animate(motion, tmp_path / "motion.gif", frames=4, fps=10, dpi=30)
    with Image.open(path) as gif:
        assert gif.format == "GIF" and gif.n_frames == 4


def test_animate_refuses_what_it_cannot_write(motion, tmp_path, monkeypatch):
    with pytest.raises(ValueError, match=r"path must end in \.gif .* or \.mp4 .*got '.*motion\.avi'"):
        animate(motion, tmp_path / "motion.avi")
    monkeypatch.setattr(mpl_animation.writers, "is_available", lambda name: False)
    with pytest.raises(RuntimeError, match=r"needs ffmpeg on the PATH .* write a \.gif"):
        animate(motion, tmp_path / "motion.mp4")
    assert not (tmp_path / "motion.mp4").exists()
    with pytest.raises(ValueError, match="frames must be an integer >= 2, got 1"):
        animation(motion, frames=1)


def test_the_sphere_path_needs_four_rods_and_a_3d_axes(motion):
    with pytest.raises(ValueError, match="ax must be a 3-d Axes"):
        draw_sphere_path(Figure().add_subplot(), motion)
    chain3 = Chain(3, 2.0)
    circle = free_motion(chain3, *pole_start(chain3), 1.0, method="charts")
    with pytest.raises(ValueError, match="needs n >= 4 .* got n = 3"):
        draw_sphere_path(Figure().add_subplot(projection="3d"), circle)


def test_a_chain_without_charts_is_drawn_without_them(tmp_path):
    """Rods of other lengths: no chart, no sphere; the chain, the energy and a hinge-space timeline still draw."""
    chain = Chain((1.0, 2.0, 1.5, 2.5, 1.2), 3.0)
    h0 = chain.from_diagonals([2.0, 2.5, 3.0], [1, -1, 1, 1])
    x0 = chain.to_point(h0)
    v0 = chain.from_point(HingeConstraints(chain).project_velocity(x0, np.linspace(-1, 1, x0.size)))
    m = free_motion(chain, h0, v0, 2.0, method="hinges", compact_mode=True)
    ax = draw_chain_at(Figure().add_subplot(), m, 1.0)
    assert ax.get_title() == "t = 1"
    xy = ax.lines[0].get_xydata()
    np.testing.assert_allclose(np.abs(np.diff(xy[:, 0] + 1j * xy[:, 1])), chain.lengths, rtol=1e-12)
    ax = draw_chart_timeline(Figure().add_subplot(), m)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["hinge space"]
    draw_energy_error(Figure().add_subplot(), m)
    fig = Figure()
    animation(m, [0.0, 1.0, 2.0], fig=fig).save(tmp_path / "m.gif", writer=mpl_animation.PillowWriter(fps=5), dpi=20)
    assert len(fig.axes) == 1 and fig.axes[0].get_title() == "t =    2.00"  # no sphere panel, no chart
    with pytest.raises(ValueError, match=r"sphere coordinates .* has none .*closed orientable 3-manifold"):
        sphere_coordinates(m, [0.0])
    with pytest.raises(ValueError, match="has none"):
        draw_sphere_path(Figure().add_subplot(projection="3d"), m)


def _segment_distance(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of the pixel ``q`` (2,) to the segments ``a[i] -> b[i]`` (pixels, ``(m, 2)``)."""
    d = b - a
    s = np.clip(np.sum((q - a) * d, axis=1) / np.maximum(np.sum(d * d, axis=1), 1e-12), 0.0, 1.0)
    return np.linalg.norm(a + s[:, None] * d - q, axis=1)


def test_animated_gif_frames_show_the_chain_at_their_times(motion, tmp_path):
    """Each frame of the GIF shows the chain at its own time: its hinges in the colour of the active chart, and
    where another frame's hinges lie away from this frame's rods, only background (read from the file's pixels)."""
    from matplotlib.colors import to_rgb

    times = np.array([0.0, 7.3, 19.1, 29.5])
    fig = Figure(figsize=(5.5, 4.8))
    path = animate(motion, tmp_path / "m.gif", times=times, fps=5, dpi=60, sphere=False, fig=fig)
    to_pixels = fig.axes[0].transData.transform  # the figure animate drew on, at its dpi: plane -> pixels
    height = fig.bbox.height
    chains = []
    for t in times:  # the polyline 0, p_1, ..., p_{n-1}, L, as image pixels (rows from the top)
        z = np.concatenate([[0.0], motion(t)[0], [motion.chain.L]])
        xy = to_pixels(np.column_stack([z.real, z.imag]))
        chains.append(np.column_stack([xy[:, 0], height - xy[:, 1]]))
    with Image.open(path) as gif:
        assert gif.n_frames == len(times)
        frames = []
        for k in range(len(times)):
            gif.seek(k)
            frames.append(np.asarray(gif.convert("RGB"), dtype=float))
    assert frames[0].shape[:2] == (round(height), round(fig.bbox.width))
    checked_background = 0
    for k, (t, image) in enumerate(zip(times, frames)):
        colour = 255 * np.array(to_rgb(f"C{motion.solution.parameters(t)[0]}"))
        for x, y in chains[k][1:-1]:  # the hinges: dots of the chart's colour
            assert np.linalg.norm(image[int(round(y)), int(round(x))] - colour) < 60, (k, x, y)
        for j in range(len(times)):  # other frames' hinges, 8 pixels or more from this frame's rods: background
            for q in chains[j][1:-1]:
                if np.min(_segment_distance(q, chains[k][:-1], chains[k][1:])) >= 8:
                    assert np.all(image[int(round(q[1])), int(round(q[0]))] > 230), (k, j, q)
                    checked_background += 1
    assert checked_background >= 10  # the frames differ where it shows
