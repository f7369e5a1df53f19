"""One command for the whole study: ``python -m benchmarks.study [--quick | --full] [--out DIR] [--only S,...]``.

``--quick`` (minutes; what CI runs through the tests) uses n = 4, short
horizons and a long-double reference; ``--full`` (the docs page; about half an
hour on 2 cores) uses n = 4 and 6 over T = 100 against a real128 reference,
long runs to T = 1e4 and sizes n = 3..10.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import heyoka as hy
import numpy as np

from . import experiments as X
from . import report

QUICK = {"wp": [(4, 40.0)], "long_T": 100.0, "size": [3, 4, 5], "size_T": 2.0, "misses": [0.0], "prec_T": 2.0}
FULL = {"wp": [(4, 100.0), (6, 100.0)], "long_T": 1e4, "size": list(range(3, 11)), "size_T": 5.0,
        "misses": [0.0, 1e-6], "prec_T": 10.0}


SECTIONS = ("work_precision", "long_run", "poles", "circle", "precision", "size")


def run(mode: str, only: tuple[str, ...] = SECTIONS, previous: dict | None = None) -> dict:
    """Run the study's ``only`` sections; the others are kept from ``previous`` results."""
    cfg = QUICK if mode == "quick" else FULL
    quick = mode == "quick"
    hy.llvm_state.set_diskcache_enabled(False)  # compile times are part of what we measure
    results = dict(previous or {})
    results.update({"mode": mode, "cores": os.cpu_count()})
    stamp = time.perf_counter()

    def step(label: str) -> None:
        print(f"[{time.perf_counter() - stamp:7.1f} s] {label}", flush=True)

    if "work_precision" in only:
        results["work_precision"] = []
        for n, T in cfg["wp"]:
            step(f"work-precision n = {n}, T = {T:g}")
            results["work_precision"].append(X.work_precision(n, T, quick=quick, repeats=3 if quick else 2))
    if "long_run" in only:
        step(f"long runs to T = {cfg['long_T']:g}")
        results["long_run"] = X.long_run(4, cfg["long_T"], quick=quick)
    if "poles" in only:
        results["poles"] = []
        for miss in cfg["misses"]:
            step(f"through a pole, miss = {miss:g}")
            results["poles"].append(X.through_pole(miss=miss))
    if "circle" in only:
        step("through t = +-pi/2")
        results["circle"] = X.through_circle_pole()
    if "precision" in only:
        step("precision")
        results["precision"] = X.precision_cost(T=cfg["prec_T"], quick=quick)
    if "size" in only:
        step(f"size n = {cfg['size']}")
        results["size"] = X.size_cost(cfg["size"], T=cfg["size_T"])
    results["conclusions"] = conclusions(results)
    step("done")
    return results


def conclusions(res: dict) -> str:
    """Plain-language answers, each computed from the numbers above it."""
    out = []
    for wp in res["work_precision"]:
        rs = X.speed_ratio_at_equal_error(wp["rows"], report.OURS, "scipy DOP853 atlas")
        ours = [r for r in wp["rows"] if r["method"] == report.OURS]
        dop = [r for r in wp["rows"] if r["method"] == "scipy DOP853 atlas" and not r["failed"]]
        best_ours, best_dop = min(r["hinge"] for r in ours), min(r["hinge"] for r in dop)
        ratio = ", ".join(f"{r:.1f}x at {e:.0e}" for e, r in rs) or "no overlap"
        verdict = ("ours is faster" if rs and min(r for _, r in rs) > 1 else
                   "DOP853 is faster: a Taylor step costs ~order^2 times the expression size, which grows like "
                   "n^3, while DOP853 pays a per-step overhead that does not grow" if rs and max(r for _, r in rs) < 1
                   else "mixed")
        out.append(f"* **Speed at equal error (n = {wp['n']}).** DOP853's wall time divided by ours, on the same "
                   f"chart ODE and switch rule: {ratio}; {verdict}. Our best error is {best_ours:.0e}, "
                   f"DOP853's {best_dop:.0e} (the geodesic flow amplifies errors exponentially over long horizons: "
                   f"the demo measures e^(0.134 t) for n = 4).")
    lr = res["long_run"]["curves"]
    s = lr[report.OURS]["slope"]
    law = "closer to Brouwer's law (slope 0.5, error ~ sqrt(t)) than to linear drift (slope 1)" if s < 0.75 \
        else "a linear drift"
    out.append(f"* **Energy error growth.** float64 Taylor in the atlas: log-log slope {s:.2f} of the running maximum "
               f"over three decades, {law}; final {max(lr[report.OURS]['energy_error']):.0e}. "
               + "; ".join(f"{k}: slope {c['slope']:.2f}" + (" (failed)" if c["failed"] else "")
                           for k, c in lr.items() if k != report.OURS) + ".")
    drift = {k: c["drift"] for k, c in lr.items()}
    out.append(f"* **Drift off the constraints (T = {res['long_run']['T']:g}).** Max rod-length error: "
               + "; ".join(f"{k} {v:.0e}" for k, v in drift.items())
               + ". Chart methods close every rod by construction; the unprojected ambient integration drifts.")
    for pole in res["poles"]:
        r = pole["runs"]
        single = r["single chart Taylor (chart 0)"]
        out.append(f"* **Through a pole (miss {pole['miss']:g}).** Ours: hinge error {r[report.OURS]['hinge']:.0e}; "
                   f"single chart: {single['failed'] or 'hinge error %.0e' % single['hinge']}; "
                   + "; ".join(f"{k}: {v['failed'] or 'hinge error %.0e' % v['hinge']}" for k, v in r.items()
                               if k not in (report.OURS, "single chart Taylor (chart 0)")) + ".")
    c = res["circle"]
    out.append(f"* **Through t = ±pi/2.** Polynomial sinc: {c['polynomial sinc (ours)']['status']} "
               f"({c['polynomial sinc (ours)']['steps']} steps); plain sin(x)/x from the crossing: "
               f"{c['plain sin(x)/x']['status']}; from t = 0.3: {c['plain sin(x)/x, off the pole']['status']}.")
    p = {r["precision"]: r for r in res["precision"]}
    f64 = p["float64"]["wall_per_time"]
    out.append("* **Cost of precision.** " + "; ".join(
        f"{k}: {r['wall_per_time'] / f64:.1f}x float64's time per unit time, energy error {r['energy_error']:.0e}"
        for k, r in p.items()) + ".")
    e = res["size"]["exponents"]
    out.append(f"* **Cost against size.** Wall time per unit time grows like n^{e['wall_per_time']:.1f}, "
               f"time per step like n^{e['ms_per_step']:.1f}, cold compile like n^{e['compile']:.1f} (n >= 4).")
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="minutes; n = 4, short horizons")
    g.add_argument("--full", action="store_true", help="the docs page (default)")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default docs/ for --full, out/study-quick for --quick)")
    parser.add_argument("--render", type=Path, default=None, help="re-render figures and page from a benchmarks.json")
    parser.add_argument("--only", default=None,
                        help=f"comma-separated sections to re-run, the rest kept from OUT/benchmarks.json: {', '.join(SECTIONS)}")
    args = parser.parse_args()
    mode = "quick" if args.quick else "full"
    out = args.out or (Path("docs") if mode == "full" else Path("out/study-quick"))
    np.seterr(all="ignore")  # failing methods are part of the study
    if args.render and args.only:
        parser.error("--render re-renders a finished run; it takes no --only")
    if args.render:
        results = json.loads(args.render.read_text())
        results["conclusions"] = conclusions(results)
    elif args.only:
        only = tuple(args.only.split(","))
        unknown = sorted(set(only) - set(SECTIONS))
        if unknown:
            parser.error(f"unknown sections {unknown}; choose from {', '.join(SECTIONS)}")
        if not (out / "benchmarks.json").is_file():
            parser.error(f"--only needs a previous run in {out / 'benchmarks.json'}: run without --only first")
        previous = json.loads((out / "benchmarks.json").read_text())
        if previous["mode"] != mode:
            parser.error(f"{out / 'benchmarks.json'} holds a {previous['mode']} run, not {mode}")
        results = run(mode, only, previous)
    else:
        results = run(mode)
    page = report.write(results, out)
    print(f"wrote {page}")


if __name__ == "__main__":
    main()
