"""Figures and the Markdown page of the study, from the experiments' plain data."""

from __future__ import annotations

import json
import platform
from pathlib import Path

import heyoka as hy
import matplotlib
import numpy as np
import scipy

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .experiments import speed_ratio_at_equal_error  # noqa: E402

#: Sections of ``benchmarks.md`` that other scripts write, kept when the study rewrites the page.
PEERS_SECTION = "## Against the strongest peers"  # written by benchmarks.peers
SECOND_MACHINE_SECTION = "## The same peers on a second machine"  # benchmarks.peers runs elsewhere, by hand
KEPT_SECTIONS = (PEERS_SECTION, SECOND_MACHINE_SECTION)

OURS = "atlas Taylor (ours)"


def _save(fig, path: Path) -> None:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _finish(fig, ax, path: Path, title: str, xlabel: str, ylabel: str | None = None,
            grid: bool = True, legend_size: str = "x-small") -> None:
    """Label, grid and legend of a one-panel figure, then save it."""
    ax.set_xlabel(xlabel)
    if ylabel:
        ax.set_ylabel(ylabel)
    ax.set_title(title)
    if grid:
        ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=legend_size)
    _save(fig, path)


def _style(name: str) -> dict:
    return {"marker": "o", "lw": 2.5 if name.startswith("atlas Taylor") else 1.2, "ms": 4}


def fig_work_precision(wp: dict, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 5))
    methods = sorted({r["method"] for r in wp["rows"]})
    for k, name in enumerate(methods):
        rows = sorted((r for r in wp["rows"] if r["method"] == name), key=lambda r: r["wall"])
        ok = [r for r in rows if not r["failed"] and np.isfinite(r["hinge"])]
        if ok:
            ax.loglog([r["wall"] for r in ok], [max(r["hinge"], 1e-17) for r in ok], label=name, color=f"C{k}", **_style(name))
        failed = [r for r in rows if r["failed"] or not np.isfinite(r["hinge"])]
        for j, r in enumerate(failed):
            ax.plot(r["wall"], 1.0, "x", color=f"C{k}", ms=10, label=f"{name}: failed" if j == 0 else None)
    _finish(fig, ax, path, f"work-precision, n = {wp['n']}, L = {wp['L']}, T = {wp['T']:g}",
            "wall time [s]", "max hinge error vs reference")


def fig_long_run(lr: dict, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 5))
    for k, (name, c) in enumerate(lr["curves"].items()):
        t, e = np.array(c["t"]), np.array(c["energy_error"])
        sel = (t > 0) & (e > 0)
        label = f"{name} (slope {c['slope']:.2f})" + (" - failed" if c["failed"] else "")
        ax.loglog(t[sel], np.maximum.accumulate(e[sel]) if sel.any() else e[sel], label=label, color=f"C{k}",
                  lw=2.5 if name == OURS else 1.2)
    t = np.geomspace(1, lr["T"], 10)
    ax.loglog(t, 1e-16 * np.sqrt(t), "k:", lw=1, label="sqrt(t) (Brouwer)")
    ax.loglog(t, 1e-16 * t, "k--", lw=1, label="t (linear drift)")
    _finish(fig, ax, path, f"long runs, n = {lr['n']}, L = {lr['L']}", "t", "max relative energy error up to t")


def fig_pole(pole: dict, path: Path) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    center = np.array(pole["pole_sphere"])
    # two unit vectors orthogonal to the pole direction span the picture plane
    e1 = np.cross(center, [0.0, 0.0, 1.0] if abs(center[2]) < 0.9 else [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(center, e1)
    for k, (name, r) in enumerate(pole["runs"].items()):
        s = np.array(r["sphere"])
        lw = 2.5 if name == OURS else 1.2
        if len(s):
            axes[0].plot(s @ e1, s @ e2, color=f"C{k}", lw=lw, label=name + (" (failed)" if r["failed"] else ""))
        t = np.array(r["t"])
        if len(t) > 1:
            axes[1].semilogy(t[1:], np.maximum(r["energy_error"][1:], 1e-17), color=f"C{k}", lw=lw, label=name)
            axes[2].semilogy(t[1:], np.maximum(r["hinge_error"][1:], 1e-17), color=f"C{k}", lw=lw, label=name)
        if r["failed"] and len(t):
            for ax in axes[1:]:
                ax.axvline(t[-1], color=f"C{k}", ls=":", lw=1)
    axes[0].plot(0, 0, "k*", ms=12, label="chart 0's pole")
    axes[0].set_aspect("equal")
    axes[0].set_title("path near the pole (sphere coordinates)")
    axes[0].legend(fontsize="x-small")
    axes[1].set_title("relative energy error")
    axes[2].set_title("hinge error vs reference")
    for ax in axes[1:]:
        ax.set_xlabel("t (pole at t = %.1f)" % (pole["T"] / 2))
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"through a suspension pole, n = {pole['n']}, L = {pole['L']}, miss = {pole['miss']:g}")
    _save(fig, path)


def fig_circle(circ: dict, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, label in enumerate(("polynomial sinc (ours)", "plain sin(x)/x", "plain sin(x)/x, off the pole")):
        r = circ[label]
        if r["t"]:
            ax.semilogy(r["t"], r["h"], ".", ms=3, color=f"C{k}", label=f"{label}: {r['status']}")
        else:
            ax.plot([], [], color=f"C{k}", label=f"{label}: {r['status']}")
    for m in range(-1, int(circ["T"] / np.pi) + 2):
        ax.axvline(np.pi / 2 + m * np.pi, color="0.85", lw=0.6, zorder=0)
    _finish(fig, ax, path,
            f"n = 3 through t = ±pi/2 (grey: crossings of the chart angle at unit chart speed), L = {circ['L']}",
            "time", "Taylor step size", grid=False)


def fig_size(size: dict, path: Path) -> None:
    fig, ax = plt.subplots(figsize=(7, 4.5))
    n = np.array([r["n"] for r in size["rows"]])
    for key, label in [("compile", "cold compile [s]"), ("wall_per_time", "wall per unit time [s]"),
                       ("ms_per_step", "ms per Taylor step")]:
        ax.loglog(n, [r[key] for r in size["rows"]], "o-", label=f"{label}, ~ n^{size['exponents'][key]:.1f}")
    ax.set_xticks(n, [str(k) for k in n])
    _finish(fig, ax, path, "cost against size", "n (rods)", legend_size="small")


def _wp_table(wp: dict) -> str:
    lines = ["| method | knob | wall s | steps (ambient: RHS evaluations) | hinge error | energy error | rod drift | failure |",
             "|---|---|---|---|---|---|---|---|"]
    for r in wp["rows"]:
        knob = "default" if r["knob"] is None else f"{r['knob']:g}"
        lines.append(f"| {r['method']} | {knob} | {r['wall']:.3f} | {r['steps']} | {r['hinge']:.1e} | "
                     f"{r['energy']:.1e} | {r['drift']:.1e} | {r['failed'] or ''} |")
    return "\n".join(lines)


def _ratios_text(wp: dict) -> str:
    rs = speed_ratio_at_equal_error(wp["rows"], OURS, "scipy DOP853 atlas")
    if not rs:
        return "no overlap of the error ranges"
    return ", ".join(f"{r:.1f}x at error {e:.0e}" for e, r in rs)


def _section_span(lines: list[str], heading: str) -> tuple[int, int] | None:
    """Line range of the section that starts at the line ``heading``, up to the next ``## `` heading."""
    starts = [k for k, line in enumerate(lines) if line.rstrip("\n") == heading]
    if not starts:
        return None
    end = next((k for k in range(starts[0] + 1, len(lines)) if lines[k].startswith("## ")), len(lines))
    return starts[0], end


def section(page: str, heading: str) -> str | None:
    """The section of ``page`` under the line ``heading`` (heading included), or ``None``."""
    lines = page.splitlines(keepends=True)
    span = _section_span(lines, heading)
    return None if span is None else "".join(lines[span[0] : span[1]])


def replace_section(page: str, heading: str, body: str) -> str:
    """``page`` with its section ``heading`` replaced by ``body`` (which starts with ``heading``), or ``body``
    appended if there is none."""
    lines = page.splitlines(keepends=True)
    span = _section_span(lines, heading)
    if span is None:
        return page.rstrip("\n") + "\n\n" + body
    rest = "".join(lines[span[1] :])
    return "".join(lines[: span[0]]) + body + ("\n" + rest if rest else "")


def write(results: dict, out: Path) -> Path:
    """Write figures, the JSON data and ``benchmarks.md`` into ``out``; return the page's path."""
    out.mkdir(parents=True, exist_ok=True)
    figs = out / "figures"
    figs.mkdir(exist_ok=True)
    (out / "benchmarks.json").write_text(json.dumps(results, indent=1, default=float))
    parts = [f"# Speed and accuracy study ({results['mode']} mode)\n",
             f"Regenerate: `python -m benchmarks.study --{results['mode']}` (one section: add `--only precision`, "
             f"keeping the others from `benchmarks.json`). Machine: {platform.machine()}, "
             f"{results['cores']} cores, Python {platform.python_version()}, numpy {np.__version__}, "
             f"scipy {scipy.__version__}, heyoka {hy.__version__}. Wall times are one run each on a shared "
             "machine: read the ratios, not the seconds.\n"]
    for wp in results["work_precision"]:
        name = f"wp_n{wp['n']}.png"
        fig_work_precision(wp, figs / name)
        parts += [f"## Work-precision, n = {wp['n']}\n",
                  f"Unit-energy generic start, L = {wp['L']}, T = {wp['T']:g}; errors are the largest hinge "
                  f"distance to the {wp['reference']} heyoka reference over {len(wp['rows'])} runs "
                  f"(reference took {wp['reference_wall']:.1f} s). DOP853 time / our time at equal error: "
                  f"{_ratios_text(wp)}.\n", f"![work-precision n = {wp['n']}](figures/{name})\n", _wp_table(wp), ""]
    if "long_run" in results:
        lr = results["long_run"]
        fig_long_run(lr, figs / "long_run.png")
        parts += ["## Long runs: energy error against time\n", "![long runs](figures/long_run.png)\n",
                  "| method | wall s | final max energy error | log-log slope | rod drift | failure |",
                  "|---|---|---|---|---|---|"]
        for name, c in lr["curves"].items():
            final = max(c["energy_error"]) if c["energy_error"] else float("nan")
            parts.append(f"| {name} | {c['wall']:.1f} | {final:.1e} | {c['slope']:.2f} | {c['drift']:.1e} | "
                         f"{c['failed'] or ''} |")
        parts.append("")
    for pole in results.get("poles", []):
        name = f"pole_miss{pole['miss']:g}.png"
        fig_pole(pole, figs / name)
        parts += [f"## Through a suspension pole (miss = {pole['miss']:g})\n", f"![pole](figures/{name})\n",
                  "| method | hinge error | energy error | failure |", "|---|---|---|---|"]
        parts += [f"| {k} | {r['hinge']:.1e} | {r['energy']:.1e} | {r['failed'] or ''} |" for k, r in pole["runs"].items()]
        parts.append("")
    if "circle" in results:
        fig_circle(results["circle"], figs / "circle_pole.png")
        c = results["circle"]
        parts += ["## Through t = ±pi/2 of the circle level\n", "![circle](figures/circle_pole.png)\n"]
        parts += [f"* {k}, from t = {c[k]['t0']:.2f}: {c[k]['status']}, {c[k]['steps']} steps"
                  for k in ("polynomial sinc (ours)", "plain sin(x)/x", "plain sin(x)/x, off the pole")]
        parts.append("")
    if "precision" in results:
        parts += ["## Cost of precision\n", "| precision | T | wall s | wall per unit time | steps | switches | energy error |",
                  "|---|---|---|---|---|---|---|"]
        parts += [f"| {r['precision']} | {r['T']:g} | {r['wall']:.2f} | {r['wall_per_time']:.3f} | {r['steps']} | "
                  f"{r['switches']} | {r['energy_error']:.1e} |" for r in results["precision"]]
        parts.append("")
    if "size" in results:
        fig_size(results["size"], figs / "size.png")
        s = results["size"]
        parts += ["## Cost against size\n", "![size](figures/size.png)\n",
                  "| n | cold compile s | wall per unit time s | Taylor steps per unit time | ms per step | decomposition |",
                  "|---|---|---|---|---|---|"]
        parts += [f"| {r['n']} | {r['compile']:.1f} | {r['wall_per_time']:.4f} | {r['steps_per_time']:.1f} | "
                  f"{r['ms_per_step']:.2f} | {r['decomposition']} |" for r in s["rows"]]
        parts.append("\nFitted exponents (n >= 4): " + ", ".join(f"{k} ~ n^{v:.2f}" for k, v in s["exponents"].items()) + "\n")
    if "conclusions" in results:
        parts += ["## Conclusions\n", results["conclusions"], ""]
    page = out / "benchmarks.md"
    text = "\n".join(parts)
    if page.is_file():  # sections other scripts write (benchmarks.peers), or runs elsewhere, are kept
        for heading in KEPT_SECTIONS:
            kept = section(page.read_text(), heading)
            if kept is not None:
                text = replace_section(text, heading, kept)
    page.write_text(text)
    return page
