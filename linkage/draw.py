"""Pictures and animations of chains and their motions (matplotlib).

Configurations: :func:`draw_configuration`, :func:`draw_configurations`.
A solved motion (a :class:`~linkage.motion.ChainMotion`): the chain at a time
(:func:`draw_chain_at`), the path on the configuration sphere coloured by the
active chart with the switches marked (:func:`draw_sphere_path`, in the
coordinates of :func:`sphere_coordinates`), the energy error and the chart
timeline against time (:func:`draw_energy_error`, :func:`draw_chart_timeline`),
and the moving chain (:func:`animation`, written to a file by :func:`animate`).

A chain without suspension charts (:attr:`~linkage.Chain.has_atlas` false: its
configuration space is not a sphere with ``L`` the dominant side) has no chart and no
configuration sphere: its motions are drawn as the chain, the energy error and
a timeline in hinge space, and the sphere pictures refuse it by name.

Every ``draw_*`` function draws on an ``Axes`` the caller made (so it works in
a plain ``matplotlib.figure.Figure`` as well as with ``pyplot``) and returns it.
matplotlib is imported inside the functions that need it, so that
``import linkage`` does not load a plotting library.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from manifold.validation import check_real, real_array

if TYPE_CHECKING:
    from matplotlib.animation import FuncAnimation
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from .motion import ChainMotion

__all__ = ["animate", "animation", "animation_writer", "draw_chain_at", "draw_chart_timeline", "draw_configuration",
           "draw_configurations", "draw_energy_error", "draw_sphere_path", "sphere_coordinates"]

#: ``gid`` of the artists that mark chart switches (find them with ``artist.get_gid()``).
SWITCH_GID = "chart switch"


def _full_chain(hinges: ArrayLike, L: float) -> NDArray:
    """``p_0 = 0, p_1, ..., p_{n-1}, p_n = L`` along the last axis."""
    h = np.asarray(hinges, dtype=complex)
    ends = np.zeros(h.shape[:-1] + (1,), dtype=complex)
    return np.concatenate([ends, h, ends + L], axis=-1)


def draw_configuration(
    ax: Axes, hinges: ArrayLike, L: float, color: Any = "C0", alpha: float = 1.0, label: str | None = None
) -> Axes:
    """Draw one configuration on ``ax``: rods as lines, hinges as dots, pins as triangles.

    The polyline is ``p_0 = 0, p_1, ..., p_{n-1}, p_n = L`` (rod ``e_k =
    p_k - p_{k-1}`` is its ``k``-th piece), drawn in the complex plane.

    Parameters
    ----------
    ax
        A matplotlib ``Axes``.
    hinges
        Complex interior hinges ``p_1 .. p_{n-1}``.
    L
        Position of the right pin on the real axis.
    color, alpha, label
        Passed to ``ax.plot`` for the rods (the hinges share color and alpha).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``, with equal aspect.
    """
    p = _full_chain(hinges, L)
    ax.plot(p.real, p.imag, "-", color=color, lw=2, alpha=alpha, label=label)
    ax.plot(p.real[1:-1], p.imag[1:-1], "o", color=color, ms=4, alpha=alpha)
    ax.plot([0, L], [0, 0], "k^", ms=9)
    ax.set_aspect("equal")
    return ax


def draw_configurations(
    ax: Axes, configurations: Sequence[ArrayLike], L: float, cmap: str = "viridis", labels: Sequence[str] | None = None
) -> Axes:
    """Overlay several configurations on ``ax``, coloured along ``cmap`` in order.

    Parameters
    ----------
    ax
        A matplotlib ``Axes``.
    configurations
        Complex interior hinges of each configuration.
    L
        Position of the right pin on the real axis.
    cmap
        Name of a matplotlib colormap; configuration ``k`` of ``m`` gets its colour at ``k / (m - 1)``.
    labels
        One legend label per configuration (no legend if ``None``).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.
    """
    import matplotlib  # here, not at module level: ``import linkage`` must not load a plotting library

    colors = matplotlib.colormaps[cmap](np.linspace(0, 1, max(len(configurations), 1)))
    for k, h in enumerate(configurations):
        draw_configuration(ax, h, L, color=colors[k], alpha=0.85, label=None if labels is None else labels[k])
    if labels is not None:
        ax.legend(fontsize="small")
    return ax


def _times(motion: ChainMotion, times: ArrayLike | None, samples: int) -> NDArray:
    """``times`` as a 1-d float array, or ``samples`` evenly spaced times over the solved span."""
    if times is None:
        return np.linspace(0.0, float(motion.solution.t_reached), samples)
    ts = real_array("times", times)
    if ts.ndim != 1 or ts.size == 0:
        raise ValueError(f"times must be a non-empty 1-d array of times, got shape {ts.shape}")
    return ts


def _integer(name: str, value: object, minimum: int) -> int:
    """``value`` as an ``int`` if it is an integer ``>= minimum``, else a ``ValueError`` naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _has_charts(motion: ChainMotion) -> bool:
    """Whether the motion can be read in charts: solved in an atlas, or its chain has one."""
    return motion.solution.metric is not None or motion.chain.has_atlas


def _atlas_ids(motion: ChainMotion) -> list:
    """The chart ids of the motion's atlas (the chain's own atlas for a method that was given none; none without)."""
    metric = motion.solution.metric
    if metric is None and not motion.chain.has_atlas:
        return []
    return list((motion.chain.atlas() if metric is None else metric.atlas).ids)


def _chart_label(motion: ChainMotion, chart: int) -> str:
    return f"chart {_atlas_ids(motion)[chart]}"


def _active_charts(motion: ChainMotion, times: NDArray) -> NDArray:
    """The chart active (or best, for a hinge-space method) at ``times``; ``-1`` where the chain has no charts."""
    if not _has_charts(motion):
        return np.full(len(times), -1)
    return np.asarray(motion.solution.parameters(times)[0])


def _title(motion: ChainMotion, t: str, chart: int) -> str:
    """``t = <t>``, and the chart if there is one (``chart >= 0``)."""
    return f"t = {t}" + ("" if chart < 0 else f", {_chart_label(motion, chart)}")


def sphere_coordinates(motion: ChainMotion, times: ArrayLike) -> NDArray:
    """The motion on the round sphere ``S^(n-2)`` in ``R^(n-1)``, read in chart 0 (shape ``(len(times), n-1)``).

    With chart 0's suspension coordinates ``a = (phi_n, ..., phi_4, t)``
    (:meth:`charts.SuspensionChart.sphere_point`)

    .. math::

        s = (\\sin\\phi_n,\\ \\cos\\phi_n \\sin\\phi_{n-1},\\ \\dots,\\
             \\textstyle\\prod_m \\cos\\phi_m \\cos t,\\ \\prod_m \\cos\\phi_m \\sin t),

    a homeomorphism of the configuration space onto the unit sphere: continuous
    through chart 0's poles (where ``cos phi_m = 0`` and ``t`` is arbitrary), so
    the picture is one smooth path whatever chart integrated it.  For ``n = 4``
    it is the whole configuration sphere ``S^2``.

    Parameters
    ----------
    motion
        A solved motion with dense output, of a chain with an atlas (else ``ValueError``).
    times
        Times within the solved span.
    """
    if not motion.chain.has_atlas:
        raise ValueError(
            f"sphere coordinates are read in chart 0 of the suspension atlas, and {motion.chain!r} has none "
            f"(only a sphere, some side of the polygon (l_1, ..., l_n, L) dominant, has one): "
            f"{motion.chain.topology().summary()}")
    chart0 = motion.chain.atlas().charts[0]
    hinges = motion(real_array("times", times))[0]
    return chart0.sphere_point(chart0.get_parameters(motion.chain.to_point(hinges)))


def draw_chain_at(ax: Axes, motion: ChainMotion, t: float, color: Any = "C0", label: str | None = None) -> Axes:
    """Draw the chain of ``motion`` at time ``t`` (:func:`draw_configuration` of ``motion(t)``), titled with ``t``.

    Parameters
    ----------
    ax
        A matplotlib ``Axes``.
    motion
        A solved motion with dense output.
    t
        A time within the solved span.
    color, label
        Passed to :func:`draw_configuration`.

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``, titled with ``t`` and the chart active there (if the chain has charts).
    """
    t = check_real("t", t)
    draw_configuration(ax, motion(t)[0], motion.chain.L, color=color, label=label)
    ax.set_title(_title(motion, f"{t:.4g}", int(_active_charts(motion, np.array([t]))[0])))
    return ax


def draw_sphere_path(
    ax: Axes, motion: ChainMotion, times: ArrayLike | None = None, *, samples: int = 2000, switches: bool = True
) -> Axes:
    """Draw the path on the configuration sphere (:func:`sphere_coordinates`), coloured by the active chart.

    One line per stretch in one chart, in colour ``C<chart>`` (a hinge-space
    method has no active chart: its path is coloured by the best chart at each
    time); a star at the start, crosses at the chart switches (``gid``
    :data:`SWITCH_GID`).  For ``n = 4`` the configuration space is the sphere
    ``S^2`` drawn (a light wireframe); for ``n > 4`` the first three of the
    ``n - 1`` sphere coordinates are shown, a projection of ``S^(n-2)``.

    Parameters
    ----------
    ax
        A 3-d matplotlib ``Axes`` (``fig.add_subplot(projection="3d")``).
    motion
        A solved motion with dense output, ``n >= 4``.
    times
        Times at which the path is sampled (default: ``samples`` evenly spaced over the solved span).
    samples
        Number of default times.
    switches
        Mark the chart switches.

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.
    """
    from mpl_toolkits.mplot3d.axes3d import Axes3D  # ships with matplotlib

    n = motion.chain.n
    if n < 4:
        raise ValueError(f"the path on the configuration sphere needs n >= 4 (S^(n-2) drawn in R^3), got n = {n}: "
                         "for n = 3 the configuration space is a circle")
    if not isinstance(ax, Axes3D):
        raise ValueError(f"ax must be a 3-d Axes (fig.add_subplot(projection='3d')), got {type(ax).__name__}")
    ts = _times(motion, times, samples)
    s = sphere_coordinates(motion, ts)[:, :3]
    active = np.asarray(motion.solution.parameters(ts)[0])
    if n == 4:
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
        ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.85", lw=0.4)
    cuts = np.flatnonzero(np.diff(active)) + 1
    labelled: set[int] = set()
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, len(ts)]):
        chart = int(active[a])
        stretch = s[a : min(b + 1, len(ts))]  # joined to the next stretch's first point: no gaps in the path
        ax.plot(*stretch.T, "-", color=f"C{chart}", lw=1.2,
                label=None if chart in labelled else _chart_label(motion, chart))
        labelled.add(chart)
    ax.plot(*s[:1].T, "*", color="k", ms=11, label="start")
    if switches and motion.solution.switches:
        marks = sphere_coordinates(motion, [sw.time for sw in motion.solution.switches])[:, :3]
        ax.plot(*marks.T, "x", color="k", ms=5, linestyle="none", label="chart switches", gid=SWITCH_GID)
    for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        set_lim(-1, 1)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("$s_1$")
    ax.set_ylabel("$s_2$")
    ax.set_zlabel("$s_3$")
    ax.set_title(f"path on $S^{{{n - 2}}}$ (chart-0 sphere coordinates" + (")" if n == 4 else ", first 3 of n-1)"))
    ax.legend(fontsize="x-small")
    return ax


def draw_energy_error(ax: Axes, motion: ChainMotion) -> Axes:
    """Draw the relative energy error ``|E(t) - E(0)| / E(0)`` of the solver's record against ``t`` (log scale).

    The record is the solver's own (every step, or every segment end with
    ``SaveAt(dense=False)``), the differences taken in the working precision
    (:meth:`manifold.GeodesicSolution.energy_deviations`); exact zeros are
    not drawn on the log scale.  Chart switches are thin grey vertical lines
    (``gid`` :data:`SWITCH_GID`).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.
    """
    sol = motion.solution
    t = np.array([float(x) for x in sol.energy_times])
    err = sol.energy_deviations()
    shown = err > 0
    ax.semilogy(t[shown], err[shown], ".-", color="C0", ms=2, lw=0.6, label="$|E - E_0| / E_0$")
    for sw in sol.switches:
        ax.axvline(sw.time, color="0.8", lw=0.5, zorder=0, gid=SWITCH_GID)
    ax.set_xlabel("t")
    ax.set_ylabel("relative energy error")
    ax.set_title(f"energy error (max {sol.relative_energy_error:.1e}; grey: switches)")
    return ax


def draw_chart_timeline(ax: Axes, motion: ChainMotion) -> Axes:
    """Draw which chart integrated the motion when: one bar per stay in a chart, at its row; switches as lines.

    Row ``i`` is chart ``i`` of the atlas (labelled with its id), coloured
    ``C<i>`` as in :func:`draw_sphere_path`; a segment integrated in hinge
    coordinates (no chart) sits in an extra row ``-1``.  Each switch is a
    vertical line from its old chart's row to its new one at the switch time
    (``gid`` :data:`SWITCH_GID`).

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.
    """
    sol = motion.solution
    ids = _atlas_ids(motion)
    rows = [-1 if seg.chart is None else seg.chart for seg in sol.segments]
    first = [k for k in range(len(rows)) if k == 0 or rows[k] != rows[k - 1]]  # an angle wrap keeps the chart
    for k, last in zip(first, first[1:] + [len(rows)]):
        ax.plot([float(sol.segments[k].t_start), float(sol.segments[last - 1].t_end)], [rows[k], rows[k]], "-", lw=6,
                solid_capstyle="butt", color="0.5" if rows[k] < 0 else f"C{rows[k]}")
    for sw in sol.switches:
        ax.plot([sw.time, sw.time], [sw.from_chart, sw.to_chart], "-", color="k", lw=0.6, gid=SWITCH_GID)
    ticks = ([-1] if -1 in rows else []) + list(range(len(ids)))
    ax.set_yticks(ticks, (["hinge space"] if -1 in rows else []) + [str(i) for i in ids])
    ax.set_ylim(min(ticks) - 0.6, len(ids) - 0.4)
    ax.set_xlabel("t")
    ax.set_title(f"active chart ({sol.n_switches} switches)")
    return ax


#: Default frames and frames per second of :func:`animation` and :func:`animate`: a 5 s clip (150 frames at 25 fps
#: before; with the palette of :func:`animate` the README example's GIF went from 5.1 MB to 0.28 MB).
FRAMES, FPS = 100, 20


def _scene(motion: ChainMotion, times: ArrayLike | None, frames: int, sphere: bool | None,
           fig: Figure | None) -> tuple[Figure, NDArray, Any]:
    """The figure of :func:`animation`, its frame times and ``update(k)`` (draws frame ``k``, returns the artists
    that move: the rods, the title, the point on the sphere)."""
    from matplotlib.figure import Figure

    ts = _times(motion, times, _integer("frames", frames, 2))
    sphere = motion.chain.n >= 4 and motion.chain.has_atlas if sphere is None else sphere
    L = motion.chain.L
    p = _full_chain(motion(ts)[0], L)
    charts = _active_charts(motion, ts)
    if fig is None:
        fig = Figure(figsize=(10.0 if sphere else 5.5, 4.8))
    ax = fig.add_subplot(1, 2 if sphere else 1, 1)
    pad = 0.15
    ax.set_xlim(min(0.0, p.real.min()) - pad, max(L, p.real.max()) + pad)
    ax.set_ylim(p.imag.min() - pad, p.imag.max() + pad)
    ax.set_aspect("equal")
    ax.plot([0, L], [0, 0], "k^", ms=9)
    (rods,) = ax.plot([], [], "-o", lw=2, ms=4)
    artists: list[Any] = [rods, ax.title]
    if sphere:
        ax3 = fig.add_subplot(1, 2, 2, projection="3d")
        draw_sphere_path(ax3, motion, np.linspace(ts.min(), ts.max(), 2000), switches=False)  # smooth, not per frame
        s = sphere_coordinates(motion, ts)[:, :3]
        (dot,) = ax3.plot(*s[:1].T, "o", color="k", ms=7)
        artists.append(dot)

    def update(k: int) -> list[Any]:
        rods.set_data(p[k].real, p[k].imag)
        rods.set_color(f"C{max(int(charts[k]), 0)}")
        ax.set_title(_title(motion, f"{ts[k]:7.2f}", int(charts[k])))
        if sphere:
            dot.set_data_3d(*s[k : k + 1].T)
        return artists

    update(0)
    fig.tight_layout()
    return fig, ts, update


def animation(
    motion: ChainMotion,
    times: ArrayLike | None = None,
    *,
    frames: int = FRAMES,
    fps: int = FPS,
    sphere: bool | None = None,
    fig: Figure | None = None,
) -> FuncAnimation:
    """The moving chain as a matplotlib ``FuncAnimation`` (show it in a notebook with ``.to_jshtml()``).

    Frame ``k`` draws the chain at ``times[k]``, coloured by the chart active
    there (``C<chart>``), and, with ``sphere``, the point moving along the
    path of :func:`draw_sphere_path`.  The axes keep one scale for all frames.

    Parameters
    ----------
    motion
        A solved motion with dense output.
    times
        Frame times within the solved span (default: ``frames`` evenly spaced over it).
    frames
        Number of default frames, ``>= 2`` (default :data:`FRAMES`).
    fps
        Frames per second (the delay between frames when shown; default :data:`FPS`).
    sphere
        Add the configuration-sphere panel (default: when ``n >= 4`` and the
        chain has an atlas; without one, frames are coloured ``C0``).
    fig
        The ``Figure`` to draw on (default: a new one, outside ``pyplot``).

    Returns
    -------
    matplotlib.animation.FuncAnimation
    """
    from matplotlib.animation import FuncAnimation

    fps = _integer("fps", fps, 1)
    fig, ts, update = _scene(motion, times, frames, sphere, fig)
    return FuncAnimation(fig, update, frames=len(ts), interval=1000.0 / fps, blit=False)


def animate(motion: ChainMotion, path: str | Path, *, dpi: float = 80.0, **kwargs: Any) -> Path:
    """Write the animation of ``motion`` (:func:`animation`) to ``path``: ``.gif`` (Pillow) or ``.mp4`` (ffmpeg).

    ``animate(motion, "motion.gif")`` is all it takes.  A GIF's frames are
    blitted: the still parts (axes, the path on the sphere) are drawn once and
    each frame only redraws what moves; they share one palette of at most
    :data:`GIF_COLORS` colours, without dithering, so that Pillow stores only
    the pixels that change from frame to frame.  The README example (n = 5,
    the sphere panel, 100 frames) took 1.4 s of CPU and 0.28 MB, where
    matplotlib's own writer, redrawing every frame, took 36 s and 5.1 MB for
    its former 150 frames (``benchmarks/animate_cost.py``).

    Parameters
    ----------
    motion
        A solved motion with dense output.
    path
        File to write; its suffix chooses the writer: ``.gif`` (Pillow, always
        available) or ``.mp4`` (matplotlib's ``FFMpegWriter``, needs the
        ``ffmpeg`` program on the ``PATH``).
    dpi
        Resolution of the frames.
    **kwargs
        Passed to :func:`animation` (``times``, ``frames``, ``fps``, ``sphere``, ``fig``).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    ValueError
        If the suffix is neither ``.gif`` nor ``.mp4``.
    RuntimeError
        For ``.mp4`` without ffmpeg.
    """
    dpi = check_real("dpi", dpi, positive=True)
    path = Path(path)
    fps = kwargs.pop("fps", FPS)
    writer = animation_writer(path, fps)
    if path.suffix.lower() == ".mp4":
        animation(motion, fps=fps, **kwargs).save(path, writer=writer, dpi=dpi)
        return path
    frames = kwargs.pop("frames", FRAMES)
    fig, ts, update = _scene(motion, kwargs.pop("times", None), frames, kwargs.pop("sphere", None),
                             kwargs.pop("fig", None))
    if kwargs:
        raise TypeError(f"animate got unexpected keyword arguments {sorted(kwargs)}")
    _write_gif(path, _blitted_frames(fig, update, len(ts), dpi), fps)
    return path


#: Colours of an animated GIF's one palette: the chart colours, black, greys and their anti-aliased blends.
GIF_COLORS = 64


def _blitted_frames(fig: Figure, update: Any, n: int, dpi: float) -> Any:
    """RGB frames ``(H, W, 3)`` of ``update(0), ..., update(n - 1)``: the figure drawn once without the moving
    artists, then per frame that background restored and only the moving artists drawn on it (Agg)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig.set_dpi(dpi)
    canvas = FigureCanvasAgg(fig)
    moving = update(0)
    for artist in moving:
        artist.set_animated(True)  # left out of canvas.draw(): the background
    try:
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
        for k in range(n):
            canvas.restore_region(background)
            for artist in update(k):
                fig.draw_artist(artist)
            yield np.asarray(canvas.buffer_rgba())[..., :3].copy()
    finally:
        for artist in moving:
            artist.set_animated(False)


def _write_gif(path: Path, frames: Any, fps: int) -> None:
    """Frames to an animated GIF with one palette (from the first, last and middle frames), not dithered."""
    from PIL import Image

    images = [Image.fromarray(f) for f in frames]
    sample = Image.new("RGB", (images[0].width, 3 * images[0].height))
    for row, k in enumerate((0, len(images) // 2, len(images) - 1)):
        sample.paste(images[k], (0, row * images[0].height))
    palette = sample.quantize(colors=GIF_COLORS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    quantized = [im.quantize(palette=palette, dither=Image.Dither.NONE) for im in images]
    quantized[0].save(path, save_all=True, append_images=quantized[1:], duration=1000.0 / fps, loop=0)


def animation_writer(path: str | Path, fps: int = FPS) -> Any:
    """The matplotlib writer for ``path``'s suffix: ``PillowWriter`` for ``.gif``, ``FFMpegWriter`` for ``.mp4``.

    Raises
    ------
    ValueError
        If the suffix is neither ``.gif`` nor ``.mp4``.
    RuntimeError
        For ``.mp4`` when ``ffmpeg`` is not on the ``PATH``.
    """
    from matplotlib import animation as mpl_animation

    fps = _integer("fps", fps, 1)
    suffix = Path(path).suffix.lower()
    if suffix == ".gif":
        return mpl_animation.PillowWriter(fps=fps)
    if suffix == ".mp4":
        if not mpl_animation.writers.is_available("ffmpeg"):
            raise RuntimeError(f"writing {str(path)!r} needs ffmpeg on the PATH (matplotlib's FFMpegWriter), and "
                               "none was found: install ffmpeg, or write a .gif (Pillow, always available)")
        return mpl_animation.FFMpegWriter(fps=fps)
    raise ValueError(f"path must end in .gif (Pillow) or .mp4 (ffmpeg), got {str(path)!r}")
